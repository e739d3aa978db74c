//! Frames cut into sample ranges over the whole film, shared by the bidirectional methods
//! (BDPT, VCM): light tracing lands on whatever pixel a light vertex projects to, so a tile
//! cannot be rendered on its own. Each task renders every pixel's samples of its range and
//! hands over the camera side's sums and its light-tracing splats (28 bytes a pixel); the
//! variance of a pixel comes from the tasks as independent batches.

use serde::{Deserialize, Serialize};
use tessera_scene::SceneDesc;

use super::film::{
    AovAcc, AovSums, Batches, FilmAcc, FilmSums, Splats, add_splats, check_aov, check_splats,
    check_sums,
};
use super::{Finished, Job, Next, Step, TaskSpec, aov};
use crate::camera::Camera;
use crate::film::{Image, Tile};
use crate::integrator::RayStats;
use crate::integrator::bdpt::BdptSums;

/// Kind of the sample-range tasks.
pub const KIND: &str = "samples";
/// Tasks per frame when the job does not say (`samples_per_task`).
const DEFAULT_TASKS: u32 = 8;

/// How a whole-film method cuts its frames.
#[derive(Debug, Clone)]
pub(super) struct Ranges {
    desc: SceneDesc,
    /// Kind of the range tasks.
    kind: &'static str,
    spp: u32,
    chunk: u32,
    samples_per_task: Option<u32>,
}

/// A sample-range method's task result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum RangePartial {
    Aov(AovSums),
    Samples {
        /// Every pixel's camera-side sums (no second moment).
        camera: FilmSums,
        /// Light tracing's splats, not exposed.
        splats: Splats,
        stats: RayStats,
    },
}

/// A sample-range method's frame.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RangeFrame {
    film: FilmAcc,
    splats: Vec<[f32; 3]>,
    batches: Batches,
    aov: AovAcc,
    stats: RayStats,
    /// Samples per pixel folded in.
    samples: u32,
    steps: u32,
    exposure: f32,
}

impl RangeFrame {
    /// Independent batches (tasks) of samples folded in.
    pub fn batches(&self) -> u32 {
        self.batches.batches()
    }
}

impl RangePartial {
    /// A task's result from the core's fixed-point sums.
    pub fn from_sums(sums: &BdptSums, stats: RayStats) -> Self {
        RangePartial::Samples {
            camera: sums.sums.clone(),
            splats: super::film::splats_from_fixed(&sums.splats),
            stats,
        }
    }
}

impl Ranges {
    /// `name` is the method's, for errors; `kind` its range tasks'.
    pub fn new(job: &Job, name: &str, kind: &'static str) -> Result<Self, String> {
        if job.target_error.is_some() || job.time_limit.is_some() {
            return Err(format!(
                "target_error: {name} refines every pixel at once (its splats land anywhere); give spp instead"
            ));
        }
        let spp = job.desc.integrator.spp.max(1);
        Ok(Ranges {
            desc: job.desc.clone(),
            kind,
            spp,
            chunk: job
                .samples_per_task
                .unwrap_or(spp.div_ceil(DEFAULT_TASKS))
                .clamp(1, spp),
            samples_per_task: job.samples_per_task,
        })
    }

    /// The whole film, as a task's rectangle.
    pub fn film(&self) -> Tile {
        Tile {
            x0: 0,
            y0: 0,
            x1: self.desc.film.width,
            y1: self.desc.film.height,
        }
    }

    /// Range tasks of `frame`'s step `step` over samples [from, to) in ranges of `chunk`,
    /// numbered from `first`.
    fn range_tasks(
        &self,
        (frame, step, first): (u32, u32, u32),
        from: u32,
        to: u32,
        chunk: u32,
    ) -> Vec<TaskSpec> {
        (from..to)
            .step_by(chunk.max(1) as usize)
            .enumerate()
            .map(|(i, s)| {
                TaskSpec::new(self.kind, frame, step, first + i as u32)
                    .with_rect(self.film())
                    .with_range(s, s.saturating_add(chunk).min(to))
            })
            .collect()
    }

    pub fn spp(&self) -> u32 {
        self.spp
    }

    pub fn start(&self, frame: u32) -> Step {
        let f = &self.desc.film;
        let mut tasks = aov::tasks(f.width, f.height, self.spp, frame, 0);
        let more = self.range_tasks((frame, 0, tasks.len() as u32), 0, self.spp, self.chunk);
        tasks.extend(more);
        Step::tasks(tasks)
    }

    /// Samples [the frame's, `spp`) in [`DEFAULT_TASKS`] ranges (or the job's samples per
    /// task).
    pub fn more(&self, frame: u32, f: &RangeFrame, spp: u32) -> Option<Step> {
        let chunk = self
            .samples_per_task
            .unwrap_or(spp.saturating_sub(f.samples).div_ceil(DEFAULT_TASKS));
        Some(Step::tasks(self.range_tasks(
            (frame, f.steps, 0),
            f.samples,
            spp,
            chunk,
        )))
    }

    /// Bytes of a frame's state: the film's and the AOVs' accumulators, the splats and the
    /// batches.
    pub fn frame_bytes(&self) -> u64 {
        let pixels = self.film().pixel_count() as u64;
        pixels
            * (FilmAcc::PIXEL_BYTES
                + std::mem::size_of::<[f32; 3]>() as u64
                + Batches::PIXEL_BYTES
                + AovAcc::PIXEL_BYTES)
    }

    pub fn new_frame(&self, frame: u32) -> RangeFrame {
        let f = &self.desc.film;
        let pixels = f.width as usize * f.height as usize;
        RangeFrame {
            film: FilmAcc::new(f.width, f.height),
            splats: vec![[0.0; 3]; pixels],
            batches: Batches::new(pixels),
            aov: AovAcc::new(f.width, f.height),
            stats: RayStats::default(),
            samples: 0,
            steps: 0,
            exposure: self.camera(frame).exposure,
        }
    }

    pub fn camera(&self, frame: u32) -> Camera {
        Camera::new(&self.desc.camera_at(frame), &self.desc.film)
    }

    /// Checks that a range task spans the film.
    pub fn check(&self, task: &TaskSpec) -> Result<(), String> {
        if task.tile() != self.film() {
            return Err(format!(
                "a {} task must span the film {:?}, got {:?}",
                task.kind,
                self.film(),
                task.tile()
            ));
        }
        Ok(())
    }

    /// Whether a result fits its task: AOVs over the task's rectangle, or the whole film's
    /// sums of the task's samples and a splat per pixel (see [`super::Method::fits`]).
    pub fn fits(&self, task: &TaskSpec, p: &RangePartial) -> Result<(), String> {
        let (w, h) = (self.desc.film.width, self.desc.film.height);
        match p {
            RangePartial::Aov(a) => check_aov(a, [task.x0, task.y0, task.x1, task.y1], w, h),
            RangePartial::Samples { camera, splats, .. } => {
                self.check(task)?;
                check_sums(camera, [0, 0, w, h], task.samples().len(), w, h)?;
                check_splats(splats, w as usize * h as usize)
            }
        }
    }

    pub fn fold(&self, f: &mut RangeFrame, task: &TaskSpec, p: RangePartial) -> Result<(), String> {
        self.fits(task, &p)?;
        match p {
            RangePartial::Aov(a) => f.aov.fold(&a),
            RangePartial::Samples {
                camera,
                splats,
                stats,
            } => {
                let n = task.samples().len();
                let exposure = f.exposure as f64;
                f.batches.fold(n, |i| {
                    (
                        camera.sum[i].map(f64::from),
                        camera.weight[i] as f64,
                        splats[i].map(|l| l as f64 * exposure),
                    )
                });
                f.film.fold(&camera)?;
                add_splats(&mut f.splats, &splats)?;
                f.stats.add(&stats);
                f.samples += n;
                Ok(())
            }
        }
    }

    pub fn advance(&self, f: &mut RangeFrame) -> Next {
        let image = self.image(f);
        let how = format!(
            "per pixel, from the frame's {} tasks as independent batches of samples, light tracing included",
            f.batches.batches()
        );
        self.finish(f, image, how)
    }

    /// Ends frame `f` with `image` (the frame's, or one built on it), whose variance is
    /// obtained as `how` says when the frame had two batches or more, else unknown.
    pub fn finish(&self, f: &mut RangeFrame, image: Image, how: String) -> Next {
        f.steps += 1;
        let (variance, estimate) = if f.batches.batches() >= 2 {
            (how, Some(crate::metrics::estimated_rel_mse(&image)))
        } else {
            (
                "unknown: the frame was one task (one batch); cut it finer (samples_per_task) for an estimate".into(),
                None,
            )
        };
        Next::Done(Finished {
            pixels_s: None,
            fixed_s: 0.0,
            image,
            stats: f.stats,
            metadata: vec![
                ("variance".into(), variance),
                (
                    "estimated_rel_mse".into(),
                    estimate.map_or("unknown (one batch)".into(), |e| format!("{e:.6e}")),
                ),
            ],
            estimated_rel_mse: estimate,
        })
    }

    /// The frame's counters so far.
    pub fn stats(f: &mut RangeFrame) -> &mut RayStats {
        &mut f.stats
    }

    /// Each pixel's filtered camera-side estimate plus its splats, which estimate the film's
    /// measurement per sample, divided by the samples per pixel.
    pub fn image(&self, f: &RangeFrame) -> Image {
        let scale = f.exposure as f64 / f.samples.max(1) as f64;
        f.aov.image(|i| {
            let m = f.film.mean(i);
            let s = f.splats[i];
            (
                std::array::from_fn(|c| (m[c] + s[c] as f64 * scale) as f32),
                f.batches.variance(i),
            )
        })
    }
}
