//! Primary-sample-space Metropolis light transport (Kelemen, Szirmay-Kalos, Antal & Csonka
//! 2002), multiplexed over BDPT's strategies (Hachisuka, Kaplanyan & Dachsbacher 2014; pbrt-v3
//! §16.4).
//!
//! A path is a deterministic function of a vector of uniform numbers (its *primary sample*):
//! the film position, the camera subpath, the light subpath, the connection, each from its own
//! stream of the vector. The chain state is (depth, primary sample); its first number picks
//! which BDPT strategy (s, t) makes a path of that depth, and the contribution is that
//! strategy's MIS-weighted estimate times the number of strategies (and of depths), so the
//! chain also explores strategies (multiplexing). Mutations: a *large step* redraws every
//! number and the depth (with probability `large_step`); a *small step* moves each number by a
//! normal offset of `sigma` (wrapped to [0, 1)) and keeps the depth. Both proposals are
//! symmetric; Metropolis–Hastings accepts with min(1, y'/y) for y the luminance. The proposal
//! and the current state are both splatted with their expected weights (Veach's "expected
//! values").
//!
//! As Veach & Guibas propose, emitted and directly reflected light (depths 0 and 1) are
//! rendered apart, by BDPT; the chains carry depths ≥ 2. Their image is the splats times
//! b / (mutations per unit of film), b = E[y] over the state space, which sets the image's
//! brightness: it is estimated by BDPT samples (every strategy of every depth ≥ 2, through
//! uniform film points) — an estimate with one strategy per sample (pbrt's bootstrap) left a
//! small light seen through glass to a handful of lucky samples and missed the mean by
//! 5–15 %. The chains start from bootstrap paths drawn in proportion to y, so no burn-in is
//! needed. Film positions cover the film extended by the filter's reach (pbrt's sample
//! bounds), so edge pixels get their share.
//!
//! Determinism: chains are seeded from (seed, chain), run in parallel, and splat into
//! fixed-point sums, so the image does not depend on thread count or scheduling; the frame is
//! cut into groups of chains ([`super::chains`]) that the farm renders as separate tasks
//! to the same bits.

use glam::Vec2;

use super::chains::{ChainSettings, Chains};
use super::primary::{
    CAMERA_STREAM, CONNECT_STREAM, LIGHT_STREAM, MIN_DEPTH, MltSampler, Paths, Rng, film_ray,
    light_tracing_scale,
};
use crate::integrator::RayStats;
use crate::integrator::bdpt::{Ctx, Splats};
use crate::sampler::Sampler;
use crate::sampler::hash::hash;
use crate::spectrum::{Spectrum, luminance};

/// The settings PSSMLT runs with.
#[derive(Debug, Clone, Copy)]
pub struct Pssmlt {
    /// Most scattering vertices on a path.
    pub max_depth: u32,
    /// Independent paths (spread evenly over the depths) for the brightness estimate and the
    /// chains' starts.
    pub bootstrap: u32,
    /// Independent Markov chains (each a task's worth of work on the farm).
    pub chains: u32,
    /// Standard deviation of a small step in primary sample space.
    pub sigma: f32,
    /// Probability of a large step (every number drawn anew).
    pub large_step: f32,
    pub seed: u64,
}

impl Pssmlt {
    /// pbrt-v3's defaults (1000 chains, σ = 0.01, large steps 30 %), with 100 000 bootstrap
    /// paths in all (pbrt has that many per depth, for depths to 5).
    pub fn new(desc: &tessera_scene::SceneDesc) -> Self {
        Pssmlt {
            max_depth: desc.integrator.max_depth,
            bootstrap: 100_000,
            chains: 1000,
            sigma: 0.01,
            large_step: 0.3,
            seed: desc.integrator.seed,
        }
    }
}

impl Chains for Pssmlt {
    type Scratch = Paths;

    fn settings(&self) -> ChainSettings {
        let depths = self.depths();
        ChainSettings {
            max_depth: self.max_depth,
            bootstrap: self.bootstrap,
            bootstrap_paths: (self.bootstrap as u64).div_ceil(depths) * depths,
            chains: self.chains,
            seed: self.seed,
        }
    }

    fn bootstrap_weight(&self, ctx: &Ctx, paths: &mut Paths, i: u64) -> (f64, RayStats) {
        let mut stats = RayStats::default();
        let mut sampler = MltSampler::new(self.seed_of(i), self.sigma, self.large_step);
        let depths = self.depths();
        let depth = MIN_DEPTH as usize + (i % depths) as usize;
        let (l, _) = self.l(ctx, &mut sampler, depth, paths, &mut stats);
        (luminance(l).max(0.0) as f64, stats)
    }

    fn run_chain(
        &self,
        ctx: &Ctx,
        paths: &mut Paths,
        chain: (u64, u64, u64),
        splats: &Splats,
    ) -> RayStats {
        let (c, steps, start) = chain;
        self.chain(ctx, c, steps, start, self.depths(), paths, splats)
    }
}

impl Pssmlt {
    /// The contribution of a path of `depth` scattering events made from the sampler's primary
    /// sample, and where on the film it lands.
    fn l(
        &self,
        ctx: &Ctx,
        sampler: &mut MltSampler,
        depth: usize,
        paths: &mut Paths,
        stats: &mut RayStats,
    ) -> (Spectrum, Vec2) {
        sampler.start_stream(CAMERA_STREAM);
        let (s, t, strategies) = if depth == 0 {
            (0, 2, 1)
        } else {
            let n = depth + 2;
            let s = ((sampler.get_1d() * n as f32) as usize).min(n - 1);
            (s, n - s, n)
        };
        let (ray, p_raster) = film_ray(ctx, sampler);
        ctx.camera_subpath(ray, t, sampler, stats, &mut paths.camera);
        if paths.camera.len() != t {
            return (Spectrum::ZERO, p_raster);
        }
        sampler.start_stream(LIGHT_STREAM);
        paths.light.clear();
        if s > 0 {
            ctx.light_subpath(s, sampler, stats, &mut paths.light);
        }
        // s = 1 samples its own light point, whether or not the subpath started.
        if s >= 2 && paths.light.len() != s {
            return (Spectrum::ZERO, p_raster);
        }
        sampler.start_stream(CONNECT_STREAM);
        let (l, raster) = ctx.connect(&paths.light, &paths.camera, s, t, 0.0, sampler, stats);
        stats.samples += 1;
        let l = l * strategies as f32 * light_tracing_scale(ctx, t);
        if !l.is_finite() {
            stats.nonfinite += 1;
            return (Spectrum::ZERO, p_raster);
        }
        (l, raster.unwrap_or(p_raster))
    }

    fn seed_of(&self, bootstrap_index: u64) -> u64 {
        hash(&[self.seed, 0x6d6c74, bootstrap_index])
    }

    /// Depths 2..=max_depth the chains carry (at least one, for the arithmetic).
    fn depths(&self) -> u64 {
        (self.max_depth.max(MIN_DEPTH) - MIN_DEPTH + 1) as u64
    }

    /// Runs chain `c` for `steps` mutations from a start drawn from the bootstrap paths. The
    /// path's depth is part of the state, changed only by large steps (a symmetric proposal:
    /// drawn anew or kept).
    #[allow(clippy::too_many_arguments)]
    fn chain(
        &self,
        ctx: &Ctx,
        c: u64,
        steps: u64,
        i: u64,
        depths: u64,
        paths: &mut Paths,
        splats: &Splats,
    ) -> RayStats {
        let mut stats = RayStats::default();
        let mut rng = Rng(hash(&[self.seed, 0x636861696e, c]));
        let mut depth = MIN_DEPTH as usize + (i % depths) as usize;
        let mut sampler = MltSampler::new(self.seed_of(i), self.sigma, self.large_step);
        let (mut l_cur, mut p_cur) = self.l(ctx, &mut sampler, depth, paths, &mut stats);
        let scene = ctx.scene;
        for _ in 0..steps {
            sampler.start_iteration();
            let new_depth = if sampler.large_step {
                MIN_DEPTH as usize
                    + ((rng.uniform() * depths as f32) as usize).min(depths as usize - 1)
            } else {
                depth
            };
            let (l_new, p_new) = self.l(ctx, &mut sampler, new_depth, paths, &mut stats);
            let (y_cur, y_new) = (luminance(l_cur), luminance(l_new));
            let accept = if y_cur > 0.0 {
                (y_new / y_cur).min(1.0)
            } else {
                1.0
            };
            if accept > 0.0 && y_new > 0.0 {
                splats.add(scene, p_new, l_new * (accept / y_new));
            }
            if accept < 1.0 && y_cur > 0.0 {
                splats.add(scene, p_cur, l_cur * ((1.0 - accept) / y_cur));
            }
            if rng.uniform() < accept {
                (l_cur, p_cur, depth) = (l_new, p_new, new_depth);
                sampler.accept();
            } else {
                sampler.reject();
            }
        }
        stats
    }
}
