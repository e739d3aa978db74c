//! The AOVs of a frame (alpha, albedo, normal, depth), the same for every method: tasks of
//! their own in a frame's first step, each over a rectangle of pixels, tracing the camera rays
//! of each pixel's first samples ([`crate::render::aov_range`]) — the rays the radiance
//! samples start with — to the first surface they meet.

use half::f16;

use super::TaskSpec;
use super::film::AovSums;
use crate::camera::Camera;
use crate::film::{SampleRange, Tile, tiles};
use crate::render::{aov_range, first_hits};
use crate::scene::Scene;

/// Kind of the AOV tasks.
pub const KIND: &str = "aov";
/// Side of an AOV task's rectangle, pixels.
const AOV_TILE: u32 = 128;

/// The AOV tasks of step 0 of `frame` of a `width`×`height` film at `spp` samples per pixel,
/// numbered from `first`.
pub fn tasks(width: u32, height: u32, spp: u32, frame: u32, first: u32) -> Vec<TaskSpec> {
    let r = aov_range(SampleRange { start: 0, end: spp });
    tiles(width, height, AOV_TILE)
        .into_iter()
        .enumerate()
        .map(|(i, t)| {
            TaskSpec::new(KIND, frame, 0, first + i as u32)
                .with_rect(t)
                .with_range(r.start, r.end)
        })
        .collect()
}

/// Traces an AOV task: per pixel, the weighted means over its samples' first hits.
pub fn execute(scene: &Scene, camera: &Camera, tile: Tile, samples: SampleRange) -> AovSums {
    let hits = first_hits(scene, camera, tile, samples);
    AovSums {
        rect: [tile.x0, tile.y0, tile.x1, tile.y1],
        weight: hits.iter().map(|h| h.weight as f32).collect(),
        hit: hits.iter().map(|h| h.hit as f32).collect(),
        albedo: hits.iter().map(|h| h.albedo.map(f16::from_f64)).collect(),
        normal: hits.iter().map(|h| h.normal.map(f16::from_f64)).collect(),
        depth: hits.iter().map(|h| h.depth as f32).collect(),
    }
}
