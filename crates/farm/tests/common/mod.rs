//! What the farm's integration tests share: tokens, a coordinator's configuration, the
//! Cornell box, a frame rendered in this process, a job submitted and run by a real worker.

#![allow(dead_code, reason = "each test file uses its share")]

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use tessera_farm::bundle::Bundle;
use tessera_farm::client::Client;
use tessera_farm::coordinator::Config;
use tessera_farm::job::{self, FrameRange, Limits, RenderSettings};
use tessera_farm::protocol::{JobRequest, JobStatus};
use tessera_render::method::local::Local;
use tessera_render::method::{Finished, Plan};
use tessera_scene::SceneDesc;

pub const CLIENT: &str = "client-token";
pub const WORKER: &str = "worker-token";

/// A coordinator on a free port keeping its data in `dir`.
pub fn config(dir: &Path) -> Config {
    let mut config = Config::new(
        "127.0.0.1:0".parse().expect("addr"),
        dir.to_path_buf(),
        CLIENT.into(),
        WORKER.into(),
    );
    config.store = tessera_farm::store::test_store_url(dir);
    config
}

/// A coordinator keeping its data in `dir`/data, its URL and a client of it.
pub async fn coordinator_in(dir: &Path) -> (tessera_farm::coordinator::Running, String, Client) {
    let running = tessera_farm::coordinator::start(config(&dir.join("data")))
        .await
        .expect("coordinator");
    let url = format!("http://{}", running.addr);
    let client = Client::new(&url, CLIENT).expect("client");
    (running, url, client)
}

pub fn cornell() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-box/scene.json")
}

/// Frame 1 of the Cornell box with `settings` applied and planned.
pub fn planned(settings: &RenderSettings) -> (SceneDesc, Box<dyn Plan>) {
    let desc = tessera_scene::load(&cornell()).expect("scene");
    let limits = Limits::default();
    let c = job::compile(
        desc,
        settings,
        FrameRange::single(1),
        job::Options::new(&limits),
    )
    .expect("plan");
    (c.job.desc, c.plan)
}

/// Frame 1 of the Cornell box with `settings`, planned and rendered in this process.
pub fn local_render(settings: &RenderSettings) -> (SceneDesc, Box<dyn Plan>, Finished) {
    let (desc, plan) = planned(settings);
    let scene = tessera_render::Scene::build(&desc);
    let noop = |_| {};
    let local = Local::new(plan.as_ref(), &scene, &desc, 2, &noop);
    local.passes().expect("passes");
    let done = local.frame(1).expect("frame");
    (desc, plan, done)
}

/// The job's frame rendered in this process, as `tessera render` writes it.
pub fn local_frame(settings: &RenderSettings, dir: &Path) -> Vec<u8> {
    let (desc, plan, done) = local_render(settings);
    let path = dir.join("local.exr");
    job::write_frame(&path, &desc, plan.as_ref(), 1, &done).expect("write");
    std::fs::read(path).expect("read")
}

/// Packs the scene at `scene`, uploads it and submits it with `settings`.
pub async fn submit(client: &Client, scene: &Path, settings: RenderSettings) -> JobStatus {
    let (bundle, _, scene_name) = Bundle::pack_scene(scene).expect("bundle");
    let hash = client
        .upload_bundle(bundle.to_tar().expect("packs"))
        .await
        .expect("upload")
        .hash;
    client
        .submit(&JobRequest {
            bundle: hash,
            scene: scene_name,
            name: None,
            frames: None,
            settings,
            priority: 0,
            require_tags: vec![],
        })
        .await
        .expect("submit")
}

/// Runs a real worker of `slots` slots until job `id` ends; its last status.
pub async fn run_to_the_end(url: &str, client: &Client, id: i64, slots: u32) -> JobStatus {
    let worker = tokio::spawn(tessera_farm::worker::run(
        tessera_farm::worker::WorkerConfig {
            coordinator: url.to_string(),
            token: WORKER.into(),
            name: "worker".into(),
            slots,
            parent_pid: None,
            tags: vec![],
            fail_tasks_with: None,
            ca: None,
        },
    ));
    let deadline = Instant::now() + Duration::from_secs(120);
    let status = loop {
        let s = client.job(id).await.expect("status");
        if s.state.is_final() {
            break s;
        }
        assert!(Instant::now() < deadline, "job still {:?}", s.state);
        tokio::time::sleep(Duration::from_millis(50)).await;
    };
    worker.abort();
    status
}
