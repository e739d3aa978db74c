//! Bidirectional path tracing (Veach 1997, ch. 10) as a frame method: every (s, t) strategy,
//! power-heuristic MIS; frames cut into sample ranges over the whole film.

use std::time::Duration;
use tessera_scene::setting;

use super::info::{MethodInfo, Model, PilotInfo, Sight, Transport};
use super::ranges::{KIND, RangeFrame, RangePartial, Ranges};
use super::{Job, Method, Next, Plan, Step, TaskCtx, TaskSpec, aov};
use crate::film::Image;
use crate::integrator::bdpt::Bdpt;

pub static BDPT: MethodInfo = MethodInfo {
    name: "bdpt",
    summary: "bidirectional path tracing (Veach): every connection of a camera and a light subpath, power-heuristic MIS",
    spp: "samples per pixel",
    settings: &[&setting::SAMPLER],
    translucent: false,
    refuses: None,
    transport: Transport::Full,
    pilot: Some(PilotInfo {
        order: 1,
        model: Model::Unbiased,
        k: 4,
        sight: Sight::NoSpecularJoin,
        photon_map: false,
        probe: None,
    }),
    per_ray: None,
    payloads: |p| {
        p.method::<BdptMethod>();
    },
    plan: |job| Ok(Box::new(BdptMethod::plan(job)?) as Box<dyn Plan>),
};

pub struct BdptMethod {
    ranges: Ranges,
    bdpt: Bdpt,
}

impl BdptMethod {
    fn plan(job: &Job) -> Result<Self, String> {
        Ok(BdptMethod {
            ranges: Ranges::new(job, "bdpt", KIND)?,
            bdpt: Bdpt::new(&job.desc),
        })
    }
}

impl Method for BdptMethod {
    type Partial = RangePartial;
    type Frame = RangeFrame;

    fn name(&self) -> &'static str {
        "bdpt"
    }

    fn decisions(&self) -> Vec<String> {
        vec!["bdpt: light tracing splats anywhere on the film, so frames are sample ranges over the whole film (not tiles); pixel variance from the ranges as batches".into()]
    }

    fn start(&self, frame: u32) -> Result<Step, String> {
        Ok(self.ranges.start(frame))
    }

    fn more(&self, frame: u32, state: &mut RangeFrame, spp: u32) -> Option<Step> {
        self.ranges.more(frame, state, spp)
    }

    fn frame_bytes(&self) -> u64 {
        self.ranges.frame_bytes()
    }

    fn new_frame(&self, frame: u32) -> RangeFrame {
        self.ranges.new_frame(frame)
    }

    fn execute(&self, ctx: &TaskCtx, task: &TaskSpec) -> Result<RangePartial, String> {
        let camera = self.ranges.camera(task.frame);
        match task.kind.as_str() {
            aov::KIND => Ok(RangePartial::Aov(aov::execute(
                ctx.scene,
                &camera,
                task.tile(),
                task.samples(),
            ))),
            KIND => {
                self.ranges.check(task)?;
                let (sums, stats) =
                    self.bdpt
                        .render_range(ctx.scene, &camera, task.samples(), &|n| {
                            ctx.progress(n * task.samples().len() as u64)
                        })?;
                Ok(RangePartial::from_sums(&sums, stats))
            }
            other => Err(format!("bdpt has no {other} tasks")),
        }
    }

    fn fits(&self, task: &TaskSpec, p: &RangePartial) -> Result<(), String> {
        self.ranges.fits(task, p)
    }

    fn fold(&self, state: &mut RangeFrame, task: &TaskSpec, p: RangePartial) -> Result<(), String> {
        self.ranges.fold(state, task, p)
    }

    fn advance(&self, _frame: u32, state: &mut RangeFrame, _: Duration) -> Result<Next, String> {
        Ok(self.ranges.advance(state))
    }

    fn preview(&self, _frame: u32, state: &RangeFrame) -> Image {
        self.ranges.image(state)
    }
}
