//! Tessera's scene description: the JSON format users write (`file`), its validation and
//! resolution into canonical units (`resolve`), and the result the renderer builds from
//! (`desc`). Bad input becomes a [`SceneError`] naming the file, the field path and what was
//! expected — never a panic.

pub mod animation;
pub mod budget;
pub mod camera;
pub mod desc;
pub mod error;
pub mod file;
pub mod gltf;
pub mod image;
pub mod media;
pub mod mesh;
pub mod photometry;
mod resolve;
pub mod setting;
pub mod source;
pub mod texture;
pub mod transform;

use std::path::Path;

pub use animation::{CameraPath, Keyframe};
pub use desc::*;
pub use error::{Problem, SceneError};
pub use resolve::{MAX_FILM_SIDE, MAX_FRAMES, MAX_PHOTONS, box_mesh, is_gltf};
pub use source::{DirSource, SceneSource};

/// Loads and validates the scene file at `path` (a `scene.json`); referenced files are
/// resolved relative to its folder and may not leave it.
pub fn load(path: &Path) -> Result<SceneDesc, SceneError> {
    let (dir, name) = source::scene_folder(path);
    resolve::load(&DirSource::new(dir), &name)
}

/// Loads and validates the scene file `name` from any [`SceneSource`] (e.g. an uploaded bundle).
pub fn load_from(source: &dyn SceneSource, name: &Path) -> Result<SceneDesc, SceneError> {
    resolve::load(source, name)
}
