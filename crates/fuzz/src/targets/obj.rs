//! `obj`: a Wavefront OBJ and its material library, drawn by a scene file; the input is the
//! OBJ, then a NUL byte, then the MTL (served for whatever `mtllib` names). Loaded, planned and
//! built: the BVH over whatever triangles it holds.

use std::path::{Path, PathBuf};

use super::{find, mesh_scene};
use crate::{Target, fixtures, load_plan_build, repo};

pub const TARGET: Target = Target {
    name: "obj",
    about: "OBJ + MTL (split at the first NUL): loaded, planned and built",
    run,
    seeds,
};

/// The scene, the OBJ as `mesh.obj`, the MTL under any `.mtl` name, a texture under any other.
struct Obj<'a> {
    scene: &'a [u8],
    obj: &'a [u8],
    mtl: &'a [u8],
    texture: &'a [u8],
}

impl tessera_scene::SceneSource for Obj<'_> {
    fn read(&self, relative: &Path) -> std::io::Result<Vec<u8>> {
        let name = relative.to_string_lossy();
        Ok(match name.as_ref() {
            "scene.json" => self.scene,
            "mesh.obj" => self.obj,
            n if n.ends_with(".mtl") => self.mtl,
            _ => self.texture,
        }
        .to_vec())
    }
    fn display_path(&self, relative: &Path) -> PathBuf {
        relative.to_path_buf()
    }
}

fn run(data: &[u8]) -> bool {
    static FIXED: std::sync::OnceLock<[Vec<u8>; 3]> = std::sync::OnceLock::new();
    let [own, named, texture] = FIXED.get_or_init(|| {
        [
            mesh_scene("mesh.obj", true),
            mesh_scene("mesh.obj", false),
            fixtures::png(4, 4),
        ]
    });
    let (obj, mtl) = match data.iter().position(|&b| b == 0) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[][..]),
    };
    let names_materials = obj.windows(6).any(|w| w == b"usemtl");
    let source = Obj {
        scene: if names_materials { named } else { own },
        obj,
        mtl,
        texture,
    };
    load_plan_build(&source, "scene.json")
}

/// The repository's OBJ files (small ones only: a large seed makes every mutation slow), each
/// with the MTL of the same name beside it when there is one.
fn seeds() -> Vec<(String, Vec<u8>)> {
    let scenes = repo().join("scenes");
    let mtls = find(&scenes, &[".mtl"]);
    find(&scenes, &[".obj"])
        .into_iter()
        .filter(|(_, bytes)| bytes.len() < 32 << 10)
        .map(|(name, mut bytes)| {
            let stem = name.trim_end_matches(".obj");
            if let Some((_, mtl)) = mtls
                .iter()
                .find(|(m, _)| m.trim_end_matches(".mtl") == stem)
            {
                bytes.push(0);
                bytes.extend_from_slice(mtl);
            }
            (name, bytes)
        })
        .collect()
}
