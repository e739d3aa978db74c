//! From a parsed [`SceneFile`] to a validated [`SceneDesc`]: field-by-field checks with full
//! paths, referenced files loaded (once each), instances flattened, units converted.
//!
//! Every check records a [`Problem`] and carries on, so a user sees all that is wrong at once.

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Affine3A, Mat3, Vec3};
use serde::de::DeserializeOwned;

use crate::animation::{CameraPath, Keyframe};
use crate::desc::*;
use crate::error::{Problem, SceneError};
use crate::file::*;
use crate::mesh::{self, RawMesh};
use crate::photometry::{self, K_M};
use crate::source::{SceneSource, confine};
use crate::transform;

/// Deepest nesting of `instance` shapes.
const MAX_INSTANCE_DEPTH: usize = 16;
/// Largest film side, in pixels.
pub const MAX_FILM_SIDE: u32 = 1 << 15;
/// Longest camera path, in frames.
pub const MAX_FRAMES: u32 = 1_000_000;
/// Most photons one map may be shot with (each stored photon takes 40 bytes; a photon is
/// stored about twice in a closed room).
pub const MAX_PHOTONS: u32 = 100_000_000;
/// Most photons in one radiance estimate (the search keeps them on the stack).
pub const MAX_PHOTON_K: u32 = 1024;
/// Most final-gather rays per gather point.
pub const MAX_GATHER_RAYS: u32 = 65_536;

/// Parses and validates the scene file `name` (relative to `source`).
pub fn load(source: &dyn SceneSource, name: &Path) -> Result<SceneDesc, SceneError> {
    let file = source.display_path(name);
    let bytes = source.read(name).map_err(|e| SceneError::Io {
        file: file.clone(),
        source: e,
    })?;
    let de = &mut serde_json::Deserializer::from_slice(&bytes);
    let parsed: SceneFile = serde_path_to_error::deserialize(de).map_err(|e| {
        let path = e.path().to_string();
        SceneError::Invalid(vec![Problem {
            file: file.clone(),
            path: if path == "." { String::new() } else { path },
            message: e.into_inner().to_string(),
        }])
    })?;
    let default_name = name
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut ctx = Ctx {
        source,
        file,
        problems: Vec::new(),
        meshes: HashMap::new(),
    };
    let desc = ctx.scene(parsed, default_name);
    if ctx.problems.is_empty() {
        Ok(desc)
    } else {
        ctx.problems.dedup();
        Err(SceneError::Invalid(ctx.problems))
    }
}

struct Ctx<'s> {
    source: &'s dyn SceneSource,
    file: PathBuf,
    problems: Vec<Problem>,
    /// Mesh files by confined path; `None` if loading failed (reported once).
    meshes: HashMap<PathBuf, Option<Arc<RawMesh>>>,
}

/// Brightness of an emitter as given in the file, before unit conversion.
struct Strength<'a> {
    /// The direct value (radiance, intensity or irradiance) and its field name.
    value: Option<NumOrArray<3>>,
    field: &'static str,
    power: Option<&'a PowerFile>,
    color: Option<Color>,
    temperature_k: Option<f32>,
}

impl Ctx<'_> {
    fn problem(&mut self, path: impl Into<String>, message: impl Into<String>) {
        self.problems.push(Problem {
            file: self.file.clone(),
            path: path.into(),
            message: message.into(),
        });
    }

    /// Parses the body of a tagged object, reporting errors under `path`.
    fn body<T: DeserializeOwned>(&mut self, path: &str, tagged: &Tagged) -> Option<T> {
        let value = serde_json::Value::Object(tagged.body.clone());
        match serde_path_to_error::deserialize::<_, T>(value) {
            Ok(v) => Some(v),
            Err(e) => {
                let inner = e.path().to_string();
                let full = if inner == "." {
                    path.to_string()
                } else {
                    format!("{path}.{inner}")
                };
                self.problem(full, e.into_inner().to_string());
                None
            }
        }
    }

    fn unknown_type(&mut self, path: &str, what: &str, kind: &str, expected: &[&str]) {
        self.problem(
            format!("{path}.type"),
            format!(
                "unknown {what} type \"{kind}\"; expected one of: {}",
                expected.join(", ")
            ),
        );
    }

    fn finite3(&mut self, path: &str, v: [f32; 3]) -> Vec3 {
        let v = Vec3::from(v);
        if !v.is_finite() {
            self.problem(path, format!("expected finite numbers, got {v}"));
        }
        v
    }

    /// Checks `lo <= v <= hi` (and finiteness); `what` describes the expectation.
    fn range(&mut self, path: &str, v: f32, lo: f32, hi: f32, what: &str) -> f32 {
        if !(v >= lo && v <= hi) {
            self.problem(path, format!("expected {what}, got {v}"));
        }
        v
    }

    /// A method name as the registry spells them (lower-case words joined by `-` or `_`);
    /// whether a method of that name exists is the render crate's to say.
    fn method_name(&mut self, name: &str) -> String {
        let word = |c: char| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-' || c == '_';
        if name.is_empty() || name.len() > 32 || !name.chars().all(word) {
            self.problem(
                "integrator.type",
                format!("expected a method name such as \"path\" or \"bdpt\", got \"{name}\""),
            );
        }
        name.to_string()
    }

    fn positive(&mut self, path: &str, v: f32) -> f32 {
        if !(v > 0.0 && v.is_finite()) {
            self.problem(path, format!("expected a positive number, got {v}"));
        }
        v
    }

    /// A reflectance: every component in [0, 1].
    fn albedo(&mut self, path: &str, c: Color) -> Vec3 {
        let v = Vec3::from(c.expand());
        if !(v.min_element() >= 0.0 && v.max_element() <= 1.0) {
            self.problem(
                path,
                format!("expected a reflectance with components in [0, 1], got {v}"),
            );
        }
        v
    }

    fn non_negative3(&mut self, path: &str, c: [f32; 3]) -> Vec3 {
        let v = Vec3::from(c);
        if !(v.min_element() >= 0.0 && v.is_finite()) {
            self.problem(
                path,
                format!("expected finite, non-negative numbers, got {v}"),
            );
        }
        v
    }

    fn transform(&mut self, path: &str, steps: &[TransformStep]) -> Affine3A {
        transform::compose(steps).unwrap_or_else(|(i, msg)| {
            self.problem(format!("{path}.transform[{i}]"), msg);
            Affine3A::IDENTITY
        })
    }

    fn scene(&mut self, f: SceneFile, default_name: String) -> SceneDesc {
        let metres_per_unit = f.units.metres();
        let film = self.film(&f.film);
        let camera = self.camera(&f.camera, &film);
        let camera_path = f
            .camera
            .path
            .as_ref()
            .and_then(|p| self.camera_path(&f.camera, p, &film));
        let integrator = self.integrator(&f.integrator);
        let material_index: BTreeMap<String, u32> = f
            .materials
            .keys()
            .enumerate()
            .map(|(i, k)| (k.clone(), i as u32))
            .collect();
        let materials = f
            .materials
            .iter()
            .map(|(name, t)| MaterialDesc {
                name: name.clone(),
                kind: self
                    .material(&format!("materials.{name}"), t, metres_per_unit)
                    .unwrap_or(MaterialKind::Diffuse { albedo: Vec3::ZERO }),
            })
            .collect();
        let mut out = Shapes {
            meshes: Vec::new(),
            spheres: Vec::new(),
            metres_per_unit,
        };
        let env = ShapeEnv {
            materials: &material_index,
            objects: &f.objects,
        };
        let mut stack = Vec::new();
        self.shapes(
            &f.shapes,
            "shapes",
            Affine3A::IDENTITY,
            &env,
            &mut stack,
            &mut out,
        );
        let lights: Vec<LightDesc> = f
            .lights
            .iter()
            .enumerate()
            .filter_map(|(i, t)| self.light(&format!("lights[{i}]"), t, metres_per_unit))
            .collect();
        if lights.is_empty()
            && out.meshes.iter().all(|m| m.emission.is_none())
            && out.spheres.iter().all(|s| s.emission.is_none())
        {
            tracing::warn!(scene = %self.file.display(), "the scene has no emitters and will render black");
        }
        SceneDesc {
            name: f.name.unwrap_or(default_name),
            metres_per_unit,
            camera,
            camera_path,
            film,
            integrator,
            materials,
            meshes: out.meshes,
            spheres: out.spheres,
            lights,
        }
    }

    fn film(&mut self, f: &FilmFile) -> FilmDesc {
        for (name, v) in [("film.width", f.width), ("film.height", f.height)] {
            if v == 0 || v > MAX_FILM_SIDE {
                self.problem(
                    name,
                    format!("expected a size from 1 to {MAX_FILM_SIDE} pixels, got {v}"),
                );
            }
        }
        let filter = match &f.filter {
            None => FilterDesc::Box { radius: 0.5 },
            Some(fl) => self.filter(fl),
        };
        FilmDesc {
            width: f.width,
            height: f.height,
            filter,
        }
    }

    fn filter(&mut self, f: &FilterFile) -> FilterDesc {
        let not_for = |s: &mut Self, field: &str, present: bool| {
            if present {
                s.problem(
                    format!("film.filter.{field}"),
                    format!("not a parameter of the {:?} filter", f.kind),
                );
            }
        };
        let radius = |s: &mut Self, default: f32| {
            let r = f.radius.unwrap_or(default);
            s.range(
                "film.filter.radius",
                r,
                0.5,
                16.0,
                "a radius from 0.5 to 16 pixels",
            )
        };
        match f.kind {
            FilterType::Box => {
                not_for(self, "sigma", f.sigma.is_some());
                not_for(self, "b", f.b.is_some());
                not_for(self, "c", f.c.is_some());
                FilterDesc::Box {
                    radius: radius(self, 0.5),
                }
            }
            FilterType::Gaussian => {
                not_for(self, "b", f.b.is_some());
                not_for(self, "c", f.c.is_some());
                let radius = radius(self, 1.5);
                let sigma = self.positive("film.filter.sigma", f.sigma.unwrap_or(0.5));
                FilterDesc::Gaussian { radius, sigma }
            }
            FilterType::Mitchell => {
                not_for(self, "sigma", f.sigma.is_some());
                let radius = radius(self, 2.0);
                let b = self.range(
                    "film.filter.b",
                    f.b.unwrap_or(1.0 / 3.0),
                    0.0,
                    1.0,
                    "B in [0, 1]",
                );
                let c = self.range(
                    "film.filter.c",
                    f.c.unwrap_or(1.0 / 3.0),
                    0.0,
                    1.0,
                    "C in [0, 1]",
                );
                FilterDesc::Mitchell { radius, b, c }
            }
        }
    }

    /// Checks one view of the camera (the still camera or a keyframe of its path, at `path`):
    /// finite points, a view direction, an up vector not along it, a field of view; returns
    /// the full vertical field of view in radians.
    #[allow(clippy::too_many_arguments)]
    fn view(
        &mut self,
        path: &str,
        position: [f32; 3],
        look_at: [f32; 3],
        up: [f32; 3],
        fov_deg: f32,
        fov_axis: FovAxis,
        film: &FilmDesc,
    ) -> (Vec3, Vec3, Vec3, f32) {
        let position = self.finite3(&format!("{path}.position"), position);
        let look_at = self.finite3(&format!("{path}.look_at"), look_at);
        let up = self.finite3(&format!("{path}.up"), up);
        let forward = look_at - position;
        if forward.length_squared() == 0.0 {
            self.problem(
                format!("{path}.look_at"),
                format!("expected a point different from {path}.position"),
            );
        } else if forward
            .normalize()
            .cross(up.normalize_or_zero())
            .length_squared()
            < 1e-8
        {
            self.problem(
                format!("{path}.up"),
                "expected an up vector that is not parallel to the view direction",
            );
        }
        let fov = self.range(
            &format!("{path}.fov_deg"),
            fov_deg,
            f32::MIN_POSITIVE,
            179.0,
            "a field of view in (0, 179] degrees",
        );
        let aspect = film.width.max(1) as f32 / film.height.max(1) as f32;
        let half = (fov.to_radians() * 0.5).tan();
        let fov_y = match fov_axis {
            FovAxis::Y => fov.to_radians(),
            FovAxis::X => 2.0 * (half / aspect).atan(),
        };
        (position, look_at, up, fov_y)
    }

    /// A camera path: fps, keyframes in strictly increasing time, each a valid view, and a
    /// valid view at every frame in between (an interpolated up may not turn along the view).
    fn camera_path(
        &mut self,
        c: &CameraFile,
        p: &CameraPathFile,
        film: &FilmDesc,
    ) -> Option<CameraPath> {
        let fps = self.range(
            "camera.path.fps",
            p.fps,
            1e-3,
            1e4,
            "frames per second in [0.001, 10000]",
        );
        if p.keyframes.is_empty() {
            self.problem("camera.path.keyframes", "expected at least one keyframe");
            return None;
        }
        let before = self.problems.len();
        let mut keyframes = Vec::with_capacity(p.keyframes.len());
        for (i, k) in p.keyframes.iter().enumerate() {
            let at = format!("camera.path.keyframes[{i}]");
            if !k.time.is_finite() {
                self.problem(
                    format!("{at}.time"),
                    format!("expected a time in seconds, got {}", k.time),
                );
            } else if let Some(prev) = keyframes.last().map(|k: &Keyframe| k.time)
                && k.time <= prev
            {
                self.problem(
                    format!("{at}.time"),
                    format!(
                        "expected keyframe times to increase, got {} after {prev}",
                        k.time
                    ),
                );
            }
            let (position, look_at, up, fov_y) = self.view(
                &at,
                k.position,
                k.look_at,
                k.up.unwrap_or(c.up),
                k.fov_deg.unwrap_or(c.fov_deg),
                c.fov_axis,
                film,
            );
            keyframes.push(Keyframe {
                time: k.time,
                position,
                look_at,
                up: up.normalize_or_zero(),
                fov_y,
            });
        }
        if self.problems.len() > before {
            return None;
        }
        let path = CameraPath { fps, keyframes };
        let frames = path.frame_count();
        if frames > MAX_FRAMES {
            self.problem(
                "camera.path",
                format!("expected at most {MAX_FRAMES} frames, the keyframes span {frames}"),
            );
            return None;
        }
        for frame in 1..=frames {
            let k = path.at(path.time(frame));
            let forward = (k.look_at - k.position).normalize_or_zero();
            if forward == Vec3::ZERO || forward.cross(k.up).length_squared() < 1e-8 {
                self.problem(
                    "camera.path.keyframes",
                    format!("at frame {frame} the interpolated camera has no valid view direction (look_at on the position, or up along the view); add a keyframe there"),
                );
                return None;
            }
        }
        Some(path)
    }

    fn camera(&mut self, c: &CameraFile, film: &FilmDesc) -> CameraDesc {
        let (position, look_at, up, fov_y) = self.view(
            "camera", c.position, c.look_at, c.up, c.fov_deg, c.fov_axis, film,
        );
        let lens = match c.kind {
            CameraType::Pinhole => {
                for (field, given) in [
                    ("aperture_radius", c.aperture_radius.is_some()),
                    ("focus_distance", c.focus_distance.is_some()),
                ] {
                    if given {
                        self.problem(
                            format!("camera.{field}"),
                            "only a thin_lens camera has this; the camera type is pinhole",
                        );
                    }
                }
                Lens::Pinhole
            }
            CameraType::ThinLens => {
                let aperture_radius = match c.aperture_radius {
                    Some(r) => self.range(
                        "camera.aperture_radius",
                        r,
                        0.0,
                        f32::MAX,
                        "a non-negative radius in scene units",
                    ),
                    None => {
                        self.problem(
                            "camera.aperture_radius",
                            "missing: a thin_lens camera needs an aperture radius in scene units",
                        );
                        0.0
                    }
                };
                let focus_distance = match c.focus_distance {
                    Some(d) => self.positive("camera.focus_distance", d),
                    None => {
                        self.problem(
                            "camera.focus_distance",
                            "missing: a thin_lens camera needs a focus distance in scene units",
                        );
                        1.0
                    }
                };
                Lens::Thin {
                    aperture_radius,
                    focus_distance,
                }
            }
        };
        let exposure_scale = match &c.exposure {
            None => 1.0,
            Some(e) => {
                let iso = self.positive("camera.exposure.iso", e.iso);
                let t = self.positive("camera.exposure.shutter_s", e.shutter_s.0);
                let n = self.positive("camera.exposure.f_number", e.f_number);
                photometry::exposure_scale(iso as f64, t as f64, n as f64) as f32
            }
        };
        CameraDesc {
            position,
            look_at,
            up,
            fov_y,
            lens,
            exposure_scale,
        }
    }

    fn integrator(&mut self, i: &IntegratorFile) -> IntegratorDesc {
        if i.spp == 0 {
            self.problem(
                "integrator.spp",
                "expected at least 1 sample per pixel, got 0",
            );
        }
        IntegratorDesc {
            method: self.method_name(&i.method),
            spp: i.spp,
            max_depth: i.max_depth,
            rr_depth: i.rr_depth,
            seed: i.seed,
            sampler: i.sampler,
            photon: self.photon_map(&i.photon_map),
            subsurface: i.subsurface,
        }
    }

    /// Checks a count knob of `integrator.photon_map` against [lo, hi].
    fn count(&mut self, name: &str, v: Option<u32>, lo: u32, hi: u32) -> Option<u32> {
        if let Some(v) = v
            && !(lo..=hi).contains(&v)
        {
            self.problem(
                format!("integrator.photon_map.{name}"),
                format!("expected {lo} to {hi}, got {v}"),
            );
        }
        v
    }

    fn photon_map(&mut self, f: &PhotonMapFile) -> PhotonDesc {
        const P: &str = "integrator.photon_map";
        for (name, v) in [("radius", f.radius), ("caustic_radius", f.caustic_radius)] {
            if let Some(v) = v {
                self.positive(&format!("{P}.{name}"), v);
            }
        }
        if let Some(a) = f.alpha
            && !(a > 0.0 && a < 1.0)
        {
            self.problem(
                format!("{P}.alpha"),
                format!("expected a fraction in (0, 1), got {a}"),
            );
        }
        let irradiance_cache = match f.irradiance_cache {
            Some(ic) if !ic.enabled => None,
            None => Some(IrradianceCacheDesc::default()),
            Some(ic) => {
                if let Some(a) = ic.accuracy {
                    self.range(
                        &format!("{P}.irradiance_cache.accuracy"),
                        a,
                        1e-3,
                        10.0,
                        "Ward's accuracy a in [0.001, 10]",
                    );
                }
                Some(IrradianceCacheDesc {
                    accuracy: ic.accuracy,
                    spacing: self.count("irradiance_cache.spacing", ic.spacing, 1, 1024),
                    keyframe_step: self.count(
                        "irradiance_cache.keyframe_step",
                        ic.keyframe_step,
                        1,
                        MAX_FRAMES,
                    ),
                    gather_rays: self.count(
                        "irradiance_cache.gather_rays",
                        ic.gather_rays,
                        1,
                        MAX_GATHER_RAYS,
                    ),
                })
            }
        };
        PhotonDesc {
            photons: self.count("photons", f.photons, 1, MAX_PHOTONS),
            caustic_photons: self.count("caustic_photons", f.caustic_photons, 0, MAX_PHOTONS),
            k: self.count("k", f.k, 1, MAX_PHOTON_K),
            caustic_k: self.count("caustic_k", f.caustic_k, 1, MAX_PHOTON_K),
            radius: f.radius,
            caustic_radius: f.caustic_radius,
            gather_rays: self.count("gather_rays", f.gather_rays, 1, MAX_GATHER_RAYS),
            caustic_filter: f.caustic_filter.unwrap_or_default(),
            irradiance_cache,
            alpha: f.alpha,
        }
    }

    fn roughness(
        &mut self,
        path: &str,
        alpha: Option<Alpha>,
        distribution: Distribution,
    ) -> Roughness {
        let [alpha_u, alpha_v] = alpha.map(|a| a.expand()).unwrap_or([0.0, 0.0]);
        for a in [alpha_u, alpha_v] {
            self.range(
                &format!("{path}.alpha"),
                a,
                0.0,
                4.0,
                "a microfacet width α in [0, 4]",
            );
        }
        if (alpha_u == 0.0) != (alpha_v == 0.0) {
            self.problem(
                format!("{path}.alpha"),
                "expected both widths zero (smooth) or both positive",
            );
        }
        Roughness {
            distribution,
            alpha_u,
            alpha_v,
        }
    }

    /// Diffuse + specular must not reflect more than arrives (per channel).
    fn energy(&mut self, path: &str, diffuse: Vec3, specular: Vec3) {
        let total = diffuse + specular;
        if total.max_element() > 1.0 {
            self.problem(
                format!("{path}.specular"),
                format!("expected diffuse + specular <= 1 per channel (energy conservation), got {total}"),
            );
        }
    }

    /// The material `t`; lengths in it (the subsurface coefficients) converted to scene units.
    fn material(&mut self, path: &str, t: &Tagged, metres_per_unit: f64) -> Option<MaterialKind> {
        Some(match t.kind.as_str() {
            "diffuse" => {
                let m: DiffuseMaterial = self.body(path, t)?;
                MaterialKind::Diffuse {
                    albedo: self.albedo(&format!("{path}.albedo"), m.albedo),
                }
            }
            "oren_nayar" => {
                let m: OrenNayarMaterial = self.body(path, t)?;
                let sigma = self.range(
                    &format!("{path}.sigma_deg"),
                    m.sigma_deg,
                    0.0,
                    90.0,
                    "an angle in [0, 90] degrees",
                );
                MaterialKind::OrenNayar {
                    albedo: self.albedo(&format!("{path}.albedo"), m.albedo),
                    sigma: sigma.to_radians(),
                }
            }
            "phong" | "blinn_phong" => {
                let m: PhongMaterial = self.body(path, t)?;
                let diffuse = self.albedo(
                    &format!("{path}.diffuse"),
                    m.diffuse.unwrap_or(NumOrArray::One(0.0)),
                );
                let specular = self.albedo(&format!("{path}.specular"), m.specular);
                self.energy(path, diffuse, specular);
                let exponent = self.range(
                    &format!("{path}.exponent"),
                    m.exponent,
                    0.0,
                    1e6,
                    "an exponent in [0, 1e6]",
                );
                if t.kind == "phong" {
                    MaterialKind::Phong {
                        diffuse,
                        specular,
                        exponent,
                    }
                } else {
                    MaterialKind::BlinnPhong {
                        diffuse,
                        specular,
                        exponent,
                    }
                }
            }
            "ward" => {
                let m: WardMaterial = self.body(path, t)?;
                let diffuse = self.albedo(
                    &format!("{path}.diffuse"),
                    m.diffuse.unwrap_or(NumOrArray::One(0.0)),
                );
                let specular = self.albedo(&format!("{path}.specular"), m.specular);
                self.energy(path, diffuse, specular);
                let alpha_x = self.range(
                    &format!("{path}.alpha_x"),
                    m.alpha_x,
                    1e-4,
                    4.0,
                    "a width in [1e-4, 4]",
                );
                let alpha_y = self.range(
                    &format!("{path}.alpha_y"),
                    m.alpha_y,
                    1e-4,
                    4.0,
                    "a width in [1e-4, 4]",
                );
                MaterialKind::Ward {
                    diffuse,
                    specular,
                    alpha_x,
                    alpha_y,
                }
            }
            "conductor" => {
                let m: ConductorMaterial = self.body(path, t)?;
                let (eta, k) = match (&m.metal, m.eta, m.k) {
                    (Some(name), None, None) => match metal(name) {
                        Some(v) => v,
                        None => {
                            self.problem(
                                format!("{path}.metal"),
                                format!(
                                    "unknown metal \"{name}\"; expected one of: {}",
                                    METALS.map(|m| m.0).join(", ")
                                ),
                            );
                            (Vec3::ONE, Vec3::ZERO)
                        }
                    },
                    (None, Some(eta), Some(k)) => {
                        let eta = self.non_negative3(&format!("{path}.eta"), eta.expand());
                        if eta.min_element() <= 0.0 {
                            self.problem(
                                format!("{path}.eta"),
                                "expected positive indices of refraction",
                            );
                        }
                        (eta, self.non_negative3(&format!("{path}.k"), k.expand()))
                    }
                    _ => {
                        self.problem(
                            path.to_string(),
                            "expected either `metal` or both `eta` and `k`",
                        );
                        (Vec3::ONE, Vec3::ZERO)
                    }
                };
                let specular = self.albedo(
                    &format!("{path}.specular"),
                    m.specular.unwrap_or(NumOrArray::One(1.0)),
                );
                let roughness = self.roughness(path, m.alpha, m.distribution);
                MaterialKind::Conductor {
                    eta,
                    k,
                    specular,
                    roughness,
                }
            }
            "dielectric" => {
                let m: DielectricMaterial = self.body(path, t)?;
                let int = self.range(
                    &format!("{path}.ior"),
                    m.ior,
                    0.01,
                    100.0,
                    "an index of refraction in [0.01, 100]",
                );
                let ext = self.range(
                    &format!("{path}.ext_ior"),
                    m.ext_ior.unwrap_or(1.0),
                    0.01,
                    100.0,
                    "an index of refraction in [0.01, 100]",
                );
                let roughness = self.roughness(path, m.alpha, m.distribution);
                MaterialKind::Dielectric {
                    eta: int / ext,
                    roughness,
                }
            }
            "mirror" => {
                let m: MirrorMaterial = self.body(path, t)?;
                MaterialKind::Mirror {
                    reflectance: self.albedo(
                        &format!("{path}.reflectance"),
                        m.reflectance.unwrap_or(NumOrArray::One(1.0)),
                    ),
                }
            }
            "subsurface" => {
                let m: SubsurfaceMaterial = self.body(path, t)?;
                self.subsurface(path, &m, metres_per_unit)
            }
            "kubelka_munk" => {
                let m: KubelkaMunkMaterial = self.body(path, t)?;
                if m.layers.is_empty() {
                    self.problem(format!("{path}.layers"), "expected at least one layer");
                }
                let layers = m
                    .layers
                    .iter()
                    .enumerate()
                    .map(|(i, l)| {
                        let at = format!("{path}.layers[{i}]");
                        KmLayer {
                            absorption: self.non_negative3(
                                &format!("{at}.absorption_per_mm"),
                                l.absorption_per_mm.expand(),
                            ),
                            scattering: self.non_negative3(
                                &format!("{at}.scattering_per_mm"),
                                l.scattering_per_mm.expand(),
                            ),
                            thickness: self.positive(&format!("{at}.thickness_mm"), l.thickness_mm),
                        }
                    })
                    .collect();
                MaterialKind::KubelkaMunk {
                    layers,
                    substrate: self.albedo(
                        &format!("{path}.substrate"),
                        m.substrate.unwrap_or(NumOrArray::One(0.0)),
                    ),
                }
            }
            "hanrahan_krueger" => {
                let m: HanrahanKruegerMaterial = self.body(path, t)?;
                MaterialKind::HanrahanKrueger {
                    sigma_s: self.non_negative3(
                        &format!("{path}.sigma_s_per_mm"),
                        m.sigma_s_per_mm.expand(),
                    ),
                    sigma_a: self.non_negative3(
                        &format!("{path}.sigma_a_per_mm"),
                        m.sigma_a_per_mm.expand(),
                    ),
                    thickness: self.positive(&format!("{path}.thickness_mm"), m.thickness_mm),
                    g: self.range(
                        &format!("{path}.g"),
                        m.g.unwrap_or(0.0),
                        -0.99,
                        0.99,
                        "a Henyey–Greenstein asymmetry in [-0.99, 0.99]",
                    ),
                    eta: self.range(
                        &format!("{path}.ior"),
                        m.ior.unwrap_or(1.4),
                        1.0,
                        3.0,
                        "an index of refraction in [1, 3]",
                    ),
                    substrate: self.albedo(
                        &format!("{path}.substrate"),
                        m.substrate.unwrap_or(NumOrArray::One(0.0)),
                    ),
                }
            }
            other => {
                self.unknown_type(
                    path,
                    "material",
                    other,
                    &[
                        "diffuse",
                        "oren_nayar",
                        "phong",
                        "blinn_phong",
                        "ward",
                        "conductor",
                        "dielectric",
                        "mirror",
                        "subsurface",
                        "kubelka_munk",
                        "hanrahan_krueger",
                    ],
                );
                return None;
            }
        })
    }

    /// A translucent material: the coefficients of its preset or its own (per mm), times
    /// `scale`, per scene unit.
    fn subsurface(
        &mut self,
        path: &str,
        m: &SubsurfaceMaterial,
        metres_per_unit: f64,
    ) -> MaterialKind {
        let (sigma_s_prime, sigma_a) = match (&m.preset, m.sigma_s_prime_per_mm, m.sigma_a_per_mm) {
            (Some(name), None, None) => match crate::media::measured(name) {
                Some(p) => (Vec3::from(p.sigma_s_prime), Vec3::from(p.sigma_a)),
                None => {
                    let known: Vec<&str> = crate::media::MEASURED.iter().map(|p| p.name).collect();
                    self.problem(
                        format!("{path}.preset"),
                        format!(
                            "unknown medium \"{name}\"; expected one of: {}",
                            known.join(", ")
                        ),
                    );
                    (Vec3::ONE, Vec3::ZERO)
                }
            },
            (None, Some(s), Some(a)) => {
                let s = self.non_negative3(&format!("{path}.sigma_s_prime_per_mm"), s.expand());
                if s.min_element() <= 0.0 {
                    self.problem(
                            format!("{path}.sigma_s_prime_per_mm"),
                            format!("expected a positive scattering coefficient per channel (a medium that does not scatter is a dielectric), got {s}"),
                        );
                }
                (
                    s,
                    self.non_negative3(&format!("{path}.sigma_a_per_mm"), a.expand()),
                )
            }
            _ => {
                self.problem(
                    path.to_string(),
                    "expected either `preset` or both `sigma_s_prime_per_mm` and `sigma_a_per_mm`",
                );
                (Vec3::ONE, Vec3::ZERO)
            }
        };
        let scale = match m.scale {
            Some(s) => self.positive(&format!("{path}.scale"), s),
            None => 1.0,
        };
        let eta = self.range(
            &format!("{path}.ior"),
            m.ior.unwrap_or(crate::media::MEASURED_ETA),
            1.0,
            3.0,
            "an index of refraction in [1, 3] (the dipole's diffuse Fresnel fit holds there)",
        );
        let g = self.range(
            &format!("{path}.g"),
            m.g.unwrap_or(0.0),
            -0.99,
            0.99,
            "a Henyey–Greenstein asymmetry in [-0.99, 0.99]",
        );
        // Per mm → per scene unit.
        let per_unit = (metres_per_unit * 1000.0) as f32 * scale;
        MaterialKind::Subsurface {
            sigma_s_prime: sigma_s_prime * per_unit,
            sigma_a: sigma_a * per_unit,
            eta,
            g,
        }
    }

    fn material_ref(&mut self, path: &str, name: &str, env: &ShapeEnv) -> u32 {
        match env.materials.get(name) {
            Some(&i) => i,
            None => {
                let known: Vec<&str> = env.materials.keys().map(String::as_str).collect();
                self.problem(
                    format!("{path}.material"),
                    format!(
                        "unknown material \"{name}\"; expected one of the scene's materials: {}",
                        known.join(", ")
                    ),
                );
                0
            }
        }
    }

    fn shapes(
        &mut self,
        list: &[Tagged],
        base: &str,
        parent: Affine3A,
        env: &ShapeEnv,
        stack: &mut Vec<String>,
        out: &mut Shapes,
    ) {
        for (i, t) in list.iter().enumerate() {
            let path = format!("{base}[{i}]");
            match t.kind.as_str() {
                "mesh" => {
                    let Some(s) = self.body::<MeshShape>(&path, t) else {
                        continue;
                    };
                    let surface = self.surface(
                        &path,
                        parent,
                        &s.transform,
                        &s.material,
                        s.emission.as_ref(),
                        env,
                    );
                    let Some(raw) = self.mesh_file(&format!("{path}.file"), &s.file) else {
                        continue;
                    };
                    let geometry = Geometry {
                        positions: &raw.positions,
                        normals: if s.smooth_normals {
                            raw.normals.as_deref()
                        } else {
                            None
                        },
                        triangles: &raw.triangles,
                    };
                    self.push_mesh(
                        &path,
                        format!("{path} ({})", s.file),
                        geometry,
                        surface,
                        out,
                    );
                }
                "quad" => {
                    let Some(s) = self.body::<QuadShape>(&path, t) else {
                        continue;
                    };
                    let surface = self.surface(
                        &path,
                        parent,
                        &s.transform,
                        &s.material,
                        s.emission.as_ref(),
                        env,
                    );
                    let o = self.finite3(&format!("{path}.origin"), s.origin);
                    let u = self.finite3(&format!("{path}.edge_u"), s.edge_u);
                    let v = self.finite3(&format!("{path}.edge_v"), s.edge_v);
                    if u.cross(v).length_squared() == 0.0 {
                        self.problem(
                            format!("{path}.edge_v"),
                            "expected two edges that are not parallel and not zero",
                        );
                    }
                    let positions = [o, o + u, o + u + v, o + v];
                    let geometry = Geometry {
                        positions: &positions,
                        normals: None,
                        triangles: &[[0, 1, 2], [0, 2, 3]],
                    };
                    self.push_mesh(&path, path.clone(), geometry, surface, out);
                }
                "box" => {
                    let Some(s) = self.body::<BoxShape>(&path, t) else {
                        continue;
                    };
                    let surface = self.surface(
                        &path,
                        parent,
                        &s.transform,
                        &s.material,
                        s.emission.as_ref(),
                        env,
                    );
                    let lo = self.finite3(&format!("{path}.min"), s.min);
                    let hi = self.finite3(&format!("{path}.max"), s.max);
                    if !lo.cmplt(hi).all() {
                        self.problem(
                            format!("{path}.max"),
                            format!("expected max > min on every axis, got min {lo} and max {hi}"),
                        );
                    }
                    let (positions, triangles) = box_mesh(lo, hi);
                    let geometry = Geometry {
                        positions: &positions,
                        normals: None,
                        triangles: &triangles,
                    };
                    self.push_mesh(&path, path.clone(), geometry, surface, out);
                }
                "sphere" => {
                    let Some(s) = self.body::<SphereShape>(&path, t) else {
                        continue;
                    };
                    let surface = self.surface(
                        &path,
                        parent,
                        &s.transform,
                        &s.material,
                        s.emission.as_ref(),
                        env,
                    );
                    let m = surface.to_world;
                    let center = self.finite3(&format!("{path}.center"), s.center);
                    let radius = self.positive(&format!("{path}.radius"), s.radius);
                    let Some(scale) = transform::uniform_scale(&m) else {
                        self.problem(format!("{path}.transform"), "expected rotations, translations and uniform scales only: a sphere cannot be squashed");
                        continue;
                    };
                    let radius = radius * scale;
                    let area_m2 =
                        4.0 * std::f64::consts::PI * (radius as f64 * out.metres_per_unit).powi(2);
                    let emission = surface
                        .emission
                        .and_then(|e| self.emission(&format!("{path}.emission"), e, area_m2));
                    out.spheres.push(SphereDesc {
                        origin: path.clone(),
                        center: m.transform_point3(center),
                        radius,
                        material: surface.material,
                        emission,
                    });
                }
                "instance" => {
                    let Some(s) = self.body::<InstanceShape>(&path, t) else {
                        continue;
                    };
                    let m = parent * self.transform(&path, &s.transform);
                    let Some(shapes) = env.objects.get(&s.object) else {
                        let known: Vec<&str> = env.objects.keys().map(String::as_str).collect();
                        self.problem(
                            format!("{path}.object"),
                            format!(
                                "unknown object \"{}\"; expected one of the scene's objects: {}",
                                s.object,
                                known.join(", ")
                            ),
                        );
                        continue;
                    };
                    if stack.contains(&s.object) || stack.len() >= MAX_INSTANCE_DEPTH {
                        self.problem(format!("{path}.object"), format!("object \"{}\" instances itself (directly or through others); expected a hierarchy without cycles, at most {MAX_INSTANCE_DEPTH} deep", s.object));
                        continue;
                    }
                    stack.push(s.object.clone());
                    self.shapes(shapes, &format!("objects.{}", s.object), m, env, stack, out);
                    stack.pop();
                }
                other => self.unknown_type(
                    &path,
                    "shape",
                    other,
                    &["mesh", "quad", "box", "sphere", "instance"],
                ),
            }
        }
    }

    /// Loads (once) the mesh file named at `path`.
    fn mesh_file(&mut self, path: &str, file: &str) -> Option<Arc<RawMesh>> {
        let rel = match confine(file) {
            Ok(rel) => rel,
            Err(msg) => {
                self.problem(path, msg);
                return None;
            }
        };
        if let Some(cached) = self.meshes.get(&rel) {
            return cached.clone();
        }
        let shown = self.source.display_path(&rel);
        let loaded = match self.source.read(&rel) {
            Err(e) => {
                self.problem(
                    path,
                    format!("cannot read mesh file {}: {e}", shown.display()),
                );
                None
            }
            Ok(bytes) => {
                let ext = rel
                    .extension()
                    .map(|e| e.to_string_lossy().into_owned())
                    .unwrap_or_default();
                match mesh::parse(&bytes, &ext) {
                    Ok(m) => Some(Arc::new(m)),
                    Err(e) => {
                        self.problems.push(Problem {
                            file: shown,
                            path: e.location,
                            message: format!("{} (referenced by {path})", e.message),
                        });
                        None
                    }
                }
            }
        };
        self.meshes.insert(rel, loaded.clone());
        loaded
    }

    /// The transform, material and emission every surface shape has.
    fn surface<'e>(
        &mut self,
        path: &str,
        parent: Affine3A,
        steps: &[TransformStep],
        material: &str,
        emission: Option<&'e EmissionFile>,
        env: &ShapeEnv,
    ) -> Surface<'e> {
        Surface {
            to_world: parent * self.transform(path, steps),
            material: self.material_ref(path, material, env),
            emission,
        }
    }

    /// Adds a triangle mesh given in its own coordinates.
    fn push_mesh(
        &mut self,
        path: &str,
        origin: String,
        g: Geometry,
        surface: Surface,
        out: &mut Shapes,
    ) {
        let m = surface.to_world;
        let nm = transform::normal_matrix(&m);
        let mirrored = m.matrix3.determinant() < 0.0;
        let mesh = MeshDesc {
            origin,
            positions: g.positions.iter().map(|&p| m.transform_point3(p)).collect(),
            normals: g.normals.map(|ns| {
                ns.iter()
                    .map(|&n| Vec3::from(nm * glam::Vec3A::from(n)).normalize_or_zero())
                    .collect()
            }),
            // A mirroring transform flips the winding; swap it back so the front face stays
            // on the side the (transformed) normals point to.
            triangles: g
                .triangles
                .iter()
                .map(|&[a, b, c]| if mirrored { [a, c, b] } else { [a, b, c] })
                .collect(),
            material: surface.material,
            emission: None,
        };
        let emission = surface.emission.and_then(|e| {
            let area_m2 = mesh.area() * out.metres_per_unit * out.metres_per_unit;
            self.emission(&format!("{path}.emission"), e, area_m2)
        });
        out.meshes.push(MeshDesc { emission, ..mesh });
    }

    fn emission(&mut self, path: &str, e: &EmissionFile, area_m2: f64) -> Option<EmissionDesc> {
        if area_m2 <= 0.0 && e.power.is_some() {
            self.problem(
                format!("{path}.power"),
                "expected an emitter with a positive area to spread the power over",
            );
            return None;
        }
        let sides = if e.two_sided { 2.0 } else { 1.0 };
        let strength = Strength {
            value: e.radiance,
            field: "radiance",
            power: e.power.as_ref(),
            color: e.color,
            temperature_k: e.temperature_k,
        };
        // Φ = π A L for a Lambertian emitter, per side.
        let radiance =
            self.strength(path, strength, Some(std::f64::consts::PI * area_m2 * sides))?;
        Some(EmissionDesc {
            radiance,
            two_sided: e.two_sided,
        })
    }

    /// Resolves an emitter's brightness and colour to an RGB value in luminous-equivalent
    /// W-based units. `power_divisor` converts a power Φ (W) to the value (Φ / divisor);
    /// `None` if a power cannot be given for this kind of emitter.
    fn strength(&mut self, path: &str, s: Strength, power_divisor: Option<f64>) -> Option<Vec3> {
        let field = s.field;
        let chroma = match (s.color, s.temperature_k) {
            (Some(_), Some(_)) => {
                self.problem(
                    format!("{path}.color"),
                    "expected `color` or `temperature_k`, not both",
                );
                return None;
            }
            (None, Some(t)) => {
                let t = self.range(
                    &format!("{path}.temperature_k"),
                    t,
                    500.0,
                    50_000.0,
                    "a colour temperature in [500, 50000] K",
                );
                photometry::blackbody_rgb(t as f64)
            }
            (Some(c), None) => {
                let c = self.non_negative3(&format!("{path}.color"), c.expand());
                let y = photometry::luminance(c);
                if y <= 0.0 {
                    self.problem(
                        format!("{path}.color"),
                        "expected a colour with positive luminance",
                    );
                    return None;
                }
                c / y
            }
            (None, None) => Vec3::ONE,
        };
        match (s.value, s.power) {
            (Some(NumOrArray::Many(rgb)), None) => {
                if s.color.is_some() || s.temperature_k.is_some() {
                    self.problem(format!("{path}.{field}"), format!("expected one number when `color` or `temperature_k` is given; an RGB {field} already has a colour"));
                }
                Some(self.non_negative3(&format!("{path}.{field}"), rgb))
            }
            (Some(NumOrArray::One(v)), None) => {
                let v = self.range(
                    &format!("{path}.{field}"),
                    v,
                    0.0,
                    f32::MAX,
                    "a finite, non-negative number",
                );
                Some(chroma * v)
            }
            (None, Some(p)) => {
                let Some(divisor) = power_divisor else {
                    self.problem(
                        format!("{path}.power"),
                        "this kind of light cannot be given a power",
                    );
                    return None;
                };
                let watts = self.power(&format!("{path}.power"), p, s.temperature_k)?;
                Some(chroma * (watts / divisor) as f32)
            }
            (Some(_), Some(_)) => {
                self.problem(
                    path.to_string(),
                    format!("expected `{field}` or `power`, not both"),
                );
                None
            }
            (None, None) => {
                self.problem(
                    path.to_string(),
                    format!("missing: expected `{field}` or `power`"),
                );
                None
            }
        }
    }

    /// A power specification in luminous-equivalent watts (lumens / 683).
    fn power(&mut self, path: &str, p: &PowerFile, temperature_k: Option<f32>) -> Option<f64> {
        let lumens = match (p.lumens, p.watts, p.efficacy_lm_per_w) {
            (Some(lm), None, None) => self.positive(&format!("{path}.lumens"), lm) as f64,
            (None, Some(w), Some(eff)) => {
                self.positive(&format!("{path}.watts"), w) as f64
                    * self.positive(&format!("{path}.efficacy_lm_per_w"), eff) as f64
            }
            (None, Some(w), None) => match temperature_k {
                Some(t) => {
                    self.positive(&format!("{path}.watts"), w) as f64
                        * photometry::blackbody_efficacy(t.clamp(500.0, 50_000.0) as f64)
                }
                None => {
                    self.problem(
                        format!("{path}.efficacy_lm_per_w"),
                        "missing: radiant watts need a spectrum; give `temperature_k` (black body), or the lamp's efficacy in lm/W",
                    );
                    return None;
                }
            },
            _ => {
                self.problem(
                    path.to_string(),
                    "expected `lumens`, or `watts` (optionally with `efficacy_lm_per_w`)",
                );
                return None;
            }
        };
        Some(lumens / K_M)
    }

    fn light(&mut self, path: &str, t: &Tagged, metres_per_unit: f64) -> Option<LightDesc> {
        let m2 = (metres_per_unit * metres_per_unit) as f32;
        Some(match t.kind.as_str() {
            "point" => {
                let l: PointLight = self.body(path, t)?;
                let position = self.finite3(&format!("{path}.position"), l.position);
                let s = Strength {
                    value: l.intensity,
                    field: "intensity",
                    power: l.power.as_ref(),
                    color: l.color,
                    temperature_k: l.temperature_k,
                };
                let intensity = self.strength(path, s, Some(4.0 * std::f64::consts::PI))?;
                LightDesc::Point {
                    position,
                    intensity: intensity / m2,
                }
            }
            "spot" => {
                let l: SpotLight = self.body(path, t)?;
                let position = self.finite3(&format!("{path}.position"), l.position);
                let target = self.finite3(&format!("{path}.look_at"), l.look_at);
                let direction = (target - position).normalize_or_zero();
                if direction == Vec3::ZERO {
                    self.problem(
                        format!("{path}.look_at"),
                        "expected a point different from the light's position",
                    );
                }
                let cone = self.range(
                    &format!("{path}.cone_angle_deg"),
                    l.cone_angle_deg,
                    0.01,
                    180.0,
                    "a half-angle in (0, 180] degrees",
                );
                let start = l.falloff_start_deg.unwrap_or(cone);
                let start = self.range(
                    &format!("{path}.falloff_start_deg"),
                    start,
                    0.0,
                    cone,
                    "a half-angle from 0 up to cone_angle_deg",
                );
                let (cos_start, cos_cone) = (start.to_radians().cos(), cone.to_radians().cos());
                // Power of a spot with a smooth fall-off (pbrt-v4, SpotLight::Phi):
                // Φ = 2π I (1 − (cos θ_start + cos θ_cone) / 2).
                let solid =
                    2.0 * std::f64::consts::PI * (1.0 - 0.5 * (cos_start as f64 + cos_cone as f64));
                let s = Strength {
                    value: l.intensity,
                    field: "intensity",
                    power: l.power.as_ref(),
                    color: l.color,
                    temperature_k: l.temperature_k,
                };
                let intensity = self.strength(path, s, Some(solid))?;
                LightDesc::Spot {
                    position,
                    direction,
                    intensity: intensity / m2,
                    cos_falloff_start: cos_start,
                    cos_cone,
                }
            }
            "directional" => {
                let l: DirectionalLight = self.body(path, t)?;
                let direction = self
                    .finite3(&format!("{path}.direction"), l.direction)
                    .normalize_or_zero();
                if direction == Vec3::ZERO {
                    self.problem(format!("{path}.direction"), "expected a non-zero direction");
                }
                let value = match (l.irradiance, l.illuminance_lux) {
                    (Some(_), Some(_)) => {
                        self.problem(
                            path.to_string(),
                            "expected `irradiance` or `illuminance_lux`, not both",
                        );
                        return None;
                    }
                    (None, Some(lux)) => Some(NumOrArray::One(
                        self.positive(&format!("{path}.illuminance_lux"), lux) / K_M as f32,
                    )),
                    (v, None) => v,
                };
                let s = Strength {
                    value,
                    field: "irradiance",
                    power: None,
                    color: l.color,
                    temperature_k: l.temperature_k,
                };
                LightDesc::Directional {
                    direction,
                    irradiance: self.strength(path, s, None)?,
                }
            }
            "environment" => {
                let l: EnvironmentLight = self.body(path, t)?;
                let m = self.transform(path, &l.transform);
                if transform::uniform_scale(&m).is_none_or(|s| (s - 1.0).abs() > 1e-4)
                    || m.translation != glam::Vec3A::ZERO
                {
                    self.problem(
                        format!("{path}.transform"),
                        "expected rotations only for an environment",
                    );
                }
                let scale = self.non_negative3(
                    &format!("{path}.radiance"),
                    l.radiance.unwrap_or(NumOrArray::One(1.0)).expand(),
                );
                let image = match &l.file {
                    None => None,
                    Some(f) => Some(self.env_image(&format!("{path}.file"), f)?),
                };
                LightDesc::Environment {
                    image,
                    scale,
                    to_world: Mat3::from(m.matrix3),
                }
            }
            other => {
                self.unknown_type(
                    path,
                    "light",
                    other,
                    &["point", "spot", "directional", "environment"],
                );
                return None;
            }
        })
    }

    fn env_image(&mut self, path: &str, file: &str) -> Option<EnvImage> {
        let rel = confine(file).map_err(|msg| self.problem(path, msg)).ok()?;
        let shown = self.source.display_path(&rel);
        let bytes = match self.source.read(&rel) {
            Ok(b) => b,
            Err(e) => {
                self.problem(
                    path,
                    format!("cannot read environment image {}: {e}", shown.display()),
                );
                return None;
            }
        };
        let img = match crate::image::read_exr_rgb(&bytes) {
            Ok(img) => img,
            Err(msg) => {
                self.problems.push(Problem {
                    file: shown,
                    path: String::new(),
                    message: format!("{msg} (referenced by {path})"),
                });
                return None;
            }
        };
        if let Some(i) = img
            .pixels
            .iter()
            .position(|p| !(p.is_finite() && p.min_element() >= 0.0))
        {
            let (x, y) = (i as u32 % img.width, i as u32 / img.width);
            self.problems.push(Problem {
                file: shown,
                path: format!("pixel ({x}, {y})"),
                message: format!(
                    "expected finite, non-negative radiance, got {}",
                    img.pixels[i]
                ),
            });
            return None;
        }
        if img.width < 2 || img.height < 1 {
            self.problem(
                path,
                "expected a latitude-longitude image at least 2 pixels wide",
            );
            return None;
        }
        Some(EnvImage {
            width: img.width,
            height: img.height,
            texels: img.pixels,
        })
    }
}

struct ShapeEnv<'a> {
    materials: &'a BTreeMap<String, u32>,
    objects: &'a BTreeMap<String, Vec<Tagged>>,
}

/// A shape's placement, material and emission, resolved.
struct Surface<'e> {
    to_world: Affine3A,
    material: u32,
    emission: Option<&'e EmissionFile>,
}

/// A triangle mesh in its own coordinates.
struct Geometry<'g> {
    positions: &'g [Vec3],
    normals: Option<&'g [Vec3]>,
    triangles: &'g [[u32; 3]],
}

struct Shapes {
    meshes: Vec<MeshDesc>,
    spheres: Vec<SphereDesc>,
    metres_per_unit: f64,
}

/// An axis-aligned box as 12 triangles wound so that normals point outwards.
pub fn box_mesh(lo: Vec3, hi: Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let corner = |i: u32| {
        Vec3::new(
            if i & 1 != 0 { hi.x } else { lo.x },
            if i & 2 != 0 { hi.y } else { lo.y },
            if i & 4 != 0 { hi.z } else { lo.z },
        )
    };
    let positions = (0..8).map(corner).collect();
    // Faces as quads (counter-clockwise seen from outside): -x, +x, -y, +y, -z, +z.
    let quads = [
        [0, 4, 6, 2],
        [1, 3, 7, 5],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 2, 3, 1],
        [4, 5, 7, 6],
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    (positions, triangles)
}

/// Named metals: complex IOR (η, k) at about 650, 550 and 450 nm (R, G, B).
const METALS: [(&str, [f32; 3], [f32; 3]); 4] = [
    ("gold", [0.143, 0.374, 1.442], [3.983, 2.385, 1.603]),
    ("silver", [0.155, 0.117, 0.138], [4.828, 3.122, 2.147]),
    ("copper", [0.200, 0.924, 1.102], [3.912, 2.452, 2.142]),
    ("aluminium", [1.657, 0.880, 0.521], [9.224, 6.270, 4.837]),
];

fn metal(name: &str) -> Option<(Vec3, Vec3)> {
    let name = if name == "aluminum" {
        "aluminium"
    } else {
        name
    };
    METALS
        .iter()
        .find(|m| m.0 == name)
        .map(|m| (Vec3::from(m.1), Vec3::from(m.2)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_normals_point_outwards() {
        let (p, t) = box_mesh(Vec3::ZERO, Vec3::ONE);
        let c = Vec3::splat(0.5);
        for [a, b, d] in t {
            let (a, b, d) = (p[a as usize], p[b as usize], p[d as usize]);
            let n = (b - a).cross(d - a);
            assert!(n.dot((a + b + d) / 3.0 - c) > 0.0);
        }
    }
}
