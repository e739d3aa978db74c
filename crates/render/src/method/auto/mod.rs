//! `auto`: the method chosen for the scene, planned as that method.
//!
//! The choice is made once per job, by measurement ([`pilot::select`]: every method the scene's
//! features leave renders a short pilot; the one predicted to reach the job's error soonest
//! wins), and travels with the job as a [`Choice`], so every process that plans the job plans
//! the same method with the same settings. A job that carries no choice (nothing measured
//! it) runs what scene analysis chooses from features alone ([`crate::analysis`]).

pub mod pilot;

use std::time::Duration;

use serde::{Deserialize, Serialize};
use tessera_scene::{SceneDesc, SubsurfaceMethod};

use super::info::{MethodInfo, Transport};
use super::lookup;
use super::{DynPass, Job, Next, Payload, Plan, Step, TaskCtx, TaskSpec};
use crate::film::Image;
use crate::wire::WireError;

pub static AUTO: MethodInfo = MethodInfo {
    name: "auto",
    summary: "the method a short pilot of every suitable method predicts to reach the error soonest",
    spp: "as the chosen method counts them",
    settings: &[],
    translucent: true,
    refuses: None,
    transport: Transport::Full,
    pilot: None,
    per_ray: None,
    // It plans the method it chooses, whose payloads those methods declare.
    payloads: |_| {},
    plan: plan_auto,
};

/// What `auto` chose for a job, by measurement: the method and the settings it runs with, and
/// the pilot's report (each candidate's prediction, why the others lost).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct Choice {
    /// The method, by its registry name.
    pub method: String,
    /// How translucent materials are rendered, where the scene has any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(value_type = Option<String>))]
    pub subsurface: Option<SubsurfaceMethod>,
    /// Photons of the photon map, where the pilot chose their count (the scene set none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub photons: Option<u32>,
    /// Samples per pixel (iterations, mutations per pixel) the method runs: the prediction
    /// for the job's goal, or the cap of its adaptive sampling.
    pub spp: u32,
    /// Adaptive sampling's target, kept where the chosen method refines tiles.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_error: Option<f64>,
    /// The decision and each candidate's measurement and prediction, one line each.
    pub report: Vec<String>,
}

impl Choice {
    /// Checks what the choice sets besides its samples and target: a method of the registry
    /// other than `auto`, and photons within the scene format's limit. The error begins with
    /// the field.
    pub fn check(&self) -> Result<(), String> {
        let method = lookup(&self.method).map_err(|e| format!("method: {e}"))?;
        if std::ptr::eq(method, &AUTO) {
            return Err(format!(
                "method: expected the method {0} chose, got {0}",
                AUTO.name
            ));
        }
        if let Some(n) = self.photons
            && !(1..=tessera_scene::MAX_PHOTONS).contains(&n)
        {
            return Err(format!(
                "photons: expected 1 to {} photons, got {n}",
                tessera_scene::MAX_PHOTONS
            ));
        }
        Ok(())
    }

    /// Sets in `desc` what the choice renders with besides its samples: the method, how
    /// translucent materials are rendered, the photon map's photons.
    pub fn apply(&self, desc: &mut SceneDesc) {
        set_method(desc, &self.method, self.subsurface, self.photons);
    }
}

/// Sets `method` in `desc`, with the subsurface method and photon count where given (a
/// candidate's pilot and the choice's render set the same).
fn set_method(
    desc: &mut SceneDesc,
    method: &str,
    subsurface: Option<SubsurfaceMethod>,
    photons: Option<u32>,
) {
    desc.integrator.method = method.into();
    if let Some(s) = subsurface {
        desc.integrator.subsurface = s;
    }
    if photons.is_some() {
        desc.integrator.photon.photons = photons;
    }
}

fn plan_auto(job: &Job) -> Result<Box<dyn Plan>, String> {
    let mut inner_job = job.clone();
    inner_job.choice = None;
    let (method, report) = match &job.choice {
        Some(c) => {
            inner_job.desc.integrator.spp = c.spp;
            inner_job.target_error = c.target_error;
            if c.target_error.is_none() {
                inner_job.time_limit = None;
            }
            c.apply(&mut inner_job.desc);
            (lookup(&c.method)?, c.report.clone())
        }
        None => (
            super::for_transport(crate::analysis::analyze(&job.desc).transport)?,
            Vec::new(),
        ),
    };
    if std::ptr::eq(method, &AUTO) {
        return Err("auto chose auto: no method to run".into());
    }
    inner_job.desc.integrator.method = method.name.into();
    Ok(Box::new(Auto {
        inner: super::plan_as(method, &inner_job)?,
        choice: job.choice.clone(),
        report,
    }))
}

/// The chosen method, whose plan this is.
struct Auto {
    inner: Box<dyn Plan>,
    choice: Option<Choice>,
    report: Vec<String>,
}

impl Plan for Auto {
    fn method(&self) -> &'static str {
        self.inner.method()
    }
    fn decisions(&self) -> Vec<String> {
        let mut out: Vec<String> = self.report.iter().map(|l| format!("auto: {l}")).collect();
        out.extend(self.inner.decisions());
        out
    }
    fn metadata(&self) -> Vec<(String, String)> {
        let mut out = self.inner.metadata();
        if let Some(c) = &self.choice {
            out.push((
                "auto_selection".into(),
                serde_json::to_string(&self.report).unwrap_or_default(),
            ));
            let subsurface = c
                .subsurface
                .map(|s| format!(" --subsurface {}", pilot::subsurface_name(s)))
                .unwrap_or_default();
            let target = c
                .target_error
                .map(|t| format!(" --target-error {t}"))
                .unwrap_or_default();
            let photons = c
                .photons
                .map(|n| format!(" and integrator.photon_map.photons {n} in the scene"))
                .unwrap_or_default();
            out.push((
                "auto_reproduce".into(),
                format!(
                    "--integrator {} --spp {}{subsurface}{target}{photons} (the choice was measured: another run may choose otherwise)",
                    c.method, c.spp
                ),
            ));
        }
        out
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
    fn fits(&self, task: &TaskSpec, p: &dyn Payload) -> Result<(), String> {
        self.inner.fits(task, p)
    }
    fn frame_bytes(&self) -> u64 {
        self.inner.frame_bytes()
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
