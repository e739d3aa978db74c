//! Tangent frames for normal maps: the file's TANGENT attribute, or MikkTSpace tangents
//! generated from positions, normals and TEXCOORD_0 (as glTF asks, with the `bevy_mikktspace`
//! crate), one per triangle corner.

use glam::{Vec2, Vec3, Vec4};

use super::GltfError;
use super::buffers;

/// Per corner of each triangle: the tangent (xyz) and the bitangent's sign (w), in the mesh's
/// own frame.
pub(super) fn corners(
    prim: &gltf::Primitive,
    data: &[Vec<u8>],
    positions: &[Vec3],
    normals: Option<&[Vec3]>,
    uvs: &[Vec2],
    triangles: &[[u32; 3]],
    at: &str,
) -> Result<Option<Vec<[Vec4; 3]>>, GltfError> {
    if let Some(t) = buffers::tangents(prim, data, positions.len(), at)? {
        return Ok(Some(
            triangles
                .iter()
                .map(|tri| tri.map(|i| t[i as usize]))
                .collect(),
        ));
    }
    Ok(mikktspace(positions, normals, uvs, triangles))
}

/// MikkTSpace tangents (xyz, w the bitangent's sign) per triangle corner, from texture
/// coordinates in glTF's convention (v down the image); `None` where they cannot be made.
pub(crate) fn mikktspace(
    positions: &[Vec3],
    normals: Option<&[Vec3]>,
    uvs: &[Vec2],
    triangles: &[[u32; 3]],
) -> Option<Vec<[Vec4; 3]>> {
    let mut g = Mikk {
        positions,
        normals,
        uvs,
        triangles,
        out: vec![[Vec4::ZERO; 3]; triangles.len()],
    };
    bevy_mikktspace::generate_tangents(&mut g).then_some(g.out)
}

struct Mikk<'a> {
    positions: &'a [Vec3],
    normals: Option<&'a [Vec3]>,
    uvs: &'a [Vec2],
    triangles: &'a [[u32; 3]],
    out: Vec<[Vec4; 3]>,
}

impl bevy_mikktspace::Geometry for Mikk<'_> {
    fn num_faces(&self) -> usize {
        self.triangles.len()
    }
    fn num_vertices_of_face(&self, _: usize) -> usize {
        3
    }
    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        self.positions[self.triangles[face][vert] as usize].to_array()
    }
    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        match self.normals {
            Some(n) => n[self.triangles[face][vert] as usize].to_array(),
            // Without normals glTF asks for flat shading: the face's normal.
            None => {
                let [a, b, c] = self.triangles[face].map(|i| self.positions[i as usize]);
                (b - a).cross(c - a).normalize_or_zero().to_array()
            }
        }
    }
    /// glTF's v grows down the image, while a normal map's +y points up it (glTF 2.0
    /// §3.9.3): MikkTSpace sees v flipped, so that the bitangent sign it gives makes
    /// B = w · N × T point up the image, as TANGENT attributes written by exporters do.
    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        let uv = self.uvs[self.triangles[face][vert] as usize];
        [uv.x, 1.0 - uv.y]
    }
    fn set_tangent_encoded(&mut self, tangent: [f32; 4], face: usize, vert: usize) {
        self.out[face][vert] = Vec4::from(tangent);
    }
}
