//! Triangle mesh files: Wavefront OBJ (with its MTL materials) and Stanford PLY.

mod obj;
mod ply;

use glam::Vec3;

/// A triangle mesh as read from a file, in the file's own coordinates.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RawMesh {
    pub positions: Vec<Vec3>,
    /// Per-vertex normals, same length as `positions`; zero where the file gave none.
    pub normals: Option<Vec<Vec3>>,
    /// Per-vertex texture coordinates, v down the image (glTF's convention).
    pub uvs: Option<Vec<glam::Vec2>>,
    pub triangles: Vec<[u32; 3]>,
    /// Per triangle, its index into `materials` (`u32::MAX`: none), where the file names
    /// materials (OBJ `usemtl`).
    pub face_materials: Option<Vec<u32>>,
    /// The materials of the file's libraries (OBJ `mtllib`), as written.
    pub materials: Vec<MtlMaterial>,
    /// Why the file's material library could not be read, if it could not.
    pub library_error: Option<String>,
    /// What was read but not used (a `usemtl` naming no material of the library).
    pub warnings: Vec<String>,
}

/// One `newmtl` of an MTL library, as written (colours, exponents, texture statements with
/// their options); what it becomes is decided where the scene is resolved.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MtlMaterial {
    pub name: String,
    pub kd: Option<Vec3>,
    pub ks: Option<Vec3>,
    pub ke: Option<Vec3>,
    pub ns: Option<f32>,
    pub ni: Option<f32>,
    pub d: Option<f32>,
    pub illum: Option<u8>,
    pub map_kd: Option<String>,
    pub map_ks: Option<String>,
    pub map_ns: Option<String>,
    pub map_d: Option<String>,
    /// `map_Bump`, `bump` or `norm`: Blender's and most exporters' tangent-space normal map.
    pub map_bump: Option<String>,
    /// Other statements (`Pr`, `Pm`, `map_Ke`, `Tf`, …), sorted by keyword.
    pub other: Vec<(String, String)>,
}

impl MtlMaterial {
    fn from_tobj(m: &tobj::Material) -> Self {
        let mut other: Vec<(String, String)> = m
            .unknown_param
            .iter()
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect();
        other.sort();
        let norm = other
            .iter()
            .position(|(k, _)| k == "norm")
            .map(|i| other.remove(i).1);
        MtlMaterial {
            name: m.name.clone(),
            kd: m.diffuse.map(Vec3::from),
            ks: m.specular.map(Vec3::from),
            ke: m.emissive.map(Vec3::from),
            ns: m.shininess,
            ni: m.optical_density,
            d: m.dissolve,
            illum: m.illumination_model,
            map_kd: m.diffuse_texture.clone(),
            map_ks: m.specular_texture.clone(),
            map_ns: m.shininess_texture.clone(),
            map_d: m.dissolve_texture.clone(),
            map_bump: m.normal_texture.clone().or(norm),
            other,
        }
    }

    /// A statement among `other`.
    pub fn get(&self, key: &str) -> Option<&str> {
        self.other
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }
}

/// A problem inside a mesh file: where (`line 12`, `vertex 3`) and what was expected.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshError {
    pub location: String,
    pub message: String,
}

impl MeshError {
    fn new(location: impl Into<String>, message: impl Into<String>) -> Self {
        MeshError {
            location: location.into(),
            message: message.into(),
        }
    }
}

/// Reads a mesh, choosing the format by the file extension, and checks it: finite
/// coordinates, indices in range, at least one triangle. `side` reads the files it names
/// (an OBJ's material libraries), relative to it.
pub fn parse(
    bytes: &[u8],
    extension: &str,
    side: &dyn Fn(&str) -> Result<Vec<u8>, String>,
) -> Result<RawMesh, MeshError> {
    let mesh = match extension.to_ascii_lowercase().as_str() {
        "obj" => obj::parse(bytes, side)?,
        "ply" => ply::parse(bytes)?,
        other => {
            return Err(MeshError::new(
                "",
                format!("expected a mesh file ending in .obj or .ply, got \".{other}\""),
            ));
        }
    };
    check(&mesh)?;
    Ok(mesh)
}

fn check(mesh: &RawMesh) -> Result<(), MeshError> {
    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        let p = mesh.positions[i];
        return Err(MeshError::new(
            format!("vertex {i}"),
            format!(
                "expected finite coordinates, got ({}, {}, {})",
                p.x, p.y, p.z
            ),
        ));
    }
    if let Some(uvs) = &mesh.uvs
        && let Some(i) = uvs.iter().position(|t| !t.is_finite())
    {
        return Err(MeshError::new(
            format!("texture coordinates of vertex {i}"),
            "expected finite components",
        ));
    }
    if let Some(normals) = &mesh.normals
        && let Some(i) = normals.iter().position(|n| !n.is_finite())
    {
        return Err(MeshError::new(
            format!("normal of vertex {i}"),
            "expected finite components",
        ));
    }
    let n = mesh.positions.len();
    for (f, t) in mesh.triangles.iter().enumerate() {
        if let Some(&bad) = t.iter().find(|&&i| i as usize >= n) {
            return Err(MeshError::new(
                format!("face {f}"),
                format!("vertex index {bad} is out of range; the mesh has {n} vertices"),
            ));
        }
    }
    if mesh.triangles.is_empty() {
        return Err(MeshError::new(
            "",
            "expected at least one face, the mesh has none",
        ));
    }
    Ok(())
}

/// Splits a polygon into a triangle fan, appending to `out`.
fn fan(polygon: &[u32], out: &mut Vec<[u32; 3]>) {
    for i in 1..polygon.len().saturating_sub(1) {
        out.push([polygon[0], polygon[i], polygon[i + 1]]);
    }
}
