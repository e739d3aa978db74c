//! Rendering tiles and frames.
//!
//! [`render_tile`] is a pure function of (scene, camera, tile, sample range): the unit of work
//! a farm task carries. [`render_frame`] runs all tiles of a frame on the current rayon pool.

use rayon::prelude::*;

use crate::camera::{Camera, camera_ray};
use crate::film::{Aov, Image, SampleRange, Tile, TileSums, tiles};
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
            let out = integrator.li(scene, ray, &mut sampler, &mut stats);
            stats.samples += 1;
            let mut l = out.l * exposure;
            // DESIGN invariant 3: no NaN or Inf reaches the film. The sample counts as black
            // (every pixel keeps as many samples as its range), and is counted.
            if !l.is_finite() {
                stats.nonfinite += 1;
                l = crate::spectrum::Spectrum::ZERO;
            }
            let aov = out.first_hit.map(|h| Aov {
                albedo: h.albedo,
                normal: h.normal,
                depth: camera.depth(h.p),
            });
            acc.add(w, l, aov.as_ref());
        }
    }
    (sums, stats)
}

/// Renders a whole frame with tiles of `tile_size` pixels, samples `range`, on the current
/// rayon pool: the tiles of [`tiles`] rendered in parallel and put in place in a fixed order.
pub fn render_frame(
    scene: &Scene,
    camera: &Camera,
    integrator: &dyn Integrator,
    tile_size: u32,
    range: SampleRange,
) -> (Image, RayStats) {
    let done: Vec<(TileSums, RayStats)> = tiles(scene.film.width, scene.film.height, tile_size)
        .par_iter()
        .map(|&tile| render_tile(scene, camera, integrator, tile, range))
        .collect();
    let mut image = Image::new(scene.film.width, scene.film.height);
    let mut stats = RayStats::default();
    for (sums, s) in &done {
        image.put(sums);
        stats.add(s);
    }
    (image, stats)
}
