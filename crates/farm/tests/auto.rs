//! `auto` on the farm: a job that asks for it with no recorded choice is accepted without
//! measuring anything in the request, queued with one task (its pilot) that a real worker
//! runs; the coordinator then plans the job with the choice the pilot returned, and the frame
//! is the one this process renders with that choice, byte for byte.

mod common;

use common::{WORKER, coordinator_in, cornell, local_frame, run_to_the_end, submit};
use tessera_farm::client::{ApiError, Client};
use tessera_farm::job::{self, PILOT_STEP, RenderSettings};
use tessera_farm::protocol::{Failure, JobState, LeaseRequest, WorkerInfo};
use tessera_render::method::auto::Choice;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn autos_pilot_runs_on_a_worker_and_the_job_is_planned_with_its_choice() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (running, url, client) = coordinator_in(dir.path()).await;

    let settings = RenderSettings {
        integrator: Some("auto".into()),
        size: Some([48, 36]),
        spp: Some(16),
        ..Default::default()
    };
    let job = submit(&client, &cornell(), settings.clone()).await;
    // Accepted unmeasured: its one task is the pilot, no method is chosen yet.
    assert!(job.measuring, "{job:?}");
    assert_eq!(job.method, "auto");
    assert!(job.settings.choice.is_none());
    assert!(job.passes.is_empty(), "{:?}", job.passes);
    let tasks = client.tasks(job.id).await.expect("tasks");
    assert_eq!(tasks.len(), 1, "{tasks:?}");
    assert_eq!(
        (
            tasks[0].spec.kind.as_str(),
            tasks[0].spec.frame,
            tasks[0].spec.step
        ),
        ("pilot", 0, PILOT_STEP)
    );
    assert!(
        job.decisions.iter().any(|d| d.contains("pilot")),
        "{:#?}",
        job.decisions
    );

    // Its preview, as the dashboard asks for it, is the film's size, black.
    let png = client.frame_preview(job.id, 1).await.expect("preview");
    let preview = image::load_from_memory(&png).expect("a PNG").to_rgb8();
    assert_eq!(preview.dimensions(), (48, 36));
    assert!(preview.pixels().all(|p| p.0 == [0, 0, 0]));

    // A pilot's result naming no method `auto` may choose is refused, with the field.
    let sim = Client::new(&url, WORKER).expect("worker client");
    let lease = LeaseRequest {
        worker: WorkerInfo::simulated("sim"),
        wait_ms: 0,
    };
    let g = sim.lease(&lease).await.expect("lease").expect("the pilot");
    assert!(job::is_pilot(&g.task), "{:?}", g.task);
    let bad = Choice {
        method: "auto".into(),
        subsurface: None,
        photons: None,
        spp: 16,
        target_error: None,
        report: vec![],
    };
    let path = dir.path().join("bad-choice.tswf");
    job::write_choice(std::fs::File::create(&path).expect("file"), &g.task, &bad).expect("write");
    let refused = sim
        .upload_result(g.task_id, g.lease, 0.0, &path)
        .await
        .unwrap_err()
        .downcast::<ApiError>()
        .expect("an API error");
    assert_eq!(refused.status.as_u16(), 400, "{}", refused.message);
    assert!(refused.message.contains("method"), "{}", refused.message);
    sim.fail(
        g.task_id,
        &Failure {
            lease: g.lease,
            worker: "sim".into(),
            error: "gave up".into(),
            permanent: false,
        },
    )
    .await
    .expect("fail");

    let status = run_to_the_end(&url, &client, job.id, 2).await;
    assert_eq!(status.state, JobState::Done, "{:?}", status.error);
    assert!(!status.measuring);
    let choice = status
        .settings
        .choice
        .clone()
        .expect("the pilot's choice is kept");
    assert_eq!(status.method, choice.method);
    assert_eq!(status.spp, choice.spp);
    assert!(
        status
            .decisions
            .iter()
            .any(|d| choice.report.iter().any(|r| d.contains(r.as_str()))),
        "the decisions hold the pilot's report: {:#?}",
        status.decisions
    );
    let tasks = client.tasks(job.id).await.expect("tasks");
    assert!(
        tasks
            .iter()
            .any(|t| t.spec.kind == "pilot" && t.state == "done"),
        "{tasks:?}"
    );
    assert!(tasks.iter().all(|t| t.state == "done"), "{tasks:?}");

    // The frame is the one this process renders with the recorded choice.
    let farm = client.frame_exr(job.id, 1).await.expect("frame");
    assert!(
        farm == local_frame(&status.settings, dir.path()),
        "the farm's frame is not the one this process renders with the pilot's choice"
    );
    running.stop().await.expect("stop");
}
