//! Rendering tiles and frames.
//!
//! [`render_tile`] is a pure function of (scene, tile, sample range): the unit of work a farm
//! task carries. [`render_frame`] runs all tiles of a frame on the current rayon pool.

use glam::Vec2;
use rayon::prelude::*;

use crate::film::{Image, Pixel, SampleRange, Tile, TileSums, tiles};
use crate::integrator::{Integrator, RayStats};
use crate::sampler::{PixelSampler, Sampler};
use crate::scene::Scene;

/// Renders samples `range` of every pixel of `tile`.
pub fn render_tile(
    scene: &Scene,
    integrator: &dyn Integrator,
    tile: Tile,
    range: SampleRange,
) -> (TileSums, RayStats) {
    let mut sums = TileSums::new(tile, range);
    let mut stats = RayStats::default();
    let mut sampler = PixelSampler::new(scene.integrator.sampler, scene.integrator.seed);
    let exposure = scene.camera.exposure;
    let lens = scene.camera.has_aperture();
    for (pixel, acc) in tile.pixels().zip(sums.pixels.iter_mut()) {
        for index in range.start..range.end {
            sampler.start_pixel_sample(pixel, index);
            let (offset, w) = scene.filter.sample(sampler.get_2d());
            let film = pixel.as_vec2() + Vec2::splat(0.5) + offset;
            let u_lens = if lens { sampler.get_2d() } else { Vec2::ZERO };
            let ray = scene.camera.generate_ray(film, u_lens);
            let out = integrator.li(scene, ray, &mut sampler, &mut stats);
            stats.samples += 1;
            let l = out.l * exposure;
            // DESIGN invariant 3: no NaN or Inf reaches the film; count what was dropped.
            if !l.is_finite() {
                stats.nonfinite += 1;
                continue;
            }
            acc.add(w, l, out.first_hit.as_ref());
        }
    }
    (sums, stats)
}

/// Renders a whole frame with tiles of `tile_size` pixels, samples `range`, on the current
/// rayon pool. `on_tile` is called as each tile finishes (from worker threads).
pub fn render_frame(
    scene: &Scene,
    integrator: &dyn Integrator,
    tile_size: u32,
    range: SampleRange,
    on_tile: &(dyn Fn(&Tile) + Sync),
) -> (Image, RayStats) {
    let tiles = tiles(scene.film.width, scene.film.height, tile_size);
    let done: Vec<(Tile, Vec<Pixel>, RayStats)> = tiles
        .par_iter()
        .map(|&tile| {
            let (sums, stats) = render_tile(scene, integrator, tile, range);
            on_tile(&tile);
            (
                tile,
                sums.pixels.iter().map(|p| p.resolve()).collect(),
                stats,
            )
        })
        .collect();
    let mut image = Image::new(scene.film.width, scene.film.height);
    let mut stats = RayStats::default();
    for (tile, pixels, s) in &done {
        for (p, v) in tile.pixels().zip(pixels) {
            image.pixels[(p.y * image.width + p.x) as usize] = *v;
        }
        stats.add(s);
    }
    (image, stats)
}
