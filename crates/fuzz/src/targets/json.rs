//! `json`: the HTTP API's JSON bodies, as its handlers read them: a job to submit (bound to the
//! Cornell box and planned under the coordinator's default limits), a job patch, a lease
//! request, a heartbeat and a failure report; and what a worker or a client reads back (a
//! lease grant, a job's status). Each input is tried as every one of them.

use std::sync::OnceLock;

use tessera_farm::job::{self, FrameRange, Limits};
use tessera_farm::protocol::*;
use tessera_scene::SceneDesc;

use crate::{Target, repo};

pub const TARGET: Target = Target {
    name: "json",
    about: "HTTP JSON bodies (job, patch, lease, heartbeat, failure, grant, status): read and checked",
    run,
    seeds,
};

fn cornell() -> &'static SceneDesc {
    static DESC: OnceLock<SceneDesc> = OnceLock::new();
    DESC.get_or_init(|| {
        tessera_scene::load(&repo().join("scenes/cornell-box/scene.json"))
            .expect("the Cornell box loads")
    })
}

fn run(data: &[u8]) -> bool {
    let mut accepted = false;
    if let Ok(req) = serde_json::from_slice::<JobRequest>(data) {
        accepted |= submit(&req).is_ok();
    }
    if let Ok(req) = serde_json::from_slice::<LeaseRequest>(data) {
        accepted |= check_tags(&req.worker.tags, "worker.tags").is_ok();
    }
    accepted |= serde_json::from_slice::<JobPatch>(data).is_ok();
    accepted |= serde_json::from_slice::<Heartbeat>(data).is_ok();
    accepted |= serde_json::from_slice::<Failure>(data).is_ok();
    accepted |= serde_json::from_slice::<LeaseGrant>(data).is_ok();
    accepted |= serde_json::from_slice::<JobStatus>(data).is_ok();
    accepted
}

/// What `POST /v1/jobs` does with a request once its bundle is found: tags checked, the
/// settings applied to the scene and the job planned under the default limits (the `auto`
/// pilot, a render, is left out).
fn submit(req: &JobRequest) -> Result<(), String> {
    check_tags(&req.require_tags, "require_tags")?;
    let desc = cornell().clone();
    let frames = req.frames.unwrap_or(FrameRange {
        first: 1,
        last: desc.frame_count(),
    });
    let limits = Limits::default();
    job::compile(desc, &req.settings, frames, job::Options::new(&limits)).map(|_| ())
}

/// One body of each kind, as the client and the worker send them.
fn seeds() -> Vec<(String, Vec<u8>)> {
    let worker = WorkerInfo::simulated("fuzz");
    let bodies = [
        (
            "job",
            serde_json::json!({
                "bundle": "0".repeat(64), "scene": "scene.json", "name": "shot",
                "frames": {"first": 1, "last": 1},
                "settings": {"spp": 4, "size": [64, 48], "tile": 16, "integrator": "path", "seed": 3},
                "priority": 2, "require_tags": ["gpu-less"]
            }),
        ),
        (
            "job-choice",
            serde_json::json!({
                "bundle": "0".repeat(64),
                "settings": {"integrator": "auto", "choice": {"method": "bdpt", "spp": 8, "report": []}}
            }),
        ),
        ("patch", serde_json::json!({"priority": 5})),
        (
            "lease",
            serde_json::to_value(LeaseRequest {
                worker: worker.clone(),
                wait_ms: 100,
            })
            .expect("json"),
        ),
        (
            "heartbeat",
            serde_json::to_value(Heartbeat {
                lease: 3,
                worker: "fuzz".into(),
                cpu: Some(1.5),
            })
            .expect("json"),
        ),
        (
            "failure",
            serde_json::to_value(Failure {
                lease: 3,
                worker: "fuzz".into(),
                error: "out of memory".into(),
                permanent: false,
            })
            .expect("json"),
        ),
    ];
    bodies
        .into_iter()
        .map(|(name, v)| (format!("{name}.json"), v.to_string().into_bytes()))
        .collect()
}
