//! The JSON scene file, as written by users (see `docs/src/guide/scene-format.md`).
//!
//! These types mirror the JSON closely; [`crate::resolve`] turns them into a validated
//! [`crate::SceneDesc`]. Objects with a `"type"` (materials, shapes, lights) are kept as
//! [`Tagged`] here and parsed in a second phase, so that errors inside them name the full
//! field path (`shapes[3].radius`) — serde's internally tagged enums lose that path.

use std::collections::BTreeMap;

use serde::Deserialize;
use serde::de::{self, Deserializer, SeqAccess, Visitor};

/// The top level of `scene.json`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    #[serde(default)]
    pub name: Option<String>,
    /// Length unit of every coordinate in the scene and its meshes.
    pub units: Units,
    pub camera: CameraFile,
    pub film: FilmFile,
    #[serde(default)]
    pub integrator: IntegratorFile,
    pub materials: BTreeMap<String, Tagged>,
    /// Named groups of shapes that `instance` shapes place with a transform.
    #[serde(default)]
    pub objects: BTreeMap<String, Vec<Tagged>>,
    pub shapes: Vec<Tagged>,
    #[serde(default)]
    pub lights: Vec<Tagged>,
    /// The sky: an equirectangular image or a constant, around the whole scene.
    #[serde(default)]
    pub environment: Option<EnvironmentFile>,
}

/// `"environment": {"image": "sky.exr", "strength": 1, "rotation_deg": 0}`: a latitude–
/// longitude OpenEXR image of radiance (omitted: a constant sky of radiance `strength`),
/// scaled by `strength` and turned by `rotation_deg` about the up axis (+y).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentFile {
    #[serde(default)]
    pub image: Option<String>,
    #[serde(default)]
    pub strength: Option<f32>,
    #[serde(default)]
    pub rotation_deg: Option<f32>,
}

/// Length units a scene may be written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Units {
    Mm,
    Cm,
    M,
    Km,
    In,
    Ft,
}

impl Units {
    /// Metres per scene unit.
    pub fn metres(self) -> f64 {
        match self {
            Units::Mm => 1e-3,
            Units::Cm => 1e-2,
            Units::M => 1.0,
            Units::Km => 1e3,
            Units::In => 0.0254,
            Units::Ft => 0.3048,
        }
    }
}

/// An object with a `"type"` field; its other fields are parsed once the type is known.
#[derive(Debug, Clone)]
pub struct Tagged {
    pub kind: String,
    pub body: serde_json::Map<String, serde_json::Value>,
}

impl<'de> Deserialize<'de> for Tagged {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let mut body = serde_json::Map::deserialize(d)?;
        match body.remove("type") {
            Some(serde_json::Value::String(kind)) => Ok(Tagged { kind, body }),
            Some(other) => Err(de::Error::custom(format!(
                "expected field `type` to be a string, got {other}"
            ))),
            None => Err(de::Error::missing_field("type")),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CameraType {
    Pinhole,
    ThinLens,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FovAxis {
    X,
    #[default]
    Y,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraFile {
    #[serde(rename = "type")]
    pub kind: CameraType,
    pub position: [f32; 3],
    pub look_at: [f32; 3],
    #[serde(default = "default_up")]
    pub up: [f32; 3],
    /// Field of view in degrees, along `fov_axis`.
    pub fov_deg: f32,
    #[serde(default)]
    pub fov_axis: FovAxis,
    /// Thin lens only: radius of the aperture, in scene units.
    #[serde(default)]
    pub aperture_radius: Option<f32>,
    /// Thin lens only: distance to the plane in focus, in scene units.
    #[serde(default)]
    pub focus_distance: Option<f32>,
    #[serde(default)]
    pub exposure: Option<ExposureFile>,
    /// A fly-through: keyframes the camera moves through.
    #[serde(default)]
    pub path: Option<CameraPathFile>,
}

/// A camera path: frames per second and keyframes in increasing time.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraPathFile {
    pub fps: f32,
    pub keyframes: Vec<KeyframeFile>,
}

/// One keyframe; `up` and `fov_deg` default to the camera's.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeyframeFile {
    /// Seconds.
    pub time: f32,
    pub position: [f32; 3],
    pub look_at: [f32; 3],
    #[serde(default)]
    pub up: Option<[f32; 3]>,
    #[serde(default)]
    pub fov_deg: Option<f32>,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

/// Physical exposure: pixel value 1 is sensor saturation at this ISO, shutter and f-number.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExposureFile {
    pub iso: f32,
    pub shutter_s: Seconds,
    pub f_number: f32,
}

/// A time in seconds, as a number (`0.0111`) or a photographer's fraction (`"1/90"`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seconds(pub f32);

impl<'de> Deserialize<'de> for Seconds {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = Seconds;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a time in seconds: a number or a fraction such as \"1/90\"")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Seconds, E> {
                Ok(Seconds(v as f32))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Seconds, E> {
                Ok(Seconds(v as f32))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Seconds, E> {
                Ok(Seconds(v as f32))
            }
            fn visit_str<E: de::Error>(self, s: &str) -> Result<Seconds, E> {
                let parse = |t: &str| t.trim().parse::<f32>().ok();
                let value = match s.split_once('/') {
                    Some((n, d)) => parse(n).zip(parse(d)).map(|(n, d)| n / d),
                    None => parse(s),
                };
                value
                    .map(Seconds)
                    .ok_or_else(|| E::invalid_value(de::Unexpected::Str(s), &self))
            }
        }
        d.deserialize_any(V)
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FilmFile {
    pub width: u32,
    pub height: u32,
    #[serde(default)]
    pub filter: Option<FilterFile>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FilterType {
    Box,
    Gaussian,
    Mitchell,
}

/// Reconstruction filter; parameters that do not apply to the type are rejected.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FilterFile {
    #[serde(rename = "type")]
    pub kind: FilterType,
    /// Half-width in pixels (box 0.5, Gaussian 1.5, Mitchell 2 by default).
    #[serde(default)]
    pub radius: Option<f32>,
    /// Gaussian standard deviation in pixels (default 0.5).
    #[serde(default)]
    pub sigma: Option<f32>,
    /// Mitchell–Netravali B and C (default 1/3 each).
    #[serde(default)]
    pub b: Option<f32>,
    #[serde(default)]
    pub c: Option<f32>,
}

/// How caustic photons are weighted by distance in a radiance estimate (Jensen 2001, §7.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PhotonFilter {
    /// Every photon in the disc counts fully.
    Box,
    /// w = 1 − d/(k·r) with k = 1, normalised by 1 − 2/(3k).
    #[default]
    Cone,
    /// Pavicic's normalised Gaussian (α = 0.918, β = 1.953).
    Gaussian,
}

/// Photon-mapping knobs (Mental Ray's: photon count, accuracy k, radius); every one optional,
/// omitted = chosen from the scene (`tessera_render::photon::PhotonSettings::resolve`).
#[derive(Debug, Clone, Copy, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhotonMapFile {
    /// Photons emitted for the global map.
    pub photons: Option<u32>,
    /// Photons emitted for the caustic map (0: no caustic map).
    pub caustic_photons: Option<u32>,
    /// Nearest photons per global radiance estimate ("accuracy").
    pub k: Option<u32>,
    /// Nearest photons per caustic estimate.
    pub caustic_k: Option<u32>,
    /// Largest search radius of a global estimate, scene units.
    pub radius: Option<f32>,
    /// Largest search radius of a caustic estimate, scene units.
    pub caustic_radius: Option<f32>,
    /// Final-gather rays per gather point.
    pub gather_rays: Option<u32>,
    pub caustic_filter: Option<PhotonFilter>,
    pub irradiance_cache: Option<IrradianceCacheFile>,
    /// SPPM: fraction of new photons kept per iteration, in (0, 1) (default 2/3).
    pub alpha: Option<f32>,
}

/// Ward's irradiance cache for the indirect diffuse term.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IrradianceCacheFile {
    #[serde(default = "default_true")]
    pub enabled: bool,
    /// Ward's accuracy a: a record serves points where its error weight exceeds 1/a.
    pub accuracy: Option<f32>,
    /// Record candidates every this many pixels of the pre-render.
    pub spacing: Option<u32>,
    /// A fly-through's records come from every this-many-th frame's camera.
    pub keyframe_step: Option<u32>,
    /// Hemisphere rays per record.
    pub gather_rays: Option<u32>,
}

fn default_true() -> bool {
    true
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SamplerType {
    /// Owen-scrambled Sobol (low discrepancy), the default.
    #[default]
    Sobol,
    /// Independent uniform random numbers (for tests and comparisons).
    Independent,
}

/// How translucent (`subsurface`) materials are rendered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SubsurfaceMethod {
    /// The dipole BSSRDF of Jensen et al. 2001, exit points sampled by probe rays.
    #[default]
    Dipole,
    /// The dipole summed over a point cloud of irradiance samples through an octree (Jensen
    /// & Buhler 2002): a view-independent pass, then no noise from the BSSRDF.
    Hierarchical,
    /// A volumetric random walk inside the object: the brute-force reference.
    RandomWalk,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IntegratorFile {
    /// The rendering method, by its name in the render crate's registry (which checks it).
    #[serde(rename = "type", default = "default_method")]
    pub method: String,
    #[serde(default = "default_spp")]
    pub spp: u32,
    #[serde(default = "default_max_depth")]
    pub max_depth: u32,
    #[serde(default = "default_rr_depth")]
    pub rr_depth: u32,
    #[serde(default)]
    pub seed: u64,
    #[serde(default)]
    pub sampler: Option<SamplerType>,
    #[serde(default)]
    pub photon_map: PhotonMapFile,
    #[serde(default)]
    pub subsurface: Option<SubsurfaceMethod>,
}

impl Default for IntegratorFile {
    fn default() -> Self {
        IntegratorFile {
            method: default_method(),
            spp: default_spp(),
            max_depth: default_max_depth(),
            rr_depth: default_rr_depth(),
            seed: 0,
            sampler: None,
            photon_map: PhotonMapFile::default(),
            subsurface: None,
        }
    }
}

fn default_method() -> String {
    "path".into()
}

fn default_spp() -> u32 {
    64
}
fn default_max_depth() -> u32 {
    64
}
fn default_rr_depth() -> u32 {
    5
}

/// One number, or an array of `N` numbers: colours (`0.5` is grey `[0.5, 0.5, 0.5]`),
/// scales, anisotropic roughness.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NumOrArray<const N: usize> {
    One(f32),
    Many([f32; N]),
}

impl<const N: usize> NumOrArray<N> {
    /// The array, with a single number repeated.
    pub fn expand(self) -> [f32; N] {
        match self {
            NumOrArray::One(v) => [v; N],
            NumOrArray::Many(a) => a,
        }
    }
}

/// A colour in linear Rec.709: one number (grey) or `[r, g, b]`.
pub type Color = NumOrArray<3>;

impl<'de, const N: usize> Deserialize<'de> for NumOrArray<N> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V<const N: usize>;
        impl<'de, const N: usize> Visitor<'de> for V<N> {
            type Value = NumOrArray<N>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                write!(f, "a number or an array of {N} numbers")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Self::Value, E> {
                Ok(NumOrArray::One(v as f32))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Self::Value, E> {
                Ok(NumOrArray::One(v as f32))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Self::Value, E> {
                Ok(NumOrArray::One(v as f32))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
                let mut a = [0.0f32; N];
                for (i, slot) in a.iter_mut().enumerate() {
                    *slot = seq
                        .next_element::<f32>()?
                        .ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                if seq.next_element::<de::IgnoredAny>()?.is_some() {
                    return Err(de::Error::invalid_length(N + 1, &self));
                }
                Ok(NumOrArray::Many(a))
            }
        }
        d.deserialize_any(V::<N>)
    }
}

/// One step of a transform; a transform is a list of steps applied in order.
#[derive(Debug, Clone, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum TransformStep {
    Translate([f32; 3]),
    /// Rotation by `angle_deg` degrees about `axis` (right-handed).
    Rotate {
        axis: [f32; 3],
        angle_deg: f32,
    },
    /// Uniform (one number) or per-axis scale.
    Scale(NumOrArray<3>),
    /// A 4×4 matrix in row-major order, applied to column vectors.
    Matrix([f32; 16]),
}

/// Emission of an area light (on a mesh, quad, box or sphere).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EmissionFile {
    /// Radiance in W·sr⁻¹·m⁻²: an RGB triple, or one number scaling `color`/`temperature_k`.
    #[serde(default)]
    pub radiance: Option<NumOrArray<3>>,
    /// Total emitted power; converted to radiance over the emitter's area.
    #[serde(default)]
    pub power: Option<PowerFile>,
    #[serde(default)]
    pub color: Option<Color>,
    #[serde(default)]
    pub temperature_k: Option<f32>,
    /// Emit from both faces (default: only the front face, given by the winding / outward normal).
    #[serde(default)]
    pub two_sided: bool,
}

/// Power of an emitter: luminous flux in lumens, or watts (radiant, or electrical with an
/// efficacy in lumens per watt, as lamp packaging states them).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PowerFile {
    #[serde(default)]
    pub watts: Option<f32>,
    #[serde(default)]
    pub efficacy_lm_per_w: Option<f32>,
    #[serde(default)]
    pub lumens: Option<f32>,
}

// ---- bodies of tagged objects -------------------------------------------------------------

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshShape {
    pub file: String,
    /// The material of every face; omitted, an OBJ's own (its MTL library, by `usemtl`).
    #[serde(default)]
    pub material: Option<String>,
    #[serde(default)]
    pub emission: Option<EmissionFile>,
    #[serde(default)]
    pub transform: Vec<TransformStep>,
    /// Use the vertex normals of the file (default true); false shades flat.
    #[serde(default = "yes")]
    pub smooth_normals: bool,
}

fn yes() -> bool {
    true
}

/// A glTF 2.0 file (`.gltf` or `.glb`): its meshes, materials and lights, its metres converted
/// to the scene's units, then placed by `transform`. Its cameras are not used.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GltfShape {
    pub file: String,
    #[serde(default)]
    pub transform: Vec<TransformStep>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct QuadShape {
    /// One corner; the quad spans `origin + s·edge_u + t·edge_v` for s, t in [0, 1].
    /// Its front face (normal `edge_u × edge_v`) is the emitting side of a light.
    pub origin: [f32; 3],
    pub edge_u: [f32; 3],
    pub edge_v: [f32; 3],
    pub material: String,
    #[serde(default)]
    pub emission: Option<EmissionFile>,
    #[serde(default)]
    pub transform: Vec<TransformStep>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxShape {
    pub min: [f32; 3],
    pub max: [f32; 3],
    pub material: String,
    #[serde(default)]
    pub emission: Option<EmissionFile>,
    #[serde(default)]
    pub transform: Vec<TransformStep>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereShape {
    pub center: [f32; 3],
    pub radius: f32,
    pub material: String,
    #[serde(default)]
    pub emission: Option<EmissionFile>,
    /// Only rotations, translations and uniform scales keep a sphere a sphere.
    #[serde(default)]
    pub transform: Vec<TransformStep>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InstanceShape {
    /// Name of an entry of the scene's `objects`.
    pub object: String,
    #[serde(default)]
    pub transform: Vec<TransformStep>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DiffuseMaterial {
    pub albedo: Color,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrenNayarMaterial {
    pub albedo: Color,
    /// Standard deviation of the facet slope angle, in degrees.
    pub sigma_deg: f32,
}

/// Normalised Phong or Blinn–Phong: diffuse + specular lobe with the given exponent.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PhongMaterial {
    #[serde(default)]
    pub diffuse: Option<Color>,
    pub specular: Color,
    pub exponent: f32,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WardMaterial {
    #[serde(default)]
    pub diffuse: Option<Color>,
    pub specular: Color,
    pub alpha_x: f32,
    pub alpha_y: f32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Distribution {
    #[default]
    Ggx,
    Beckmann,
}

/// Microfacet width α (Walter et al. 2007): one number, or `[α_u, α_v]` for anisotropy.
pub type Alpha = NumOrArray<2>;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConductorMaterial {
    /// A named metal (`gold`, `silver`, `copper`, `aluminium`, `chrome`), or give `eta` and `k`.
    #[serde(default)]
    pub metal: Option<String>,
    #[serde(default)]
    pub eta: Option<Color>,
    #[serde(default)]
    pub k: Option<Color>,
    #[serde(default)]
    pub alpha: Option<Alpha>,
    #[serde(default)]
    pub distribution: Distribution,
    /// Multiplier on the Fresnel reflectance (default 1; not physical, for art direction).
    #[serde(default)]
    pub specular: Option<Color>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DielectricMaterial {
    /// Index of refraction inside (on the side opposite the normal).
    pub ior: f32,
    /// Index of refraction outside (default 1, vacuum/air).
    #[serde(default)]
    pub ext_ior: Option<f32>,
    #[serde(default)]
    pub alpha: Option<Alpha>,
    #[serde(default)]
    pub distribution: Distribution,
    /// Absorption of the interior, σa per millimetre (tinted glass, coloured liquids).
    #[serde(default)]
    pub sigma_a_per_mm: Option<NumOrArray<3>>,
    /// What each crossing of the interface keeps (default 1).
    #[serde(default)]
    pub tint: Option<Color>,
    /// A thin sheet (a window pane): transmits without bending light, no interior.
    #[serde(default)]
    pub thin: bool,
}

/// A translucent material: a measured medium by name (`preset`) or its coefficients.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SubsurfaceMaterial {
    /// A medium of Jensen et al. 2001 (`marble`, `skin1`, `whole-milk`, …).
    #[serde(default)]
    pub preset: Option<String>,
    /// Reduced scattering coefficient σs′ in mm⁻¹ (without `preset`).
    #[serde(default)]
    pub sigma_s_prime_per_mm: Option<NumOrArray<3>>,
    /// Absorption coefficient σa in mm⁻¹ (without `preset`).
    #[serde(default)]
    pub sigma_a_per_mm: Option<NumOrArray<3>>,
    /// Multiplies both coefficients (default 1): 10 renders an object as if it were ten times
    /// larger — light travels a tenth as far through it.
    #[serde(default)]
    pub scale: Option<f32>,
    /// Index of refraction inside (default 1.3, the paper's).
    #[serde(default)]
    pub ior: Option<f32>,
    /// Henyey–Greenstein asymmetry of the phase function, in (−1, 1) (default 0).
    #[serde(default)]
    pub g: Option<f32>,
}

/// Kubelka–Munk layers over a substrate.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KubelkaMunkMaterial {
    /// Top first.
    pub layers: Vec<KmLayerFile>,
    /// Diffuse reflectance under the last layer (default 0: black).
    #[serde(default)]
    pub substrate: Option<Color>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KmLayerFile {
    /// Kubelka–Munk absorption K, mm⁻¹.
    pub absorption_per_mm: NumOrArray<3>,
    /// Kubelka–Munk scattering S, mm⁻¹.
    pub scattering_per_mm: NumOrArray<3>,
    pub thickness_mm: f32,
}

/// Hanrahan & Krueger's layer: a coated scattering layer over a diffuse substrate.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HanrahanKruegerMaterial {
    /// Scattering coefficient σs, mm⁻¹.
    pub sigma_s_per_mm: NumOrArray<3>,
    /// Absorption coefficient σa, mm⁻¹.
    pub sigma_a_per_mm: NumOrArray<3>,
    pub thickness_mm: f32,
    /// Henyey–Greenstein asymmetry (default 0).
    #[serde(default)]
    pub g: Option<f32>,
    /// Index of refraction of the layer (default 1.4, skin's).
    #[serde(default)]
    pub ior: Option<f32>,
    /// Diffuse reflectance under the layer (default 0: black).
    #[serde(default)]
    pub substrate: Option<Color>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MirrorMaterial {
    #[serde(default)]
    pub reflectance: Option<Color>,
}

/// The glTF 2.0 metallic-roughness material (as glTF files give it, so scene.json can too).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MetallicRoughnessMaterial {
    /// Linear base colour (default white).
    #[serde(default)]
    pub base_color: Option<Color>,
    #[serde(default)]
    pub metallic: Option<f32>,
    /// Perceptual roughness in [0, 1]; GGX α = roughness².
    #[serde(default)]
    pub roughness: Option<f32>,
    /// Index of refraction of the dielectric layer (default 1.5).
    #[serde(default)]
    pub ior: Option<f32>,
    #[serde(default)]
    pub specular_color: Option<Color>,
    #[serde(default)]
    pub specular: Option<f32>,
    /// Share of the base that is specular transmission (KHR_materials_transmission).
    #[serde(default)]
    pub transmission: Option<f32>,
    /// Share of the diffuse base transmitted diffusely (KHR_materials_diffuse_transmission),
    /// and its colour.
    #[serde(default)]
    pub diffuse_transmission: Option<f32>,
    #[serde(default)]
    pub diffuse_transmission_color: Option<Color>,
    /// Thin-walled: specular transmission does not bend light.
    #[serde(default)]
    pub thin: bool,
}

// The lights repeat their brightness fields (`power`, `color`, `temperature_k`, ...) rather
// than sharing a struct: serde cannot combine `flatten` with `deny_unknown_fields`, and
// rejecting misspelt fields matters more.

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointLight {
    pub position: [f32; 3],
    /// Radiant intensity in W/sr: RGB, or one number scaling `color`/`temperature_k`.
    #[serde(default)]
    pub intensity: Option<NumOrArray<3>>,
    #[serde(default)]
    pub power: Option<PowerFile>,
    #[serde(default)]
    pub color: Option<Color>,
    #[serde(default)]
    pub temperature_k: Option<f32>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpotLight {
    pub position: [f32; 3],
    pub look_at: [f32; 3],
    /// Half-angle of the cone, in degrees, beyond which nothing is emitted.
    pub cone_angle_deg: f32,
    /// Half-angle at which the smooth fall-off starts (default: the cone angle, a hard edge).
    #[serde(default)]
    pub falloff_start_deg: Option<f32>,
    #[serde(default)]
    pub intensity: Option<NumOrArray<3>>,
    #[serde(default)]
    pub power: Option<PowerFile>,
    #[serde(default)]
    pub color: Option<Color>,
    #[serde(default)]
    pub temperature_k: Option<f32>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DirectionalLight {
    /// Direction the light travels in.
    pub direction: [f32; 3],
    /// Irradiance on a surface facing the light, W/m²: RGB or one number scaling the colour.
    #[serde(default)]
    pub irradiance: Option<NumOrArray<3>>,
    #[serde(default)]
    pub illuminance_lux: Option<f32>,
    #[serde(default)]
    pub color: Option<Color>,
    #[serde(default)]
    pub temperature_k: Option<f32>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentLight {
    /// A latitude–longitude OpenEXR image; omit it for a constant environment.
    #[serde(default)]
    pub file: Option<String>,
    /// Constant radiance (without `file`) or a multiplier on the image (with `file`).
    #[serde(default)]
    pub radiance: Option<Color>,
    /// Rotations only.
    #[serde(default)]
    pub transform: Vec<TransformStep>,
}
