//! Frames of independent tiles, shared by the methods whose samples land only on their own
//! pixel (path tracing, direct lighting, photon mapping): a frame's tasks are tiles × sample
//! ranges, and adaptive sampling adds rounds for the noisiest tiles.
//!
//! Adaptive sampling: after a first round, the tiles that contribute most to the relMSE the
//! film's own variance predicts get their samples doubled, round after round, until the
//! estimate meets the target, the time limit passes (in-process renders only), or every tile
//! has the maximum. The choices depend only on the folded sums, so a target-error frame is
//! the same whoever renders it.

use std::time::Duration;

use serde::{Deserialize, Serialize};

use super::film::{AovAcc, AovSums, FilmAcc, FilmSums, check_aov, check_sums};
use super::{Finished, Job, Next, Step, TaskSpec, aov};
use crate::camera::Camera;
use crate::film::{Image, Tile, tiles};
use crate::integrator::{Integrator, RayStats};
use crate::render::render_tile;
use crate::scene::Scene;

/// Kind of the tile tasks.
pub const KIND: &str = "tile";
/// Samples per pixel of an adaptive frame's first round.
pub const ADAPTIVE_FIRST_SPP: u32 = 16;

/// When an adaptive render stops.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Adaptive {
    /// Stop when the estimated relMSE is at most this.
    pub target_rel_mse: Option<f64>,
    /// Start no new round after this long.
    pub time_limit: Option<Duration>,
    /// Samples per pixel in the first round (every tile).
    pub first_spp: u32,
    /// No tile takes more samples per pixel than this.
    pub max_spp: u32,
}

/// How a tile method cuts its frames.
#[derive(Debug, Clone)]
pub(super) struct Tiles {
    width: u32,
    height: u32,
    spp: u32,
    tiles: Vec<Tile>,
    /// Samples per task.
    chunk: u32,
    pub adaptive: Option<Adaptive>,
}

/// A tile method's task result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum TilePartial {
    Aov(AovSums),
    Tile { sums: FilmSums, stats: RayStats },
}

/// A tile method's frame.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct TileFrame {
    film: FilmAcc,
    aov: AovAcc,
    stats: RayStats,
    /// Samples per pixel of each tile so far.
    tile_samples: Vec<u32>,
    rounds: u32,
    stopped: Option<String>,
}

impl Tiles {
    pub fn new(job: &Job) -> Result<Self, String> {
        let d = &job.desc;
        let spp = d.integrator.spp.max(1);
        if !(1..=super::MAX_TILE).contains(&job.tile) {
            return Err(format!(
                "tile: expected 1 to {} pixels, got {}",
                super::MAX_TILE,
                job.tile
            ));
        }
        let adaptive = (job.target_error.is_some() || job.time_limit.is_some()).then(|| Adaptive {
            target_rel_mse: job.target_error,
            time_limit: job.time_limit,
            first_spp: ADAPTIVE_FIRST_SPP.min(spp),
            max_spp: spp,
        });
        Ok(Tiles {
            width: d.film.width,
            height: d.film.height,
            spp,
            tiles: tiles(d.film.width, d.film.height, job.tile),
            chunk: job.samples_per_task.unwrap_or(spp).clamp(1, spp),
            adaptive,
        })
    }

    /// Tile tasks of `frame`'s step `step`, numbered from `first`: tile i from its samples so
    /// far to `end`, cut into ranges of the job's samples per task, for each (i, from, end).
    fn tile_tasks(
        &self,
        frame: u32,
        step: u32,
        first: u32,
        plan: &[(usize, u32, u32)],
    ) -> Vec<TaskSpec> {
        let mut out = Vec::new();
        for &(i, from, end) in plan {
            let mut start = from;
            while start < end {
                let stop = end.min(start.saturating_add(self.chunk));
                out.push(
                    TaskSpec::new(KIND, frame, step, first + out.len() as u32)
                        .with_rect(self.tiles[i])
                        .with_range(start, stop),
                );
                start = stop;
            }
        }
        out
    }

    /// Step 0: the AOVs, then every tile to the first round's samples (all of them unless
    /// adaptive).
    pub fn start(&self, frame: u32) -> Step {
        let mut tasks = aov::tasks(self.width, self.height, self.spp, frame, 0);
        let end = self
            .adaptive
            .map_or(self.spp, |a| a.first_spp.clamp(1, a.max_spp));
        let plan: Vec<(usize, u32, u32)> = (0..self.tiles.len()).map(|i| (i, 0, end)).collect();
        let more = self.tile_tasks(frame, 0, tasks.len() as u32, &plan);
        tasks.extend(more);
        Step::tasks(tasks)
    }

    /// Every tile of a finished frame on to `spp` samples per pixel, a task per tile (not for
    /// adaptive frames).
    pub fn more(&self, frame: u32, f: &TileFrame, spp: u32) -> Option<Step> {
        if self.adaptive.is_some() {
            return None;
        }
        let tasks = f
            .tile_samples
            .iter()
            .enumerate()
            .filter(|&(_, &s)| s < spp)
            .enumerate()
            .map(|(k, (i, &s))| {
                TaskSpec::new(KIND, frame, f.rounds, k as u32)
                    .with_rect(self.tiles[i])
                    .with_range(s, spp)
            })
            .collect();
        Some(Step::tasks(tasks))
    }

    /// Bytes of a frame's state: the film's and the AOVs' accumulators, the tiles' counts.
    pub fn frame_bytes(&self) -> u64 {
        let pixels = self.width as u64 * self.height as u64;
        pixels * (FilmAcc::PIXEL_BYTES + AovAcc::PIXEL_BYTES) + 4 * self.tiles.len() as u64
    }

    pub fn new_frame(&self) -> TileFrame {
        TileFrame {
            film: FilmAcc::new(self.width, self.height),
            aov: AovAcc::new(self.width, self.height),
            stats: RayStats::default(),
            tile_samples: vec![0; self.tiles.len()],
            rounds: 0,
            stopped: None,
        }
    }

    /// Whether a result fits its task: AOVs over the task's rectangle, or sums over one of
    /// the frame's tiles with the task's samples (see [`super::Method::fits`]).
    pub fn fits(&self, task: &TaskSpec, p: &TilePartial) -> Result<(), String> {
        let rect = [task.x0, task.y0, task.x1, task.y1];
        match p {
            TilePartial::Aov(a) => check_aov(a, rect, self.width, self.height),
            TilePartial::Tile { sums, .. } => {
                self.tile_index(task)?;
                check_sums(sums, rect, task.samples().len(), self.width, self.height)
            }
        }
    }

    fn tile_index(&self, task: &TaskSpec) -> Result<usize, String> {
        self.tiles
            .iter()
            .position(|t| *t == task.tile())
            .ok_or_else(|| format!("task {task:?} is not one of the frame's tiles"))
    }

    pub fn fold(&self, f: &mut TileFrame, task: &TaskSpec, p: TilePartial) -> Result<(), String> {
        self.fits(task, &p)?;
        match p {
            TilePartial::Aov(a) => f.aov.fold(&a),
            TilePartial::Tile { sums, stats } => {
                let i = self.tile_index(task)?;
                f.film.fold(&sums)?;
                f.stats.add(&stats);
                f.tile_samples[i] = f.tile_samples[i].max(task.end);
                Ok(())
            }
        }
    }

    /// After a step: another adaptive round, or the frame.
    pub fn advance(&self, frame: u32, f: &mut TileFrame, elapsed: Duration) -> Next {
        f.rounds += 1;
        let Some(rule) = &self.adaptive else {
            return Next::Done(self.finish(f, Vec::new()));
        };
        match next_round(
            &self.tile_errors(f),
            &f.tile_samples,
            self.pixels(),
            rule,
            elapsed,
        ) {
            Round::Render(plan) => {
                let plan: Vec<(usize, u32, u32)> = plan
                    .into_iter()
                    .map(|(i, end)| (i, f.tile_samples[i], end))
                    .collect();
                Next::Step(Step::tasks(self.tile_tasks(frame, f.rounds, 0, &plan)))
            }
            Round::Stop(reason) => {
                f.stopped = Some(reason.to_string());
                let image = self.image(f);
                let (lo, hi) = spp_range(&f.tile_samples);
                // Unknown, never 0, where a pixel has a single sample.
                let estimate = (lo >= 2).then(|| crate::metrics::estimated_rel_mse(&image));
                let mut meta = vec![
                    (
                        "estimated_rel_mse".to_string(),
                        estimate.map_or("unknown (a pixel has one sample)".into(), |e| {
                            format!("{e:.6e}")
                        }),
                    ),
                    ("adaptive_spp_min".into(), lo.to_string()),
                    ("adaptive_spp_max".into(), hi.to_string()),
                    ("adaptive_rounds".into(), f.rounds.to_string()),
                    ("adaptive_stopped".into(), reason.to_string()),
                ];
                if let Some(t) = rule.target_rel_mse {
                    meta.push(("target_rel_mse".into(), format!("{t:e}")));
                }
                // How many rounds fit in a time depends on the machine and its load.
                if let Some(limit) = rule.time_limit {
                    meta.push((
                        "reproducible".into(),
                        format!(
                            "no: a time limit ({:.1} s) decided how many rounds ran ({}); the same settings may stop after another round, and the image differs",
                            limit.as_secs_f64(),
                            f.rounds
                        ),
                    ));
                }
                let mut done = self.finish(f, meta);
                done.estimated_rel_mse = estimate;
                Next::Done(done)
            }
        }
    }

    fn finish(&self, f: &TileFrame, mut metadata: Vec<(String, String)>) -> Finished {
        metadata.push((
            "variance".into(),
            "per pixel, of the mean of its samples taken as independent (the Sobol sampler's \
             stratification makes it err high); for photon mapping, the noise of the camera \
             samples given the photon maps and cache, not their bias"
                .into(),
        ));
        Finished {
            pixels_s: None,
            fixed_s: 0.0,
            image: self.image(f),
            stats: f.stats,
            metadata,
            estimated_rel_mse: None,
        }
    }

    fn pixels(&self) -> f64 {
        self.width as f64 * self.height as f64
    }

    /// The frame so far.
    pub fn image(&self, f: &TileFrame) -> Image {
        f.aov.image(|i| {
            let m = f.film.mean(i);
            ([m[0] as f32, m[1] as f32, m[2] as f32], f.film.variance(i))
        })
    }

    /// Each tile's share of the estimated relMSE numerator: Σ over its pixels and channels of
    /// Var / (x² + 0.01).
    fn tile_errors(&self, f: &TileFrame) -> Vec<f64> {
        self.tiles
            .iter()
            .map(|t| {
                t.pixels()
                    .map(|p| {
                        let i = (p.y * self.width + p.x) as usize;
                        let (m, v) = (f.film.mean(i), f.film.variance(i));
                        (0..3)
                            .map(|c| {
                                let x = m[c] as f32 as f64;
                                v[c] as f64 / (x * x + 0.01)
                            })
                            .sum::<f64>()
                    })
                    .sum()
            })
            .collect()
    }
}

/// Renders a tile task with `integrator` (radiance samples; the AOVs are tasks of their own).
pub(super) fn execute_tile(
    scene: &Scene,
    camera: &Camera,
    integrator: &dyn Integrator,
    task: &TaskSpec,
) -> TilePartial {
    let (sums, stats) = render_tile(scene, camera, integrator, task.tile(), task.samples());
    TilePartial::Tile {
        sums: FilmSums::from_tile(&sums, true),
        stats,
    }
}

/// Samples per pixel of the least and the most sampled tile.
fn spp_range(samples: &[u32]) -> (u32, u32) {
    let lo = samples.iter().copied().min().unwrap_or(0);
    (lo, samples.iter().copied().max().unwrap_or(0))
}

/// What an adaptive render does after a round.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Round {
    /// Stop, for this reason.
    Stop(&'static str),
    /// Render tile i up to `end` samples per pixel, for each (i, end).
    Render(Vec<(usize, u32)>),
}

/// The adaptive rule's next step from the tiles' errors and samples so far.
fn next_round(
    errors: &[f64],
    samples: &[u32],
    pixels: f64,
    rule: &Adaptive,
    elapsed: Duration,
) -> Round {
    let max_spp = rule.max_spp.max(1);
    let total: f64 = errors.iter().sum();
    let estimate = total / (3.0 * pixels);
    // A pixel of one sample has no variance estimate: its zero says nothing.
    if rule.target_rel_mse.is_some_and(|t| estimate <= t) && samples.iter().all(|&s| s >= 2) {
        return Round::Stop("target error reached");
    }
    if rule.time_limit.is_some_and(|l| elapsed >= l) {
        return Round::Stop("time limit reached");
    }
    // Tiles of one sample per pixel first get a second, so that their error can be known.
    let single: Vec<(usize, u32)> = (0..samples.len())
        .filter(|&i| samples[i] < 2 && max_spp >= 2)
        .map(|i| (i, 2))
        .collect();
    if !single.is_empty() {
        return Round::Render(single);
    }
    // Tiles by error, largest first; doubling a tile's samples about halves its error.
    let mut order: Vec<usize> = (0..errors.len())
        .filter(|&i| samples[i] < max_spp)
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
        plan.push((i, (samples[i].max(1) * 2).min(max_spp)));
    }
    plan.sort_unstable();
    Round::Render(plan)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounds_double_the_noisiest_tiles_until_the_target() {
        let rule = Adaptive {
            target_rel_mse: Some(0.8),
            time_limit: None,
            first_spp: 4,
            max_spp: 16,
        };
        // Two of four tiles carry the error: doubling them (halving theirs) meets the target.
        let r = next_round(&[9.0, 0.1, 8.0, 0.1], &[4; 4], 4.0, &rule, Duration::ZERO);
        assert_eq!(r, Round::Render(vec![(0, 8), (2, 8)]));
        let r = next_round(&[0.1; 4], &[4; 4], 4.0, &rule, Duration::ZERO);
        assert_eq!(r, Round::Stop("target error reached"));
        // One sample per pixel estimates no variance (0): not a reached target; every such
        // tile gets a second sample.
        let r = next_round(&[0.0; 4], &[1, 4, 1, 4], 4.0, &rule, Duration::ZERO);
        assert_eq!(r, Round::Render(vec![(0, 2), (2, 2)]));
        let r = next_round(&[9.0; 4], &[16; 4], 4.0, &rule, Duration::ZERO);
        assert_eq!(r, Round::Stop("maximum samples per pixel reached"));
    }
}
