//! Farm benchmarks: figures, not assertions.
//!
//! - `bench farm`: the same frame by `tessera render --threads T` and by a coordinator with
//!   local worker processes plus a client (upload, submit, poll, download), as wall times and
//!   their ratio; the two EXRs must be identical.
//! - `bench leases`: how many leases per second a coordinator grants to many simulated workers
//!   over loopback HTTP, leasing only and leasing + posting (empty) results.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::{Duration, Instant};

use anyhow::Context;
use tessera_farm::bundle::Bundle;
use tessera_farm::client::Client;
use tessera_farm::codec;
use tessera_farm::coordinator::{self, Config};
use tessera_farm::job::{RenderSettings, TaskOutput};
use tessera_farm::protocol::{JobRequest, JobState, LeaseRequest, WorkerInfo};
use tessera_render::RayStats;
use tessera_render::film::TileSums;

#[derive(clap::Args)]
pub struct FarmArgs {
    #[arg(default_value = "scenes/cornell-box/scene.json")]
    pub scene: PathBuf,
    #[arg(long, default_value_t = 256)]
    pub spp: u32,
    /// Threads for `render`, and local worker processes (one slot per core each) for the farm.
    #[arg(long, default_value_t = 2)]
    pub workers: u32,
    /// Runs of each, alternating; the medians are reported.
    #[arg(long, default_value_t = 3)]
    pub repeat: u32,
}

#[derive(clap::Args)]
pub struct LeaseArgs {
    #[arg(default_value = "scenes/cornell-box/scene.json")]
    pub scene: PathBuf,
    /// Simulated workers, each with its own connection.
    #[arg(long, default_value_t = 200)]
    pub workers: u32,
    /// Tile side: 256×256 with 2-pixel tiles is 16384 tasks.
    #[arg(long, default_value_t = 2)]
    pub tile: u32,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// A coordinator on loopback with `local_workers` supervised workers, once they have all
/// asked for work (their start is not part of any job's time), and a client of it.
pub(super) async fn local_coordinator(
    data: PathBuf,
    local_workers: u32,
) -> anyhow::Result<(coordinator::Running, Client)> {
    let token = coordinator::random_token()?;
    let mut config = Config::new(
        "127.0.0.1:0".parse()?,
        data,
        token.clone(),
        coordinator::random_token()?,
    );
    config.local_workers = local_workers;
    let running = coordinator::start(config).await?;
    let client = Client::new(&format!("http://{}", running.addr), &token)?;
    let start = Instant::now();
    while client.workers().await?.len() < local_workers as usize {
        anyhow::ensure!(
            start.elapsed() < Duration::from_secs(30),
            "local workers did not start"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    Ok((running, client))
}

pub async fn farm(args: FarmArgs) -> anyhow::Result<()> {
    let dir = tempfile_dir()?;
    let exe = std::env::current_exe()?;
    let (running, client) = local_coordinator(dir.join("data"), args.workers).await?;
    let (bundle, _, scene_name) = Bundle::pack_scene(&args.scene)?;
    let tar = bundle.to_tar();
    let (mut local, mut farm) = (Vec::new(), Vec::new());
    for run in 0..args.repeat {
        let out = dir.join(format!("render_{run}.exr"));
        let t = Instant::now();
        let status = tokio::process::Command::new(&exe)
            .arg("render")
            .arg(&args.scene)
            .args([
                "--spp",
                &args.spp.to_string(),
                "--threads",
                &args.workers.to_string(),
                "-q",
                "-o",
            ])
            .arg(&out)
            .stdout(std::process::Stdio::null())
            .status()
            .await?;
        anyhow::ensure!(status.success(), "tessera render failed");
        local.push(t.elapsed().as_secs_f64());

        let t = Instant::now();
        let info = client.upload_bundle(tar.clone()).await?;
        let job = client
            .submit(&JobRequest {
                bundle: info.hash,
                scene: scene_name.clone(),
                name: None,
                frames: None,
                settings: RenderSettings {
                    spp: Some(args.spp),
                    ..Default::default()
                },
                priority: 0,
            })
            .await?;
        let done = loop {
            let s = client.job(job.id).await?;
            if s.state.is_final() {
                break s;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        };
        anyhow::ensure!(
            done.state == JobState::Done,
            "farm job failed: {:?}",
            done.error
        );
        let exr = client.frame_exr(job.id, done.frames.first).await?;
        farm.push(t.elapsed().as_secs_f64());
        let same = std::fs::read(&out)? == exr;
        anyhow::ensure!(same, "the farm's EXR differs from tessera render's");
        crate::print(&format!(
            "run {}: render {:.2} s, farm {:.2} s ({} tasks), identical EXR\n",
            run + 1,
            local.last().copied().unwrap_or(0.0),
            farm.last().copied().unwrap_or(0.0),
            done.tasks.total
        ))?;
    }
    let (l, f) = (median(local), median(farm));
    crate::print(&format!(
        "median wall: tessera render --threads {w} {l:.2} s; serve --local-workers {w} + submit {f:.2} s; farm/render = {:.3} ({:+.1} %)\n",
        f / l,
        (f / l - 1.0) * 100.0,
        w = args.workers
    ))?;
    running.stop().await?;
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}

pub async fn leases(args: LeaseArgs) -> anyhow::Result<()> {
    let dir = tempfile_dir()?;
    let (running, client) = local_coordinator(dir.join("data"), 0).await?;
    let worker_token = running.app.config.worker_token.clone();
    let url = format!("http://{}", running.addr);
    let (bundle, _, scene_name) = Bundle::pack_scene(&args.scene)?;
    let info = client.upload_bundle(bundle.to_tar()).await?;
    let submit = || JobRequest {
        bundle: info.hash.clone(),
        scene: scene_name.clone(),
        name: Some("lease benchmark".into()),
        frames: None,
        settings: RenderSettings {
            spp: Some(1),
            tile: Some(args.tile),
            ..Default::default()
        },
        priority: 0,
    };

    for complete in [false, true] {
        let job = client.submit(&submit()).await?;
        let tasks = job.tasks.total;
        let granted = Arc::new(AtomicU64::new(0));
        let start = Instant::now();
        let mut handles = Vec::new();
        for i in 0..args.workers {
            let (url, token, granted) = (url.clone(), worker_token.clone(), granted.clone());
            handles.push(tokio::spawn(async move {
                let client = Client::new(&url, &token)?;
                let req = LeaseRequest {
                    worker: WorkerInfo {
                        id: format!("sim-{i}"),
                        name: format!("sim-{i}"),
                        host: "bench".into(),
                        pid: std::process::id(),
                        slots: 1,
                        scene_builds: 0,
                        version: env!("CARGO_PKG_VERSION").into(),
                    },
                    wait_ms: 0,
                };
                while let Some(grant) = client.lease(&req).await? {
                    granted.fetch_add(1, Relaxed);
                    if complete {
                        let t = grant.task;
                        let out = TaskOutput {
                            sums: TileSums::new(t.tile(), t.samples()),
                            stats: RayStats::default(),
                        };
                        client
                            .upload_result(grant.task_id, grant.lease, 0.0, codec::encode(&out))
                            .await?;
                    }
                }
                anyhow::Ok(())
            }));
        }
        for h in handles {
            h.await??;
        }
        let secs = start.elapsed().as_secs_f64();
        let n = granted.load(Relaxed);
        anyhow::ensure!(n == tasks, "granted {n} of {tasks} tasks");
        crate::print(&format!(
            "{} simulated workers, {n} tasks, {}: {:.2} s, {:.0} leases/s\n",
            args.workers,
            if complete {
                "lease + result"
            } else {
                "lease only"
            },
            secs,
            n as f64 / secs
        ))?;
        if complete {
            // Let the coordinator stitch the (black) frame before it stops.
            while !client.job(job.id).await?.state.is_final() {
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        } else {
            client.cancel(job.id).await?;
        }
    }
    running.stop().await?;
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}

/// A fresh scratch directory under the system temp dir.
pub(super) fn tempfile_dir() -> anyhow::Result<PathBuf> {
    let dir = std::env::temp_dir().join(format!("tessera-bench-{}", coordinator::random_token()?));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    Ok(dir)
}
