//! Rendering tiles and frames.
//!
//! [`render_tile`] is a pure function of (scene, camera, tile, sample range): the unit of work
//! a farm task carries. [`render_frame`] runs all tiles of a frame on the current rayon pool.

use rayon::prelude::*;

use crate::camera::{Camera, camera_ray};
use crate::film::{Image, SampleRange, Tile, TileSums, tiles};
use crate::integrator::{Integrator, RayStats};
use crate::method::aov::{self, AOV_SAMPLES};
use crate::method::film::AovAcc;
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
            // DESIGN invariant 3: no NaN or Inf reaches the film. The sample counts as black
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

/// Renders a whole frame with tiles of `tile_size` pixels, samples `range`, on the current
/// rayon pool: the tiles of [`tiles`] rendered in parallel and put in place in a fixed order,
/// the AOVs from the first [`AOV_SAMPLES`] camera rays of the range (as a farm frame's AOV
/// tasks trace them).
pub fn render_frame(
    scene: &Scene,
    camera: &Camera,
    integrator: &dyn Integrator,
    tile_size: u32,
    range: SampleRange,
) -> (Image, RayStats) {
    let (width, height) = (scene.film.width, scene.film.height);
    let aov_range = SampleRange {
        start: range.start,
        end: range.start + range.len().clamp(1, AOV_SAMPLES),
    };
    let done: Vec<_> = tiles(width, height, tile_size)
        .par_iter()
        .map(|&tile| {
            let (sums, stats) = render_tile(scene, camera, integrator, tile, range);
            (sums, aov::execute(scene, camera, tile, aov_range), stats)
        })
        .collect();
    let mut film = Image::new(width, height);
    let mut aovs = AovAcc::new(width, height);
    let mut stats = RayStats::default();
    for (sums, aov, s) in &done {
        film.put(sums);
        aovs.fold(aov).expect("a tile's AOVs fit its frame");
        stats.add(s);
    }
    let image = aovs.image(|i| (film.pixels[i].rgb, film.pixels[i].variance));
    (image, stats)
}
