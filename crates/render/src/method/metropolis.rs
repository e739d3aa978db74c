//! The Metropolis renderers as frame methods: primary-sample-space MLT (Kelemen et al. 2002,
//! multiplexed over BDPT's strategies as Hachisuka et al. 2014) and path-space MLT (Veach &
//! Guibas 1997: bidirectional, lens subpath, lens and caustic perturbation mutations; pinhole
//! cameras and lights at finite distance only). Both leave direct light to BDPT, in sample
//! ranges over the whole film (as [`super::ranges`]), and run their chains in
//! [`GROUPS`](crate::integrator::metropolis::GROUPS) tasks, each a group of chains with its
//! share of the brightness samples and bootstrap paths. The chains' image is scaled by the
//! brightness b, the mean over every group's samples, once all are folded.

use serde::{Deserialize, Serialize};
use tessera_scene::setting;

use super::film::{Ratios, Splats, add_splats, check_splats, splats_from_fixed};
use super::ranges::{RangeFrame, RangePartial, Ranges};
use std::time::{Duration, Instant};

use tessera_scene::SceneDesc;

use super::info::{MethodInfo, Model, PilotInfo, Probe, Sight, Transport};
use super::{Finished, Job, Method, Next, Plan, Step, TaskCtx, TaskSpec, aov};
use crate::camera::Camera;
use crate::film::Image;
use crate::integrator::RayStats;
use crate::integrator::metropolis::mlt::Mlt;
use crate::integrator::metropolis::pssmlt::Pssmlt;
use crate::integrator::metropolis::{GROUPS, GroupWork, Metropolis};
use crate::scene::Scene;

/// Kind of the direct-light tasks.
pub const DIRECT: &str = "direct";
/// Kind of the chain tasks.
pub const CHAINS: &str = "chains";

/// A Metropolis method's task result.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum MetroPartial {
    /// The AOVs or a range of direct light.
    Direct(RangePartial),
    /// A group of chains: their splats (Σ f / f* × acceptance per pixel) and the group's
    /// brightness samples (sum and count).
    Chains {
        splats: Splats,
        brightness: f64,
        count: u64,
        stats: RayStats,
        /// Wall seconds of the group's bootstrap (see [`GroupWork::fixed_s`]).
        #[serde(default)]
        fixed_s: f64,
    },
}

/// A Metropolis method's frame.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MetroFrame {
    direct: RangeFrame,
    chain: Vec<[f32; 3]>,
    /// Each group's own estimate of the chains' image, b_g × its splats: independent
    /// batches of the chains' share (the chains within a group are correlated, the groups
    /// are not).
    groups: Ratios,
    brightness: f64,
    count: u64,
    exposure: f32,
    /// The groups' bootstrap seconds, summed.
    #[serde(default)]
    fixed_s: f64,
}

pub static PSSMLT: MethodInfo = MethodInfo {
    name: "pssmlt",
    summary: "primary-sample-space Metropolis light transport (Kelemen), multiplexed over BDPT's strategies",
    spp: "mutations per pixel",
    settings: &[&setting::SAMPLER],
    translucent: false,
    refuses: None,
    transport: Transport::Full,
    pilot: Some(pilot(5, |d, scene, frame, k| {
        probe(Metropolis::Pssmlt(Pssmlt::new(d)), d, scene, frame, k)
    })),
    per_ray: None,
    payloads: |p| {
        p.method::<MetropolisMethod>();
    },
    plan: |job| {
        let m = Metropolis::Pssmlt(Pssmlt::new(&job.desc));
        Ok(Box::new(MetropolisMethod::plan(job, PSSMLT.name, m)?) as Box<dyn Plan>)
    },
};

pub static MLT: MethodInfo = MethodInfo {
    name: "mlt",
    summary: "Metropolis light transport in path space (Veach & Guibas): bidirectional, lens and caustic mutations",
    spp: "mutations per pixel",
    settings: &[],
    translucent: false,
    refuses: Some(refuse_for_mlt),
    transport: Transport::Full,
    pilot: Some(pilot(6, |d, scene, frame, k| {
        probe(Metropolis::Mlt(Mlt::new(d)), d, scene, frame, k)
    })),
    per_ray: None,
    payloads: |p| {
        p.method::<MetropolisMethod>();
    },
    plan: |job| {
        let m = Metropolis::Mlt(Mlt::new(&job.desc));
        Ok(Box::new(MetropolisMethod::plan(job, MLT.name, m)?) as Box<dyn Plan>)
    },
};

/// A Metropolis method's pilot, measured `order`-th: unbiased, four mutations a pixel a half,
/// its frames timed first by `probe`.
const fn pilot(order: u32, probe: Probe) -> PilotInfo {
    PilotInfo {
        order,
        model: Model::Unbiased,
        k: 4,
        sight: Sight::All,
        photon_map: false,
        probe: Some(probe),
    }
}

/// A Metropolis frame's bootstrap (its brightness samples and bootstrap paths) costs the same
/// whatever the film: the seconds of a pilot's two frames of `k` mutations per pixel, from
/// one group of `m`'s chains (see [`GROUPS`]).
fn probe(
    m: Metropolis,
    desc: &SceneDesc,
    scene: &Scene,
    frame: u32,
    k: u32,
) -> Result<f64, String> {
    let camera = Camera::new(&desc.camera_at(frame), &desc.film);
    let start = Instant::now();
    m.chains(scene, &camera, k, 0, &|_| {})?;
    Ok(start.elapsed().as_secs_f64() * 2.0 * GROUPS as f64)
}

pub struct MetropolisMethod {
    name: &'static str,
    m: Metropolis,
    ranges: Ranges,
    mutations: u32,
}

impl MetropolisMethod {
    fn plan(job: &Job, name: &'static str, m: Metropolis) -> Result<Self, String> {
        let ranges = Ranges::new(job, name, DIRECT)?;
        Ok(MetropolisMethod {
            name,
            m,
            mutations: ranges.spp(),
            ranges,
        })
    }
}

/// What path-space MLT does not support, refused before anything is queued.
fn refuse_for_mlt(d: &SceneDesc) -> Result<(), String> {
    use tessera_scene::Lens;
    if matches!(d.camera.lens, Lens::Thin { aperture_radius, .. } if aperture_radius > 0.0) {
        return Err(
            "integrator.type: mlt supports pinhole cameras only; use pssmlt or bdpt".into(),
        );
    }
    Ok(())
}

impl Method for MetropolisMethod {
    type Partial = MetroPartial;
    type Frame = MetroFrame;

    fn name(&self) -> &'static str {
        self.name
    }

    fn decisions(&self) -> Vec<String> {
        vec![format!(
            "{}: Markov chains wander over the whole film, so a frame's chains are {GROUPS} tasks, each a group with its share of the brightness samples and bootstrap paths, beside direct light by BDPT in sample ranges over the film ({})",
            self.name,
            self.m.describe(self.mutations)
        )]
    }

    fn start(&self, frame: u32) -> Result<Step, String> {
        let mut step = self.ranges.start(frame);
        let first = step.tasks.len() as u32;
        let film = self.ranges.film();
        step.tasks.extend((0..GROUPS).map(|g| {
            TaskSpec::new(CHAINS, frame, 0, first + g)
                .with_rect(film)
                .with_range(g, g + 1)
        }));
        Ok(step)
    }

    /// The direct light's frame, the chains' splats and their groups' batches.
    fn frame_bytes(&self) -> u64 {
        let pixels = self.ranges.film().pixel_count() as u64;
        self.ranges.frame_bytes()
            + pixels * (std::mem::size_of::<[f32; 3]>() as u64 + Ratios::PIXEL_BYTES)
    }

    fn new_frame(&self, frame: u32) -> MetroFrame {
        let direct = self.ranges.new_frame(frame);
        let pixels = self.ranges.film().pixel_count();
        MetroFrame {
            direct,
            chain: vec![[0.0; 3]; pixels],
            groups: Ratios::new(pixels),
            brightness: 0.0,
            count: 0,
            exposure: self.ranges.camera(frame).exposure,
            fixed_s: 0.0,
        }
    }

    fn execute(&self, ctx: &TaskCtx, task: &TaskSpec) -> Result<MetroPartial, String> {
        let camera = self.ranges.camera(task.frame);
        match task.kind.as_str() {
            aov::KIND => Ok(MetroPartial::Direct(RangePartial::Aov(aov::execute(
                ctx.scene,
                &camera,
                task.tile(),
                task.samples(),
            )))),
            DIRECT => {
                self.ranges.check(task)?;
                let (sums, stats) = self.m.direct(ctx.scene, &camera, task.samples())?;
                ctx.progress(task.pixels() * task.samples().len() as u64);
                Ok(MetroPartial::Direct(RangePartial::from_sums(&sums, stats)))
            }
            CHAINS => {
                self.ranges.check(task)?;
                let GroupWork {
                    sums,
                    stats,
                    fixed_s,
                } = self
                    .m
                    .chains(ctx.scene, &camera, self.mutations, task.start, &|n| {
                        ctx.progress(n)
                    })?;
                Ok(MetroPartial::Chains {
                    splats: splats_from_fixed(&sums.splats),
                    brightness: sums.brightness.0 as f64 / 4_294_967_296.0,
                    count: sums.brightness.1,
                    stats,
                    fixed_s,
                })
            }
            other => Err(format!("{} has no {other} tasks", self.m.name())),
        }
    }

    fn fits(&self, task: &TaskSpec, p: &MetroPartial) -> Result<(), String> {
        match p {
            MetroPartial::Direct(d) => self.ranges.fits(task, d),
            MetroPartial::Chains {
                splats, brightness, ..
            } => {
                check_splats(splats, self.ranges.film().pixel_count())?;
                if !(brightness.is_finite() && *brightness >= 0.0) {
                    return Err(format!(
                        "chains of brightness {brightness}: expected a finite, non-negative sum"
                    ));
                }
                Ok(())
            }
        }
    }

    fn fold(&self, f: &mut MetroFrame, task: &TaskSpec, p: MetroPartial) -> Result<(), String> {
        if let MetroPartial::Chains { .. } = p {
            Method::fits(self, task, &p)?;
        }
        match p {
            // The ranges' fold checks its own result.
            MetroPartial::Direct(d) => self.ranges.fold(&mut f.direct, task, d),
            MetroPartial::Chains {
                splats,
                brightness,
                count,
                stats,
                fixed_s,
            } => {
                f.fixed_s += fixed_s;
                add_splats(&mut f.chain, &splats)?;
                let b = if count > 0 {
                    brightness / count as f64
                } else {
                    0.0
                };
                f.groups.fold(|i| (splats[i].map(|v| v as f64 * b), 1.0));
                f.brightness += brightness;
                f.count += count;
                Ranges::stats(&mut f.direct).add(&stats);
                Ok(())
            }
        }
    }

    fn advance(&self, _frame: u32, f: &mut MetroFrame, _: Duration) -> Result<Next, String> {
        let image = self.image(f);
        let how = format!(
            "per pixel: direct light from its {} tasks as independent batches, the chains from their {} groups as independent batches (each its own brightness and chains)",
            f.direct.batches(),
            f.groups.batches
        );
        Ok(match self.ranges.finish(&mut f.direct, image, how) {
            Next::Done(done) => Next::Done(Finished {
                fixed_s: f.fixed_s,
                ..done
            }),
            next => next,
        })
    }

    fn preview(&self, _frame: u32, f: &MetroFrame) -> Image {
        self.image(f)
    }
}

impl MetropolisMethod {
    /// Direct light plus the chains' splats, which are f / f* per mutation: b per mutation of
    /// the film makes them radiance. The chains' variance is that of the mean of the groups'
    /// own estimates G·e/M · b_g · splats_g.
    fn image(&self, f: &MetroFrame) -> Image {
        let mut image = self.ranges.image(&f.direct);
        let b = f.brightness / f.count.max(1) as f64;
        let per_mutation = f.exposure as f64 / self.mutations.max(1) as f64;
        let scale = b * per_mutation;
        let group = (GROUPS as f64 * per_mutation).powi(2);
        for (i, (px, s)) in image.pixels.iter_mut().zip(&f.chain).enumerate() {
            for (p, v) in px.rgb.iter_mut().zip(s) {
                *p += (*v as f64 * scale) as f32;
            }
            let v = f.groups.variance(i);
            for (p, v) in px.variance.iter_mut().zip(v) {
                *p += (v * group) as f32;
            }
        }
        image
    }
}
