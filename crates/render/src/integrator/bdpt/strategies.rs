//! Per-strategy images for debugging (Veach's figure 10.3; pbrt's `visualizeStrategies`).

use glam::Vec2;
use rayon::prelude::*;

use super::Bdpt;
use super::splats::{Splats, add_splats};
use super::subpath::Ctx;
use crate::SampleRange;
use crate::camera::Camera;
use crate::film::{Image, tiles};
use crate::scene::Scene;
use crate::spectrum::Spectrum;

/// One strategy's images (see [`Bdpt::render_strategies`]).
pub struct StrategyImage {
    pub s: u32,
    pub t: u32,
    pub weighted: Image,
    pub unweighted: Image,
}

/// Where [`Bdpt::render_strategies`] collects each strategy's contributions.
pub(super) struct Recorder<'a> {
    strategies: &'a [(usize, usize)],
    /// (weighted, unweighted) per strategy.
    films: &'a [(Splats, Splats)],
}

impl Recorder<'_> {
    #[allow(clippy::too_many_arguments)]
    pub(super) fn record(
        &self,
        scene: &Scene,
        s: usize,
        t: usize,
        pixel: glam::UVec2,
        raster: Option<Vec2>,
        weighted: Spectrum,
        unweighted: Spectrum,
    ) {
        let Some(i) = self.strategies.iter().position(|&x| x == (s, t)) else {
            return;
        };
        let (a, b) = &self.films[i];
        let at = raster.unwrap_or(pixel.as_vec2() + Vec2::splat(0.5));
        for (film, l) in [(a, weighted), (b, unweighted)] {
            match raster {
                Some(_) => film.add(scene, at, l),
                None => film.add_pixel(pixel, l),
            }
        }
    }
}

impl Bdpt {
    /// Per-strategy images for debugging (Veach's figure 10.3; pbrt's `visualizeStrategies`):
    /// for every (s, t) of depth s + t − 2 ≤ `depth`, what the strategy contributes to the
    /// image with its MIS weight, and without (the strategy's own estimate of all light of
    /// that depth, wherever it can sample it). Camera-side contributions land on their pixel,
    /// light tracing through the film filter; each is exposed and divided by the samples.
    pub fn render_strategies(
        &self,
        scene: &Scene,
        camera: &Camera,
        range: SampleRange,
        depth: u32,
    ) -> Result<Vec<StrategyImage>, String> {
        let ctx = Ctx::new(scene, camera, self.rr_depth);
        let (w, h) = (scene.film.width, scene.film.height);
        let depth = depth.min(self.max_depth) as usize;
        let strategies: Vec<(usize, usize)> = (0..=depth)
            .flat_map(|d| (0..=d + 1).map(move |s| (s, d + 2 - s)))
            .filter(|&st| st != (1, 1))
            .collect();
        let films: Vec<(Splats, Splats)> = strategies
            .iter()
            .map(|_| (Splats::new(w, h), Splats::new(w, h)))
            .collect();
        let recorder = Recorder {
            strategies: &strategies,
            films: &films,
        };
        let splats = Splats::new(w, h);
        tiles(w, h, 16).into_par_iter().for_each(|tile| {
            self.render_tile(&ctx, tile, range, &splats, Some(&recorder));
        });
        let scale = camera.exposure as f64 / range.end.saturating_sub(range.start).max(1) as f64;
        let image = |f: &Splats| {
            let mut image = Image::new(w, h);
            add_splats(&mut image, &f.totals(), scale);
            image
        };
        Ok(strategies
            .iter()
            .zip(&films)
            .map(|(&(s, t), (weighted, unweighted))| StrategyImage {
                s: s as u32,
                t: t as u32,
                weighted: image(weighted),
                unweighted: image(unweighted),
            })
            .collect())
    }
}
