//! From a parsed [`SceneFile`] to a validated [`SceneDesc`]: field-by-field checks with full
//! paths, referenced files loaded (once each), instances flattened, units converted.
//!
//! Every check records a [`Problem`] and carries on, so a user sees all that is wrong at once.

mod camera;
mod gltf;
mod light;
mod material;
mod mtl;
mod shapes;

pub use gltf::is_gltf;
pub use shapes::box_mesh;
use shapes::{Geometry, ShapeEnv, Shapes, Surface};

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
pub use crate::setting::{MAX_FRAMES, MAX_PHOTONS};

/// Parses and validates the scene file `name` (relative to `source`).
pub fn load(source: &dyn SceneSource, name: &Path) -> Result<SceneDesc, SceneError> {
    let file = source.display_path(name);
    let default_name = name
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut ctx = Ctx {
        source,
        file: file.clone(),
        problems: Vec::new(),
        meshes: HashMap::new(),
        gltfs: HashMap::new(),
        images: HashMap::new(),
        warnings: Vec::new(),
    };
    let parsed = if is_gltf(name) {
        match ctx.gltf_scene_file(name) {
            Some(f) => f,
            None => return Err(SceneError::Invalid(ctx.problems)),
        }
    } else {
        let bytes = source.read(name).map_err(|e| SceneError::Io {
            file: file.clone(),
            source: e,
        })?;
        let de = &mut serde_json::Deserializer::from_slice(&bytes);
        serde_path_to_error::deserialize(de).map_err(|e| {
            let path = e.path().to_string();
            SceneError::Invalid(vec![Problem {
                file: file.clone(),
                path: if path == "." { String::new() } else { path },
                message: e.into_inner().to_string(),
            }])
        })?
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
    /// glTF files likewise.
    gltfs: HashMap<PathBuf, Option<Arc<crate::gltf::GltfScene>>>,
    /// Image textures of MTL libraries, decoded by file and role.
    images: HashMap<(PathBuf, crate::texture::TextureRole), Arc<crate::texture::TextureImage>>,
    /// What was read but not modelled.
    warnings: Vec<String>,
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
        let mut materials: Vec<MaterialDesc> = f
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
            first_material: materials.len() as u32,
            materials: Vec::new(),
            lights: Vec::new(),
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
        materials.append(&mut out.materials);
        let mut lights: Vec<LightDesc> = f
            .lights
            .iter()
            .enumerate()
            .filter_map(|(i, t)| self.light(&format!("lights[{i}]"), t, metres_per_unit))
            .collect();
        lights.append(&mut out.lights);
        if let Some(env) = &f.environment {
            let already = lights
                .iter()
                .position(|l| matches!(l, LightDesc::Environment { .. }));
            if let Some(i) = already {
                self.problem(
                    "environment",
                    format!("an environment is given here and as lights[{i}]: expected one"),
                );
            } else if let Some(l) = self.environment(env) {
                lights.push(l);
            }
        }
        for w in &self.warnings {
            tracing::warn!(scene = %self.file.display(), "{w}");
        }
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
            warnings: std::mem::take(&mut self.warnings),
        }
    }
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
