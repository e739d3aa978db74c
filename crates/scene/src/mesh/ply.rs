//! Stanford PLY (ASCII and binary), read with `ply-rs-bw`: `vertex` elements with `x y z`
//! (and optional `nx ny nz`), `face` elements with a `vertex_indices` (or `vertex_index`)
//! list; polygons are triangulated as fans. Other elements are skipped.

use glam::Vec3;
use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{DefaultElement, PropertyAccess, PropertyAccessResult};

use super::{MeshError, RawMesh, fan};

#[derive(Default)]
struct Vertex {
    p: [f32; 3],
    n: [f32; 3],
    has_normal: bool,
}

impl Vertex {
    fn set(&mut self, name: &str, v: f32) -> PropertyAccessResult {
        match name {
            "x" => self.p[0] = v,
            "y" => self.p[1] = v,
            "z" => self.p[2] = v,
            "nx" | "ny" | "nz" => {
                self.has_normal = true;
                self.n[(name.as_bytes()[1] - b'x') as usize] = v;
            }
            _ => return PropertyAccessResult::Ignored,
        }
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Vertex::default()
    }
    fn set_float(&mut self, name: &str, v: f32) -> PropertyAccessResult {
        self.set(name, v)
    }
    fn set_double(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        self.set(name, v as f32)
    }
    fn set_int(&mut self, name: &str, v: i32) -> PropertyAccessResult {
        self.set(name, v as f32)
    }
    fn set_uint(&mut self, name: &str, v: u32) -> PropertyAccessResult {
        self.set(name, v as f32)
    }
    fn set_short(&mut self, name: &str, v: i16) -> PropertyAccessResult {
        self.set(name, v as f32)
    }
    fn set_ushort(&mut self, name: &str, v: u16) -> PropertyAccessResult {
        self.set(name, v as f32)
    }
}

#[derive(Default)]
struct Face {
    indices: Vec<i64>,
}

impl Face {
    fn set<T: Into<i64> + Copy>(&mut self, name: &str, v: Vec<T>) -> PropertyAccessResult {
        if name != "vertex_indices" && name != "vertex_index" {
            return PropertyAccessResult::Ignored;
        }
        self.indices = v.iter().map(|&i| i.into()).collect();
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for Face {
    fn new() -> Self {
        Face::default()
    }
    fn set_list_int(&mut self, name: &str, v: Vec<i32>) -> PropertyAccessResult {
        self.set(name, v)
    }
    fn set_list_uint(&mut self, name: &str, v: Vec<u32>) -> PropertyAccessResult {
        self.set(name, v)
    }
    fn set_list_short(&mut self, name: &str, v: Vec<i16>) -> PropertyAccessResult {
        self.set(name, v)
    }
    fn set_list_ushort(&mut self, name: &str, v: Vec<u16>) -> PropertyAccessResult {
        self.set(name, v)
    }
    fn set_list_char(&mut self, name: &str, v: Vec<i8>) -> PropertyAccessResult {
        self.set(name, v)
    }
    fn set_list_uchar(&mut self, name: &str, v: Vec<u8>) -> PropertyAccessResult {
        self.set(name, v)
    }
}

/// Checks each element's stated count against the bytes after the header: an element takes
/// at least its scalars' and list counts' sizes in binary, and a line in ASCII. A parser
/// would otherwise read a count of empty elements from no bytes at all.
fn check_counts(header: &ply_rs_bw::ply::Header, bytes: &[u8]) -> Result<(), MeshError> {
    use ply_rs_bw::ply::{Encoding, PropertyType, ScalarType};
    let size = |t: &ScalarType| match t {
        ScalarType::Char | ScalarType::UChar => 1u64,
        ScalarType::Short | ScalarType::UShort => 2,
        ScalarType::Int | ScalarType::UInt | ScalarType::Float => 4,
        ScalarType::Double => 8,
    };
    let end = b"end_header";
    let body = bytes
        .windows(end.len())
        .position(|w| w == end)
        .map_or(0, |at| bytes.len() - at - end.len()) as u64;
    for (name, element) in &header.elements {
        let min_bytes = match header.encoding {
            Encoding::Ascii => 1,
            _ => element
                .properties
                .values()
                .map(|p| match &p.data_type {
                    PropertyType::Scalar(t) => size(t),
                    PropertyType::List(count, _) => size(count),
                })
                .sum(),
        };
        crate::budget::check_count(
            &format!("{name} elements"),
            element.count as u64,
            min_bytes,
            body,
        )
        .map_err(|e| MeshError::new("header", e))?;
    }
    Ok(())
}

pub(super) fn parse(bytes: &[u8]) -> Result<RawMesh, MeshError> {
    let mut reader = Reader::new(std::io::BufReader::new(bytes));
    let vertex_parser = Parser::<Vertex>::new();
    let face_parser = Parser::<Face>::new();
    let other_parser = Parser::<DefaultElement>::new();
    let bad = |what: &str, e: ply_rs_bw::parser::ParseError| {
        MeshError::new(what.to_string(), format!("not a valid PLY file: {e}"))
    };
    let header = vertex_parser
        .read_header(&mut reader)
        .map_err(|e| bad("header", e))?;

    check_counts(&header, bytes)?;
    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    for (name, element) in &header.elements {
        match name.as_str() {
            "vertex" => {
                vertices = vertex_parser
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(|e| bad("vertex data", e))?
            }
            "face" => {
                faces = face_parser
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(|e| bad("face data", e))?
            }
            _ => {
                other_parser
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(|e| bad(&format!("{name} data"), e))?;
            }
        }
    }

    let n = vertices.len();
    let mut triangles = Vec::with_capacity(faces.len());
    let mut poly = Vec::new();
    for (f, face) in faces.iter().enumerate() {
        if face.indices.len() < 3 {
            return Err(MeshError::new(
                format!("face {f}"),
                "expected at least 3 vertex indices",
            ));
        }
        poly.clear();
        for &i in &face.indices {
            if i < 0 || i as usize >= n {
                return Err(MeshError::new(
                    format!("face {f}"),
                    format!("vertex index {i} is out of range; the file has {n} vertices"),
                ));
            }
            poly.push(i as u32);
        }
        fan(&poly, &mut triangles);
    }
    let has_normals = vertices.iter().any(|v| v.has_normal);
    Ok(RawMesh {
        positions: vertices.iter().map(|v| Vec3::from(v.p)).collect(),
        normals: has_normals.then(|| vertices.iter().map(|v| Vec3::from(v.n)).collect()),
        triangles,
        ..RawMesh::default()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const ASCII: &str = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
property float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face 1\n\
property list uchar int vertex_indices\nend_header\n0 0 0 0 0 1\n1 0 0 0 0 1\n1 1 0 0 0 1\n\
0 1 0 0 0 1\n4 0 1 2 3\n";

    #[test]
    fn ascii_quad_with_normals() {
        let m = parse(ASCII.as_bytes()).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert_eq!(m.normals.unwrap()[2], Vec3::Z);
    }

    #[test]
    fn binary_little_endian_triangle() {
        let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\n\
property double y\nproperty double z\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n"
            .to_vec();
        for p in [[0.0f64, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0]] {
            for c in p {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
        bytes.push(3);
        for i in [0u32, 1, 2] {
            bytes.extend_from_slice(&i.to_le_bytes());
        }
        let m = parse(&bytes).unwrap();
        assert_eq!(m.positions[2], Vec3::new(0.0, 2.0, 0.0));
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn out_of_range_index_is_reported() {
        let src = ASCII.replace("4 0 1 2 3", "3 0 1 9");
        let e = parse(src.as_bytes()).unwrap_err();
        assert_eq!(e.location, "face 0");
        assert!(e.message.contains("out of range"));
    }

    #[test]
    fn a_claimed_count_is_checked_against_the_bytes() {
        // Four billion elements of nothing, from a header alone.
        let src = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nelement junk 4000000000\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
        let e = parse(src.as_bytes()).unwrap_err().message;
        assert!(e.contains("4000000000 junk elements"), "{e}");
        let binary =
            b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000\nproperty float x\n\
property float y\nproperty float z\nend_header\n";
        let e = parse(binary).unwrap_err().message;
        assert!(
            e.contains("1000000 vertex elements of at least 12 bytes"),
            "{e}"
        );
    }
}
