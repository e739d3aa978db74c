//! `ply`: a PLY mesh (ASCII or binary) drawn by a scene file; loaded, planned and built.

use super::{With, mesh_scene};
use crate::{Mem, Target, load_plan_build};

pub const TARGET: Target = Target {
    name: "ply",
    about: "PLY (ASCII, binary little and big endian): loaded, planned and built",
    run,
    seeds,
};

fn run(data: &[u8]) -> bool {
    static FOLDER: std::sync::OnceLock<Mem> = std::sync::OnceLock::new();
    let base =
        FOLDER.get_or_init(|| Mem::default().with("scene.json", mesh_scene("mesh.ply", true)));
    let source = With {
        base,
        name: "mesh.ply",
        bytes: data,
    };
    load_plan_build(&source, "scene.json")
}

/// A quad (two triangles, with normals and uv) in each of PLY's three encodings.
fn seeds() -> Vec<(String, Vec<u8>)> {
    let vertices = [
        [-1f32, -1., 0., 0., 0., 1., 0., 0.],
        [1., -1., 0., 0., 0., 1., 1., 0.],
        [1., 1., 0., 0., 0., 1., 1., 1.],
        [-1., 1., 0., 0., 0., 1., 0., 1.],
    ];
    let faces: [[u32; 3]; 2] = [[0, 1, 2], [0, 2, 3]];
    let header = |format: &str| {
        format!(
            "ply\nformat {format} 1.0\ncomment a quad\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\nelement face 2\nproperty list uchar uint vertex_indices\nend_header\n"
        )
    };
    let mut ascii = header("ascii").into_bytes();
    for v in &vertices {
        let line: Vec<String> = v.iter().map(|c| c.to_string()).collect();
        ascii.extend_from_slice(format!("{}\n", line.join(" ")).as_bytes());
    }
    for f in &faces {
        ascii.extend_from_slice(format!("3 {} {} {}\n", f[0], f[1], f[2]).as_bytes());
    }
    let binary = |format: &str, le: bool| {
        let mut out = header(format).into_bytes();
        for v in &vertices {
            for c in v {
                out.extend_from_slice(&if le { c.to_le_bytes() } else { c.to_be_bytes() });
            }
        }
        for f in &faces {
            out.push(3);
            for i in f {
                out.extend_from_slice(&if le { i.to_le_bytes() } else { i.to_be_bytes() });
            }
        }
        out
    };
    vec![
        ("quad-ascii.ply".into(), ascii),
        ("quad-le.ply".into(), binary("binary_little_endian", true)),
        ("quad-be.ply".into(), binary("binary_big_endian", false)),
    ]
}
