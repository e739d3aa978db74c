//! glTF files in a scene: a `gltf` shape places one (its meshes, materials and lights) under
//! a transform, and a `.gltf`/`.glb` given alone becomes a scene of its own whose camera is
//! the file's.

use super::*;
use crate::gltf::GltfScene;

/// Film width of a scene made from a glTF file alone; the height follows the camera's aspect.
const GLTF_FILM_WIDTH: u32 = 1280;
/// Aspect of a glTF camera that does not give one.
const DEFAULT_ASPECT: f32 = 16.0 / 9.0;

/// Whether `name` is a glTF file by its extension.
pub fn is_gltf(name: &Path) -> bool {
    name.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"))
}

impl Ctx<'_> {
    /// Loads (once) the glTF file named at `path`; problems are reported against the file.
    pub(super) fn gltf_file(&mut self, path: &str, file: &str) -> Option<Arc<GltfScene>> {
        self.load_once(
            path,
            file,
            |c| &mut c.gltfs,
            |ctx, rel| {
                let shown = ctx.source.display_path(rel);
                match crate::gltf::load(ctx.source, rel) {
                    Ok(g) => {
                        // Named as the scene names the file: warnings become the job's
                        // decisions and the EXR header, alike wherever the scene is read.
                        for w in &g.warnings {
                            ctx.warnings.push(format!("{}: {w}", rel.display()));
                        }
                        Some(g)
                    }
                    Err(e) => {
                        ctx.problems.push(Problem {
                            file: shown,
                            path: e.location,
                            message: if path.is_empty() {
                                e.message
                            } else {
                                format!("{} (referenced by {path})", e.message)
                            },
                        });
                        None
                    }
                }
            },
        )
    }

    /// A `gltf` shape: the file's meshes, materials and lights, its metres turned into scene
    /// units, then placed by `parent` and the shape's transform.
    pub(super) fn gltf_shape(
        &mut self,
        path: &str,
        t: &Tagged,
        parent: Affine3A,
        out: &mut Shapes,
    ) {
        let Some(s) = self.body::<GltfShape>(path, t) else {
            return;
        };
        let Some(g) = self.gltf_file(&format!("{path}.file"), &s.file) else {
            return;
        };
        // (A glTF file alone is a scene whose one shape is the file: its sky is used.)
        if g.environment.is_some() && !is_gltf(&self.file) {
            self.warnings.push(format!(
                "{path}: {} names a sky in its scene's extras.{}; as a shape it is not used \
                 (the scene.json's own `environment` is the sky)",
                s.file,
                crate::gltf::ENVIRONMENT_EXTRA
            ));
        }
        let metres = Affine3A::from_scale(Vec3::splat((1.0 / out.metres_per_unit) as f32));
        let to_world = parent * self.transform(path, &s.transform) * metres;
        let base = out.first_material + out.materials.len() as u32;
        let metres_per_unit = out.metres_per_unit as f32;
        out.materials.extend(g.materials.iter().map(|m| {
            let mut kind = m.kind.clone();
            // Coefficients are per metre in glTF, per scene unit here.
            match &mut kind {
                MaterialKind::Dielectric { absorption, .. } => *absorption *= metres_per_unit,
                MaterialKind::Subsurface {
                    sigma_s_prime,
                    sigma_a,
                    ..
                } => {
                    *sigma_s_prime *= metres_per_unit;
                    *sigma_a *= metres_per_unit;
                }
                _ => {}
            }
            MaterialDesc {
                name: format!("{} / {}", s.file, m.name),
                kind,
            }
        }));
        for m in &g.meshes {
            let geometry = Geometry {
                positions: &m.positions,
                normals: m.normals.as_deref(),
                uvs: m.uvs.as_deref(),
                uvs1: m.uvs1.as_deref(),
                tangents: m.tangents.as_deref(),
                triangles: &m.triangles,
            };
            let surface = Surface {
                to_world: to_world * Affine3A::from_mat4(m.to_root),
                material: base + m.material,
                emission: None,
            };
            self.push_mesh(
                path,
                format!("{path} ({}: {})", s.file, m.origin),
                geometry,
                surface,
                out,
            );
            if let Some(e) = &g.emission[m.material as usize]
                && let Some(last) = out.meshes.last_mut()
            {
                if e.texture.is_some() && m.uvs.is_none() {
                    self.warnings.push(format!(
                        "{path} ({}: {}): an emissiveTexture without TEXCOORD_0 cannot be \
                         placed: its factor alone is used",
                        s.file, m.origin
                    ));
                }
                last.emission = Some(e.clone());
            }
        }
        // Intensities are per metre² of distance²; scene distances are in scene units.
        let per_unit2 = (out.metres_per_unit * out.metres_per_unit) as f32;
        let dir = |d: Vec3| to_world.transform_vector3(d).normalize_or_zero();
        for l in &g.lights {
            let mut l = l.clone();
            match &mut l {
                LightDesc::Point {
                    position,
                    intensity,
                }
                | LightDesc::Spot {
                    position,
                    intensity,
                    ..
                } => {
                    *position = to_world.transform_point3(*position);
                    *intensity /= per_unit2;
                }
                LightDesc::Directional { .. } | LightDesc::Environment { .. } => {}
            }
            if let LightDesc::Spot { direction, .. } | LightDesc::Directional { direction, .. } =
                &mut l
            {
                *direction = dir(*direction);
            }
            out.lights.push(l);
        }
    }

    /// The scene a glTF file makes alone: its own camera (or, without one, a view of its
    /// bounds, said in a warning), a film [`GLTF_FILM_WIDTH`] wide at the camera's aspect, the
    /// default integrator, and the file as its one shape.
    pub(super) fn gltf_scene_file(&mut self, name: &Path) -> Option<SceneFile> {
        let file = name.to_string_lossy().into_owned();
        let g = self.gltf_file("", &file)?;
        let (camera, aspect) = match g.camera {
            Some(c) => {
                if c.aspect.is_none() {
                    self.warnings.push(format!(
                        "the camera gives no aspectRatio: the film is {}:9 (--size sets another)",
                        (DEFAULT_ASPECT * 9.0).round()
                    ));
                }
                let camera = serde_json::json!({
                    "type": "pinhole",
                    "position": c.position.to_array(),
                    "look_at": c.look_at.to_array(),
                    "up": c.up.to_array(),
                    "fov_deg": c.yfov.to_degrees(),
                    "fov_axis": "y",
                });
                (camera, c.aspect.unwrap_or(DEFAULT_ASPECT))
            }
            None => {
                let (lo, hi) = g
                    .meshes
                    .iter()
                    .flat_map(|m| m.positions.iter().map(|&p| m.to_root.transform_point3(p)))
                    .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
                        (lo.min(p), hi.max(p))
                    });
                if !lo.is_finite() {
                    self.problem(
                        "",
                        "the glTF file has neither a camera nor any mesh to look at",
                    );
                    return None;
                }
                let centre = (lo + hi) * 0.5;
                let radius = ((hi - lo).length() * 0.5).max(1e-3);
                let fov = 40f32;
                let distance = radius / (fov.to_radians() * 0.5).sin();
                self.warnings.push(
                    "the file has no perspective camera: looking at its bounds from +z".into(),
                );
                let camera = serde_json::json!({
                    "type": "pinhole",
                    "position": (centre + Vec3::Z * distance).to_array(),
                    "look_at": centre.to_array(),
                    "fov_deg": fov,
                });
                (camera, DEFAULT_ASPECT)
            }
        };
        let height = ((GLTF_FILM_WIDTH as f32 / aspect).round() as u32).clamp(1, MAX_FILM_SIDE);
        let mut json = serde_json::json!({
            "units": "m",
            "camera": camera,
            "film": {"width": GLTF_FILM_WIDTH, "height": height},
            "materials": {},
            "shapes": [{"type": "gltf", "file": file}],
        });
        if let Some(e) = &g.environment {
            // The image is named relative to the glTF file, as its buffers and images are.
            let image = e.image.as_ref().map(|i| {
                let dir = name.parent().unwrap_or(Path::new(""));
                dir.join(i).to_string_lossy().into_owned()
            });
            json["environment"] = serde_json::json!({
                "image": image,
                "strength": e.strength,
                "rotation_deg": e.rotation_deg,
            });
        }
        match serde_json::from_value(json) {
            Ok(f) => Some(f),
            Err(e) => {
                self.problem(
                    "",
                    format!("the camera or film read from the glTF file: {e}"),
                );
                None
            }
        }
    }
}
