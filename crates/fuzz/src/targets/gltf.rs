//! `gltf`: a glTF scene, as a `.glb` when the input starts with glTF's magic and as `.gltf`
//! JSON otherwise (other files it names are a small PNG); loaded as the scene file itself,
//! planned and built.

use std::path::{Path, PathBuf};

use super::find;
use crate::{Target, fixtures, load_plan_build, repo};

pub const TARGET: Target = Target {
    name: "gltf",
    about: "glTF 2.0 (.gltf JSON or .glb): loaded as the scene, planned and built",
    run,
    seeds,
};

struct Gltf<'a> {
    name: &'a str,
    bytes: &'a [u8],
    other: &'a [u8],
}

impl tessera_scene::SceneSource for Gltf<'_> {
    fn read(&self, relative: &Path) -> std::io::Result<Vec<u8>> {
        Ok(match relative == Path::new(self.name) {
            true => self.bytes,
            false => self.other,
        }
        .to_vec())
    }
    fn display_path(&self, relative: &Path) -> PathBuf {
        relative.to_path_buf()
    }
}

fn run(data: &[u8]) -> bool {
    static PNG: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    let name = match data.starts_with(b"glTF") {
        true => "scene.glb",
        false => "scene.gltf",
    };
    let source = Gltf {
        name,
        bytes: data,
        other: PNG.get_or_init(|| fixtures::png(4, 4)),
    };
    load_plan_build(&source, name)
}

/// A one-triangle glTF as JSON and as GLB, and the repository's GLB files (Blender's exports).
fn seeds() -> Vec<(String, Vec<u8>)> {
    let mut out = vec![
        ("triangle.gltf".to_string(), fixtures::gltf_triangle()),
        (
            "triangle.glb".to_string(),
            fixtures::glb(&fixtures::gltf_triangle()),
        ),
    ];
    out.extend(find(&repo().join("scenes"), &[".glb", ".gltf"]));
    // The same scenes made small by glTF-Transform (seeds/README.md): fast to mutate.
    out.extend(find(&repo().join("crates/fuzz/seeds/gltf"), &[".glb"]));
    out
}
