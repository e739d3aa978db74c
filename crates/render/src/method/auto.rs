//! `auto`: the method scene analysis chooses ([`crate::analysis`]), planned as that method.
//! Every process that plans the job makes the same choice from the same scene.

use std::time::Duration;

use super::registry::{MethodInfo, lookup};
use super::{DynPass, Job, Next, Payload, Plan, Step, TaskCtx, TaskSpec};
use crate::analysis::analyze;
use crate::film::Image;
use crate::wire::WireError;

pub static AUTO: MethodInfo = MethodInfo {
    name: "auto",
    summary: "the method scene analysis chooses, with its reasons in the job's decisions",
    spp: "as the chosen method counts them",
    params: &[],
    plan: plan_auto,
};

fn plan_auto(job: &Job) -> Result<Box<dyn Plan>, String> {
    let analysis = analyze(&job.desc);
    let chosen = lookup(&analysis.method)?;
    if chosen.name == "auto" {
        return Err("scene analysis chose auto: no method to run".into());
    }
    let mut inner_job = job.clone();
    inner_job.desc.integrator.method = chosen.name.into();
    Ok(Box::new(Auto {
        inner: (chosen.plan)(&inner_job)?,
    }))
}

/// The chosen method, whose plan this is.
struct Auto {
    inner: Box<dyn Plan>,
}

impl Plan for Auto {
    fn method(&self) -> &'static str {
        self.inner.method()
    }
    fn decisions(&self) -> Vec<String> {
        self.inner.decisions()
    }
    fn metadata(&self) -> Vec<(String, String)> {
        self.inner.metadata()
    }
    fn passes(&self) -> Vec<&dyn DynPass> {
        self.inner.passes()
    }
    fn start(&self, frame: u32) -> Result<Step, String> {
        self.inner.start(frame)
    }
    fn later_tasks(&self) -> u64 {
        self.inner.later_tasks()
    }
    fn more(&self, frame: u32, state: &mut dyn Payload, spp: u32) -> Option<Step> {
        self.inner.more(frame, state, spp)
    }
    fn execute(&self, ctx: &TaskCtx, task: &TaskSpec) -> Result<Box<dyn Payload>, String> {
        self.inner.execute(ctx, task)
    }
    fn decode(&self, payload: &mut dyn std::io::Read) -> Result<Box<dyn Payload>, WireError> {
        self.inner.decode(payload)
    }
    fn new_frame(&self, frame: u32) -> Box<dyn Payload> {
        self.inner.new_frame(frame)
    }
    fn decode_frame(&self, payload: &mut dyn std::io::Read) -> Result<Box<dyn Payload>, WireError> {
        self.inner.decode_frame(payload)
    }
    fn fold(
        &self,
        state: &mut dyn Payload,
        task: &TaskSpec,
        p: Box<dyn Payload>,
    ) -> Result<(), String> {
        self.inner.fold(state, task, p)
    }
    fn advance(
        &self,
        frame: u32,
        state: &mut dyn Payload,
        elapsed: Duration,
    ) -> Result<Next, String> {
        self.inner.advance(frame, state, elapsed)
    }
    fn preview(&self, frame: u32, state: &dyn Payload) -> Image {
        self.inner.preview(frame, state)
    }
}
