//! Wavefront OBJ through the `tobj` crate: positions, normals, texture coordinates and
//! polygons (triangulated as fans, 1-based and negative indices), with the materials of its
//! `mtllib` files and the `usemtl` group of every face. Texture coordinates are turned to
//! glTF's convention (v down the image: v' = 1 − v). tobj's errors do not say where; the
//! line is found again here so that every error names it.

use std::cell::RefCell;
use std::io::Cursor;
use std::path::Path;

use glam::{Vec2, Vec3};

use super::{MeshError, MtlMaterial, RawMesh};

/// Reads `bytes`; `side` reads a file the OBJ names (its material libraries), relative to it.
pub(super) fn parse(
    bytes: &[u8],
    side: &dyn Fn(&str) -> Result<Vec<u8>, String>,
) -> Result<RawMesh, MeshError> {
    let text = std::str::from_utf8(bytes)
        .map_err(|e| MeshError::new("", format!("expected UTF-8 text: {e}")))?;
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    check_face_indices(text)?;
    let library_problem: RefCell<Option<String>> = RefCell::new(None);
    let loaded = tobj::load_obj_buf(&mut Cursor::new(bytes), &options, |p: &Path| {
        let name = p.to_string_lossy();
        match side(&name).and_then(|b| check_mtl(&b).map(|()| b)) {
            Ok(b) => tobj::load_mtl_buf(&mut Cursor::new(b)).inspect_err(|e| {
                *library_problem.borrow_mut() = Some(format!(
                    "material library {name}: {e} (expected MTL statements)"
                ));
            }),
            Err(e) if e.starts_with("line ") => {
                *library_problem.borrow_mut() = Some(format!("material library {name}: {e}"));
                Err(tobj::LoadError::MaterialParseError)
            }
            Err(e) => {
                *library_problem.borrow_mut() =
                    Some(format!("cannot read material library {name}: {e}"));
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
    });
    let (models, materials) = loaded.map_err(|e| located(text, e))?;
    let (materials, library_error) = match materials {
        Ok(m) => (m, None),
        Err(e) => (
            Vec::new(),
            Some(
                library_problem
                    .into_inner()
                    .unwrap_or_else(|| format!("its material library: {e}")),
            ),
        ),
    };

    // tobj reads "nan" and "inf" as numbers.
    let finite = |m: &tobj::Model| m.mesh.positions.iter().all(|c| c.is_finite());
    if !models.iter().all(finite) {
        return Err(MeshError::new(
            first_bad_line(text, "v").map_or_else(String::new, |n| format!("line {n}")),
            "expected `v x y z` with three finite numbers",
        ));
    }
    let mut mesh = RawMesh::default();
    let has_normals = models.iter().any(|m| !m.mesh.normals.is_empty());
    let has_uvs = models.iter().any(|m| !m.mesh.texcoords.is_empty());
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    let mut face_materials = Vec::new();
    for model in &models {
        let m = &model.mesh;
        let first = mesh.positions.len() as u32;
        let count = m.positions.len() / 3;
        mesh.positions.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0], p[1], p[2])),
        );
        if has_normals {
            if m.normals.len() == m.positions.len() {
                normals.extend(
                    m.normals
                        .chunks_exact(3)
                        .map(|n| Vec3::new(n[0], n[1], n[2])),
                );
            } else {
                // Faces without `vn`: zero, which shading takes as "use the face's normal".
                normals.extend(std::iter::repeat_n(Vec3::ZERO, count));
            }
        }
        if has_uvs {
            if m.texcoords.len() == count * 2 {
                uvs.extend(
                    m.texcoords
                        .chunks_exact(2)
                        .map(|t| Vec2::new(t[0], 1.0 - t[1])),
                );
            } else {
                uvs.extend(std::iter::repeat_n(Vec2::ZERO, count));
            }
        }
        let material = m.material_id.map_or(u32::MAX, |i| i as u32);
        for t in m.indices.chunks_exact(3) {
            mesh.triangles
                .push([first + t[0], first + t[1], first + t[2]]);
            face_materials.push(material);
        }
    }
    mesh.normals = has_normals.then_some(normals);
    mesh.uvs = has_uvs.then_some(uvs);
    if face_materials.iter().any(|&m| m != u32::MAX)
        || !materials.is_empty()
        || library_error.is_some()
    {
        mesh.face_materials = Some(face_materials);
    }
    mesh.library_error = library_error;
    mesh.materials = materials.iter().map(MtlMaterial::from_tobj).collect();
    if mesh.library_error.is_none() {
        // tobj gives the faces of an unknown usemtl no material, silently.
        for (i, raw) in text.lines().enumerate() {
            if let Some(name) = raw.trim().strip_prefix("usemtl ") {
                let name = name.trim();
                if !materials.iter().any(|m| m.name == name) {
                    mesh.warnings.push(format!(
                        "line {}: usemtl {name} names no material of the library: its faces \
                         get the OBJ default material",
                        i + 1
                    ));
                }
            }
        }
    }
    Ok(mesh)
}

/// What tobj's MTL reader assumes without checking: a colour statement (`Ka`, `Kd`, `Ks`,
/// `Ke`) has three values (with fewer, tobj panics).
fn check_mtl(bytes: &[u8]) -> Result<(), String> {
    for (i, line) in String::from_utf8_lossy(bytes).lines().enumerate() {
        let line = line.split('#').next().unwrap_or("");
        let mut words = line.split_whitespace();
        if let Some(key @ ("Ka" | "Kd" | "Ks" | "Ke")) = words.next() {
            let n = words.count();
            if n < 3 {
                return Err(format!(
                    "line {}: expected `{key} r g b` with three numbers, got {n}",
                    i + 1
                ));
            }
        }
    }
    Ok(())
}

/// tobj's error, with the line it comes from.
fn located(text: &str, e: tobj::LoadError) -> MeshError {
    use tobj::LoadError as E;
    let (record, expected) = match e {
        E::PositionParseError => ("v", "`v x y z` with three finite numbers"),
        E::NormalParseError => ("vn", "`vn x y z` with three numbers"),
        E::TexcoordParseError => ("vt", "`vt u v` with numbers"),
        E::FaceParseError | E::InvalidPolygon => (
            "f",
            "`f` with at least three corners v, v/vt, v//vn or v/vt/vn",
        ),
        E::FaceVertexOutOfBounds | E::FaceTexCoordOutOfBounds | E::FaceNormalOutOfBounds => (
            "f",
            "a face's indices to refer to records defined before it (1-based, or negative \
             counting back), but one is out of range",
        ),
        _ => ("", "an OBJ file"),
    };
    let line = (!record.is_empty())
        .then(|| first_bad_line(text, record))
        .flatten();
    MeshError::new(
        line.map_or_else(String::new, |n| format!("line {n}")),
        format!("expected {expected} ({e})"),
    )
}

/// The first line of `record` that does not read (numbers, or indices in range).
fn first_bad_line(text: &str, record: &str) -> Option<usize> {
    let mut defined = [0usize; 3]; // v, vt, vn
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim();
        let mut tokens = line.split_whitespace();
        let head = tokens.next();
        let numbers = |n: usize, tokens: std::str::SplitWhitespace| {
            let v: Vec<Option<f32>> = tokens.map(|t| t.parse::<f32>().ok()).collect();
            v.len() >= n && v.iter().all(|x| x.is_some_and(f32::is_finite))
        };
        let bad = match head {
            Some("v") => {
                defined[0] += 1;
                record == "v" && !numbers(3, tokens)
            }
            Some("vt") => {
                defined[1] += 1;
                record == "vt" && !numbers(1, tokens)
            }
            Some("vn") => {
                defined[2] += 1;
                record == "vn" && !numbers(3, tokens)
            }
            Some("f") if record == "f" => {
                let corners: Vec<&str> = tokens.collect();
                corners.len() < 3 || !corners.iter().all(|c| corner_in_range(c, &defined))
            }
            _ => false,
        };
        if bad {
            return Some(i + 1);
        }
    }
    None
}

/// Every index of every face corner refers to a record defined before it. tobj's own check
/// multiplies an index before comparing it, which overflows for a huge one (a panic, or in a
/// release build a wrong record), so the indices are checked here first.
fn check_face_indices(text: &str) -> Result<(), MeshError> {
    let mut defined = [0usize; 3]; // v, vt, vn
    for (i, raw) in text.lines().enumerate() {
        let line = raw.split('#').next().unwrap_or("").trim();
        let mut tokens = line.split_whitespace();
        match tokens.next() {
            Some("v") => defined[0] += 1,
            Some("vt") => defined[1] += 1,
            Some("vn") => defined[2] += 1,
            Some("f") if !tokens.all(|c| corner_in_range(c, &defined)) => {
                return Err(MeshError::new(
                    format!("line {}", i + 1),
                    "expected a face's indices to refer to records defined before it \
                     (1-based, or negative counting back), but one is out of range",
                ));
            }
            _ => {}
        }
    }
    Ok(())
}

/// A corner `v`, `v/vt`, `v//vn` or `v/vt/vn` whose indices are in range.
fn corner_in_range(corner: &str, defined: &[usize; 3]) -> bool {
    corner
        .split('/')
        .enumerate()
        .all(|(k, s)| index_ok(s, defined[k.min(2)]) || s.is_empty() && k > 0)
}

fn index_ok(token: &str, defined: usize) -> bool {
    token.parse::<i64>().is_ok_and(|i| {
        let r = if i > 0 { i - 1 } else { defined as i64 + i };
        i != 0 && r >= 0 && r < defined as i64
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(src: &[u8]) -> Result<RawMesh, MeshError> {
        parse(src, &|name| Err(format!("no file {name} here")))
    }

    #[test]
    fn quad_is_triangulated_and_negative_indices_resolve() {
        let m = read(b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf -4 -3 -2 -1\n").unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
        assert!(m.normals.is_none() && m.uvs.is_none() && m.face_materials.is_none());
    }

    #[test]
    fn normals_and_texture_coordinates_split_vertices_per_distinct_corner() {
        let src = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.25 0.75\nvn 0 0 1\nvn 0 0 -1\n\
                    f 1/1/1 2/1/1 3/1/1\nf 1/1/2 3/1/2 2/1/2\n";
        let m = read(src).unwrap();
        assert_eq!(m.positions.len(), 6);
        let n = m.normals.unwrap();
        assert_eq!(n[0], Vec3::Z);
        assert_eq!(n[3], -Vec3::Z);
        // v up in the OBJ, down in ours.
        assert_eq!(m.uvs.unwrap()[0], Vec2::new(0.25, 0.25));
    }

    #[test]
    fn materials_come_from_the_library_by_usemtl() {
        let obj = b"mtllib lib.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n\
                    usemtl red\nf 1 2 3\nusemtl blue\nf 2 4 3\n";
        let mtl =
            b"newmtl blue\nKd 0 0 1\nnewmtl red\nKd 1 0 0\nNs 50\nmap_Kd -s 2 2 1 wood grain.png\n";
        let m = parse(obj, &|name| {
            assert_eq!(name, "lib.mtl");
            Ok(mtl.to_vec())
        })
        .unwrap();
        assert!(m.library_error.is_none());
        let names: Vec<&str> = m.materials.iter().map(|x| x.name.as_str()).collect();
        let faces = m.face_materials.expect("materials per face");
        assert_eq!(names[faces[0] as usize], "red");
        assert_eq!(names[faces[1] as usize], "blue");
        let red = &m.materials[faces[0] as usize];
        assert_eq!(red.kd, Some(Vec3::X));
        assert_eq!(red.ns, Some(50.0));
        assert_eq!(red.map_kd.as_deref(), Some("-s 2 2 1 wood grain.png"));
        // An unknown name is said.
        let m = parse(
            &[obj.as_slice(), b"usemtl green\nf 1 2 3\n"].concat(),
            &|_| Ok(mtl.to_vec()),
        )
        .unwrap();
        assert!(
            m.warnings[0].contains("line 10: usemtl green"),
            "{:?}",
            m.warnings
        );
        // A library that cannot be read is said, not ignored.
        let m = read(obj).unwrap();
        assert!(m.library_error.expect("an error").contains("lib.mtl"));
    }

    #[test]
    fn errors_name_the_line() {
        let e = read(b"v 0 0 0\nv 1 0 0\nf 1 2 7\n").unwrap_err();
        assert_eq!(e.location, "line 3");
        assert!(e.message.contains("indices"), "{}", e.message);
        let e = read(b"v 0 0 0\nv 1 nan 0\nf 1 2 1\n").unwrap_err();
        assert_eq!(e.location, "line 2");
        let e = read(b"v 0 0 0\nv 1 0 x\n").unwrap_err();
        assert_eq!(e.location, "line 2");
        assert!(e.message.contains("three finite numbers"), "{}", e.message);
        // Found by the `obj` fuzz target: indices so large that tobj's own check overflowed.
        for face in [
            "f 1/9223372036854775807 2/1 3/1",
            "f 1//4611686018427387904 2//1 3//1",
        ] {
            let src = format!("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n{face}\n");
            let e = read(src.as_bytes()).unwrap_err();
            assert_eq!(e.location, "line 6", "{face}");
            assert!(e.message.contains("out of range"), "{}", e.message);
        }
    }
}
