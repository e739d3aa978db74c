//! The coordinator folds results in each step's task order, whatever order they arrive in: a
//! simulated worker leases every task of a job, runs them, and uploads the results last
//! first (and, for a second job, shuffled); the frames are byte-identical to the frame the
//! same job renders in one process. Also: a result that is not a whole wire stream of its
//! task is refused with a clear error, and one over the coordinator's limit says so.

use std::io::BufWriter;
use std::path::Path;
use std::time::{Duration, Instant};

mod common;

use common::{CLIENT, WORKER, config, cornell, local_frame, planned, run_to_the_end, submit};
use reqwest::StatusCode;
use tessera_farm::bundle::Bundle;
use tessera_farm::client::Client;
use tessera_farm::coordinator::{self, Running};
use tessera_farm::job::RenderSettings;
use tessera_farm::protocol::{JobRequest, JobState, LeaseGrant, LeaseRequest, WorkerInfo};
use tessera_render::method::{LoadFn, Loaded, Plan, Resources, TaskCtx};
use tessera_render::wire::Header;

async fn start(dir: &Path, max_result: u64) -> Running {
    let mut config = config(dir);
    config.max_result = max_result;
    coordinator::start(config).await.expect("coordinator")
}

/// A worker's view of nothing: these jobs read no artifacts or step inputs.
struct Bare;

impl Resources for Bare {
    fn artifact(&self, key: &str, _: LoadFn) -> Result<Loaded, String> {
        Err(format!("no artifact {key}"))
    }
    fn input(&self, _: LoadFn) -> Result<Loaded, String> {
        Err("no input".into())
    }
    fn memo(&self, _: &str, make: &dyn Fn() -> Result<Loaded, String>) -> Result<Loaded, String> {
        make()
    }
}

fn worker_info() -> WorkerInfo {
    WorkerInfo::simulated("sim")
}

/// Runs a leased task here and writes its result as a worker does.
fn result_file(
    plan: &dyn Plan,
    scene: &tessera_render::Scene,
    desc: &tessera_scene::SceneDesc,
    g: &LeaseGrant,
    dir: &Path,
) -> std::path::PathBuf {
    let ctx = TaskCtx {
        scene,
        desc,
        resources: &Bare,
    };
    let partial = plan.execute(&ctx, &g.task).expect("runs");
    let mut header = Header::new("result", &plan.schema());
    header.task = Some(g.task.clone());
    let path = dir.join(format!("{}.tswf", g.task_id));
    let file = std::fs::File::create(&path).expect("file");
    partial
        .write_to(&header, &mut BufWriter::new(file))
        .expect("write");
    path
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn results_arriving_in_any_order_fold_to_the_frame_one_process_renders() {
    let dir = tempfile::tempdir().expect("temp dir");
    let running = start(&dir.path().join("data"), 1 << 30).await;
    let url = format!("http://{}", running.addr);
    let client = Client::new(&url, CLIENT).expect("client");
    let worker = Client::new(&url, WORKER).expect("worker client");
    let (bundle, _, scene_name) = Bundle::pack_scene(&cornell()).expect("bundle");
    let hash = client
        .upload_bundle(bundle.to_tar().expect("packs"))
        .await
        .expect("upload")
        .hash;
    let cases = [
        (
            "bdpt",
            RenderSettings {
                integrator: Some("bdpt".into()),
                size: Some([40, 30]),
                spp: Some(6),
                samples_per_task: Some(1),
                ..Default::default()
            },
        ),
        (
            "path",
            RenderSettings {
                integrator: Some("path".into()),
                size: Some([40, 30]),
                spp: Some(3),
                tile: Some(8),
                ..Default::default()
            },
        ),
    ];
    for (shuffle, (name, settings)) in cases.into_iter().enumerate() {
        let (desc, plan) = planned(&settings);
        let scene = tessera_render::Scene::build(&desc);
        let job = client
            .submit(&JobRequest {
                bundle: hash.clone(),
                scene: scene_name.clone(),
                name: None,
                frames: None,
                settings: settings.clone(),
                priority: 0,
                require_tags: vec![],
            })
            .await
            .expect("submit");
        // Lease everything first, then answer in an order other than the plan's.
        let req = LeaseRequest {
            worker: worker_info(),
            wait_ms: 0,
        };
        let mut grants = Vec::new();
        while let Some(g) = worker.lease(&req).await.expect("lease") {
            grants.push(g);
        }
        assert!(grants.len() > 4, "{name}: {} tasks", grants.len());
        if shuffle == 0 {
            grants.reverse();
        } else {
            // A fixed permutation: odd positions first, then even, each backwards.
            let (odd, even): (Vec<_>, Vec<_>) = grants
                .into_iter()
                .enumerate()
                .partition(|(i, _)| i % 2 == 1);
            grants = odd
                .into_iter()
                .rev()
                .chain(even.into_iter().rev())
                .map(|(_, g)| g)
                .collect();
        }
        for g in &grants {
            let path = result_file(plan.as_ref(), &scene, &desc, g, dir.path());
            worker
                .upload_result(g.task_id, g.lease, 0.0, &path)
                .await
                .expect("upload");
        }
        let start = Instant::now();
        let status = loop {
            let s = client.job(job.id).await.expect("status");
            if s.state.is_final() {
                break s;
            }
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "{name}: not folded"
            );
            tokio::time::sleep(Duration::from_millis(20)).await;
        };
        assert_eq!(status.state, JobState::Done, "{name}: {:?}", status.error);
        let farm = client.frame_exr(job.id, 1).await.expect("frame");
        let local = local_frame(&settings, dir.path());
        assert!(
            farm == local,
            "{name}: the frame depends on the order results arrived in"
        );
        // The results are gone once the frame is written.
        let results = dir
            .path()
            .join("data/jobs")
            .join(job.id.to_string())
            .join("results");
        let left = std::fs::read_dir(&results).map(|d| d.count()).unwrap_or(0);
        assert_eq!(left, 0, "{name}: results left on disk");
    }
    running.stop().await.expect("stop");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_and_oversized_results_are_refused_with_what_was_wrong() {
    let dir = tempfile::tempdir().expect("temp dir");
    let running = start(&dir.path().join("data"), 64 << 10).await;
    let url = format!("http://{}", running.addr);
    let client = Client::new(&url, CLIENT).expect("client");
    let worker = Client::new(&url, WORKER).expect("worker client");
    let (bundle, _, scene_name) = Bundle::pack_scene(&cornell()).expect("bundle");
    let hash = client
        .upload_bundle(bundle.to_tar().expect("packs"))
        .await
        .expect("upload")
        .hash;
    // One job of one 128×128 tile (a result of some 150 KiB), one of one 8×8 tile.
    let big = RenderSettings {
        size: Some([128, 128]),
        spp: Some(1),
        tile: Some(128),
        ..Default::default()
    };
    let small = RenderSettings {
        size: Some([8, 8]),
        tile: Some(8),
        ..big.clone()
    };
    for settings in [&big, &small] {
        client
            .submit(&JobRequest {
                bundle: hash.clone(),
                scene: scene_name.clone(),
                name: None,
                frames: None,
                settings: settings.clone(),
                priority: 0,
                require_tags: vec![],
            })
            .await
            .expect("submit");
    }
    let req = LeaseRequest {
        worker: worker_info(),
        wait_ms: 0,
    };
    let mut tiles = Vec::new();
    while let Some(g) = worker.lease(&req).await.expect("lease") {
        if g.task.kind == "tile" {
            tiles.push(g);
        }
    }
    let [g_big, g_small] = <[LeaseGrant; 2]>::try_from(tiles).expect("two tile tasks");
    let status_of = |e: anyhow::Error| {
        let api = e
            .downcast::<tessera_farm::client::ApiError>()
            .expect("an API error");
        (api.status, api.message)
    };
    let run = |settings: &RenderSettings, g: &LeaseGrant| {
        let (desc, plan) = planned(settings);
        let scene = tessera_render::Scene::build(&desc);
        result_file(plan.as_ref(), &scene, &desc, g, dir.path())
    };
    // Over this coordinator's limit: which limit, and how to raise it.
    let path = run(&big, &g_big);
    let (status, message) = status_of(
        worker
            .upload_result(g_big.task_id, g_big.lease, 0.0, &path)
            .await
            .unwrap_err(),
    );
    assert_eq!(status, StatusCode::PAYLOAD_TOO_LARGE, "{message}");
    assert!(
        message.contains("64 KiB") && message.contains("--max-result-mib"),
        "{message}"
    );
    // Workers are told the limit with the lease, to refuse such a result themselves.
    assert_eq!(g_big.max_result_bytes, Some(64 << 10));
    // Not a wire stream at all.
    let junk = dir.path().join("junk");
    std::fs::write(&junk, b"hello").expect("write");
    let (status, message) = status_of(
        worker
            .upload_result(g_small.task_id, g_small.lease, 0.0, &junk)
            .await
            .unwrap_err(),
    );
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(message.contains("TSWF"), "{message}");
    // A whole stream, but of another task.
    let other = LeaseGrant {
        task: tessera_farm::job::TaskSpec {
            index: g_small.task.index + 7,
            ..g_small.task.clone()
        },
        ..g_small.clone()
    };
    let path = run(&small, &other);
    let (status, message) = status_of(
        worker
            .upload_result(g_small.task_id, g_small.lease, 0.0, &path)
            .await
            .unwrap_err(),
    );
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(message.contains("names task"), "{message}");
    // Its own, cut short.
    let path = run(&small, &g_small);
    let mut bytes = std::fs::read(&path).expect("read");
    bytes.truncate(bytes.len() - 5);
    std::fs::write(&path, &bytes).expect("write");
    let (status, message) = status_of(
        worker
            .upload_result(g_small.task_id, g_small.lease, 0.0, &path)
            .await
            .unwrap_err(),
    );
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(message.contains("cut short"), "{message}");
    // And whole: accepted.
    let path = run(&small, &g_small);
    worker
        .upload_result(g_small.task_id, g_small.lease, 0.0, &path)
        .await
        .expect("accepted");
    running.stop().await.expect("stop");
}

/// A real worker whose result is over the coordinator's limit does not upload it: the task
/// fails on the worker with the limit, the result's size and how to raise the limit, and after
/// its attempts the job fails with that message.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_worker_refuses_a_result_over_the_limit_and_the_job_says_which_limit() {
    let dir = tempfile::tempdir().expect("temp dir");
    let running = start(&dir.path().join("data"), 64 << 10).await;
    let url = format!("http://{}", running.addr);
    let client = Client::new(&url, CLIENT).expect("client");
    let settings = RenderSettings {
        size: Some([128, 128]),
        spp: Some(1),
        tile: Some(128),
        ..Default::default()
    };
    let job = submit(&client, &cornell(), settings).await;
    let status = run_to_the_end(&url, &client, job.id, 1).await;
    assert_eq!(status.state, JobState::Failed);
    let error = status.error.unwrap_or_default();
    assert!(
        error.contains("64 KiB") && error.contains("bytes)") && error.contains("--max-result-mib"),
        "{error}"
    );
}

/// A photon pass that stores more than a job may hold fails its job as the results come in,
/// naming the pass, what it held and the limit, before the coordinator runs out of memory;
/// the frame itself fitted the budget at admission.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pass_outgrowing_the_job_memory_budget_fails_its_job_with_the_figures() {
    let dir = tempfile::tempdir().expect("temp dir");
    let scene_dir = dir.path().join("scene");
    std::fs::create_dir(&scene_dir).expect("dir");
    let cornell_dir = cornell().parent().expect("folder").to_path_buf();
    for e in std::fs::read_dir(&cornell_dir).expect("cornell") {
        let path = e.expect("entry").path();
        if path.extension().is_some_and(|x| x == "obj") {
            std::fs::copy(&path, scene_dir.join(path.file_name().expect("name"))).expect("copy");
        }
    }
    let scene = std::fs::read_to_string(cornell()).expect("scene").replace(
        r#""integrator": { "type": "path", "spp": 256, "max_depth": 64, "rr_depth": 3, "seed": 0 }"#,
        r#""integrator": { "type": "photon", "spp": 1, "photon_map": { "photons": 400000, "irradiance_cache": { "enabled": false } } }"#,
    );
    assert!(
        scene.contains("400000"),
        "the Cornell box's integrator line changed"
    );
    std::fs::write(scene_dir.join("scene.json"), scene).expect("write");
    let mut config = config(&dir.path().join("data"));
    // A 32×32 frame fits; 400,000 photons landing on the box's walls (52 bytes each) do not.
    config.limits.max_memory = 1 << 20;
    let running = coordinator::start(config).await.expect("coordinator");
    let url = format!("http://{}", running.addr);
    let client = Client::new(&url, CLIENT).expect("client");
    let settings = RenderSettings {
        size: Some([32, 32]),
        ..Default::default()
    };
    // Admitted: the frame fits.
    let job = submit(&client, &scene_dir.join("scene.json"), settings).await;
    let status = run_to_the_end(&url, &client, job.id, 2).await;
    assert_eq!(status.state, JobState::Failed);
    let error = status.error.unwrap_or_default();
    assert!(
        error.contains("photons pass holds")
            && error.contains("GiB a job")
            && error.contains("--max-job-memory-gib"),
        "{error}"
    );
    running.stop().await.expect("stop");
}
