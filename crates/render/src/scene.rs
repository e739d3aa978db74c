//! The scene at render time: acceleration structure, materials, lights and film, built once
//! from a validated [`SceneDesc`] and shared read-only by every thread. The camera is not part
//! of it: a camera-only fly-through builds the scene once and renders every frame from it.

use glam::{Mat2, Mat3A, Vec2, Vec3A, Vec4};
use tessera_scene::{Coverage, CoverageMode, FilmDesc, IntegratorDesc, LightDesc, SceneDesc};

use crate::bsdf::{self, Bsdf, BsdfFlags};
use crate::bssrdf::Subsurface;
use crate::filter::Filter;
use crate::geometry::{Accel, Prim, PrimHit};
use crate::light::{
    DirectionalLight, EnvironmentLight, Light, LightSample, LightSet, PointLight, ShadowTarget,
    SphereLight, SpotLight, Target, TriangleLight,
};
use crate::math::{Frame, offset_ray_origin};
use crate::ray::Ray;
use crate::spectrum::Spectrum;
use crate::texture::{MipMap, Textures};

/// Index meaning "not an emitter".
pub const NO_LIGHT: u32 = u32::MAX;

/// Shadow rays stop this fraction short of their target (pbrt-v4's ShadowEpsilon): the target
/// point is already offset off the emitter by its error bound, this keeps the rounding of the
/// distance itself from registering the emitter as its own occluder. Relative to the segment,
/// so it is scale-free.
const SHADOW_EPSILON: f32 = 1e-4;

/// Most surfaces a ray passes through where they are not there (cut-out or blended coverage)
/// before the next one counts as a hit: a bound on work through dense foliage.
const MAX_HOLES: u32 = 256;

/// A material: its BSDF and how to orient it, and for a translucent one what lies beneath
/// its interface.
#[derive(Debug)]
pub struct Material {
    pub bsdf: Box<dyn Bsdf>,
    pub flags: BsdfFlags,
    pub subsurface: Option<Box<Translucent>>,
    /// A textured material builds its BSDF per hit ([`Material::bsdf_at`]); `bsdf` is then
    /// its untextured factors' (its flags hold for every hit).
    pub textured: Option<Box<TexturedPbr>>,
    /// σa of an absorbing interior (per scene unit), for glass that tints what it passes.
    pub absorption: Option<Spectrum>,
}

/// A tangent-space normal map: its texture, the scale on x and y, and `axes`, which turn a
/// texel's (x, y) into the tangent frame's where the texture coordinates are transformed
/// (KHR_texture_transform): the texel's x points along increasing s, its y up the image
/// (decreasing t); each is carried back to the mesh's (u, v) by the transform's inverse.
#[derive(Debug)]
struct NormalMap {
    map: MipMap,
    scale: f32,
    axes: Mat2,
}

impl NormalMap {
    fn new(map: MipMap, scale: f32, transform: Mat2) -> Self {
        let inverse = transform.inverse();
        let a = inverse.col(0).normalize_or_zero();
        let b = inverse.col(1).normalize_or_zero();
        // Texel (x, y) is the direction a·x − b·y in (u, v); the tangent frame's y is −v.
        NormalMap {
            map,
            scale,
            axes: Mat2::from_cols(Vec2::new(a.x, -a.y), Vec2::new(-b.x, b.y)),
        }
    }
}

/// The glTF metallic-roughness BRDF with image textures multiplying its factors.
#[derive(Debug)]
pub struct TexturedPbr {
    /// The BRDF of the factors alone.
    factors: bsdf::MetallicRoughness,
    base_color_map: Option<MipMap>,
    metallic_roughness_map: Option<MipMap>,
    /// A tangent-space normal map and its scale on x and y (applied where the hit is found).
    normal_map: Option<NormalMap>,
    /// Where the surface is there at all (tested where rays are traced).
    coverage: Option<Coverage>,
}

impl TexturedPbr {
    /// The BSDF at texture coordinates `uv` (both sets) for a footprint `width` wide (uv
    /// units of each).
    #[inline]
    fn at(&self, uv: Uv, width: UvWidth) -> bsdf::MetallicRoughness {
        let base = self
            .base_color_map
            .as_ref()
            .map_or(Vec3A::ONE, |m| Vec3A::from(m.at(uv, width).truncate()));
        let (metallic, roughness) = self
            .metallic_roughness_map
            .as_ref()
            .map_or((1.0, 1.0), |m| {
                let t = m.at(uv, width);
                (t.z, t.y)
            });
        self.factors.scaled(base, metallic, roughness)
    }

    /// Whether the surface is there at `uv` (footprint `width`) for a ray whose own uniform
    /// number is `u`: coverage α = factor × the base colour texture's alpha, kept where
    /// α ≥ the cutoff (mask) or with probability α (blend).
    #[inline]
    fn covers(&self, uv: Uv, width: UvWidth, u: impl FnOnce() -> f32) -> bool {
        let Some(c) = self.coverage else {
            return true;
        };
        let alpha = c.factor
            * self
                .base_color_map
                .as_ref()
                .map_or(1.0, |m| m.at(uv, width).w);
        match c.mode {
            CoverageMode::Mask { cutoff } => alpha >= cutoff,
            CoverageMode::Blend => u() < alpha,
        }
    }
}

/// The BSDF at one hit: the material's own, one built there from its textures, or the
/// material's own behind the absorbing interior the path crossed to reach the hit.
pub enum HitBsdf<'a> {
    Shared(&'a dyn Bsdf),
    Textured(bsdf::MetallicRoughness),
    Attenuated(Attenuated<'a>),
}

/// A BSDF scaled by the transmittance of the segment by which its hit was reached inside an
/// absorbing object (Beer–Lambert, exp(−σa d)). Every path through the hit contains that
/// segment exactly once, and scatters or connects here through this BSDF: so the segment's
/// transmittance multiplies every such path, in every method, without a medium of its own.
/// (A connection between two points inside the same absorbing object, possible only with
/// rough glass, crosses its interior without it.)
#[derive(Debug)]
pub struct Attenuated<'a> {
    inner: &'a dyn Bsdf,
    transmittance: Spectrum,
}

impl Bsdf for Attenuated<'_> {
    fn flags(&self) -> BsdfFlags {
        self.inner.flags()
    }
    fn eval(&self, wo: Vec3A, wi: Vec3A, mode: bsdf::TransportMode) -> Spectrum {
        self.inner.eval(wo, wi, mode) * self.transmittance
    }
    fn sample(
        &self,
        wo: Vec3A,
        u_lobe: f32,
        u: Vec2,
        mode: bsdf::TransportMode,
    ) -> Option<bsdf::BsdfSample> {
        let mut s = self.inner.sample(wo, u_lobe, u, mode)?;
        s.f *= self.transmittance;
        Some(s)
    }
    fn pdf(&self, wo: Vec3A, wi: Vec3A, mode: bsdf::TransportMode) -> f32 {
        self.inner.pdf(wo, wi, mode)
    }
    fn albedo(&self) -> Spectrum {
        self.inner.albedo()
    }
}

impl<'a> std::ops::Deref for HitBsdf<'a> {
    type Target = dyn Bsdf + 'a;
    #[inline]
    fn deref(&self) -> &Self::Target {
        match self {
            HitBsdf::Shared(b) => *b,
            HitBsdf::Textured(b) => b,
            HitBsdf::Attenuated(b) => b,
        }
    }
}

/// A translucent material's BSSRDF and its exit lobe Sw, the material a path continues with
/// after subsurface transport.
#[derive(Debug)]
pub struct Translucent {
    pub bssrdf: Subsurface,
    pub exit: Material,
}

impl Material {
    /// The material of `kind`, its textures' pyramids built in (or taken from) `textures`.
    pub fn with_textures(kind: &tessera_scene::MaterialKind, textures: &mut Textures) -> Material {
        let mut m = Material::from_desc(kind);
        if let tessera_scene::MaterialKind::MetallicRoughness { textures: maps, .. } = kind
            && !maps.is_empty()
            && let Some(factors) = bsdf::metallic_roughness_of(kind)
        {
            m.textured = Some(Box::new(TexturedPbr {
                factors,
                base_color_map: maps.base_color.as_ref().map(|t| textures.mipmap(t)),
                metallic_roughness_map: maps
                    .metallic_roughness
                    .as_ref()
                    .map(|t| textures.mipmap(t)),
                normal_map: maps
                    .normal
                    .as_ref()
                    .map(|(t, s)| NormalMap::new(textures.mipmap(t), *s, t.transform.matrix2)),
                coverage: maps.coverage,
            }));
        }
        m
    }

    /// The material of `kind` without its textures (tests, tools).
    pub fn from_desc(kind: &tessera_scene::MaterialKind) -> Material {
        let mut m = Material::from_bsdf(bsdf::from_desc(kind));
        if let tessera_scene::MaterialKind::Dielectric { absorption, .. } = *kind
            && absorption.max_element() > 0.0
        {
            m.absorption = Some(Vec3A::from(absorption));
        }
        if let tessera_scene::MaterialKind::Subsurface {
            sigma_s_prime,
            sigma_a,
            eta,
            g,
        } = *kind
        {
            m.subsurface = Some(Box::new(Translucent {
                bssrdf: Subsurface::new(sigma_s_prime, sigma_a, eta, g),
                exit: Material::from_bsdf(Box::new(bsdf::SubsurfaceExit::new(eta))),
            }));
        }
        m
    }

    pub fn from_bsdf(bsdf: Box<dyn Bsdf>) -> Material {
        Material {
            flags: bsdf.flags(),
            bsdf,
            subsurface: None,
            textured: None,
            absorption: None,
        }
    }

    /// The BSDF at hit `si` (built from the textures there, for a textured material; behind
    /// the absorbing interior crossed to reach it, for tinted glass).
    #[inline]
    pub fn bsdf_at(&self, si: &SurfaceInteraction) -> HitBsdf<'_> {
        match (&self.textured, self.absorption) {
            (Some(t), _) => HitBsdf::Textured(t.at(si.uv, si.uv_width)),
            (None, Some(sigma_a)) if si.interior > 0.0 => HitBsdf::Attenuated(Attenuated {
                inner: self.bsdf.as_ref(),
                transmittance: (-sigma_a * si.interior).exp(),
            }),
            (None, _) => HitBsdf::Shared(self.bsdf.as_ref()),
        }
    }

    /// Nothing is scattered: paths end here.
    pub fn is_black(&self) -> bool {
        !self.flags.smooth && !self.flags.specular
    }

    /// The BSDF's local frame at `si` for light leaving toward `wo`. Reflection-only BSDFs are
    /// two-sided: the frame is turned to face `wo`. Transmissive ones keep the normal outward.
    #[inline]
    pub fn frame(&self, si: &SurfaceInteraction, wo: Vec3A) -> Frame {
        let f = Frame::from_normal(si.ns);
        if !self.flags.transmission && wo.dot(si.ns) < 0.0 {
            f.flipped()
        } else {
            f
        }
    }
}

/// The shading normal `ns` turned by a tangent-space normal-map texel `texel` (xyz in [0, 1]
/// encoding [−1, 1], x and y turned by `axes` and scaled by `scale`), in the frame of tangent
/// `t` (xyz, w the bitangent's sign: B = w · ns × T) made orthogonal to `ns` (glTF 2.0
/// §3.9.3, MikkTSpace). Kept as it was where the frame degenerates or the result would face
/// away from `ng`.
#[inline]
fn perturb(ns: Vec3A, ng: Vec3A, t: Vec4, texel: Vec4, scale: f32, axes: Mat2) -> Vec3A {
    let tangent = Vec3A::from(t.truncate());
    let tangent = (tangent - ns * ns.dot(tangent)).normalize_or_zero();
    if tangent == Vec3A::ZERO {
        return ns;
    }
    let bitangent = ns.cross(tangent) * if t.w < 0.0 { -1.0 } else { 1.0 };
    let xy = axes * (Vec2::new(texel.x, texel.y) * 2.0 - Vec2::ONE) * scale;
    let m = Vec3A::new(xy.x, xy.y, texel.z * 2.0 - 1.0);
    let n = (tangent * m.x + bitangent * m.y + ns * m.z).normalize_or_zero();
    if n.dot(ng) > 0.0 { n } else { ns }
}

/// A ray's hit on a surface.
#[derive(Debug, Clone, Copy)]
pub struct SurfaceInteraction {
    pub p: Vec3A,
    pub p_error: Vec3A,
    pub t: f32,
    /// Geometric normal of the front face (the side an emitter emits from).
    pub ng: Vec3A,
    /// Shading normal, in the hemisphere of `ng`.
    pub ns: Vec3A,
    pub material: u32,
    /// Emitter index into the scene's lights, or [`NO_LIGHT`].
    pub light: u32,
    /// Texture coordinates, TEXCOORD_0 and _1 (zero where the surface has none).
    pub uv: Uv,
    /// The width, in uv units of each set, of a camera pixel's footprint at this distance
    /// along the ray (the texture filter's width; an estimate without ray differentials).
    pub uv_width: UvWidth,
    /// How far the ray that found this hit travelled inside the object whose surface it is:
    /// its length if it arrived at the back of the front face (from inside a closed mesh,
    /// wound outward), else 0.
    pub interior: f32,
}

/// Both sets of texture coordinates at a point.
pub type Uv = [Vec2; 2];
/// A footprint's width in each set's units.
pub type UvWidth = [f32; 2];

impl SurfaceInteraction {
    /// The shading normal turned to the side of `w`.
    #[inline]
    pub fn ns_toward(&self, w: Vec3A) -> Vec3A {
        if self.ns.dot(w) < 0.0 {
            -self.ns
        } else {
            self.ns
        }
    }

    /// A ray leaving the surface in direction `d`, from an origin offset past the error bound.
    #[inline]
    pub fn spawn(&self, d: Vec3A) -> Ray {
        Ray::new(offset_ray_origin(self.p, self.p_error, self.ng, d), d)
    }
}

struct MeshRuntime {
    material: u32,
    first_triangle: u32,
    /// The triangles' vertex indices (as wound for the BVH), where vertices carry normals or
    /// texture coordinates.
    indices: Vec<[u32; 3]>,
    /// Per-vertex shading normals, for smooth meshes.
    normals: Option<Vec<Vec3A>>,
    /// Per-vertex texture coordinates, and per triangle √(uv area / world area), for
    /// TEXCOORD_0 and _1.
    uvs: [Option<(Vec<Vec2>, Vec<f32>)>; 2],
    /// Per triangle corner: tangent and bitangent sign, for normal maps.
    tangents: Option<Vec<[Vec4; 3]>>,
}

impl MeshRuntime {
    /// Texture coordinates at barycentrics `b` of triangle `local`, and the width in uv of a
    /// footprint `width` wide in the scene.
    #[inline]
    fn uv(&self, local: usize, b: [f32; 3], width: f32) -> (Uv, UvWidth) {
        let mut uv = [Vec2::ZERO; 2];
        let mut w = [0.0; 2];
        for (k, set) in self.uvs.iter().enumerate() {
            if let Some((uvs, scale)) = set {
                let [i0, i1, i2] = self.indices[local];
                uv[k] = uvs[i0 as usize] * b[0] + uvs[i1 as usize] * b[1] + uvs[i2 as usize] * b[2];
                w[k] = scale[local] * width;
            }
        }
        (uv, w)
    }
}

struct SphereRuntime {
    material: u32,
    light: u32,
}

/// Sizes of what was built, for logs.
#[derive(Debug, Clone, Copy, Default)]
pub struct SceneStats {
    pub triangles: usize,
    pub spheres: usize,
    pub lights: usize,
    pub emissive_triangles: usize,
    /// Bytes of the texture pyramids (each image once).
    pub texture_bytes: usize,
}

pub struct Scene {
    accel: Accel,
    meshes: Vec<MeshRuntime>,
    /// Triangle id → mesh index.
    triangle_mesh: Vec<u32>,
    /// Triangle id → light index or NO_LIGHT.
    triangle_light: Vec<u32>,
    spheres: Vec<SphereRuntime>,
    materials: Vec<Material>,
    pub lights: LightSet,
    pub filter: Filter,
    pub film: FilmDesc,
    pub integrator: IntegratorDesc,
    /// Bounding sphere of all geometry.
    pub center: Vec3A,
    pub radius: f32,
    /// Every mesh and sphere: its bounding sphere and material (projection maps aim at them).
    pub objects: Vec<(Target, u32)>,
    pub stats: SceneStats,
    /// A camera pixel's angular width (radians), for texture footprints.
    pixel_angle: f32,
    /// Whether any material has partial coverage: rays then test it at each hit.
    holes: bool,
}

/// A camera pixel's angular width, for texture footprints: t × this is its width at distance
/// t (the camera of the first frame; a fly-through's keeps its field of view). The pixel's
/// samples already average over it, so the texture filter takes a share: 1/√spp of it, but no
/// less than 1/8 (pbrt-v4 scales its ray differentials alike).
fn pixel_angle(desc: &SceneDesc) -> f32 {
    let share = (1.0 / (desc.integrator.spp.max(1) as f32).sqrt()).max(0.125);
    share * desc.camera.fov_y / desc.film.height.max(1) as f32
}

impl Scene {
    /// Takes the film and integrator settings of `desc`, a description of the same geometry,
    /// materials and lights with other settings (`auto`'s pilots render it smaller, with
    /// other methods and seeds).
    pub fn set_settings(&mut self, desc: &SceneDesc) {
        self.film = desc.film;
        self.filter = Filter::new(desc.film.filter);
        self.integrator = desc.integrator.clone();
        self.pixel_angle = pixel_angle(desc);
    }

    pub fn build(desc: &SceneDesc) -> Scene {
        // Image textures, each image's pyramid once, shared by materials and emitters.
        let mut textures = Textures::default();
        let mut triangles: Vec<[Vec3A; 3]> = Vec::new();
        let mut meshes = Vec::with_capacity(desc.meshes.len());
        let mut triangle_mesh = Vec::new();
        let mut triangle_light = Vec::new();
        let mut lights = Vec::new();
        let mut emissive_triangles = 0;
        let mut objects = Vec::with_capacity(desc.meshes.len() + desc.spheres.len());
        for (mi, m) in desc.meshes.iter().enumerate() {
            let first_triangle = triangles.len() as u32;
            let (lo, hi) = m.positions.iter().fold(
                (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY)),
                |(lo, hi), &p| (lo.min(p.into()), hi.max(p.into())),
            );
            if lo.x <= hi.x {
                let center = 0.5 * (lo + hi);
                let radius = m
                    .positions
                    .iter()
                    .map(|&p| (Vec3A::from(p) - center).length())
                    .fold(0.0f32, f32::max);
                objects.push((Target { center, radius }, m.material));
            }
            let normals: Option<Vec<Vec3A>> = m
                .normals
                .as_ref()
                .map(|n| n.iter().map(|&v| Vec3A::from(v)).collect());
            let mut indices = Vec::with_capacity(m.triangles.len());
            let mut uv_scale = [Vec::new(), Vec::new()];
            let mut tangents = m.tangents.as_ref().map(|t| Vec::with_capacity(t.len()));
            for (ti, &[a, b, c]) in m.triangles.iter().enumerate() {
                let v = [a, b, c].map(|i| Vec3A::from(m.positions[i as usize]));
                let winding = (v[1] - v[0]).cross(v[2] - v[0]);
                let flip = m.faces_against_normals([a, b, c]);
                let (v, idx) = if flip {
                    ([v[0], v[2], v[1]], [a, c, b])
                } else {
                    (v, [a, b, c])
                };
                indices.push(idx);
                if let (Some(out), Some(t)) = (&mut tangents, &m.tangents) {
                    let [t0, t1, t2] = t[ti];
                    out.push(if flip { [t0, t2, t1] } else { [t0, t1, t2] });
                }
                for (k, set) in [&m.uvs, &m.uvs1].into_iter().enumerate() {
                    if let Some(uv) = set {
                        let [ta, tb, tc] = [a, b, c].map(|i| uv[i as usize]);
                        let uv_area = (tb - ta).perp_dot(tc - ta).abs();
                        let area = winding.length();
                        uv_scale[k].push(if area > 0.0 {
                            (uv_area / area).sqrt()
                        } else {
                            0.0
                        });
                    }
                }
                triangles.push(v);
                triangle_mesh.push(mi as u32);
                let light = match &m.emission {
                    Some(e) if winding.length_squared() > 0.0 => {
                        let mut light = TriangleLight::new(v, Vec3A::from(e.radiance), e.two_sided);
                        let set = match e.texture.as_ref().map(|t| t.texcoord) {
                            Some(1) => &m.uvs1,
                            _ => &m.uvs,
                        };
                        if let (Some(t), Some(uv)) = (&e.texture, set) {
                            let corners = idx.map(|i| uv[i as usize]);
                            light = light.with_texture(textures.mipmap(t), corners);
                        }
                        lights.push(Light::Triangle(light));
                        emissive_triangles += 1;
                        lights.len() as u32 - 1
                    }
                    _ => NO_LIGHT,
                };
                triangle_light.push(light);
            }
            let [scale0, scale1] = uv_scale;
            let uvs = [
                m.uvs.as_ref().map(|uv| (uv.clone(), scale0)),
                m.uvs1.as_ref().map(|uv| (uv.clone(), scale1)),
            ];
            meshes.push(MeshRuntime {
                material: m.material,
                first_triangle,
                indices: if normals.is_some() || uvs.iter().any(Option::is_some) {
                    indices
                } else {
                    Vec::new()
                },
                normals,
                uvs,
                tangents,
            });
        }

        let mut sphere_geometry = Vec::with_capacity(desc.spheres.len());
        let mut spheres = Vec::with_capacity(desc.spheres.len());
        for s in &desc.spheres {
            let center = Vec3A::from(s.center);
            sphere_geometry.push((center, s.radius));
            objects.push((
                Target {
                    center,
                    radius: s.radius,
                },
                s.material,
            ));
            let light = match &s.emission {
                Some(e) => {
                    lights.push(Light::Sphere(SphereLight::new(
                        center,
                        s.radius,
                        Vec3A::from(e.radiance),
                        e.two_sided,
                    )));
                    lights.len() as u32 - 1
                }
                None => NO_LIGHT,
            };
            spheres.push(SphereRuntime {
                material: s.material,
                light,
            });
        }

        let (mut lo, mut hi) = (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY));
        for v in triangles.iter().flatten() {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
        for &(c, r) in &sphere_geometry {
            lo = lo.min(c - Vec3A::splat(r));
            hi = hi.max(c + Vec3A::splat(r));
        }
        let (center, radius) = if lo.x <= hi.x {
            (0.5 * (lo + hi), 0.5 * (hi - lo).length())
        } else {
            (Vec3A::ZERO, 1.0)
        };

        for l in &desc.lights {
            lights.push(match l {
                LightDesc::Point {
                    position,
                    intensity,
                } => Light::Point(PointLight::new((*position).into(), (*intensity).into())),
                LightDesc::Spot {
                    position,
                    direction,
                    intensity,
                    cos_falloff_start,
                    cos_cone,
                } => Light::Spot(SpotLight::new(
                    (*position).into(),
                    (*direction).into(),
                    (*intensity).into(),
                    *cos_falloff_start,
                    *cos_cone,
                )),
                LightDesc::Directional {
                    direction,
                    irradiance,
                } => Light::Directional(DirectionalLight::new(
                    (*direction).into(),
                    (*irradiance).into(),
                )),
                LightDesc::Environment {
                    image,
                    scale,
                    to_world,
                } => Light::Environment(EnvironmentLight::new(
                    image.as_ref(),
                    (*scale).into(),
                    Mat3A::from(*to_world),
                )),
            });
        }

        let stats = SceneStats {
            triangles: triangles.len(),
            spheres: spheres.len(),
            lights: lights.len(),
            emissive_triangles,
            texture_bytes: 0,
        };
        let materials: Vec<Material> = desc
            .materials
            .iter()
            .map(|m| Material::with_textures(&m.kind, &mut textures))
            .collect();
        let holes = materials
            .iter()
            .any(|m| m.textured.as_ref().is_some_and(|t| t.coverage.is_some()));
        let stats = SceneStats {
            texture_bytes: textures.bytes(),
            ..stats
        };
        let pixel_angle = pixel_angle(desc);
        Scene {
            accel: Accel::build(&triangles, &sphere_geometry),
            meshes,
            triangle_mesh,
            triangle_light,
            spheres,
            materials,
            lights: LightSet::new(lights, radius),
            filter: Filter::new(desc.film.filter),
            film: desc.film,
            integrator: desc.integrator.clone(),
            center,
            radius,
            objects,
            stats,
            pixel_angle,
            holes,
        }
    }

    #[inline]
    pub fn material(&self, i: u32) -> &Material {
        &self.materials[i as usize]
    }

    /// The normal map of material `i`, if it has one.
    #[inline]
    fn normal_map(&self, i: u32) -> Option<&NormalMap> {
        let t = self.materials[i as usize].textured.as_ref()?;
        t.normal_map.as_ref()
    }

    /// The closest surface along `ray` (passing through where surfaces are not there).
    /// The scene's BVHs alone (for measuring ray casting).
    pub fn into_accel(self) -> Accel {
        self.accel
    }

    pub fn intersect(&self, ray: &Ray) -> Option<SurfaceInteraction> {
        let hit = if self.holes {
            self.through_holes(ray, f32::INFINITY)?
        } else {
            self.accel.intersect(ray, f32::INFINITY)?
        };
        Some(self.interaction(hit, ray.d))
    }

    /// Whether something is there along `ray` before `t_max`.
    #[inline]
    fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        if self.holes {
            self.through_holes(ray, t_max).is_some()
        } else {
            self.accel.occluded(ray, t_max)
        }
    }

    /// The first hit along `ray` before `t_max` where the surface is there (its `t` from the
    /// ray's origin), passing through at most [`MAX_HOLES`] where it is not (the next hit
    /// then counts as there).
    fn through_holes(&self, ray: &Ray, t_max: f32) -> Option<PrimHit> {
        let mut from = *ray;
        let mut hit = self.accel.intersect(&from, t_max)?;
        for _ in 0..MAX_HOLES {
            let t = (hit.p - ray.o).dot(ray.d);
            if self.covers(ray, &hit, t) {
                return Some(PrimHit { t, ..hit });
            }
            // On from just beyond the surface.
            from = Ray::new(offset_ray_origin(hit.p, hit.p_error, hit.n, ray.d), ray.d);
            let left = t_max - (from.o - ray.o).dot(ray.d);
            if left <= 0.0 {
                return None;
            }
            hit = self.accel.intersect(&from, left)?;
        }
        let t = (hit.p - ray.o).dot(ray.d);
        Some(PrimHit { t, ..hit })
    }

    /// Whether the surface `hit` (at distance `t` along `ray`) is there. A blended surface is
    /// there with a probability; its uniform number hashes the ray and the triangle, so the
    /// same ray always meets the same surfaces (determinism) and each layer decides apart.
    #[inline]
    fn covers(&self, ray: &Ray, hit: &PrimHit, t: f32) -> bool {
        let Prim::Triangle { id, b } = hit.prim else {
            return true;
        };
        let mesh = &self.meshes[self.triangle_mesh[id as usize] as usize];
        let Some(textured) = self.materials[mesh.material as usize].textured.as_ref() else {
            return true;
        };
        if textured.coverage.is_none() {
            return true;
        }
        let local = (id - mesh.first_triangle) as usize;
        let (uv, width) = mesh.uv(local, b, t * self.pixel_angle);
        // A blended surface's number, hashed only where one is needed.
        let u = || {
            let bits = |v: Vec3A| {
                let [x, y, z] = v.to_array().map(f32::to_bits);
                ((x as u64) << 32 | y as u64) ^ ((z as u64) << 16)
            };
            let h = crate::sampler::hash::hash(&[bits(ray.o), bits(ray.d), id as u64]);
            crate::sampler::hash::u32_to_unit(h as u32)
        };
        textured.covers(uv, width, u)
    }

    /// The surface interaction at `hit`, found travelling along `d`.
    fn interaction(&self, hit: PrimHit, d: Vec3A) -> SurfaceInteraction {
        let (ns, material, light, uv, uv_width) = match hit.prim {
            Prim::Triangle { id, b } => {
                let mesh = &self.meshes[self.triangle_mesh[id as usize] as usize];
                let local = (id - mesh.first_triangle) as usize;
                let (uv, uv_width) = mesh.uv(local, b, hit.t * self.pixel_angle);
                let ns = match &mesh.normals {
                    Some(normals) => {
                        let [i0, i1, i2] = mesh.indices[local];
                        let n = normals[i0 as usize] * b[0]
                            + normals[i1 as usize] * b[1]
                            + normals[i2 as usize] * b[2];
                        // Zero or opposing normals (bad input) fall back to flat shading.
                        let n = n.normalize_or_zero();
                        if n.dot(hit.n) > 0.0 { n } else { hit.n }
                    }
                    None => hit.n,
                };
                // Only meshes of normal-mapped materials carry tangents.
                let ns = match &mesh.tangents {
                    Some(t) => match self.normal_map(mesh.material) {
                        Some(n) => {
                            let [c0, c1, c2] = t[local];
                            let t = c0 * b[0] + c1 * b[1] + c2 * b[2];
                            let texel = n.map.at(uv, uv_width);
                            perturb(ns, hit.n, t, texel, n.scale, n.axes)
                        }
                        None => ns,
                    },
                    None => ns,
                };
                (
                    ns,
                    mesh.material,
                    self.triangle_light[id as usize],
                    uv,
                    uv_width,
                )
            }
            Prim::Sphere { id } => {
                let s = &self.spheres[id as usize];
                (hit.n, s.material, s.light, [Vec2::ZERO; 2], [0.0; 2])
            }
        };
        SurfaceInteraction {
            p: hit.p,
            p_error: hit.p_error,
            t: hit.t,
            ng: hit.n,
            ns,
            material,
            light,
            uv,
            uv_width,
            interior: if d.dot(hit.n) > 0.0 { hit.t } else { 0.0 },
        }
    }

    /// Whether nothing blocks the light sample `ls` as seen from `si`.
    pub fn unoccluded(&self, si: &SurfaceInteraction, ls: &LightSample) -> bool {
        match ls.target {
            ShadowTarget::Infinite => self.unoccluded_to_infinity((si.p, si.p_error, si.ng), ls.wi),
            ShadowTarget::Point { p, p_error, n } => {
                self.unoccluded_between((si.p, si.p_error, si.ng), (p, p_error, n))
            }
        }
    }

    /// Whether nothing blocks the ray from a point (position, error bound, normal) along `w`
    /// to infinity: the way to a light at infinity.
    pub fn unoccluded_to_infinity(&self, (p, p_error, n): (Vec3A, Vec3A, Vec3A), w: Vec3A) -> bool {
        let o = if n == Vec3A::ZERO {
            p
        } else {
            offset_ray_origin(p, p_error, n, w)
        };
        !self.occluded(&Ray::new(o, w), f32::INFINITY)
    }

    /// Whether nothing blocks the segment between two points, each (position, error bound,
    /// normal; a zero normal for a point in space, such as a pinhole or a point light).
    pub fn unoccluded_between(&self, a: (Vec3A, Vec3A, Vec3A), b: (Vec3A, Vec3A, Vec3A)) -> bool {
        let end = |(p, e, n): (Vec3A, Vec3A, Vec3A), toward: Vec3A| {
            if n == Vec3A::ZERO {
                p
            } else {
                offset_ray_origin(p, e, n, toward - p)
            }
        };
        let o = end(a, b.0);
        let target = end(b, o);
        let d = target - o;
        let dist = d.length();
        dist == 0.0 || !self.occluded(&Ray::new(o, d / dist), dist * (1.0 - SHADOW_EPSILON))
    }
}
