//! The validated scene, in canonical units, ready for the renderer to build from.
//!
//! Units (invariant 2 of docs/src/design/overview.md): lengths in scene units (`metres_per_unit` converts);
//! radiometry in SI with RGB in linear Rec.709: radiance in W·sr⁻¹·m⁻², intensity in W·sr⁻¹,
//! irradiance in W·m⁻². "W" here is luminous-equivalent: luminance Y (0.2126 R + 0.7152 G +
//! 0.0722 B) times 683 lm/W is the photometric value (cd/m², cd, lux). Emitters given as power
//! were converted to radiance/intensity once, at load. Instances are flattened: every mesh
//! and sphere is in world space.

use glam::{Mat3, Vec3};

pub use crate::camera::{CameraDesc, Lens};
pub use crate::file::{Distribution, FovAxis, PhotonFilter, SamplerType, SubsurfaceMethod};

/// A scene ready to render.
#[derive(Debug, Clone)]
pub struct SceneDesc {
    /// Human-readable name (the `name` field, or the file name).
    pub name: String,
    pub metres_per_unit: f64,
    pub camera: CameraDesc,
    /// A fly-through: the camera moves from frame to frame, nothing else does.
    pub camera_path: Option<crate::animation::CameraPath>,
    pub film: FilmDesc,
    pub integrator: IntegratorDesc,
    pub materials: Vec<MaterialDesc>,
    pub meshes: Vec<MeshDesc>,
    pub spheres: Vec<SphereDesc>,
    pub lights: Vec<LightDesc>,
    /// What the scene's files hold that is read but not modelled (a glTF texture, say), for
    /// the render summary and the job's decisions.
    pub warnings: Vec<String>,
}

impl SceneDesc {
    /// Names of the translucent (`subsurface`) materials.
    pub fn translucent_materials(&self) -> Vec<&str> {
        self.materials
            .iter()
            .filter(|m| matches!(m.kind, MaterialKind::Subsurface { .. }))
            .map(|m| m.name.as_str())
            .collect()
    }

    /// Frames of the scene's animation (1 without a camera path).
    pub fn frame_count(&self) -> u32 {
        self.camera_path.as_ref().map_or(1, |p| p.frame_count())
    }

    /// The camera of frame `frame` (1-based; the still camera without a path).
    pub fn camera_at(&self, frame: u32) -> CameraDesc {
        match &self.camera_path {
            Some(path) => path.camera(frame, &self.camera),
            None => self.camera,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilmDesc {
    pub width: u32,
    pub height: u32,
    pub filter: FilterDesc,
}

/// Pixel reconstruction filter; radii in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FilterDesc {
    Box { radius: f32 },
    Gaussian { radius: f32, sigma: f32 },
    Mitchell { radius: f32, b: f32, c: f32 },
}

/// Photon-mapping knobs as the scene gives them; `None` = chosen from the scene.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PhotonDesc {
    pub photons: Option<u32>,
    pub caustic_photons: Option<u32>,
    pub k: Option<u32>,
    pub caustic_k: Option<u32>,
    pub radius: Option<f32>,
    pub caustic_radius: Option<f32>,
    pub gather_rays: Option<u32>,
    pub caustic_filter: PhotonFilter,
    /// `None`: no irradiance cache (final gathering at every camera sample).
    pub irradiance_cache: Option<IrradianceCacheDesc>,
    /// SPPM's α.
    pub alpha: Option<f32>,
}

#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct IrradianceCacheDesc {
    pub accuracy: Option<f32>,
    pub spacing: Option<u32>,
    pub keyframe_step: Option<u32>,
    pub gather_rays: Option<u32>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct IntegratorDesc {
    /// The rendering method's name (`tessera_render::method` lists them and checks it).
    pub method: String,
    pub spp: u32,
    /// Longest path, in scattering events.
    pub max_depth: u32,
    /// Depth from which Russian roulette may end paths.
    pub rr_depth: u32,
    pub seed: u64,
    pub sampler: SamplerType,
    pub photon: PhotonDesc,
    pub subsurface: SubsurfaceMethod,
    /// The settings the scene file gave a value ([`crate::setting::ALL`]), in its order; those
    /// it left out take their defaults.
    pub given: Vec<&'static crate::setting::Setting>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct MaterialDesc {
    pub name: String,
    pub kind: MaterialKind,
}

/// Microfacet roughness: distribution and widths along the tangent and bitangent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Roughness {
    pub distribution: Distribution,
    pub alpha_u: f32,
    pub alpha_v: f32,
}

impl Roughness {
    /// Isotropic GGX of perceptual roughness `r` (glTF's and Blender's: α = r²). Below
    /// α 1e-3 the interface is a mirror in every respect but its float range: smooth.
    pub fn ggx(r: f32) -> Self {
        let alpha = r * r;
        let alpha = if alpha < 1e-3 { 0.0 } else { alpha };
        Roughness {
            distribution: crate::file::Distribution::Ggx,
            alpha_u: alpha,
            alpha_v: alpha,
        }
    }

    /// α = 0: a perfectly smooth (specular, delta) interface.
    pub fn is_smooth(&self) -> bool {
        self.alpha_u == 0.0 && self.alpha_v == 0.0
    }
}

#[derive(Debug, Clone, PartialEq)]
pub enum MaterialKind {
    Diffuse {
        albedo: Vec3,
    },
    OrenNayar {
        albedo: Vec3,
        sigma: f32,
    },
    Phong {
        diffuse: Vec3,
        specular: Vec3,
        exponent: f32,
    },
    BlinnPhong {
        diffuse: Vec3,
        specular: Vec3,
        exponent: f32,
    },
    Ward {
        diffuse: Vec3,
        specular: Vec3,
        alpha_x: f32,
        alpha_y: f32,
    },
    /// Conductor with complex index of refraction η + ik per channel.
    Conductor {
        eta: Vec3,
        k: Vec3,
        specular: Vec3,
        roughness: Roughness,
    },
    /// Dielectric interface: `eta` = interior IOR / exterior IOR; the interior absorbs
    /// `absorption` (σa per scene unit of length, per channel; zero: clear), so that light
    /// crossing a length d of it keeps exp(−σa d) (Beer–Lambert). Each crossing keeps `tint`
    /// (glTF's base colour; white for clear glass). `thin`: a thin sheet (a window pane, a
    /// thin-walled glTF material) that reflects and transmits without bending light and has
    /// no interior.
    Dielectric {
        eta: f32,
        roughness: Roughness,
        absorption: Vec3,
        tint: Vec3,
        thin: bool,
    },
    Mirror {
        reflectance: Vec3,
    },
    /// The glTF 2.0 metallic-roughness BRDF (its appendix B): a Lambertian base under a GGX
    /// layer with Schlick's Fresnel (F0 from `ior` and the KHR_materials_specular colour and
    /// weight), blended with a metal of reflectance `base_color` by `metallic`; GGX
    /// α = roughness².
    MetallicRoughness {
        base_color: Vec3,
        metallic: f32,
        roughness: f32,
        ior: f32,
        specular_color: Vec3,
        specular: f32,
        /// Image textures that multiply the factors, if any.
        textures: PbrTextures,
        /// How much of the dielectric base lets light through (none for an opaque one).
        transmission: PbrTransmission,
    },
    /// A translucent object: a smooth dielectric interface of relative index `eta` around a
    /// homogeneous scattering medium — reduced scattering σs′ = σs (1 − g) and absorption σa
    /// per scene unit of length, Henyey–Greenstein asymmetry `g`.
    Subsurface {
        sigma_s_prime: Vec3,
        sigma_a: Vec3,
        eta: f32,
        g: f32,
    },
    /// Kubelka–Munk layers, top first, over an opaque substrate of diffuse reflectance
    /// `substrate`: a Lambertian surface with the stack's reflectance.
    KubelkaMunk {
        layers: Vec<KmLayer>,
        substrate: Vec3,
    },
    /// Hanrahan & Krueger 1993: a smooth coat of relative index `eta` over a layer of a
    /// scattering medium (σs and σa per mm, `thickness` mm, Henyey–Greenstein `g`), scattered
    /// to first order, over a Lambertian substrate of reflectance `substrate`.
    HanrahanKrueger {
        sigma_s: Vec3,
        sigma_a: Vec3,
        thickness: f32,
        g: f32,
        eta: f32,
        substrate: Vec3,
    },
}

/// Transmission of a metallic-roughness material's dielectric base, as glTF's
/// KHR_materials_transmission and KHR_materials_diffuse_transmission define it: of the light
/// the specular layer lets into the base, a share `specular` crosses a (rough) dielectric
/// interface of the material's IOR and roughness, tinted by the base colour, instead of
/// meeting the diffuse base; of the diffuse base, a share `diffuse` is transmitted diffusely
/// to the other side with colour `diffuse_color`. `thin`: the surface is a thin wall (glTF
/// without KHR_materials_volume), so specular transmission does not bend light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PbrTransmission {
    pub specular: f32,
    pub diffuse: f32,
    pub diffuse_color: Vec3,
    pub thin: bool,
}

impl Default for PbrTransmission {
    fn default() -> Self {
        PbrTransmission {
            specular: 0.0,
            diffuse: 0.0,
            diffuse_color: Vec3::ONE,
            thin: false,
        }
    }
}

impl PbrTransmission {
    /// Lets no light through.
    pub fn is_opaque(&self) -> bool {
        self.specular <= 0.0 && self.diffuse <= 0.0
    }
}

/// What varies over a metallic-roughness material's surface: the base colour's texture
/// (sRGB-decoded, multiplies `base_color`; its alpha is coverage), the metallic-roughness one
/// (linear; blue is metalness, green roughness, multiplying the factors), a normal map, and
/// coverage (glTF's alphaMode).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PbrTextures {
    pub base_color: Option<crate::texture::TextureDesc>,
    pub metallic_roughness: Option<crate::texture::TextureDesc>,
    /// A tangent-space normal map (linear) and its scale on x and y.
    pub normal: Option<(crate::texture::TextureDesc, f32)>,
    /// Where the surface is not there at all; `None` for an opaque one.
    pub coverage: Option<Coverage>,
}

impl PbrTextures {
    pub fn is_empty(&self) -> bool {
        self.base_color.is_none()
            && self.metallic_roughness.is_none()
            && self.normal.is_none()
            && self.coverage.is_none()
    }
}

/// A surface's coverage α = `factor` × the base colour texture's alpha (glTF alphaMode):
/// `Mask` keeps the surface where α ≥ the cutoff and removes it elsewhere (cut-out leaves,
/// fences); `Blend` keeps it with probability α, so a ray passes with probability 1 − α
/// (stochastic transparency, unbiased for every method).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coverage {
    pub factor: f32,
    pub mode: CoverageMode,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CoverageMode {
    Mask { cutoff: f32 },
    Blend,
}

/// One Kubelka–Munk layer: absorption K and scattering S per mm, thickness in mm (only the
/// products K·d and S·d matter, so the scene's units do not enter).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KmLayer {
    pub absorption: Vec3,
    pub scattering: Vec3,
    pub thickness: f32,
}

/// An area emitter's radiance, constant over its surface or multiplied by an image texture
/// (sRGB-decoded colour, glTF's emissiveTexture) at the surface's texture coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct EmissionDesc {
    pub radiance: Vec3,
    pub two_sided: bool,
    pub texture: Option<crate::texture::TextureDesc>,
}

/// A triangle mesh in world space.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshDesc {
    /// Where it came from, for messages (`shapes[2] (floor.obj)`).
    pub origin: String,
    pub positions: Vec<Vec3>,
    /// Per-vertex shading normals (unit length), if the mesh has them and they are wanted.
    pub normals: Option<Vec<Vec3>>,
    /// Per-vertex texture coordinates (TEXCOORD_0), if the mesh has them.
    pub uvs: Option<Vec<glam::Vec2>>,
    /// A second set (TEXCOORD_1), read by textures that name it.
    pub uvs1: Option<Vec<glam::Vec2>>,
    /// Tangent frames per triangle corner (xyz, w the bitangent's sign), for normal maps.
    pub tangents: Option<Vec<[glam::Vec4; 3]>>,
    pub triangles: Vec<[u32; 3]>,
    pub material: u32,
    pub emission: Option<EmissionDesc>,
}

impl MeshDesc {
    /// Whether triangle `[a, b, c]` as listed faces away from its vertex normals (summed),
    /// where the mesh has them: the normals decide the front face, so renderers and exports
    /// wind such a triangle the other way, `[a, c, b]`.
    pub fn faces_against_normals(&self, [a, b, c]: [u32; 3]) -> bool {
        let Some(n) = &self.normals else {
            return false;
        };
        let [p0, p1, p2] = [a, b, c].map(|i| self.positions[i as usize]);
        (p1 - p0)
            .cross(p2 - p0)
            .dot(n[a as usize] + n[b as usize] + n[c as usize])
            < 0.0
    }

    /// Total surface area, in scene units squared (degenerate triangles count zero).
    pub fn area(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.positions[i as usize].as_dvec3());
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct SphereDesc {
    /// Where it came from, for messages (`shapes[4]`).
    pub origin: String,
    pub center: Vec3,
    pub radius: f32,
    pub material: u32,
    pub emission: Option<EmissionDesc>,
}

impl SphereDesc {
    /// Surface area, in scene units squared.
    pub fn area(&self) -> f64 {
        4.0 * std::f64::consts::PI * (self.radius as f64).powi(2)
    }
}

#[derive(Debug, Clone, PartialEq)]
pub enum LightDesc {
    /// Intensity already divided by metres-per-unit², so irradiance = intensity / d² with d in
    /// scene units.
    Point { position: Vec3, intensity: Vec3 },
    Spot {
        position: Vec3,
        direction: Vec3,
        intensity: Vec3,
        cos_falloff_start: f32,
        cos_cone: f32,
    },
    /// `direction` is where the light travels; irradiance on a surface facing it.
    Directional { direction: Vec3, irradiance: Vec3 },
    Environment {
        image: Option<EnvImage>,
        scale: Vec3,
        to_world: Mat3,
    },
}

/// A latitude–longitude environment image, rows top (+Y, up) to bottom.
#[derive(Debug, Clone, PartialEq)]
pub struct EnvImage {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<Vec3>,
}
