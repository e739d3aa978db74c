//! Vertex connection and merging (Georgiev et al. 2012) as a frame method: each iteration
//! depends only on its index, so frames are ranges of iterations over the whole film, as
//! BDPT's samples.

use std::time::Duration;
use tessera_scene::setting;

use super::info::{MethodInfo, Model, PilotInfo, Sight, Transport};
use super::ranges::{KIND, RangeFrame, RangePartial, Ranges};
use super::{Job, Method, Next, Plan, Step, TaskCtx, TaskSpec, aov};
use crate::film::Image;
use crate::integrator::vcm::Vcm;

pub static VCM: MethodInfo = MethodInfo {
    name: "vcm",
    summary: "vertex connection and merging (Georgiev et al.): BDPT plus photon merging under one MIS",
    spp: "iterations (one light and one camera subpath per pixel each)",
    settings: &[&setting::SAMPLER],
    translucent: false,
    refuses: None,
    transport: Transport::Full,
    pilot: Some(PilotInfo {
        order: 2,
        model: Model::Unbiased,
        k: 4,
        sight: Sight::All,
        photon_map: false,
        probe: None,
    }),
    per_ray: None,
    payloads: |p| {
        p.method::<VcmMethod>();
    },
    plan: |job| Ok(Box::new(VcmMethod::plan(job)?) as Box<dyn Plan>),
};

pub struct VcmMethod {
    ranges: Ranges,
}

impl VcmMethod {
    fn plan(job: &Job) -> Result<Self, String> {
        Ok(VcmMethod {
            ranges: Ranges::new(job, "vcm", KIND)?,
        })
    }
}

impl Method for VcmMethod {
    type Partial = RangePartial;
    type Frame = RangeFrame;

    fn name(&self) -> &'static str {
        "vcm"
    }

    fn decisions(&self) -> Vec<String> {
        vec!["vcm: light tracing splats and merges reach the whole film, so frames are ranges of iterations over the whole film (not tiles); pixel variance from the ranges as batches".into()]
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
                let vcm = Vcm::new(ctx.desc, ctx.scene);
                let (sums, stats) =
                    vcm.render_range(ctx.scene, &camera, task.samples(), &|n| ctx.progress(n))?;
                Ok(RangePartial::from_sums(&sums, stats))
            }
            other => Err(format!("vcm has no {other} tasks")),
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
