//! Several coordinators, one farm: `tessera serve` processes sharing one PostgreSQL store and
//! one object store (`--objects`: a directory, as NFS would be), each with a data directory of
//! its own, serve the same queue to workers that
//! each talk to one of them. A job submitted to one is rendered by workers of both; when the
//! coordinator folding its frames is SIGKILLed, another takes its claims over once they lapse
//! and finishes the job. Every frame equals `tessera render`'s byte for byte.
//!
//! Needs a PostgreSQL: runs where `TESSERA_TEST_POSTGRES` names one (CI's second run of the
//! suite), and says it was skipped elsewhere.

mod common;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use common::*;
use tessera_farm::client::Client;
use tessera_farm::protocol::JobState;

fn flythrough() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-flythrough/scene.json")
}

#[test]
fn coordinators_sharing_a_store_are_one_farm_and_one_dying_loses_nothing() {
    if std::env::var("TESSERA_TEST_POSTGRES").is_err() {
        eprintln!("skipped: TESSERA_TEST_POSTGRES names no PostgreSQL to share");
        return;
    }
    let dir = tempfile::tempdir().expect("temp dir");
    // One job store (tests/common: a schema named for this path) and one object store;
    // nothing else shared.
    let store = tessera_farm::store::test_store_url(&dir.path().join("farm")).expect("PostgreSQL");
    let objects = dir.path().join("objects");
    let objects = objects.to_str().expect("utf-8 temp path");
    let shared = ["--store", &store, "--objects", objects];
    let (mut a, url_a) = serve_with(&dir.path().join("data-a"), "127.0.0.1:0", "2", &shared);
    let (_b, url_b) = serve_with(&dir.path().join("data-b"), "127.0.0.1:0", "2", &shared);
    assert_ne!(url_a, url_b);
    let logs: Vec<PathBuf> = (0..3)
        .map(|i| dir.path().join(format!("w{i}.log")))
        .collect();
    let _wa = worker(&url_a, "on-a", &logs[0]);
    let _wb = worker(&url_b, "on-b", &logs[1]);
    let _wb2 = worker(&url_b, "on-b-2", &logs[2]);
    let rt = runtime();
    let on_a = Client::new(&url_a, CLIENT_TOKEN).expect("client");
    let on_b = Client::new(&url_b, CLIENT_TOKEN).expect("client");

    // Submitted to a, seen and served by b.
    let spp = 32;
    let args = ["--frames", "1-3", "--tile", "32", "--spp", "32"];
    let id = submit_scene(&url_a, &flythrough(), &args);
    assert_eq!(rt.block_on(on_b.job(id)).expect("b sees the job").id, id);

    // Both coordinators' workers render; a folds the frames whose results reach it first.
    let start = Instant::now();
    loop {
        let workers = rt.block_on(on_b.workers()).expect("workers");
        let busy = |name: &str| workers.iter().any(|w| w.name == name && w.tasks_done > 0);
        let done = rt
            .block_on(on_b.tasks(id))
            .expect("tasks")
            .iter()
            .filter(|t| t.state == "done")
            .count();
        if busy("on-a") && busy("on-b") && done >= 8 {
            break;
        }
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "workers of both coordinators never both rendered"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    // A preview makes a coordinator fold the frame (claiming it), so a holds a frame's claim
    // when it dies: b may fold that frame only once a's claim lapses. The other coordinator
    // refuses a preview of a frame a folds, naming a.
    let held = (1..=3)
        .find(|&f| rt.block_on(on_a.frame_preview(id, f)).is_ok())
        .expect("a folds some frame");
    let refused = rt
        .block_on(on_b.frame_preview(id, held))
        .expect_err("b does not fold the frame a folds")
        .to_string();
    assert!(refused.contains("being folded by coordinator"), "{refused}");
    let job = rt.block_on(on_b.job(id)).expect("job");
    assert!(!job.state.is_final(), "the job finished before the kill");
    a.0.kill().expect("SIGKILL coordinator a");
    let _ = a.0.wait();

    let job = wait_for(&rt, &on_b, id, Duration::from_secs(180));
    assert_eq!(job.state, JobState::Done, "{:?}", job.error);
    for frame in job.frames.iter() {
        let farm = rt
            .block_on(on_b.frame_exr(id, frame))
            .expect("download the frame from b");
        let local = render_locally(
            &flythrough(),
            &["--frame", &frame.to_string(), "--spp", &spp.to_string()],
            &dir.path().join(format!("render_{frame}.exr")),
        );
        assert!(
            farm == local,
            "frame {frame}: the farm's EXR differs from tessera render's"
        );
    }
    // Every task was done once (a lease cut by a's death is the only reason to do one twice).
    let tasks = rt.block_on(on_b.tasks(id)).expect("tasks");
    assert!(tasks.iter().all(|t| t.state == "done"), "{tasks:?}");
    // The frames, bundle and artifacts are in the object store, not in a coordinator's data.
    for frame in job.frames.iter() {
        let name = tessera_farm::job::frame_file_name(frame);
        assert!(
            dir.path()
                .join(format!("objects/jobs/{id}/{name}"))
                .is_file(),
            "{name}"
        );
    }
    for data in ["data-a", "data-b"] {
        for kept in ["jobs", "bundles", "cache"] {
            assert!(!dir.path().join(data).join(kept).exists(), "{data}/{kept}");
        }
    }
}
