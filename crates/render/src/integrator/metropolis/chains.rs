//! What the two Metropolis renderers share: direct light and the brightness b by BDPT,
//! bootstrap paths to start chains from, and the cutting of a frame's work into [`GROUPS`].
//!
//! A frame's work is cut into [`GROUPS`] groups, each with its share of the direct-light
//! samples, of the brightness samples, of the bootstrap paths and of the chains (which start
//! from their own group's bootstrap). A group's result is fixed-point sums
//! ([`BdptSums`]: direct light, chain splats, brightness), so the frame is the same bits
//! whether its groups are rendered together or as separate farm tasks merged in any order.

use std::ops::Range;
use std::time::Instant;

use rayon::prelude::*;

use super::primary::{MIN_DEPTH, MltSampler, Paths, Rng, brightness, ctx_area};
use crate::SampleRange;
use crate::camera::Camera;
use crate::integrator::RayStats;
use crate::integrator::bdpt::{Bdpt, BdptSums, Ctx, Splats, fixed_brightness};
use crate::sampler::hash::hash;
use crate::scene::Scene;

/// Groups a Metropolis frame's work is cut into (its farm tasks).
pub const GROUPS: u32 = 8;

/// What [`render_groups`] needs of a Metropolis renderer's settings.
#[derive(Debug, Clone, Copy)]
pub(super) struct ChainSettings {
    pub max_depth: u32,
    /// The fewest brightness samples (more with the budget: a sixteenth of the mutations).
    pub bootstrap: u32,
    /// Bootstrap paths the chains start from.
    pub bootstrap_paths: u64,
    pub chains: u32,
    pub seed: u64,
}

/// A Metropolis renderer: its bootstrap paths' weights and its chains (the rest of a frame
/// is [`render_groups`]'s).
pub(super) trait Chains: Sync {
    /// A thread's scratch space.
    type Scratch: Default + Send;

    fn settings(&self) -> ChainSettings;

    /// The context the chains run in (no roulette: chains fix the path length); refuses what
    /// the renderer does not support.
    fn ctx<'a>(&self, scene: &'a Scene, camera: &'a Camera) -> Result<Ctx<'a>, String> {
        Ok(Ctx::new(scene, camera, u32::MAX))
    }

    /// Bootstrap path `i`'s weight (and what tracing it cost).
    fn bootstrap_weight(&self, ctx: &Ctx, scratch: &mut Self::Scratch, i: u64) -> (f64, RayStats);

    /// Runs `chain` = (index, mutations, bootstrap path it starts from), splatting into
    /// `splats`.
    fn run_chain(
        &self,
        ctx: &Ctx,
        scratch: &mut Self::Scratch,
        chain: (u64, u64, u64),
        splats: &Splats,
    ) -> RayStats;
}

/// Groups `groups` of a frame of `m` with `mutations` per pixel: their direct light and
/// brightness samples, and their chains' splats from starts drawn from their own bootstrap
/// paths.
pub(super) fn render_groups<C: Chains>(
    m: &C,
    scene: &Scene,
    camera: &Camera,
    mutations: u32,
    groups: Range<u32>,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(BdptSums, RayStats), String> {
    let s = m.settings();
    let ctx = m.ctx(scene, camera)?;
    let direct = shares(mutations.max(1) as u64, &groups);
    let range = SampleRange {
        start: direct.start as u32,
        end: direct.end as u32,
    };
    let (mut sums, mut stats) = direct_light(&ctx, s.max_depth, range)?;
    let (chains, st, _) = chain_groups(m, &ctx, mutations, groups, progress);
    stats.add(&st);
    sums.brightness = chains.brightness;
    sums.chain = chains.splats;
    Ok((sums, stats))
}

/// What a group of chains adds to a frame: its chains' splats (Σ f / f* × acceptance per
/// pixel, 2⁻³² units) and its brightness samples (their sum, 2⁻³² units, and count).
#[derive(Debug, Clone, PartialEq)]
pub struct ChainSums {
    pub splats: Vec<[i64; 3]>,
    pub brightness: (i128, u64),
}

/// Emitted and directly reflected light (depths 0 and 1) by BDPT, samples `range` of every
/// pixel, as Veach & Guibas do: it is what sampling independently does best; the chains are
/// left the indirect light.
pub(super) fn direct_light(
    ctx: &Ctx,
    max_depth: u32,
    range: SampleRange,
) -> Result<(BdptSums, RayStats), String> {
    let direct = Bdpt {
        max_depth: max_depth.min(MIN_DEPTH - 1),
        min_depth: 0,
        rr_depth: u32::MAX,
    };
    direct.render_range(ctx.scene, ctx.camera, range, &|_| {})
}

/// Groups `groups` of the chains of a frame with `mutations` per pixel: their share of the
/// brightness samples and bootstrap paths, and their chains' splats; and the wall seconds of
/// the work that does not grow with the film or the mutations (see [`GroupWork::fixed_s`]).
pub(super) fn chain_groups<C: Chains>(
    m: &C,
    ctx: &Ctx,
    mutations: u32,
    groups: Range<u32>,
    progress: &(dyn Fn(u64) + Sync),
) -> (ChainSums, RayStats, f64) {
    let started = Instant::now();
    let s = m.settings();
    let (w, h) = (ctx.scene.film.width, ctx.scene.film.height);
    let mut out = ChainSums {
        splats: vec![[0; 3]; w as usize * h as usize],
        brightness: (0, 0),
    };
    if s.max_depth < MIN_DEPTH {
        return (out, RayStats::default(), 0.0);
    }
    let all = (mutations as f64 * ctx_area(ctx)) as u64;
    let (brightness, mut stats) = brightness_samples(
        ctx,
        s.max_depth,
        (all / 16).max(s.bootstrap as u64),
        s.seed,
        &groups,
    );
    out.brightness = brightness;
    let (boots, st) = bootstrap_cdfs(
        s.bootstrap_paths,
        groups.clone(),
        C::Scratch::default,
        |scratch, i| m.bootstrap_weight(ctx, scratch, i),
    );
    stats.add(&st);
    // The fewest brightness samples and the bootstrap paths are the same whatever the film.
    let fixed_s = started.elapsed().as_secs_f64();
    let splats = Splats::new(w, h);
    let chain_stats: Vec<RayStats> = chain_list(s.chains, all, groups.clone())
        .into_par_iter()
        .map_init(C::Scratch::default, |scratch, (c, steps, g)| {
            let Some(start) = boots[(g - groups.start) as usize].pick(c, s.seed) else {
                return RayStats::default();
            };
            let st = m.run_chain(ctx, scratch, (c, steps, start), &splats);
            progress(steps);
            st
        })
        .collect();
    for st in &chain_stats {
        stats.add(st);
    }
    out.splats = splats.totals();
    (out, stats, fixed_s)
}

/// The part of `n` items group `g` owns.
pub fn share(n: u64, g: u32) -> Range<u64> {
    let part = |g: u32| (n as u128 * g as u128 / GROUPS as u128) as u64;
    part(g)..part(g + 1)
}

/// The parts of `n` items groups `groups` own, together.
fn shares(n: u64, groups: &Range<u32>) -> Range<u64> {
    share(n, groups.start).start..share(n, groups.end.max(groups.start + 1) - 1).end
}

/// Groups `groups`' share of `n` samples of the brightness b, the mean luminance of the
/// indirect light (depths 2..=`max_depth`) over the extended film, each a BDPT sample with
/// every strategy of every depth (so rare bright paths, a small light seen in glass, count as
/// often as the film shows them, not as rarely as one strategy finds them): their sum (2⁻³²
/// units) and count. b's error scales the chains' image.
fn brightness_samples(
    ctx: &Ctx,
    max_depth: u32,
    n: u64,
    seed: u64,
    groups: &Range<u32>,
) -> ((i128, u64), RayStats) {
    // Roulette is fine here (no chain to reject it).
    let rr = Ctx {
        rr_depth: 3,
        ..*ctx
    };
    let bright: Vec<(f64, RayStats)> = shares(n, groups)
        .into_par_iter()
        .map_init(Paths::default, |paths, i| {
            let mut stats = RayStats::default();
            let mut sampler = MltSampler::independent(hash(&[seed, 0x627269676874, i]));
            let y = brightness(&rr, max_depth, &mut sampler, paths, &mut stats);
            (y, stats)
        })
        .collect();
    let (mut sum, mut stats) = ((0i128, 0u64), RayStats::default());
    for (y, st) in &bright {
        sum.0 += fixed_brightness(*y);
        sum.1 += 1;
        stats.add(st);
    }
    (sum, stats)
}

/// The mean of n samples with sum `sum` and sum of squares `sum2`, and its standard error.
pub(super) fn mean_and_error(sum: f64, sum2: f64, n: u64) -> (f64, f64) {
    let n = n.max(1) as f64;
    let mean = sum / n;
    (mean, ((sum2 / n - mean * mean).max(0.0) / n).sqrt())
}

/// One group's bootstrap paths, to start chains from in proportion to their weights.
pub(super) struct Bootstrap {
    first: u64,
    cdf: Vec<f64>,
}

impl Bootstrap {
    /// The bootstrap path chain `c` starts from (drawn ∝ weight with a generator seeded by
    /// (seed, c)); `None` if every weight is zero.
    pub(super) fn pick(&self, c: u64, seed: u64) -> Option<u64> {
        let total = *self.cdf.last()?;
        if total <= 0.0 {
            return None;
        }
        let u = Rng(hash(&[seed, 0x7374617274, c])).uniform() as f64 * total;
        let i = self
            .cdf
            .partition_point(|&v| v <= u)
            .min(self.cdf.len() - 1);
        Some(self.first + i as u64)
    }
}

/// Each group's share of `n` bootstrap paths, path i weighing `weight(scratch, i)`.
fn bootstrap_cdfs<S: Send>(
    n: u64,
    groups: Range<u32>,
    scratch: impl Fn() -> S + Sync + Send,
    weight: impl Fn(&mut S, u64) -> (f64, RayStats) + Sync + Send,
) -> (Vec<Bootstrap>, RayStats) {
    let mut stats = RayStats::default();
    let boots = groups
        .map(|g| {
            let ids = share(n, g);
            let first = ids.start;
            let weights: Vec<(f64, RayStats)> =
                ids.into_par_iter().map_init(&scratch, &weight).collect();
            let mut total = 0.0;
            let cdf = weights
                .iter()
                .map(|(w, st)| {
                    stats.add(st);
                    total += w.max(0.0);
                    total
                })
                .collect();
            Bootstrap { first, cdf }
        })
        .collect();
    (boots, stats)
}

/// The chains of groups `groups` (of `chains` in all, at most one per mutation), each with
/// its mutations (a share of `all`) and its group: (chain, mutations, group).
fn chain_list(chains: u32, all: u64, groups: Range<u32>) -> Vec<(u64, u64, u32)> {
    let chains = (chains as u64).clamp(1, all.max(1));
    groups
        .flat_map(|g| {
            share(chains, g).map(move |c| (c, all / chains + u64::from(c < all % chains), g))
        })
        .collect()
}
