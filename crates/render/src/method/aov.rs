//! The AOVs of a frame (alpha, albedo, normal, depth), the same for every method: tasks of
//! their own in a frame's first step, each over a rectangle of pixels, tracing the camera rays
//! of the first [`AOV_SAMPLES`] samples of each pixel — the rays the radiance samples start
//! with — to the first surface they meet.

use half::f16;

use super::TaskSpec;
use super::film::AovSums;
use crate::camera::Camera;
use crate::camera::camera_ray;
use crate::film::{SampleRange, Tile, tiles};
use crate::sampler::{PixelSampler, Sampler};
use crate::scene::Scene;

/// Kind of the AOV tasks.
pub const KIND: &str = "aov";
/// Most samples per pixel the AOVs average.
pub const AOV_SAMPLES: u32 = 16;
/// Side of an AOV task's rectangle, pixels.
const AOV_TILE: u32 = 128;

/// The AOV tasks of step 0 of `frame` of a `width`×`height` film at `spp` samples per pixel,
/// numbered from `first`.
pub fn tasks(width: u32, height: u32, spp: u32, frame: u32, first: u32) -> Vec<TaskSpec> {
    tiles(width, height, AOV_TILE)
        .into_iter()
        .enumerate()
        .map(|(i, t)| {
            TaskSpec::new(KIND, frame, 0, first + i as u32)
                .with_rect(t)
                .with_range(0, spp.clamp(1, AOV_SAMPLES))
        })
        .collect()
}

/// Traces an AOV task: per pixel, the weighted means over its samples' first hits.
pub fn execute(scene: &Scene, camera: &Camera, tile: Tile, samples: SampleRange) -> AovSums {
    let n = tile.pixel_count();
    let mut out = AovSums {
        rect: [tile.x0, tile.y0, tile.x1, tile.y1],
        weight: Vec::with_capacity(n),
        hit: Vec::with_capacity(n),
        albedo: Vec::with_capacity(n),
        normal: Vec::with_capacity(n),
        depth: Vec::with_capacity(n),
    };
    let mut sampler = PixelSampler::new(scene.integrator.sampler, scene.integrator.seed);
    for pixel in tile.pixels() {
        let (mut w_all, mut w_hit, mut depth) = (0.0f64, 0.0f64, 0.0f64);
        let (mut albedo, mut normal) = ([0.0f64; 3], [0.0f64; 3]);
        for index in samples.start..samples.end {
            sampler.start_pixel_sample(pixel, index);
            let (ray, w) = camera_ray(scene, camera, pixel, &mut sampler);
            let w = w as f64;
            w_all += w;
            let Some(si) = scene.intersect(&ray) else {
                continue;
            };
            let a = scene.material(si.material).bsdf_at(&si).albedo();
            w_hit += w;
            depth += w * camera.depth(si.p) as f64;
            for c in 0..3 {
                albedo[c] += w * a[c] as f64;
                normal[c] += w * si.ns[c] as f64;
            }
        }
        let mean = |v: f64| if w_hit != 0.0 { v / w_hit } else { 0.0 };
        out.weight.push(w_all as f32);
        out.hit.push(w_hit as f32);
        out.albedo.push(albedo.map(|v| f16::from_f64(mean(v))));
        out.normal.push(normal.map(|v| f16::from_f64(mean(v))));
        out.depth.push(mean(depth) as f32);
    }
    out
}
