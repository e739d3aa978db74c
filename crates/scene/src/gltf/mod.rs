//! glTF 2.0 scenes (`.gltf` with its buffers, or one `.glb`): the default scene's node
//! hierarchy flattened into triangle meshes, its materials as the glTF metallic-roughness
//! BRDF, its first perspective camera and its KHR_lights_punctual lights.
//!
//! Units: glTF lengths are metres; punctual lights are photometric (point and spot intensity
//! in candela, directional illuminance in lux) and become our luminous-equivalent watts by
//! dividing by K_m = 683 lm/W; `emissiveFactor` × `emissiveStrength` is surface radiance.
//! Everything read is checked: a malformed file, a missing buffer, an accessor outside its
//! buffer, a non-finite position or a required extension we do not implement is an error
//! naming the object; what we read but do not model yet is a warning.

mod buffers;
mod checks;
mod materials;
mod tangents;

pub(crate) use tangents::mikktspace;

use std::path::Path;

use glam::{Mat4, Vec3};

use crate::desc::{EmissionDesc, LightDesc, MaterialDesc};
use crate::file::EnvironmentFile;
use crate::photometry::K_M;
use crate::source::SceneSource;

/// Extensions whose content we read (or whose absence of effect we state in a warning).
pub const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_diffuse_transmission",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_volume",
    "KHR_texture_transform",
];

/// Deepest node hierarchy followed (glTF's is a tree; this bounds a malformed one).
const MAX_DEPTH: usize = 256;

/// A glTF file read into world space (the glTF scene's root frame, in metres).
#[derive(Debug, Clone)]
pub struct GltfScene {
    pub meshes: Vec<GltfMesh>,
    /// One per glTF material, then the default material if a primitive has none.
    pub materials: Vec<MaterialDesc>,
    /// What each material emits (radiance in W·sr⁻¹·m⁻²), if it does.
    pub emission: Vec<Option<EmissionDesc>>,
    pub camera: Option<GltfCamera>,
    /// KHR_lights_punctual lights in world space (metres), radiometric.
    pub lights: Vec<LightDesc>,
    /// The sky the glTF scene's `extras.tessera_environment` names (glTF has no environment
    /// of its own): used when the file is the whole scene, its image relative to the file.
    pub environment: Option<EnvironmentFile>,
    /// What was read but is not modelled, for the render summary and the job's decisions.
    pub warnings: Vec<String>,
}

/// The key in a glTF scene's `extras` (Blender: a custom property of the scene, exported with
/// "Include → Custom Properties") holding `{"image", "strength", "rotation_deg"}`, as the
/// top-level `environment` of a scene.json.
pub const ENVIRONMENT_EXTRA: &str = "tessera_environment";

/// One primitive of one mesh instance, in its mesh's own coordinates, placed in the glTF
/// scene's root frame by `to_root` (the scene placing the file applies it with its own
/// transform, once).
#[derive(Debug, Clone)]
pub struct GltfMesh {
    /// `mesh 2 "Chair" primitive 0 (node 5 "Chair.001")`, for messages.
    pub origin: String,
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    /// TEXCOORD_0, one per vertex.
    pub uvs: Option<Vec<glam::Vec2>>,
    /// TEXCOORD_1, one per vertex.
    pub uvs1: Option<Vec<glam::Vec2>>,
    /// Tangent frames per triangle corner (xyz, w the bitangent's sign), where the
    /// material has a normal map.
    pub tangents: Option<Vec<[glam::Vec4; 3]>>,
    pub triangles: Vec<[u32; 3]>,
    /// Index into [`GltfScene::materials`].
    pub material: u32,
    /// The node's world matrix (an affine transform: glTF node transforms are).
    pub to_root: Mat4,
}

/// A perspective camera placed by its node: looking down its local −z with +y up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GltfCamera {
    pub position: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    /// Vertical field of view, radians.
    pub yfov: f32,
    /// Width / height, if the file gives it.
    pub aspect: Option<f32>,
}

/// What went wrong, and where in the file (`meshes[2] "Chair" primitives[0]`).
#[derive(Debug, Clone, PartialEq)]
pub struct GltfError {
    pub location: String,
    pub message: String,
}

impl GltfError {
    fn new(location: impl Into<String>, message: impl Into<String>) -> Self {
        GltfError {
            location: location.into(),
            message: message.into(),
        }
    }
}

/// `meshes[2] "Chair"`: an object's array, index and name.
fn named(array: &str, index: usize, name: Option<&str>) -> String {
    match name {
        Some(n) => format!("{array}[{index}] \"{n}\""),
        None => format!("{array}[{index}]"),
    }
}

/// Reads the glTF file `name` from `source` (its buffers relative to it).
pub fn load(source: &dyn SceneSource, name: &Path) -> Result<GltfScene, GltfError> {
    let bytes = source
        .read(name)
        .map_err(|e| GltfError::new("", format!("cannot read the file: {e}")))?;
    let invalid = |e: gltf::Error| GltfError::new("", format!("not a valid glTF 2.0 file: {e}"));
    // Checked wherever the gltf crate's parser, validation or readers would overflow or
    // index out of bounds themselves (the GLB header before parsing, the rest after), then
    // validated.
    checks::glb_header(&bytes)?;
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(&bytes).map_err(invalid)?;
    let root = document.into_json();
    checks::check(&root)?;
    let document = gltf::Document::from_json(root).map_err(invalid)?;
    let doc = &document;
    let mut warnings = Vec::new();
    for ext in doc.extensions_required() {
        if !SUPPORTED_EXTENSIONS.contains(&ext) {
            return Err(GltfError::new(
                "extensionsRequired",
                format!(
                    "the file requires extension {ext}, which Tessera does not implement; \
                     expected only: {}",
                    SUPPORTED_EXTENSIONS.join(", ")
                ),
            ));
        }
    }
    for ext in doc.extensions_used() {
        if !SUPPORTED_EXTENSIONS.contains(&ext) {
            warnings.push(format!("extension {ext} is used by the file and ignored"));
        }
    }
    let dir = name.parent().unwrap_or(Path::new(""));
    let data = buffers::load(doc, blob.as_deref(), source, dir)?;
    let mut images = materials::Images::new(&data, source, dir);
    let materials::Materials {
        mut materials,
        mut emission,
        thin_by_default,
    } = materials::read(doc, &mut images, &mut warnings)?;
    let default_material = materials.len() as u32;

    let scene = match doc.default_scene() {
        Some(s) => s,
        None => {
            let Some(s) = doc.scenes().next() else {
                return Err(GltfError::new("scenes", "the file has no scene to render"));
            };
            warnings.push(format!(
                "no default scene (`scene`): rendering {}",
                named("scenes", s.index(), s.name())
            ));
            s
        }
    };
    let environment = environment(&scene)?;
    let mut walk = Walk {
        data: &data,
        default_material,
        meshes: Vec::new(),
        cameras: Vec::new(),
        lights: Vec::new(),
        warnings: &mut warnings,
        uses_default_material: false,
    };
    for node in scene.nodes() {
        walk.node(&node, Mat4::IDENTITY, 0)?;
    }
    let Walk {
        mut meshes,
        cameras,
        lights,
        uses_default_material,
        ..
    } = walk;
    if uses_default_material {
        materials.push(materials::default_material());
        emission.push(None);
    }
    solid_where_closed(
        &mut meshes,
        &mut materials,
        &mut emission,
        &thin_by_default,
        &mut warnings,
    );
    let camera = cameras.first().map(|(c, _)| *c);
    if cameras.len() > 1 {
        warnings.push(format!(
            "{} cameras in the scene: rendering through the first, {}",
            cameras.len(),
            cameras[0].1
        ));
    }
    Ok(GltfScene {
        meshes,
        materials,
        emission,
        camera,
        lights,
        environment,
        warnings,
    })
}

/// Transmissive materials without KHR_materials_volume are thin walls by the glTF
/// specification; exporters write them so for closed glass objects too (Blender's exporter
/// does for every glass it exports, and Cycles renders it solid). A primitive whose mesh is
/// closed takes its material as a solid (refracting into an interior); an open one (a window
/// pane, a leaf) stays a thin wall. Each such choice is a warning, so it is never silent;
/// KHR_materials_volume with a thickness states solid, and with thickness 0 states thin.
fn solid_where_closed(
    meshes: &mut [GltfMesh],
    materials: &mut Vec<MaterialDesc>,
    emission: &mut Vec<Option<EmissionDesc>>,
    thin_by_default: &[bool],
    warnings: &mut Vec<String>,
) {
    let mut twins: std::collections::HashMap<u32, u32> = std::collections::HashMap::new();
    for mesh in meshes.iter_mut() {
        let m = mesh.material as usize;
        if !thin_by_default.get(m).copied().unwrap_or(false) || !is_closed(mesh) {
            continue;
        }
        let twin = *twins.entry(mesh.material).or_insert_with(|| {
            let desc = &materials[m];
            warnings.push(format!(
                "material \"{}\" transmits without KHR_materials_volume, which makes it a thin \
                 wall, but closed meshes use it: rendered solid on them (refracting into an \
                 interior, as Cycles renders it); state KHR_materials_volume to choose",
                desc.name
            ));
            let solid = MaterialDesc {
                name: format!("{} (solid)", desc.name),
                kind: materials::solid(&desc.kind),
            };
            materials.push(solid);
            emission.push(emission[m].clone());
            (materials.len() - 1) as u32
        });
        mesh.material = twin;
    }
}

/// Whether a primitive's triangles close a volume: with corners welded by position, every
/// edge is shared by exactly two triangles.
fn is_closed(mesh: &GltfMesh) -> bool {
    if mesh.triangles.is_empty() {
        return false;
    }
    let mut ids: std::collections::HashMap<[u32; 3], u32> = std::collections::HashMap::new();
    let welded: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| {
            let n = ids.len() as u32;
            *ids.entry(p.to_array().map(f32::to_bits)).or_insert(n)
        })
        .collect();
    let mut edges: std::collections::HashMap<(u32, u32), u32> = std::collections::HashMap::new();
    for t in &mesh.triangles {
        let c = t.map(|i| welded[i as usize]);
        for (a, b) in [(c[0], c[1]), (c[1], c[2]), (c[2], c[0])] {
            if a == b {
                continue;
            }
            *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    !edges.is_empty() && edges.values().all(|&n| n == 2)
}

/// The scene's `extras.tessera_environment`, if it has one; other extras are the user's.
fn environment(scene: &gltf::Scene) -> Result<Option<EnvironmentFile>, GltfError> {
    let Some(raw) = scene.extras() else {
        return Ok(None);
    };
    let at = format!(
        "{} extras.{ENVIRONMENT_EXTRA}",
        named("scenes", scene.index(), scene.name())
    );
    let extras: serde_json::Map<String, serde_json::Value> = match serde_json::from_str(raw.get()) {
        Ok(m) => m,
        // Extras may be anything; only an object can hold ours.
        Err(_) => return Ok(None),
    };
    let Some(v) = extras.get(ENVIRONMENT_EXTRA) else {
        return Ok(None);
    };
    serde_json::from_value(v.clone()).map(Some).map_err(|e| {
        GltfError::new(
            at,
            format!(
                "expected {{\"image\": \"sky.exr\", \"strength\": 1, \"rotation_deg\": 0}} \
                 (each optional): {e}"
            ),
        )
    })
}

struct Walk<'a> {
    data: &'a [Vec<u8>],
    default_material: u32,
    meshes: Vec<GltfMesh>,
    /// Perspective cameras with where they come from.
    cameras: Vec<(GltfCamera, String)>,
    lights: Vec<LightDesc>,
    warnings: &'a mut Vec<String>,
    uses_default_material: bool,
}

impl Walk<'_> {
    fn node(&mut self, node: &gltf::Node, parent: Mat4, depth: usize) -> Result<(), GltfError> {
        let here = named("nodes", node.index(), node.name());
        if depth >= MAX_DEPTH {
            return Err(GltfError::new(
                here,
                format!("the node hierarchy is deeper than {MAX_DEPTH}: expected a tree"),
            ));
        }
        let local = Mat4::from_cols_array_2d(&node.transform().matrix());
        let world = parent * local;
        if !world.is_finite() {
            return Err(GltfError::new(
                here,
                "expected a finite transform (matrix or translation/rotation/scale)",
            ));
        }
        if let Some(mesh) = node.mesh() {
            self.mesh(&mesh, &world, &here)?;
        }
        if let Some(camera) = node.camera() {
            let at = named("cameras", camera.index(), camera.name());
            match camera.projection() {
                gltf::camera::Projection::Perspective(p) => {
                    let position = world.transform_point3(Vec3::ZERO);
                    let forward = world.transform_vector3(-Vec3::Z).normalize_or_zero();
                    let up = world.transform_vector3(Vec3::Y).normalize_or_zero();
                    let yfov = p.yfov();
                    if !(yfov > 0.0 && yfov < std::f32::consts::PI) || forward == Vec3::ZERO {
                        return Err(GltfError::new(
                            at,
                            format!(
                                "expected yfov in (0, π) and an invertible placement, got yfov {yfov}"
                            ),
                        ));
                    }
                    self.cameras.push((
                        GltfCamera {
                            position,
                            look_at: position + forward,
                            up,
                            yfov,
                            aspect: p.aspect_ratio().filter(|a| *a > 0.0 && a.is_finite()),
                        },
                        format!("{at} on {here}"),
                    ));
                }
                gltf::camera::Projection::Orthographic(_) => self.warnings.push(format!(
                    "{at} on {here} is orthographic, which Tessera does not render: skipped"
                )),
            }
        }
        if let Some(light) = node.light() {
            self.light(&light, &world, &here)?;
        }
        for child in node.children() {
            self.node(&child, world, depth + 1)?;
        }
        Ok(())
    }

    fn light(
        &mut self,
        light: &gltf::khr_lights_punctual::Light,
        world: &Mat4,
        here: &str,
    ) -> Result<(), GltfError> {
        use gltf::khr_lights_punctual::Kind;
        let at = format!(
            "{} on {here}",
            named("KHR_lights_punctual.lights", light.index(), light.name())
        );
        let color = Vec3::from(light.color());
        let intensity = light.intensity();
        if !(color.is_finite()
            && color.min_element() >= 0.0
            && intensity >= 0.0
            && intensity.is_finite())
        {
            return Err(GltfError::new(
                at,
                format!("expected a non-negative colour and intensity, got {color} × {intensity}"),
            ));
        }
        if light.range().is_some() {
            self.warnings.push(format!(
                "{at}: `range` ignored (light falls off with the inverse square, without a cut-off)"
            ));
        }
        // Candela (lm/sr) and lux (lm/m²) to luminous-equivalent W/sr and W/m².
        let radiometric = color * (intensity / K_M as f32);
        let position = world.transform_point3(Vec3::ZERO);
        let direction = world.transform_vector3(-Vec3::Z).normalize_or_zero();
        if direction == Vec3::ZERO {
            return Err(GltfError::new(at, "expected an invertible node transform"));
        }
        self.lights.push(match light.kind() {
            Kind::Point => LightDesc::Point {
                position,
                intensity: radiometric,
            },
            Kind::Directional => LightDesc::Directional {
                direction,
                irradiance: radiometric,
            },
            Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => {
                let half_pi = std::f32::consts::FRAC_PI_2;
                // Equal angles (Blender's export of a spot without blend) make a hard edge.
                if !(0.0 <= inner_cone_angle
                    && inner_cone_angle <= outer_cone_angle
                    && 0.0 < outer_cone_angle
                    && outer_cone_angle <= half_pi)
                {
                    return Err(GltfError::new(
                        at,
                        format!(
                            "expected 0 ≤ innerConeAngle ≤ outerConeAngle ≤ π/2 and a cone, got {inner_cone_angle} and {outer_cone_angle}"
                        ),
                    ));
                }
                LightDesc::Spot {
                    position,
                    direction,
                    intensity: radiometric,
                    cos_falloff_start: inner_cone_angle.cos(),
                    cos_cone: outer_cone_angle.cos(),
                }
            }
        });
        Ok(())
    }

    fn mesh(&mut self, mesh: &gltf::Mesh, world: &Mat4, here: &str) -> Result<(), GltfError> {
        let mesh_at = named("meshes", mesh.index(), mesh.name());
        for prim in mesh.primitives() {
            let at = format!("{mesh_at} primitives[{}] (on {here})", prim.index());
            let Some(tri) = buffers::triangles(&prim, self.data, &at, self.warnings)? else {
                continue;
            };
            let (positions, normals) = buffers::attributes(&prim, self.data, &at, self.warnings)?;
            let n = positions.len();
            let uvs = buffers::uvs(&prim, self.data, 0, n, &at)?;
            let uvs1 = buffers::uvs(&prim, self.data, 1, n, &at)?;
            if let Some(i) = tri.iter().flatten().find(|&&i| i as usize >= n) {
                return Err(GltfError::new(
                    at,
                    format!("index {i} refers past the {n} vertices"),
                ));
            }
            let material = match prim.material().index() {
                Some(i) => i as u32,
                None => {
                    self.uses_default_material = true;
                    self.default_material
                }
            };
            // Every texture must find the coordinates it reads.
            let m = prim.material();
            let pbr = m.pbr_metallic_roughness();
            let sets = [
                pbr.base_color_texture().map(|t| t.tex_coord()),
                pbr.metallic_roughness_texture().map(|t| t.tex_coord()),
                m.normal_texture().map(|t| t.tex_coord()),
                m.emissive_texture().map(|t| t.tex_coord()),
            ];
            for k in [0u32, 1] {
                let present = if k == 0 {
                    uvs.is_some()
                } else {
                    uvs1.is_some()
                };
                if !present && sets.contains(&Some(k)) {
                    self.warnings.push(format!(
                        "{at}: its material's textures read TEXCOORD_{k}, which it lacks: they \
                         show one texel"
                    ));
                }
            }
            // Tangents follow the coordinates the normal map reads.
            let normal_set = prim.material().normal_texture().map(|t| t.tex_coord());
            let normal_uvs = if normal_set == Some(1) { &uvs1 } else { &uvs };
            let tangents = match (normal_uvs, normal_set.is_some()) {
                (Some(uv), true) => {
                    let t = tangents::corners(
                        &prim,
                        self.data,
                        &positions,
                        normals.as_deref(),
                        uv,
                        &tri,
                        &at,
                    )?;
                    if t.is_none() {
                        self.warnings.push(format!(
                            "{at}: no tangent frames could be made: its normal map is not applied"
                        ));
                    }
                    t
                }
                (None, true) => {
                    self.warnings.push(format!(
                        "{at}: a normal map without its TEXCOORD_{} cannot be placed: not applied",
                        normal_set.unwrap_or(0)
                    ));
                    None
                }
                _ => None,
            };
            self.meshes.push(GltfMesh {
                origin: at,
                positions,
                normals,
                uvs,
                uvs1,
                tangents,
                triangles: tri,
                material,
                to_root: *world,
            });
        }
        Ok(())
    }
}
