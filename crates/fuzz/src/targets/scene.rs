//! `scene`: a scene file (`scene.json`) among the Cornell box's meshes, a small sky and a
//! texture; loaded, planned and built as `tessera render` does before its first ray.

use std::sync::OnceLock;

use super::{With, find};
use crate::{Mem, Target, fixtures, load_plan_build, repo};

pub const TARGET: Target = Target {
    name: "scene",
    about: "scene.json: loaded, planned and built (BVH, lights, textures)",
    run,
    seeds,
};

fn folder() -> &'static Mem {
    static FOLDER: OnceLock<Mem> = OnceLock::new();
    FOLDER.get_or_init(fixtures::scene_folder)
}

fn run(data: &[u8]) -> bool {
    let source = With {
        base: folder(),
        name: "scene.json",
        bytes: data,
    };
    load_plan_build(&source, "scene.json")
}

fn seeds() -> Vec<(String, Vec<u8>)> {
    find(&repo().join("scenes"), &[".json"])
}
