//! Progressive and adaptive rendering of one frame.
//!
//! [`Accumulator`] adds sample ranges to per-tile fixed-point sums, so a frame can be looked at
//! (and its error estimated) after any number of samples, and the result is bit-identical to
//! rendering the same ranges at once. [`render_adaptive`] uses it to put samples where the image
//! is noisy: after a first round it repeatedly doubles the samples of the tiles that contribute
//! most to the estimated relMSE, until the estimate meets a target, a time limit passes, or every
//! tile has the maximum. Its choices depend only on the sums, so a target-error render is
//! deterministic; a time limit is not (it depends on the machine).

use std::time::{Duration, Instant};

use rayon::prelude::*;
use tessera_render::camera::Camera;
use tessera_render::film::{TileSums, tiles};
use tessera_render::{Image, RayStats, SampleRange, metrics, render};
use tessera_scene::SceneDesc;

#[cfg(test)]
use crate::job::FrameRange;
use crate::job::Prepared;

/// A frame accumulated over successive sample ranges (progressive rendering): per-tile sums
/// merged in sample order, so the image after N samples is bit-identical to rendering
/// [0, N) at once.
pub struct Accumulator {
    width: u32,
    height: u32,
    tiles: Vec<TileSums>,
    stats: RayStats,
    /// Samples per pixel so far, in every tile (the least, after adaptive rounds).
    pub samples: u32,
}

impl Accumulator {
    pub fn new(desc: &SceneDesc, tile: u32) -> Self {
        let empty = SampleRange { start: 0, end: 0 };
        Accumulator {
            width: desc.film.width,
            height: desc.film.height,
            tiles: tiles(desc.film.width, desc.film.height, tile)
                .into_iter()
                .map(|t| TileSums::new(t, empty))
                .collect(),
            stats: RayStats::default(),
            samples: 0,
        }
    }

    /// Renders samples [samples, end) of every tile on the current rayon pool and adds them.
    pub fn render_to(&mut self, prepared: &Prepared, camera: &Camera, end: u32) {
        let plan: Vec<(usize, u32)> = (0..self.tiles.len()).map(|i| (i, end)).collect();
        self.render_tiles(prepared, camera, &plan);
    }

    /// The frame so far.
    pub fn image(&self) -> (Image, RayStats) {
        (
            Image::from_tiles(self.width, self.height, &self.tiles),
            self.stats,
        )
    }
}

impl Accumulator {
    /// Renders tile `i` up to `end` samples per pixel, for each (i, end).
    fn render_tiles(&mut self, prepared: &Prepared, camera: &Camera, plan: &[(usize, u32)]) {
        let mut chosen: Vec<(&mut TileSums, u32)> = Vec::with_capacity(plan.len());
        let mut ends = vec![None; self.tiles.len()];
        for &(i, end) in plan {
            ends[i] = Some(end);
        }
        for (sums, end) in self.tiles.iter_mut().zip(ends) {
            if let Some(end) = end.filter(|&e| e > sums.samples.end) {
                chosen.push((sums, end));
            }
        }
        let stats: Vec<RayStats> = chosen
            .par_iter_mut()
            .map(|(sums, end)| {
                let range = SampleRange {
                    start: sums.samples.end,
                    end: *end,
                };
                let integrator = prepared
                    .integrator()
                    .expect("in-process renders run their passes in Prepared::new");
                let (more, stats) =
                    render::render_tile(&prepared.scene, camera, integrator, sums.tile, range);
                sums.merge(&more);
                stats
            })
            .collect();
        for s in &stats {
            self.stats.add(s);
        }
        self.samples = self.tiles.iter().map(|t| t.samples.end).min().unwrap_or(0);
    }

    pub fn tiles(&self) -> &[TileSums] {
        &self.tiles
    }
}

/// Each tile's share of the estimated relMSE numerator: Σ over its pixels and channels of
/// Var / (x² + 0.01).
pub fn tile_errors(tiles: &[TileSums]) -> Vec<f64> {
    tiles
        .iter()
        .map(|t| {
            t.pixels
                .iter()
                .map(|p| {
                    let r = p.resolve();
                    (0..3)
                        .map(|c| {
                            let x = r.rgb[c] as f64;
                            r.variance[c] as f64 / (x * x + 0.01)
                        })
                        .sum::<f64>()
                })
                .sum()
        })
        .collect()
}

/// Samples per pixel of the least and the most sampled tile.
pub fn spp_range(tiles: &[TileSums]) -> (u32, u32) {
    let ends = tiles.iter().map(|t| t.samples.end);
    (ends.clone().min().unwrap_or(0), ends.max().unwrap_or(0))
}

/// What an adaptive render does after a round.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Round {
    /// Stop, for this reason.
    Stop(&'static str),
    /// Render tile `i` (in [`tiles`] order) up to `end` samples per pixel, for each (i, end).
    Render(Vec<(usize, u32)>),
}

/// The adaptive rule's next step from the tiles' sums so far. Shared by in-process renders and
/// the coordinator, so both make the same choices and give the same image.
pub fn next_round(tiles: &[TileSums], pixels: f64, rule: &Adaptive, elapsed: Duration) -> Round {
    let max_spp = rule.max_spp.max(1);
    let errors = tile_errors(tiles);
    let total: f64 = errors.iter().sum();
    let estimate = total / (3.0 * pixels);
    if rule.target_rel_mse.is_some_and(|t| estimate <= t) {
        return Round::Stop("target error reached");
    }
    if rule.time_limit.is_some_and(|l| elapsed >= l) {
        return Round::Stop("time limit reached");
    }
    // Tiles by error, largest first; doubling a tile's samples about halves its error.
    let mut order: Vec<usize> = (0..errors.len())
        .filter(|&i| tiles[i].samples.end < max_spp)
        .collect();
    if order.is_empty() {
        return Round::Stop("maximum samples per pixel reached");
    }
    order.sort_by(|&a, &b| errors[b].total_cmp(&errors[a]).then(a.cmp(&b)));
    let goal = rule.target_rel_mse.map(|t| t * 3.0 * pixels);
    let median = errors[order[order.len() / 2]];
    let mut projected = total;
    let mut plan = Vec::new();
    for &i in &order {
        let enough = match goal {
            Some(g) => projected <= g,
            // Without a target: the noisier half.
            None => errors[i] < median,
        };
        if enough && !plan.is_empty() {
            break;
        }
        projected -= errors[i] / 2.0;
        plan.push((i, (tiles[i].samples.end.max(1) * 2).min(max_spp)));
    }
    plan.sort_unstable();
    Round::Render(plan)
}

/// EXR header entries of a finished adaptive frame whose estimated relMSE is `estimate`.
pub fn adaptive_metadata(
    estimate: f64,
    tiles: &[TileSums],
    stopped: &str,
    rule: &Adaptive,
) -> Vec<(String, String)> {
    let (spp_min, spp_max) = spp_range(tiles);
    let mut out = vec![
        ("estimated_rel_mse".to_string(), format!("{estimate:.6e}")),
        ("adaptive_spp_min".into(), spp_min.to_string()),
        ("adaptive_spp_max".into(), spp_max.to_string()),
        ("adaptive_stopped".into(), stopped.to_string()),
    ];
    if let Some(t) = rule.target_rel_mse {
        out.push(("target_rel_mse".into(), format!("{t:e}")));
    }
    out
}

/// When an adaptive render stops.
#[derive(Debug, Clone, Copy)]
pub struct Adaptive {
    /// Stop when the estimated relMSE is at most this.
    pub target_rel_mse: Option<f64>,
    /// Stop starting new rounds after this long.
    pub time_limit: Option<Duration>,
    /// Samples per pixel in the first round (every tile).
    pub first_spp: u32,
    /// No tile takes more samples per pixel than this.
    pub max_spp: u32,
}

/// What an adaptive render achieved.
#[derive(Debug, Clone)]
pub struct AdaptiveResult {
    pub image: Image,
    pub stats: RayStats,
    /// relMSE estimated from the film's variance when it stopped.
    pub estimated_rel_mse: f64,
    pub spp_min: u32,
    pub spp_max: u32,
    pub rounds: u32,
    /// Why it stopped.
    pub stopped: &'static str,
    /// EXR header entries: the estimate, the spp range, why it stopped, the target.
    pub metadata: Vec<(String, String)>,
}

/// Renders a frame adaptively (see the module documentation) on the current rayon pool.
pub fn render_adaptive(
    prepared: &Prepared,
    camera: &Camera,
    tile: u32,
    rule: &Adaptive,
) -> AdaptiveResult {
    let start = Instant::now();
    let mut acc = Accumulator::new(&prepared.desc, tile);
    let max_spp = rule.max_spp.max(1);
    acc.render_to(prepared, camera, rule.first_spp.clamp(1, max_spp));
    let mut rounds = 1;
    let pixels = (prepared.desc.film.width as f64) * (prepared.desc.film.height as f64);
    let stopped = loop {
        match next_round(acc.tiles(), pixels, rule, start.elapsed()) {
            Round::Stop(reason) => break reason,
            Round::Render(plan) => acc.render_tiles(prepared, camera, &plan),
        }
        rounds += 1;
    };
    let (image, stats) = acc.image();
    let (spp_min, spp_max) = spp_range(acc.tiles());
    let estimated_rel_mse = metrics::estimated_rel_mse(&image);
    AdaptiveResult {
        metadata: adaptive_metadata(estimated_rel_mse, acc.tiles(), stopped, rule),
        estimated_rel_mse,
        image,
        stats,
        spp_min,
        spp_max,
        rounds,
        stopped,
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::job::tests::cornell;
    use crate::job::{RenderSettings, TaskOutput, plan_frame, stitch};

    #[test]
    fn progressive_accumulation_equals_one_render() {
        let desc = cornell();
        let prepared = Prepared::new(desc.clone(), FrameRange::single(1));
        let camera = prepared.camera(1);
        let mut acc = Accumulator::new(&desc, 16);
        acc.render_to(&prepared, &camera, 1);
        acc.render_to(&prepared, &camera, 3);
        acc.render_to(&prepared, &camera, 5);
        let tasks = plan_frame(&desc, &RenderSettings::default(), 1);
        let outs: Vec<TaskOutput> = tasks.iter().map(|t| prepared.execute(t)).collect();
        assert_eq!(
            acc.image(),
            stitch(desc.film.width, desc.film.height, &outs)
        );
    }

    #[test]
    fn adaptive_sampling_puts_more_samples_where_it_is_noisy_and_is_deterministic() {
        let desc = cornell();
        let prepared = Prepared::new(desc.clone(), FrameRange::single(1));
        let camera = prepared.camera(1);
        let rule = Adaptive {
            target_rel_mse: Some(0.02),
            time_limit: None,
            first_spp: 4,
            max_spp: 256,
        };
        let a = render_adaptive(&prepared, &camera, 8, &rule);
        assert_eq!(a.stopped, "target error reached");
        assert!(a.estimated_rel_mse <= 0.02);
        assert!(a.spp_max > a.spp_min, "{} {}", a.spp_min, a.spp_max);
        let b = render_adaptive(&prepared, &camera, 8, &rule);
        assert_eq!(a.image, b.image);
    }

    /// Issue 4's honesty check: on the Cornell box the relMSE the adaptive render estimates for
    /// itself and the one measured against the converged reference differ by less than 2×.
    /// (The estimate assumes independent samples; Owen-scrambled Sobol does better than that,
    /// so it errs high, by about 1.6× on this scene.)
    #[test]
    fn the_adaptive_error_estimate_is_honest_on_the_cornell_box() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-box");
        let desc = tessera_scene::load(&path.join("scene.json")).unwrap_or_else(|e| panic!("{e}"));
        let prepared = Prepared::new(desc, FrameRange::single(1));
        let camera = prepared.camera(1);
        let rule = Adaptive {
            target_rel_mse: Some(4e-3),
            time_limit: None,
            first_spp: 16,
            max_spp: 1024,
        };
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .expect("pool");
        let r = pool.install(|| render_adaptive(&prepared, &camera, 32, &rule));
        assert_eq!(r.stopped, "target error reached");
        let reference = tessera_render::read_exr(&path.join("reference.exr")).expect("reference");
        let rgb: Vec<glam::Vec3A> = r.image.pixels.iter().map(|p| p.rgb.into()).collect();
        let refs: Vec<glam::Vec3A> = reference.pixels.iter().map(|&p| p.into()).collect();
        let measured = metrics::compare(&rgb, &refs).rel_mse;
        let ratio = r.estimated_rel_mse / measured;
        assert!(
            (0.5..2.0).contains(&ratio),
            "estimated {:.3e}, measured {measured:.3e}",
            r.estimated_rel_mse
        );
    }
}
