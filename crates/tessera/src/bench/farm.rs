//! Farm benchmarks: figures, not assertions.
//!
//! - `bench farm`: the same frame by `tessera render --threads T` and by a coordinator with
//!   local worker processes plus a client (upload, submit, poll, download), for every method
//!   of the registry (or those given): wall times, whether the two EXRs are byte-identical,
//!   each method's result bytes per task and per pixel (uploaded and before compression), the
//!   processes' peak resident memory, and the data directory against the jobs' output.
//! - `bench leases`: how many leases per second coordinators grant to many simulated workers
//!   over loopback HTTP (the workers spread over the coordinators), and the latency of a lease,
//!   leasing only and leasing + running the (tiny) task + posting its result; on the embedded
//!   SQLite store or on PostgreSQL (`--store`), with one or several coordinators sharing it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::{Duration, Instant};

use anyhow::Context;
use tessera_farm::bundle::Bundle;
use tessera_farm::client::Client;
use tessera_farm::coordinator::{self, Config};
use tessera_farm::job::{self, FrameRange, Limits, RenderSettings};
use tessera_farm::protocol::{JobRequest, JobState, LeaseRequest, WorkerInfo};

#[derive(clap::Args)]
pub struct FarmArgs {
    #[arg(default_value = "scenes/cornell-box/scene.json")]
    pub scene: PathBuf,
    /// Samples per pixel (iterations, mutations) for every method.
    #[arg(long, default_value_t = 4)]
    pub spp: u32,
    /// Film size WxH (default: the scene's).
    #[arg(long)]
    pub size: Option<crate::render::Size>,
    /// Methods, comma-separated (default: every method of the registry).
    #[arg(long, value_delimiter = ',')]
    pub methods: Vec<String>,
    /// Threads for `render`, and local worker processes (one slot per core each) for the farm.
    #[arg(long, default_value_t = 2)]
    pub workers: u32,
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
    /// The job store: a PostgreSQL URL (default: the embedded SQLite).
    #[arg(long)]
    pub store: Option<String>,
    /// Coordinators sharing the store (more than one needs --store), in this process.
    #[arg(long, default_value_t = 1)]
    pub coordinators: u32,
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
    config.worker_log = Some("warn".into());
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

/// `tessera serve --local-workers N` as a process of its own (so its memory and CPU are its
/// own), on a free port, on the embedded store or `store`, once its workers have asked for
/// work; with a client of it and the worker token.
pub(super) async fn serve_process(
    data: &Path,
    local_workers: u32,
    store: Option<&str>,
) -> anyhow::Result<(tokio::process::Child, Client, String)> {
    use tokio::io::AsyncBufReadExt;
    let token = coordinator::random_token()?;
    let worker_token = coordinator::random_token()?;
    let mut child = tokio::process::Command::new(std::env::current_exe()?)
        .args(["serve", "--listen", "127.0.0.1:0", "--local-workers"])
        .arg(local_workers.to_string())
        .arg("--data")
        .arg(data)
        .args(["--client-token", &token, "--worker-token", &worker_token])
        .args(store.map(|s| ["--store", s]).into_iter().flatten())
        .env("RUST_LOG", "warn")
        .stdout(std::process::Stdio::piped())
        .kill_on_drop(true)
        .spawn()
        .context("starting tessera serve")?;
    let stdout = child.stdout.take().context("serve's output")?;
    let mut line = String::new();
    tokio::io::BufReader::new(stdout)
        .read_line(&mut line)
        .await?;
    let url = line
        .trim()
        .rsplit(' ')
        .next()
        .filter(|u| u.starts_with("http://"))
        .with_context(|| format!("no URL in serve's first line {line:?}"))?;
    let client = Client::new(url, &token)?;
    let start = Instant::now();
    while client.workers().await.map_or(0, |w| w.len()) < local_workers as usize {
        anyhow::ensure!(
            start.elapsed() < Duration::from_secs(30),
            "local workers did not start"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    Ok((child, client, worker_token))
}

/// Peak resident memory of a process (`VmHWM`), MiB, where the platform tells it.
pub(super) fn peak_rss_mib(pid: u32) -> Option<f64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// Resets a process's peak resident memory to its current size (Linux: `clear_refs` 5), so
/// that the next [`peak_rss_mib`] is the peak since; false where that is not possible.
fn reset_peak_rss(pid: u32) -> bool {
    std::fs::write(format!("/proc/{pid}/clear_refs"), "5").is_ok()
}

/// Bytes under `dir`, and under its `cache` folder.
fn disk_use(dir: &Path) -> (u64, u64) {
    fn walk(p: &Path) -> u64 {
        std::fs::read_dir(p)
            .map(|entries| {
                entries
                    .flatten()
                    .map(|e| match e.file_type() {
                        Ok(t) if t.is_dir() => walk(&e.path()),
                        _ => e.metadata().map_or(0, |m| m.len()),
                    })
                    .sum()
            })
            .unwrap_or(0)
    }
    (walk(dir), walk(&dir.join("cache")))
}

/// One method's figures.
struct MethodRun {
    method: String,
    render_s: f64,
    farm_s: f64,
    identical: bool,
    tasks: usize,
    /// By task kind: (tasks, wire bytes, payload bytes, pixels).
    kinds: BTreeMap<String, (u64, u64, u64, u64)>,
    output_bytes: u64,
}

pub async fn farm(args: FarmArgs) -> anyhow::Result<()> {
    let dir = tempfile_dir()?;
    let exe = std::env::current_exe()?;
    let data = dir.join("data");
    let (mut serve, client, _) = serve_process(&data, args.workers, None).await?;
    let serve_pid = serve.id().context("serve's pid")?;
    let (bundle, desc, scene_name) = Bundle::pack_scene(&args.scene)?;
    let tar = bundle.to_tar().map_err(anyhow::Error::msg)?;
    let methods: Vec<String> = if args.methods.is_empty() {
        tessera_render::method::names()
            .into_iter()
            .map(String::from)
            .collect()
    } else {
        args.methods.clone()
    };
    let size = args.size.map(|s| s.0);
    let (w, h) = size.map_or((desc.film.width, desc.film.height), |[w, h]| (w, h));
    crate::print(&format!(
        "{}: {w}×{h}, {} spp, tessera render --threads {n} against serve --local-workers {n}\n",
        args.scene.display(),
        args.spp,
        n = args.workers
    ))?;
    let mut runs = Vec::new();
    for method in &methods {
        let settings = RenderSettings {
            spp: Some(args.spp),
            size,
            integrator: Some(method.clone()),
            ..Default::default()
        };
        let limits = Limits::default();
        let options = job::Options::new(&limits);
        if let Err(e) = job::compile(desc.clone(), &settings, FrameRange::single(1), options) {
            crate::print(&format!("{method:>8}: skipped — {e}\n"))?;
            continue;
        }
        let out = dir.join(format!("render_{method}.exr"));
        // `tessera render` of the job into `out`, with `extra` arguments.
        let render = |extra: Vec<String>| {
            let mut cmd = tokio::process::Command::new(&exe);
            cmd.arg("render")
                .arg(&args.scene)
                .args(["--spp", &args.spp.to_string(), "--integrator", method])
                .args(["--threads", &args.workers.to_string(), "-q", "-o"])
                .arg(&out)
                .args(extra);
            if let Some([w, h]) = size {
                cmd.args(["--size", &format!("{w}x{h}")]);
            }
            async move {
                let o = cmd.output().await?;
                anyhow::ensure!(
                    o.status.success(),
                    "tessera render --integrator {method} failed: {}",
                    String::from_utf8_lossy(&o.stderr)
                );
                Ok(o)
            }
        };
        let t = Instant::now();
        let o = render(Vec::new()).await?;
        let render_s = t.elapsed().as_secs_f64();
        // The render reports its own peak resident memory.
        let render_mib = String::from_utf8_lossy(&o.stdout)
            .lines()
            .find_map(|l| l.strip_prefix("peak resident memory "))
            .and_then(|l| l.split_whitespace().next())
            .and_then(|v| v.parse::<f64>().ok());

        let farm_pids: Vec<u32> = std::iter::once(serve_pid)
            .chain(
                client
                    .workers()
                    .await?
                    .iter()
                    .filter(|w| w.alive)
                    .map(|w| w.pid),
            )
            .collect();
        let per_job = farm_pids.iter().all(|&pid| reset_peak_rss(pid));
        let t = Instant::now();
        let info = client.upload_bundle(tar.clone()).await?;
        let job = client
            .submit(&JobRequest {
                bundle: info.hash,
                scene: scene_name.clone(),
                name: None,
                frames: None,
                settings,
                priority: 0,
                require_tags: vec![],
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
            "farm job ({method}) failed: {:?}",
            done.error
        );
        let exr = client.frame_exr(job.id, done.frames.first).await?;
        let farm_s = t.elapsed().as_secs_f64();
        let png = client.frame_preview(job.id, done.frames.first).await?;
        // `auto` measures where it is planned: the local render is compared once it replays the
        // farm's choice.
        if let Some(choice) = &done.settings.choice {
            render(vec!["--auto-choice".into(), serde_json::to_string(choice)?]).await?;
        }
        let identical = std::fs::read(&out)? == exr;
        let mut kinds: BTreeMap<String, (u64, u64, u64, u64)> = BTreeMap::new();
        let tasks = client.tasks(job.id).await?;
        for t in &tasks {
            let k = kinds.entry(t.spec.kind.clone()).or_default();
            k.0 += 1;
            k.1 += t.result_bytes.unwrap_or(0);
            k.2 += t.payload_bytes.unwrap_or(0);
            k.3 += t.spec.pixels();
        }
        let run = MethodRun {
            method: done.method.clone(),
            render_s,
            farm_s,
            identical,
            tasks: tasks.len(),
            kinds,
            output_bytes: (exr.len() + png.len()) as u64,
        };
        let workers = client.workers().await?;
        let worker_peaks: Vec<String> = workers
            .iter()
            .filter(|w| w.alive)
            .filter_map(|w| peak_rss_mib(w.pid).map(|m| format!("{m:.0}")))
            .collect();
        crate::print(&format!(
            "{method:>8}: render {:.2} s, farm {:.2} s ({} tasks), EXR {}; peak resident MiB: render {}; {}: coordinator {}, workers {}\n",
            run.render_s,
            run.farm_s,
            run.tasks,
            if identical {
                "byte-identical"
            } else {
                "DIFFERS"
            },
            render_mib.map_or("?".into(), |m| format!("{m:.0}")),
            if per_job {
                "during this job"
            } else {
                "since they started"
            },
            peak_rss_mib(serve_pid).map_or("?".into(), |m| format!("{m:.0}")),
            worker_peaks.join(", ")
        ))?;
        for (kind, (n, wire, payload, pixels)) in &run.kinds {
            let per_pixel = |b: u64| {
                if *pixels == 0 {
                    "–".to_string()
                } else {
                    format!("{:.1}", b as f64 / *pixels as f64)
                }
            };
            crate::print(&format!(
                "{:>10} {kind:<16} {n:>5} tasks, per task {:>10.0} B payload / {:>10.0} B uploaded, per pixel {:>6} / {:>6} B\n",
                "",
                *payload as f64 / *n as f64,
                *wire as f64 / *n as f64,
                per_pixel(*payload),
                per_pixel(*wire),
            ))?;
        }
        runs.push(run);
    }
    let (total, cache) = disk_use(&data);
    let output: u64 = runs.iter().map(|r| r.output_bytes).sum();
    crate::print(&format!(
        "data directory after {} jobs: {:.1} MiB, of it the artifact cache {:.1} MiB; the jobs' output (EXR + PNG) {:.1} MiB: (data − cache) / output = {:.2}\n",
        runs.len(),
        total as f64 / 1048576.0,
        cache as f64 / 1048576.0,
        output as f64 / 1048576.0,
        (total - cache) as f64 / output.max(1) as f64
    ))?;

    let different: Vec<&str> = runs
        .iter()
        .filter(|r| !r.identical)
        .map(|r| r.method.as_str())
        .collect();
    let _ = serve.kill().await;
    let _ = std::fs::remove_dir_all(&dir);
    anyhow::ensure!(
        different.is_empty(),
        "the farm's EXR differs from tessera render's for {}",
        different.join(", ")
    );
    Ok(())
}

pub async fn leases(args: LeaseArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.coordinators >= 1 && (args.coordinators == 1 || args.store.is_some()),
        "--coordinators: more than one shares a store; give it with --store postgres://…"
    );
    let dir = tempfile_dir()?;
    let (client_token, worker_token) = (coordinator::random_token()?, coordinator::random_token()?);
    let mut coordinators = Vec::new();
    for _ in 0..args.coordinators {
        let mut config = Config::new(
            "127.0.0.1:0".parse()?,
            dir.join("data"),
            client_token.clone(),
            worker_token.clone(),
        );
        config.store = args.store.clone();
        coordinators.push(coordinator::start(config).await?);
    }
    let urls: Vec<String> = coordinators
        .iter()
        .map(|c| format!("http://{}", c.addr))
        .collect();
    let client = Client::new(&urls[0], &client_token)?;
    let sim =
        Arc::new(SimulatedJob::upload(&client, &args.scene, args.tile, "lease benchmark").await?);

    for complete in [false, true] {
        let job = client.submit(&sim.request).await?;
        let tasks = job.tasks.total;
        let granted = Arc::new(AtomicU64::new(0));
        let start = Instant::now();
        let mut handles = Vec::new();
        for i in 0..args.workers {
            let url = urls[i as usize % urls.len()].clone();
            let (token, granted) = (worker_token.clone(), granted.clone());
            let (sim, dir) = (sim.clone(), dir.clone());
            handles.push(tokio::spawn(async move {
                let client = Client::new(&url, &token)?;
                let req = LeaseRequest {
                    worker: WorkerInfo::simulated(&format!("sim-{i}")),
                    wait_ms: 0,
                };
                let mut latencies = Vec::new();
                loop {
                    let asked = Instant::now();
                    let Some(grant) = client.lease(&req).await? else {
                        break;
                    };
                    latencies.push(asked.elapsed().as_secs_f64());
                    granted.fetch_add(1, Relaxed);
                    if complete {
                        let path = dir.join(format!("{}.tswf", grant.task_id));
                        sim.write_result(&grant.task, &path)?;
                        client
                            .upload_result(grant.task_id, grant.lease, 0.0, &path)
                            .await?;
                        let _ = std::fs::remove_file(&path);
                    }
                }
                anyhow::Ok(latencies)
            }));
        }
        let mut latencies = Vec::new();
        for h in handles {
            latencies.extend(h.await??);
        }
        let secs = start.elapsed().as_secs_f64();
        let n = granted.load(Relaxed);
        anyhow::ensure!(n == tasks, "granted {n} of {tasks} tasks");
        latencies.sort_by(f64::total_cmp);
        let quantile = |q: f64| latencies[((latencies.len() - 1) as f64 * q) as usize] * 1e3;
        crate::print(&format!(
            "{} store, {} coordinator(s), {} simulated workers, {n} tasks, {}: {:.2} s, {:.0} leases/s, lease latency p50 {:.1} ms, p99 {:.1} ms\n",
            if args.store.is_some() {
                "PostgreSQL"
            } else {
                "SQLite"
            },
            args.coordinators,
            args.workers,
            if complete {
                "lease + run + result"
            } else {
                "lease only"
            },
            secs,
            n as f64 / secs,
            quantile(0.5),
            quantile(0.99),
        ))?;
        if complete {
            // Let the coordinator fold and write the frame before it stops.
            while !client.job(job.id).await?.state.is_final() {
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        } else {
            client.cancel(job.id).await?;
        }
    }
    for c in coordinators {
        c.stop().await?;
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}

/// A job of simulated workers: the scene uploaded, at 1 spp in `tile`-pixel tiles, planned and
/// built here too, so that a simulated worker runs its (tiny) tasks for real and posts real
/// results.
pub(super) struct SimulatedJob {
    pub request: JobRequest,
    plan: Box<dyn tessera_render::method::Plan>,
    scene: tessera_render::Scene,
    desc: tessera_scene::SceneDesc,
}

impl SimulatedJob {
    pub async fn upload(
        client: &Client,
        scene: &Path,
        tile: u32,
        name: &str,
    ) -> anyhow::Result<SimulatedJob> {
        let (bundle, desc, scene_name) = Bundle::pack_scene(scene)?;
        let info = client
            .upload_bundle(bundle.to_tar().map_err(anyhow::Error::msg)?)
            .await?;
        let settings = RenderSettings {
            spp: Some(1),
            tile: Some(tile),
            ..Default::default()
        };
        let limits = Limits::default();
        let compiled = job::compile(
            desc,
            &settings,
            FrameRange::single(1),
            job::Options::new(&limits),
        )
        .map_err(anyhow::Error::msg)?;
        let (desc, plan) = (compiled.job.desc, compiled.plan);
        Ok(SimulatedJob {
            request: JobRequest {
                bundle: info.hash,
                scene: scene_name,
                name: Some(name.into()),
                frames: None,
                settings,
                priority: 0,
                require_tags: vec![],
            },
            plan,
            scene: tessera_render::Scene::build(&desc),
            desc,
        })
    }

    /// Runs `task` in this process and writes its result to `path` as a worker does.
    pub fn write_result(&self, task: &job::TaskSpec, path: &Path) -> anyhow::Result<()> {
        write_result(self.plan.as_ref(), &self.scene, &self.desc, task, path)
    }
}

/// Runs a task of `plan` in this process and writes its result as a worker does.
fn write_result(
    plan: &dyn tessera_render::method::Plan,
    scene: &tessera_render::Scene,
    desc: &tessera_scene::SceneDesc,
    task: &job::TaskSpec,
    path: &Path,
) -> anyhow::Result<()> {
    struct NoResources;
    impl tessera_render::method::Resources for NoResources {
        fn artifact(
            &self,
            key: &str,
            _: tessera_render::method::LoadFn,
        ) -> Result<tessera_render::method::Loaded, String> {
            Err(format!("no artifact {key} here"))
        }
        fn input(
            &self,
            _: tessera_render::method::LoadFn,
        ) -> Result<tessera_render::method::Loaded, String> {
            Err("no step input here".into())
        }
        fn memo(
            &self,
            _: &str,
            make: &dyn Fn() -> Result<tessera_render::method::Loaded, String>,
        ) -> Result<tessera_render::method::Loaded, String> {
            make()
        }
    }
    let ctx = tessera_render::method::TaskCtx {
        scene,
        desc,
        resources: &NoResources,
    };
    let partial = plan.execute(&ctx, task).map_err(anyhow::Error::msg)?;
    let mut header = tessera_render::wire::Header::new("result", &plan.schema());
    header.task = Some(task.clone());
    let file = std::fs::File::create(path).with_context(|| path.display().to_string())?;
    partial.write_to(&header, &mut std::io::BufWriter::new(file))?;
    Ok(())
}

/// A fresh scratch directory under the system temp dir.
pub(super) fn tempfile_dir() -> anyhow::Result<PathBuf> {
    let dir = std::env::temp_dir().join(format!("tessera-bench-{}", coordinator::random_token()?));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    Ok(dir)
}
