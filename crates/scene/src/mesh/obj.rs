//! Wavefront OBJ: `v`, `vn` and polygon `f` records (triangulated as fans), with 1-based and
//! negative (relative) indices. Texture coordinates, groups, materials and smoothing groups
//! are ignored. Errors give the line number.

use std::collections::HashMap;

use glam::Vec3;

use super::{MeshError, RawMesh, fan};

pub(super) fn parse(bytes: &[u8]) -> Result<RawMesh, MeshError> {
    let text = std::str::from_utf8(bytes)
        .map_err(|e| MeshError::new("", format!("expected UTF-8 text: {e}")))?;
    let mut positions = Vec::new();
    let mut file_normals = Vec::new();
    // Faces as (position, normal) index pairs; vertices are split per distinct pair only when
    // the file has normals.
    let mut corners: Vec<(u32, Option<u32>)> = Vec::new();
    let mut polygons: Vec<(usize, usize)> = Vec::new(); // ranges into `corners`

    for (line_index, raw) in text.lines().enumerate() {
        let line_no = line_index + 1;
        let at = || format!("line {line_no}");
        let line = raw.split('#').next().unwrap_or("").trim();
        let mut tokens = line.split_whitespace();
        match tokens.next() {
            Some("v") => {
                positions.push(parse_vec3(&mut tokens).map_err(|m| MeshError::new(at(), m))?)
            }
            Some("vn") => {
                file_normals.push(parse_vec3(&mut tokens).map_err(|m| MeshError::new(at(), m))?)
            }
            Some("f") => {
                let start = corners.len();
                for token in tokens {
                    let mut parts = token.split('/');
                    let v = parts.next().unwrap_or("");
                    let _vt = parts.next();
                    let vn = parts.next().filter(|s| !s.is_empty());
                    let p =
                        resolve_index(v, positions.len()).map_err(|m| MeshError::new(at(), m))?;
                    let n = vn
                        .map(|s| resolve_index(s, file_normals.len()))
                        .transpose()
                        .map_err(|m| MeshError::new(at(), m))?;
                    corners.push((p, n));
                }
                if corners.len() - start < 3 {
                    return Err(MeshError::new(
                        at(),
                        "expected a face with at least 3 vertices",
                    ));
                }
                polygons.push((start, corners.len()));
            }
            _ => {} // comments, blank lines, vt, o, g, s, usemtl, mtllib, l, p, ...
        }
    }

    let mut triangles = Vec::new();
    let has_normals = corners.iter().any(|c| c.1.is_some());
    if !has_normals {
        for &(a, b) in &polygons {
            let poly: Vec<u32> = corners[a..b].iter().map(|c| c.0).collect();
            fan(&poly, &mut triangles);
        }
        return Ok(RawMesh {
            positions,
            normals: None,
            triangles,
        });
    }

    // Give every distinct (position, normal) pair its own vertex.
    let mut vertex_of: HashMap<(u32, Option<u32>), u32> = HashMap::new();
    let mut out_positions = Vec::new();
    let mut out_normals = Vec::new();
    for &(a, b) in &polygons {
        let poly: Vec<u32> = corners[a..b]
            .iter()
            .map(|&(p, n)| {
                *vertex_of.entry((p, n)).or_insert_with(|| {
                    out_positions.push(positions[p as usize]);
                    out_normals.push(n.map_or(Vec3::ZERO, |n| file_normals[n as usize]));
                    (out_positions.len() - 1) as u32
                })
            })
            .collect();
        fan(&poly, &mut triangles);
    }
    Ok(RawMesh {
        positions: out_positions,
        normals: Some(out_normals),
        triangles,
    })
}

fn parse_vec3<'a>(tokens: &mut impl Iterator<Item = &'a str>) -> Result<Vec3, String> {
    let mut v = [0.0f32; 3];
    for (i, slot) in v.iter_mut().enumerate() {
        let token = tokens
            .next()
            .ok_or_else(|| format!("expected 3 coordinates, got {i}"))?;
        *slot = token
            .parse()
            .map_err(|_| format!("expected a number, got \"{token}\""))?;
        if !slot.is_finite() {
            return Err(format!("expected a finite coordinate, got \"{token}\""));
        }
    }
    Ok(Vec3::from(v))
}

/// OBJ indices are 1-based; negative ones count back from the last element defined so far.
fn resolve_index(token: &str, defined: usize) -> Result<u32, String> {
    let i: i64 = token
        .parse()
        .map_err(|_| format!("expected a vertex index, got \"{token}\""))?;
    let resolved = if i > 0 { i - 1 } else { defined as i64 + i };
    if i == 0 || resolved < 0 || resolved >= defined as i64 {
        return Err(format!(
            "index {i} is out of range: {defined} defined so far"
        ));
    }
    Ok(resolved as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quad_is_triangulated_and_negative_indices_resolve() {
        let m = parse(b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf -4 -3 -2 -1\n").unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert!(m.normals.is_none());
    }

    #[test]
    fn normals_split_vertices_per_distinct_pair() {
        let src =
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 -1\nf 1//1 2//1 3//1\nf 1//2 3//2 2//2\n";
        let m = parse(src).unwrap();
        assert_eq!(m.positions.len(), 6);
        let n = m.normals.unwrap();
        assert_eq!(n[0], Vec3::Z);
        assert_eq!(n[3], -Vec3::Z);
    }

    #[test]
    fn errors_name_the_line() {
        let e = parse(b"v 0 0 0\nv 1 nan 0\n").unwrap_err();
        assert_eq!(e.location, "line 2");
        assert!(e.message.contains("finite"));
        let e = parse(b"v 0 0 0\nv 1 0 0\nf 1 2 7\n").unwrap_err();
        assert_eq!(e.location, "line 3");
        assert!(e.message.contains("out of range"));
        let e = parse(b"v 0 0 0\nv 1 0 x\n").unwrap_err();
        assert!(e.message.contains("\"x\""));
    }
}
