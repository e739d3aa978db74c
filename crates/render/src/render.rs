//! Rendering tiles and frames.
//!
//! [`render_tile`] is a pure function of (scene, camera, tile, sample range): the unit of work
//! a farm task carries. [`render_frame`] runs all tiles of a frame on the current rayon pool.

use rayon::prelude::*;

use crate::camera::{Camera, camera_ray};
use crate::film::{Image, SampleRange, Tile, TileSums, tiles};
use crate::integrator::{Integrator, RayStats};
use crate::sampler::{PixelSampler, Sampler};
use crate::scene::Scene;

/// Renders samples `range` of every pixel of `tile`, seen by `camera`.
pub fn render_tile(
    scene: &Scene,
    camera: &Camera,
    integrator: &dyn Integrator,
    tile: Tile,
    range: SampleRange,
) -> (TileSums, RayStats) {
    let mut sums = TileSums::new(tile, range);
    let mut stats = RayStats::default();
    let mut sampler = PixelSampler::new(scene.integrator.sampler, scene.integrator.seed);
    let exposure = camera.exposure;
    for (pixel, acc) in tile.pixels().zip(sums.pixels.iter_mut()) {
        for index in range.start..range.end {
            sampler.start_pixel_sample(pixel, index);
            let (ray, w) = camera_ray(scene, camera, pixel, &mut sampler);
            let mut l = integrator.li(scene, ray, &mut sampler, &mut stats) * exposure;
            stats.samples += 1;
            // invariant 3 of docs/src/design/overview.md: no NaN or Inf reaches the film. The sample counts as black
            // (every pixel keeps as many samples as its range), and is counted.
            if !l.is_finite() {
                stats.nonfinite += 1;
                l = crate::spectrum::Spectrum::ZERO;
            }
            acc.add(w, l);
        }
    }
    (sums, stats)
}

/// Most samples per pixel whose camera rays the AOVs average.
pub const AOV_SAMPLES: u32 = 16;

/// The samples whose camera rays give the AOVs of a render of samples `range`: its first
/// [`AOV_SAMPLES`] (at least one).
pub fn aov_range(range: SampleRange) -> SampleRange {
    SampleRange {
        start: range.start,
        end: range.start + range.len().clamp(1, AOV_SAMPLES),
    }
}

/// What the camera rays of a pixel's samples first hit: the filter weights of all of them and
/// of those that hit a surface, and the weighted means over the hits.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FirstHits {
    pub weight: f64,
    pub hit: f64,
    pub albedo: [f64; 3],
    /// World-space shading normal.
    pub normal: [f64; 3],
    /// Distance along the camera's axis.
    pub depth: f64,
}

/// The first hits of the camera rays of samples `range` of every pixel of `tile`, row-major:
/// the rays the radiance samples start with, traced to the first surface only (the AOVs).
pub fn first_hits(
    scene: &Scene,
    camera: &Camera,
    tile: Tile,
    range: SampleRange,
) -> Vec<FirstHits> {
    let mut sampler = PixelSampler::new(scene.integrator.sampler, scene.integrator.seed);
    tile.pixels()
        .map(|pixel| {
            let mut sums = FirstHits::default();
            for index in range.start..range.end {
                sampler.start_pixel_sample(pixel, index);
                let (ray, w) = camera_ray(scene, camera, pixel, &mut sampler);
                let w = w as f64;
                sums.weight += w;
                let Some(si) = scene.intersect(&ray) else {
                    continue;
                };
                let a = scene.material(si.material).bsdf_at(&si).albedo();
                sums.hit += w;
                sums.depth += w * camera.depth(si.p) as f64;
                for c in 0..3 {
                    sums.albedo[c] += w * a[c] as f64;
                    sums.normal[c] += w * si.ns[c] as f64;
                }
            }
            let mean = |v: f64| if sums.hit != 0.0 { v / sums.hit } else { 0.0 };
            FirstHits {
                albedo: sums.albedo.map(mean),
                normal: sums.normal.map(mean),
                depth: mean(sums.depth),
                ..sums
            }
        })
        .collect()
}

/// Renders a whole frame with tiles of `tile_size` pixels, samples `range`, on the current
/// rayon pool: the tiles of [`tiles`] rendered in parallel and put in place in a fixed order,
/// the AOVs from the camera rays of the range's first [`AOV_SAMPLES`] samples (as a farm
/// frame's AOV tasks trace them).
pub fn render_frame(
    scene: &Scene,
    camera: &Camera,
    integrator: &dyn Integrator,
    tile_size: u32,
    range: SampleRange,
) -> (Image, RayStats) {
    let aov_range = aov_range(range);
    let done: Vec<_> = tiles(scene.film.width, scene.film.height, tile_size)
        .par_iter()
        .map(|&tile| {
            let (sums, stats) = render_tile(scene, camera, integrator, tile, range);
            (sums, first_hits(scene, camera, tile, aov_range), stats)
        })
        .collect();
    let mut image = Image::new(scene.film.width, scene.film.height);
    let mut stats = RayStats::default();
    for (sums, hits, s) in &done {
        image.put(sums);
        for (p, h) in sums.tile.pixels().zip(hits) {
            let pixel = &mut image.pixels[(p.y * image.width + p.x) as usize];
            pixel.alpha = if h.weight != 0.0 {
                (h.hit / h.weight) as f32
            } else {
                0.0
            };
            pixel.albedo = h.albedo.map(|v| v as f32);
            pixel.normal = h.normal.map(|v| v as f32);
            pixel.depth = h.depth as f32;
        }
        stats.add(s);
    }
    (image, stats)
}
