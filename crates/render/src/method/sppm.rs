//! Stochastic progressive photon mapping (Hachisuka & Jensen 2009) as a frame method: a
//! frame's iterations are its steps, one after another (each pixel's radius comes from the
//! iteration before: the step's input), and each iteration is a camera task (every pixel's
//! emitted and direct light) and photon tasks, chunks of the iteration's photons gathered at
//! every pixel's visible point. Each process traces an iteration's camera paths once and keeps
//! them for the chunks it runs.

use std::time::{Duration, Instant};
use tessera_scene::setting;

use serde::{Deserialize, Serialize};
use tessera_scene::SceneDesc;

use super::film::{AovAcc, check_aov};
use super::info::{MethodInfo, Model, PilotInfo, Sight, Transport};
use super::{Finished, Job, Method, Next, Plan, Step, TaskCtx, TaskSpec, aov};
use crate::analysis::analyze;
use crate::camera::Camera;
use crate::film::{Image, Tile};
use crate::integrator::RayStats;
use crate::integrator::sppm::{self, Sppm, SppmSettings, SppmState, VisiblePoints, radius2};
use crate::photon::{KdTree, Photon, PhotonSettings};

pub static SPPM: MethodInfo = MethodInfo {
    name: "sppm",
    summary: "stochastic progressive photon mapping (Hachisuka & Jensen): consistent photon mapping",
    spp: "iterations (one camera sample per pixel and photon_map.photons photons each)",
    settings: &[
        &setting::SAMPLER,
        &setting::PHOTONS,
        &setting::RADIUS,
        &setting::ALPHA,
    ],
    translucent: false,
    refuses: None,
    transport: Transport::Full,
    pilot: Some(PilotInfo {
        order: 3,
        model: Model::Progressive,
        k: 1,
        sight: Sight::All,
        photon_map: false,
        probe: None,
    }),
    per_ray: None,
    payloads: |p| {
        p.method::<SppmMethod>()
            .input::<Vec<f32>>("step input (squared radii)");
    },
    plan: |job| Ok(Box::new(SppmMethod::plan(job)?) as Box<dyn Plan>),
};

const CAMERA: &str = "camera";
const PHOTONS: &str = "photons";

pub struct SppmMethod {
    desc: SceneDesc,
    photon: PhotonSettings,
    settings: SppmSettings,
    /// The job's target relMSE: the frame stops at the first iteration (from the second) whose
    /// estimate, the variance of its iterations' mean, is at most this; its spp is the cap.
    target_error: Option<f64>,
}

/// An SPPM task's result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum SppmPartial {
    Aov(super::film::AovSums),
    /// Every pixel's emitted and direct light (times the filter weight), the camera paths'
    /// counters, and the wall seconds the task spent on them (not the
    /// image: what `auto` times).
    Camera {
        ld: Vec<[f32; 3]>,
        stats: RayStats,
        #[serde(default)]
        pixels_s: f64,
    },
    /// What a chunk of photons left at the pixels it reached: pixel, M, Φ; and the wall
    /// seconds of the work that grows with the pixels (the camera paths where this task
    /// traced them, the gathering).
    Photons {
        pixels: Vec<u32>,
        m: Vec<u32>,
        phi: Vec<[f32; 3]>,
        #[serde(default)]
        pixels_s: f64,
    },
}

/// An SPPM frame: the state between iterations, and the running iteration's sums.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SppmFrame {
    state: SppmState,
    ld: Vec<[f32; 3]>,
    phi: Vec<[f64; 3]>,
    m: Vec<u64>,
    aov: AovAcc,
    stats: RayStats,
    /// Iterations to render.
    target: u32,
    /// Wall seconds of the work that grows with the pixels so far (camera paths, gathering;
    /// not the photons).
    #[serde(default)]
    pixels_s: f64,
    exposure: f32,
}

impl SppmFrame {
    /// Every pixel's statistics across the iterations so far.
    pub fn state(&self) -> &SppmState {
        &self.state
    }
}

impl SppmMethod {
    fn plan(job: &Job) -> Result<Self, String> {
        let d = &job.desc;
        if job.time_limit.is_some() {
            return Err("time_limit: sppm runs whole iterations over every pixel; give spp (its iterations) or target_error instead".into());
        }
        if let Some(a) = d.integrator.photon.alpha {
            let alpha = &tessera_scene::setting::ALPHA;
            alpha
                .kind
                .check(a.into())
                .map_err(|e| format!("integrator.{}: {e}", alpha.name))?;
        }
        let (photon, settings) = SppmSettings::resolve(d, &analyze(d));
        if settings.photons == 0 {
            return Err(
                "integrator.photon_map.photons: sppm needs at least 1 photon per iteration".into(),
            );
        }
        // Photon indices are u32: every iteration's photons must have one.
        if settings.iterations as u64 * settings.photons as u64 > u32::MAX as u64 {
            return Err(format!(
                "spp: sppm's iterations × photons per iteration must stay below 2^32 (photon indices), got {} × {}",
                settings.iterations, settings.photons
            ));
        }
        Ok(SppmMethod {
            desc: d.clone(),
            photon,
            settings,
            target_error: job.target_error,
        })
    }

    fn camera(&self, frame: u32) -> Camera {
        Camera::new(&self.desc.camera_at(frame), &self.desc.film)
    }

    fn pixels(&self) -> usize {
        self.desc.film.width as usize * self.desc.film.height as usize
    }

    /// The tasks of iteration `t` of `frame`, numbered from `first`: the camera paths, then
    /// the photon chunks.
    fn iteration(&self, frame: u32, t: u32, first: u32) -> Vec<TaskSpec> {
        let film = Tile {
            x0: 0,
            y0: 0,
            x1: self.desc.film.width,
            y1: self.desc.film.height,
        };
        let mut out = vec![TaskSpec::new(CAMERA, frame, t, first).with_rect(film)];
        for (i, c) in sppm::chunks(self.settings.photons).into_iter().enumerate() {
            out.push(
                TaskSpec::new(PHOTONS, frame, t, first + 1 + i as u32)
                    .with_rect(film)
                    .with_range(c.start, c.end),
            );
        }
        out
    }

    /// The step of iteration `t` after the iterations in `f`: its tasks and its radii.
    fn next_step(&self, frame: u32, f: &SppmFrame) -> Step {
        Step {
            tasks: self.iteration(frame, f.state.iterations, 0),
            input: Some(Box::new(f.state.radii2())),
        }
    }

    /// Iteration `task.step`'s camera paths, traced once per process.
    fn visible_points(
        &self,
        ctx: &TaskCtx,
        task: &TaskSpec,
    ) -> Result<std::sync::Arc<VisiblePoints>, String> {
        ctx.memo("visible points", || {
            let sppm = Sppm::new(ctx.scene, &self.photon, self.settings);
            Ok(sppm.visible_points_parallel(&self.camera(task.frame), task.step))
        })
    }
}

impl Method for SppmMethod {
    type Partial = SppmPartial;
    type Frame = SppmFrame;

    fn name(&self) -> &'static str {
        "sppm"
    }

    fn decisions(&self) -> Vec<String> {
        vec![format!(
            "{} — each frame's iterations run in turn (each one's radii come from the one before), each iteration a camera task and {} photon tasks",
            self.settings.describe(),
            sppm::chunks(self.settings.photons).len()
        )]
    }

    fn metadata(&self) -> Vec<(String, String)> {
        vec![("sppm".into(), self.settings.describe())]
    }

    fn start(&self, frame: u32) -> Result<Step, String> {
        let f = &self.desc.film;
        let mut tasks = aov::tasks(f.width, f.height, self.settings.iterations, frame, 0);
        let first = tasks.len() as u32;
        tasks.extend(self.iteration(frame, 0, first));
        Ok(Step::tasks(tasks))
    }

    fn later_tasks(&self) -> u64 {
        let per_iteration = 1 + sppm::chunks(self.settings.photons).len() as u64;
        self.settings.iterations.saturating_sub(1) as u64 * per_iteration
    }

    fn more(&self, frame: u32, f: &mut SppmFrame, spp: u32) -> Option<Step> {
        f.target = spp;
        (f.state.iterations < spp).then(|| self.next_step(frame, f))
    }

    /// Every pixel's statistics across iterations (six f64 columns, four of them vectors),
    /// the direct light, the photons' sums and the AOVs.
    fn frame_bytes(&self) -> u64 {
        use std::mem::size_of;
        let state = 4 * size_of::<[f64; 3]>() + 2 * size_of::<f64>();
        let sums = size_of::<[f32; 3]>() + size_of::<[f64; 3]>() + size_of::<u64>();
        self.pixels() as u64 * ((state + sums) as u64 + AovAcc::PIXEL_BYTES)
    }

    fn new_frame(&self, frame: u32) -> SppmFrame {
        let f = &self.desc.film;
        SppmFrame {
            state: SppmState::new(
                f.width,
                f.height,
                self.settings.initial_radius,
                crate::filter::Filter::new(f.filter).mean_weight(),
            ),
            ld: Vec::new(),
            phi: Vec::new(),
            m: Vec::new(),
            aov: AovAcc::new(f.width, f.height),
            stats: RayStats::default(),
            target: self.settings.iterations,
            pixels_s: 0.0,
            exposure: self.camera(frame).exposure,
        }
    }

    fn execute(&self, ctx: &TaskCtx, task: &TaskSpec) -> Result<SppmPartial, String> {
        match task.kind.as_str() {
            aov::KIND => Ok(SppmPartial::Aov(aov::execute(
                ctx.scene,
                &self.camera(task.frame),
                task.tile(),
                task.samples(),
            ))),
            CAMERA => {
                let tracing = Instant::now();
                let vps = self.visible_points(ctx, task)?;
                ctx.progress(self.pixels() as u64);
                Ok(SppmPartial::Camera {
                    ld: vps.camera.ld.iter().map(|l| l.to_array()).collect(),
                    stats: vps.camera.stats,
                    pixels_s: tracing.elapsed().as_secs_f64(),
                })
            }
            PHOTONS => {
                // The camera paths, if this task is the first to want them (they are traced once).
                let tracing = Instant::now();
                let vps = self.visible_points(ctx, task)?;
                let mut pixels_s = tracing.elapsed().as_secs_f64();
                let r2 = if task.step == 0 {
                    std::sync::Arc::new(vec![
                        radius2(self.settings.initial_radius as f64);
                        self.pixels()
                    ])
                } else {
                    ctx.input::<Vec<f32>>()?
                };
                if r2.len() != self.pixels() {
                    return Err(format!(
                        "sppm radii for {} pixels, the film has {}",
                        r2.len(),
                        self.pixels()
                    ));
                }
                let sppm = Sppm::new(ctx.scene, &self.photon, self.settings);
                let chunk = task.start..task.end;
                // `auto`'s pilot shoots the first iterations' photons and hands them on.
                let key =
                    sppm::photons_key(&self.photon, &self.settings, task.frame, task.step, &chunk);
                let photons = match ctx.reuse::<KdTree<Photon>>(&key) {
                    Some(p) => p,
                    None => std::sync::Arc::new(sppm.shoot(task.step, chunk, true)),
                };
                let gathering = Instant::now();
                let sums = sppm.gather_parallel(&vps, &r2, &photons);
                pixels_s += gathering.elapsed().as_secs_f64();
                ctx.progress((task.end - task.start) as u64);
                Ok(SppmPartial::Photons {
                    pixels: sums.iter().map(|s| s.pixel).collect(),
                    m: sums.iter().map(|s| s.m).collect(),
                    phi: sums.iter().map(|s| s.phi.map(|v| v as f32)).collect(),
                    pixels_s,
                })
            }
            other => Err(format!("sppm has no {other} tasks")),
        }
    }

    fn fits(&self, task: &TaskSpec, p: &SppmPartial) -> Result<(), String> {
        let n = self.pixels();
        let film = &self.desc.film;
        match p {
            SppmPartial::Aov(a) => check_aov(
                a,
                [task.x0, task.y0, task.x1, task.y1],
                film.width,
                film.height,
            ),
            SppmPartial::Camera { ld, .. } if ld.len() != n => Err(format!(
                "sppm camera paths for {} pixels, the film has {n}",
                ld.len()
            )),
            SppmPartial::Camera { .. } => Ok(()),
            SppmPartial::Photons { pixels, m, phi, .. } => {
                if m.len() != pixels.len() || phi.len() != pixels.len() {
                    return Err("sppm sums with columns of different lengths".into());
                }
                // Strictly increasing pixel indices on the film.
                let ordered = pixels.windows(2).all(|w| w[0] < w[1]);
                if !ordered || pixels.last().is_some_and(|&p| p as usize >= n) {
                    return Err(format!(
                        "sppm sums: pixels out of order or off the {n}-pixel film"
                    ));
                }
                Ok(())
            }
        }
    }

    fn fold(&self, f: &mut SppmFrame, task: &TaskSpec, p: SppmPartial) -> Result<(), String> {
        Method::fits(self, task, &p)?;
        let n = self.pixels();
        match p {
            SppmPartial::Aov(a) => f.aov.fold(&a),
            SppmPartial::Camera {
                ld,
                stats,
                pixels_s,
            } => {
                f.pixels_s += pixels_s;
                if ld.len() != n {
                    return Err(format!(
                        "sppm camera paths for {} pixels, the film has {n}",
                        ld.len()
                    ));
                }
                f.ld = ld;
                f.stats.add(&stats);
                Ok(())
            }
            SppmPartial::Photons {
                pixels,
                m,
                phi,
                pixels_s,
            } => {
                f.pixels_s += pixels_s;
                if m.len() != pixels.len() || phi.len() != pixels.len() {
                    return Err("sppm sums with columns of different lengths".into());
                }
                if f.phi.is_empty() {
                    f.phi = vec![[0.0; 3]; n];
                    f.m = vec![0; n];
                }
                let mut last = None;
                for ((&p, &mi), ph) in pixels.iter().zip(&m).zip(&phi) {
                    if p as usize >= n || last.is_some_and(|l| l >= p) {
                        return Err(format!(
                            "sppm sums: pixel {p} out of order or off the {n}-pixel film"
                        ));
                    }
                    last = Some(p);
                    let i = p as usize;
                    for (p, v) in f.phi[i].iter_mut().zip(ph) {
                        *p += *v as f64;
                    }
                    f.m[i] += mi as u64;
                }
                Ok(())
            }
        }
    }

    fn advance(&self, frame: u32, f: &mut SppmFrame, _: Duration) -> Result<Next, String> {
        if f.ld.len() != self.pixels() {
            return Err(format!(
                "sppm iteration {} of frame {frame} ended without its camera paths",
                f.state.iterations
            ));
        }
        if f.phi.is_empty() {
            f.phi = vec![[0.0; 3]; self.pixels()];
            f.m = vec![0; self.pixels()];
        }
        f.state.add_sums(&f.ld, &f.phi, &f.m, self.settings.alpha);
        f.ld = Vec::new();
        f.phi = Vec::new();
        f.m = Vec::new();
        // The variance of the iterations' mean needs two of them; with a target error the
        // frame stops at the first whose estimate reaches it.
        let (image, estimate) = match (self.target_error, f.state.iterations >= 2) {
            (Some(_), true) => {
                let image = Method::preview(self, frame, f);
                let e = crate::metrics::estimated_rel_mse(&image);
                (Some(image), Some(e))
            }
            _ => (None, None),
        };
        let reached = self
            .target_error
            .zip(estimate)
            .is_some_and(|(target, e)| e <= target);
        if f.state.iterations < f.target && !reached {
            return Ok(Next::Step(self.next_step(frame, f)));
        }
        let image = image.unwrap_or_else(|| Method::preview(self, frame, f));
        let estimate = estimate.or_else(|| {
            (f.state.iterations >= 2).then(|| crate::metrics::estimated_rel_mse(&image))
        });
        let mut metadata = vec![
            (
                "variance".into(),
                "per pixel, of the mean of the iterations' own estimates taken as independent samples: the noise, not the kernel's bias".into(),
            ),
            (
                "estimated_rel_mse".into(),
                estimate.map_or("unknown (one iteration)".into(), |e| {
                    format!("{e:.6e} (variance only; the kernel's bias is not in it)")
                }),
            ),
        ];
        if let Some(t) = self.target_error {
            metadata.push(("target_rel_mse".into(), format!("{t:e}")));
            metadata.push((
                "sppm_stopped".into(),
                if reached {
                    format!(
                        "iteration {}: the estimated relMSE (variance only) reached the target",
                        f.state.iterations
                    )
                } else {
                    format!(
                        "iteration {}: the cap (spp) before the estimated relMSE reached the target",
                        f.state.iterations
                    )
                },
            ));
        }
        Ok(Next::Done(Finished {
            pixels_s: Some(f.pixels_s),
            fixed_s: 0.0,
            image,
            stats: f.stats,
            metadata,
            estimated_rel_mse: estimate,
        }))
    }

    fn preview(&self, _frame: u32, f: &SppmFrame) -> Image {
        let sppm = f.state.image(f.exposure);
        f.aov
            .image(|i| (sppm.pixels[i].rgb, sppm.pixels[i].variance))
    }
}
