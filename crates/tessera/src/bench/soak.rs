//! `tessera bench soak`: a simulated farm for minutes on end. A coordinator process (on the
//! embedded SQLite store, or on PostgreSQL with `--store`) serves many simulated workers on
//! loopback, each with its own connection, that lease, run the (tiny) task for real and post
//! its result, while a client keeps jobs queued. When the time is up no more jobs are
//! submitted, the workers finish what is queued, and the run is checked: every job done, every
//! task's result accepted exactly once (none lost, none twice). Figures: tasks per second,
//! lease latency, the store's size, and the coordinator process's CPU and memory.

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context;
use tessera_farm::client::{Client, is_transient};
use tessera_farm::protocol::{JobState, LeaseRequest, WorkerInfo};
use tessera_farm::store::{Location, Store};

use super::farm::{SimulatedJob, peak_rss_mib, serve_process, tempfile_dir};

#[derive(clap::Args)]
pub struct SoakArgs {
    #[arg(default_value = "scenes/cornell-box/scene.json")]
    pub scene: PathBuf,
    /// Simulated workers, each with its own connection.
    #[arg(long, default_value_t = 1000)]
    pub workers: u32,
    /// How long jobs keep arriving, minutes.
    #[arg(long, default_value_t = 10.0)]
    pub minutes: f64,
    /// Tile side: the scene's 256×256 film with 8-pixel tiles is 1,024 tasks a job.
    #[arg(long, default_value_t = 8)]
    pub tile: u32,
    /// The job store: a PostgreSQL URL (default: the embedded SQLite).
    #[arg(long)]
    pub store: Option<String>,
}

pub async fn run(args: SoakArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.minutes > 0.0 && args.minutes.is_finite(),
        "--minutes: expected a positive number"
    );
    anyhow::ensure!(args.workers >= 1, "--workers: expected at least 1");
    let dir = tempfile_dir()?;
    let data = dir.join("data");
    let (mut serve, client, worker_token) = serve_process(&data, 0, args.store.as_deref()).await?;
    let serve_pid = serve.id().context("serve's pid")?;
    let sim = Arc::new(SimulatedJob::upload(&client, &args.scene, args.tile, "soak").await?);

    let started = Instant::now();
    let cpu_start = crate::render::process_cpu_seconds(&serve_pid.to_string());
    let deadline = started + Duration::from_secs_f64(args.minutes * 60.0);
    let submitting = Arc::new(AtomicBool::new(true));
    // Results accepted, by task: each must be 1.
    let accepted: Arc<Mutex<HashMap<i64, u32>>> = Arc::default();
    let (leased, refused) = (Arc::new(AtomicU64::new(0)), Arc::new(AtomicU64::new(0)));
    let mut handles = Vec::new();
    for i in 0..args.workers {
        let url = client.url("");
        let token = worker_token.clone();
        let (sim, dir) = (sim.clone(), dir.clone());
        let (submitting, accepted, leased, refused) = (
            submitting.clone(),
            accepted.clone(),
            leased.clone(),
            refused.clone(),
        );
        handles.push(tokio::spawn(async move {
            let client = Client::new(&url, &token)?;
            let req = LeaseRequest {
                worker: WorkerInfo::simulated(&format!("soak-{i}")),
                wait_ms: 1000,
            };
            let mut latencies = Vec::new();
            loop {
                let asked = Instant::now();
                let grant = match client.lease(&req).await {
                    Ok(Some(g)) => g,
                    // Nothing queued: stop once no more jobs are coming.
                    Ok(None) if submitting.load(Relaxed) => continue,
                    Ok(None) => break,
                    Err(e) if is_transient(&e) => {
                        tokio::time::sleep(Duration::from_millis(100)).await;
                        continue;
                    }
                    Err(e) => return Err(e),
                };
                latencies.push(asked.elapsed().as_secs_f64());
                leased.fetch_add(1, Relaxed);
                let path = dir.join(format!("{}-{}.tswf", grant.task_id, grant.lease));
                sim.write_result(&grant.task, &path)?;
                let upload = client
                    .upload_result(grant.task_id, grant.lease, 0.0, &path)
                    .await;
                let _ = std::fs::remove_file(&path);
                match upload {
                    Ok(()) => {
                        *accepted
                            .lock()
                            .unwrap_or_else(|e| e.into_inner())
                            .entry(grant.task_id)
                            .or_default() += 1;
                    }
                    // A lease that expired under load: the task is leased again.
                    Err(e)
                        if tessera_farm::client::status_of(&e)
                            == Some(reqwest::StatusCode::CONFLICT) =>
                    {
                        refused.fetch_add(1, Relaxed);
                    }
                    Err(e) => return Err(e.context(format!("task {}", grant.task_id))),
                }
            }
            anyhow::Ok(latencies)
        }));
    }

    // Keep two jobs' worth of tasks ahead of the workers until the time is up.
    let mut jobs = Vec::new();
    let progress = indicatif::ProgressBar::new((args.minutes * 60.0) as u64).with_style(
        indicatif::ProgressStyle::with_template("{elapsed_precise} {bar:30} {msg}")?,
    );
    while Instant::now() < deadline {
        let open = open_jobs(&client, &jobs).await?;
        if open < 2 {
            jobs.push(client.submit(&sim.request).await?.id);
        }
        let done = accepted.lock().unwrap_or_else(|e| e.into_inner()).len();
        progress.set_position(started.elapsed().as_secs());
        progress.set_message(format!(
            "{} jobs, {done} tasks done, {:.0}/s",
            jobs.len(),
            done as f64 / started.elapsed().as_secs_f64()
        ));
        tokio::time::sleep(Duration::from_millis(500)).await;
    }
    submitting.store(false, Relaxed);
    progress.finish_and_clear();
    let mut latencies = Vec::new();
    for h in handles {
        latencies.extend(h.await??);
    }
    let wall = started.elapsed().as_secs_f64();
    let cpu = match (
        cpu_start,
        crate::render::process_cpu_seconds(&serve_pid.to_string()),
    ) {
        (Some(a), Some(b)) => Some(b - a),
        _ => None,
    };
    let rss = peak_rss_mib(serve_pid);

    // Every job done, every task of them accepted exactly once.
    let mut tasks = 0;
    for &id in &jobs {
        let start = Instant::now();
        let job = loop {
            let job = client.job(id).await?;
            if job.state.is_final() || start.elapsed() > Duration::from_secs(120) {
                break job;
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
        };
        anyhow::ensure!(
            job.state == JobState::Done,
            "job {id} ended {:?}: {:?}",
            job.state,
            job.error
        );
        tasks += job.tasks.total;
    }
    let accepted = accepted.lock().unwrap_or_else(|e| e.into_inner()).clone();
    let twice = accepted.values().filter(|&&n| n > 1).count();
    let lost = tasks.saturating_sub(accepted.len() as u64);
    let _ = serve.kill().await;
    let _ = serve.wait().await;
    let store = match &args.store {
        Some(url) => Store::open_at(Location::Postgres(url))?,
        None => Store::open(&data.join("tessera.db"))?,
    };
    let store_bytes = store.size_bytes()?;
    drop(store);

    latencies.sort_by(f64::total_cmp);
    let quantile = |q: f64| {
        latencies
            .get(((latencies.len().max(1) - 1) as f64 * q) as usize)
            .map_or(f64::NAN, |s| s * 1e3)
    };
    crate::print(&format!(
        "{} store, {} simulated workers, {:.1} min of arrivals ({:.0} s in all): {} jobs, {tasks} tasks, {:.0} tasks/s; {} leases, {} results refused (lease expired), lease latency p50 {:.1} ms, p99 {:.1} ms\n\
         lost {lost}, accepted twice {twice}; store {:.1} MiB; coordinator CPU {} s ({} cores on average), peak memory {} MiB\n",
        if args.store.is_some() {
            "PostgreSQL"
        } else {
            "SQLite"
        },
        args.workers,
        args.minutes,
        wall,
        jobs.len(),
        tasks as f64 / wall,
        leased.load(Relaxed),
        refused.load(Relaxed),
        quantile(0.5),
        quantile(0.99),
        store_bytes as f64 / 1048576.0,
        cpu.map_or("?".into(), |c| format!("{c:.0}")),
        cpu.map_or("?".into(), |c| format!("{:.2}", c / wall)),
        rss.map_or("?".into(), |m| format!("{m:.0}")),
    ))?;
    let _ = std::fs::remove_dir_all(&dir);
    anyhow::ensure!(
        lost == 0 && twice == 0,
        "{lost} tasks lost, {twice} accepted twice"
    );
    Ok(())
}

/// How many of `jobs` have not ended.
async fn open_jobs(client: &Client, jobs: &[i64]) -> anyhow::Result<usize> {
    let mut open = 0;
    for &id in jobs.iter().rev().take(3) {
        if !client.job(id).await?.state.is_final() {
            open += 1;
        }
    }
    Ok(open)
}
