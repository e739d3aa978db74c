//! The registry of fuzz targets, one file each.

mod bundle;
mod gltf;
mod image;
mod json;
mod obj;
mod ply;
mod result;
mod scene;

use std::path::{Path, PathBuf};

use crate::{Mem, Target};

/// Every target, in the order `scripts/fuzz` runs them.
pub static TARGETS: &[Target] = &[
    scene::TARGET,
    obj::TARGET,
    ply::TARGET,
    gltf::TARGET,
    image::TARGET,
    bundle::TARGET,
    result::TARGET,
    json::TARGET,
];

/// A folder with one file of it replaced by the input (or added): the input is `name`,
/// everything else is `base`.
struct With<'a> {
    base: &'a Mem,
    name: &'a str,
    bytes: &'a [u8],
}

impl tessera_scene::SceneSource for With<'_> {
    fn read(&self, relative: &Path) -> std::io::Result<Vec<u8>> {
        match relative == Path::new(self.name) {
            true => Ok(self.bytes.to_vec()),
            false => self.base.read(relative),
        }
    }
    fn display_path(&self, relative: &Path) -> PathBuf {
        relative.to_path_buf()
    }
}

/// A scene file that draws one mesh file under a sky, for the mesh targets; with a diffuse
/// material of its own, or with the materials the mesh names (an OBJ's `usemtl`).
fn mesh_scene(file: &str, own_material: bool) -> Vec<u8> {
    let mut shape = serde_json::json!({"type": "mesh", "file": file});
    if own_material {
        shape["material"] = "white".into();
    }
    serde_json::json!({
        "units": "m",
        "camera": {"type": "pinhole", "position": [0, 0, 5], "look_at": [0, 0, 0], "fov_deg": 40},
        "film": {"width": 16, "height": 16},
        "materials": {"white": {"type": "diffuse", "albedo": 0.8}},
        "shapes": [shape],
        "lights": [{"type": "environment", "radiance": 1}]
    })
    .to_string()
    .into_bytes()
}

/// Every file under `dir` (recursively) whose name ends in one of `extensions`.
fn find(dir: &Path, extensions: &[&str]) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in entries.filter_map(|e| e.ok()) {
            let path = e.path();
            let name = path.to_string_lossy().into_owned();
            if path.is_dir() {
                stack.push(path);
            } else if extensions.iter().any(|x| name.ends_with(x)) {
                let label = path
                    .strip_prefix(dir)
                    .unwrap_or(&path)
                    .to_string_lossy()
                    .replace('/', "_");
                if let Ok(bytes) = std::fs::read(&path) {
                    out.push((label, bytes));
                }
            }
        }
    }
    out.sort();
    out
}
