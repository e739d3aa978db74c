//! Triangle mesh files: Wavefront OBJ and Stanford PLY.

mod obj;
mod ply;

use glam::Vec3;

/// A triangle mesh as read from a file, in the file's own coordinates.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RawMesh {
    pub positions: Vec<Vec3>,
    /// Per-vertex normals, same length as `positions`; zero where the file gave none.
    pub normals: Option<Vec<Vec3>>,
    pub triangles: Vec<[u32; 3]>,
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
/// coordinates, indices in range, at least one triangle.
pub fn parse(bytes: &[u8], extension: &str) -> Result<RawMesh, MeshError> {
    let mesh = match extension.to_ascii_lowercase().as_str() {
        "obj" => obj::parse(bytes)?,
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
