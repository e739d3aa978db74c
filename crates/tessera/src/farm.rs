//! `tessera serve`, `tessera worker` and `tessera submit`: the farm from the command line.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use tessera_farm::bundle::Bundle;
use tessera_farm::coordinator::{self, Config};
use tessera_farm::job::{self, FrameRange, RenderSettings};
use tessera_farm::protocol::{JobRequest, JobState};
use tessera_farm::worker::{self, WorkerConfig};

#[derive(clap::Args)]
pub struct ServeArgs {
    /// Address to listen on (port 0: any free port; the address is printed).
    #[arg(long, default_value = "127.0.0.1:8720")]
    pub listen: SocketAddr,
    /// This coordinator's directory: the job store (unless --store), tokens, a spool for
    /// files in transit, and the objects (unless --objects).
    #[arg(long, default_value = "tessera-data")]
    pub data: PathBuf,
    /// The job store in PostgreSQL instead of the embedded SQLite in --data:
    /// postgres://USER:PASSWORD@HOST:PORT/DATABASE (a libpq URL; `?options=-csearch_path%3DS`
    /// keeps the farm's tables in schema S, made if missing). Coordinators sharing it are one
    /// farm.
    #[arg(long, env = "TESSERA_STORE", hide_env_values = true)]
    pub store: Option<String>,
    /// Where scene bundles, task results, checkpoints, frames and pass artifacts live: a
    /// directory (coordinators sharing --store must share it: NFS, say) or s3://BUCKET/PREFIX
    /// (credentials, region and endpoint from AWS_ACCESS_KEY_ID, AWS_SECRET_ACCESS_KEY,
    /// AWS_REGION, AWS_ENDPOINT_URL, AWS_ALLOW_HTTP). Default: --data.
    #[arg(long, env = "TESSERA_OBJECTS")]
    pub objects: Option<String>,
    /// Worker processes to start and supervise on this machine.
    #[arg(long, default_value_t = 0)]
    pub local_workers: u32,
    /// Token clients must send (default: generated once and kept in DIR/tokens.json).
    #[arg(long, env = "TESSERA_CLIENT_TOKEN", hide_env_values = true)]
    pub client_token: Option<String>,
    /// Token workers must send (default: generated once and kept in DIR/tokens.json).
    #[arg(long, env = "TESSERA_WORKER_TOKEN", hide_env_values = true)]
    pub worker_token: Option<String>,
    /// Seconds a lease lasts without a heartbeat.
    #[arg(long, default_value_t = 15.0)]
    pub lease_seconds: f64,
    /// Failures a task may have (on workers not blocklisted for its job) before its job
    /// fails.
    #[arg(long, default_value_t = 3)]
    pub max_attempts: u32,
    /// Failures of a job's tasks on one worker after which that worker is blocklisted for
    /// the job (its tasks go to other workers).
    #[arg(long, default_value_t = 3)]
    pub blocklist_after: u32,
    /// Serve HTTPS: the certificate chain (PEM). With --tls-key.
    #[arg(long, requires = "tls_key")]
    pub tls_cert: Option<PathBuf>,
    /// Serve HTTPS: the private key (PEM). With --tls-cert.
    #[arg(long, requires = "tls_cert")]
    pub tls_key: Option<PathBuf>,
    /// Largest film side a job may ask for, pixels.
    #[arg(long, default_value_t = 16384)]
    pub max_resolution: u32,
    /// Most samples per pixel a job may ask for.
    #[arg(long, default_value_t = 1 << 20)]
    pub max_spp: u32,
    /// Most frames per job.
    #[arg(long, default_value_t = 100_000)]
    pub max_frames: u32,
    /// Most memory one job's frames may take to fold at the coordinator, GiB (default: half
    /// of this machine's memory); a larger job is refused with its figures.
    #[arg(long)]
    pub max_job_memory_gib: Option<f64>,
    /// Largest scene bundle upload, MiB.
    #[arg(long, default_value_t = 512)]
    pub max_upload_mib: usize,
    /// Largest task result a worker may upload, MiB (results stream to disk).
    #[arg(long, default_value_t = 4096)]
    pub max_result_mib: u64,
    /// Size cap of the pass-artifact cache (photon maps, irradiance caches, point clouds),
    /// GiB: the least recently used artifacts are evicted beyond it.
    #[arg(long, default_value_t = 8.0)]
    pub cache_max_gib: f64,
    /// Delete finished, failed and cancelled jobs (frames, results, bundle) this many days
    /// after they ended (default: keep them until deleted).
    #[arg(long)]
    pub retain_days: Option<f64>,
}

pub async fn serve(args: ServeArgs) -> anyhow::Result<()> {
    let (client_token, worker_token, generated) =
        coordinator::tokens(&args.data, args.client_token, args.worker_token)?;
    anyhow::ensure!(
        args.lease_seconds > 0.0 && args.lease_seconds.is_finite(),
        "--lease-seconds: expected a positive number of seconds"
    );
    anyhow::ensure!(
        args.max_attempts >= 1,
        "--max-attempts: expected at least 1"
    );
    let mut config = Config::new(
        args.listen,
        args.data.clone(),
        client_token.clone(),
        worker_token.clone(),
    );
    if let Some(url) = &args.store {
        anyhow::ensure!(
            url.starts_with("postgres://") || url.starts_with("postgresql://"),
            "--store: expected a PostgreSQL URL (postgres://user:password@host:port/database); \
             leave it out for the embedded SQLite store in --data"
        );
    }
    config.store = args.store.clone();
    config.objects = args.objects.clone();
    config.lease_ms = (args.lease_seconds * 1000.0) as u64;
    config.max_attempts = args.max_attempts;
    anyhow::ensure!(
        args.blocklist_after >= 1,
        "--blocklist-after: expected at least 1"
    );
    config.blocklist_after = args.blocklist_after;
    config.tls = args.tls_cert.clone().zip(args.tls_key.clone());
    config.limits.max_resolution = args.max_resolution;
    config.limits.max_spp = args.max_spp;
    config.limits.max_frames = args.max_frames;
    if let Some(gib) = args.max_job_memory_gib {
        anyhow::ensure!(
            gib > 0.0 && gib.is_finite(),
            "--max-job-memory-gib: expected a positive size in GiB, got {gib}"
        );
        config.limits.max_memory = (gib * (1u64 << 30) as f64) as u64;
    }
    config.max_upload = args.max_upload_mib << 20;
    config.max_result = args.max_result_mib << 20;
    anyhow::ensure!(
        args.cache_max_gib >= 0.0 && args.cache_max_gib.is_finite(),
        "--cache-max-gib: expected a size in GiB, got {}",
        args.cache_max_gib
    );
    config.cache_max = (args.cache_max_gib * (1u64 << 30) as f64) as u64;
    if let Some(days) = args.retain_days {
        anyhow::ensure!(
            days > 0.0 && days.is_finite(),
            "--retain-days: expected a positive number of days, got {days}"
        );
        config.retain = Some(Duration::from_secs_f64(days * 86400.0));
    }
    config.local_workers = args.local_workers;
    let running = coordinator::start(config).await?;
    let scheme = if args.tls_cert.is_some() {
        "https"
    } else {
        "http"
    };
    let url = format!("{scheme}://{}", running.addr);
    let mut text = format!("tessera coordinator listening on {url}\n");
    text += &format!("data: {}\n", args.data.display());
    if args.store.is_some() {
        text += "job store: PostgreSQL (--store)\n";
    }
    if let Some(objects) = &args.objects {
        text += &format!("objects: {objects}\n");
    }
    text += &format!("dashboard: {url}/ (log in with the client token); API docs: {url}/docs\n");
    if generated {
        text += &format!(
            "tokens (kept in {}):\n  clients: export TESSERA_COORDINATOR={url} TESSERA_CLIENT_TOKEN={client_token}\n  workers: tessera worker --coordinator {url} --token {worker_token}\n",
            args.data.join("tokens.json").display()
        );
    }
    if args.local_workers > 0 {
        text += &format!("started {} local workers\n", args.local_workers);
    }
    crate::print(&text)?;
    running.wait().await
}

#[derive(clap::Args)]
pub struct WorkerArgs {
    /// The coordinator's URL, or several of one farm, comma-separated (coordinators sharing a
    /// store): the next is used when one cannot be reached.
    #[arg(long, env = "TESSERA_COORDINATOR")]
    pub coordinator: String,
    /// The worker token.
    #[arg(long, env = "TESSERA_WORKER_TOKEN", hide_env_values = true)]
    pub token: String,
    /// A name to show in the worker list (default: the host name).
    #[arg(long)]
    pub name: Option<String>,
    /// Tasks to render at once (default: one per core).
    #[arg(long)]
    pub slots: Option<u32>,
    /// Exit when this process stops being the parent (set by `serve --local-workers`).
    #[arg(long, hide = true)]
    pub parent_pid: Option<u32>,
    /// What this worker offers, comma-separated (`big-memory,fast`): jobs submitted with
    /// --require-tags run only on workers with all of theirs.
    #[arg(long, value_delimiter = ',')]
    pub tags: Vec<String>,
    /// A private certificate authority to trust (PEM), for an https:// coordinator.
    #[arg(long, env = "TESSERA_CA")]
    pub ca: Option<PathBuf>,
    /// Fault injection, for testing a farm: fail every task with this message.
    #[arg(long, hide = true)]
    pub fail_tasks_with: Option<String>,
}

pub async fn worker(args: WorkerArgs) -> anyhow::Result<()> {
    let name = args
        .name
        .or_else(worker::hostname)
        .unwrap_or_else(|| "worker".into());
    let slots = args
        .slots
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get() as u32));
    anyhow::ensure!(slots >= 1, "--slots: expected at least 1");
    worker::run(WorkerConfig {
        coordinator: args.coordinator,
        token: args.token,
        name,
        slots,
        parent_pid: args.parent_pid,
        tags: args.tags,
        fail_tasks_with: args.fail_tasks_with,
        ca: args.ca,
    })
    .await
}

#[derive(clap::Args)]
pub struct SubmitArgs {
    /// The scene file (scene.json); it and every file it references are uploaded.
    pub scene: PathBuf,
    #[command(flatten)]
    pub remote: crate::remote::Remote,
    /// Tags a worker must have to run the job's tasks, comma-separated.
    #[arg(long, value_delimiter = ',')]
    pub require_tags: Vec<String>,
    /// Samples per pixel (overrides the scene's integrator.spp).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Random seed (overrides the scene's integrator.seed).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Frames to render: N or A-B (default: every frame of the camera path).
    #[arg(long, value_parser = FrameRange::parse)]
    pub frames: Option<FrameRange>,
    /// Tile size in pixels (does not change the image).
    #[arg(long)]
    pub tile: Option<u32>,
    /// Samples per task (does not change the image).
    #[arg(long)]
    pub samples_per_task: Option<u32>,
    /// Film size WxH (overrides the scene's film; the vertical field of view is kept).
    #[arg(long)]
    pub size: Option<crate::render::Size>,
    /// Adaptive sampling: rounds until the estimated relMSE is at most this (--spp is the
    /// maximum per pixel).
    #[arg(long)]
    pub target_error: Option<f64>,
    /// The rendering method (overrides the scene's integrator.type): one of the registry's,
    /// listed by `tessera methods`.
    #[arg(long, value_parser = crate::render::parse_method)]
    pub integrator: Option<String>,
    /// Build pass artifacts (photon maps, irradiance caches) anew even where the coordinator
    /// has one with the same key.
    #[arg(long)]
    pub no_reuse: bool,
    /// Higher runs first.
    #[arg(long, default_value_t = 0)]
    pub priority: i32,
    /// A name to show (default: the scene's).
    #[arg(long)]
    pub name: Option<String>,
    /// Wait for the job, with a progress bar, and download its frames.
    #[arg(long)]
    pub wait: bool,
    /// Where --wait puts the frames (frame_0001.exr, ...).
    #[arg(short, long, default_value = ".")]
    pub output: PathBuf,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

pub async fn submit(args: SubmitArgs) -> anyhow::Result<()> {
    // Validate locally first: the same checks the coordinator makes, with local paths.
    let scene_path = args.scene.clone();
    let (bundle, desc, scene_name) =
        tokio::task::spawn_blocking(move || Bundle::pack_scene(&scene_path)).await??;
    let settings = RenderSettings {
        spp: args.spp,
        seed: args.seed,
        tile: args.tile,
        samples_per_task: args.samples_per_task,
        size: args.size.map(|s| s.0),
        target_error: args.target_error,
        integrator: args.integrator,
        choice: None,
        reuse: args.no_reuse.then_some(false),
    };
    let frames = args.frames.unwrap_or(FrameRange {
        first: 1,
        last: desc.frame_count(),
    });
    let compiled = job::compile(desc.clone(), &settings, frames, job::Options::admitted())
        .map_err(|e| crate::render::setting_error(&args.scene, e))?;
    for u in &compiled.unread {
        tracing::warn!("{u}");
    }

    let client = args.remote.client()?;
    let tar = bundle.to_tar().map_err(anyhow::Error::msg)?;
    let size = tar.len();
    let info = client
        .upload_bundle(tar)
        .await
        .context("uploading the scene bundle")?;
    let job = client
        .submit(&JobRequest {
            bundle: info.hash.clone(),
            scene: scene_name,
            name: args.name.clone(),
            frames: Some(frames),
            settings,
            priority: args.priority,
            require_tags: args.require_tags.clone(),
        })
        .await
        .context("submitting the job")?;
    crate::print(&format!(
        "job {} queued: {}, frames {}, {}×{} at {} spp, {} tasks (bundle {} files, {} bytes)\nstatus: {}\n",
        job.id,
        job.name,
        job.frames,
        job.width,
        job.height,
        job.spp,
        job.tasks.total.max(job.tasks.planned),
        info.files.len(),
        size,
        client.url(&format!("/v1/jobs/{}", job.id)),
    ))?;
    if !args.wait {
        return Ok(());
    }
    let progress = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(job.tasks.total.max(job.tasks.planned))
    };
    progress.set_style(
        ProgressStyle::with_template(
            "{spinner} {wide_bar} {pos}/{len} tasks {elapsed_precise} eta {eta} {msg}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let status = loop {
        let s = match client.job(job.id).await {
            Ok(s) => s,
            Err(e) if tessera_farm::client::is_transient(&e) => {
                progress.set_message("coordinator unavailable; retrying");
                tokio::time::sleep(Duration::from_secs(1)).await;
                continue;
            }
            Err(e) => return Err(e),
        };
        progress.set_length(s.tasks.total.max(s.tasks.planned));
        progress.set_position(s.tasks.done);
        let frames_done = s.frame_status.iter().filter(|f| f.state == "done").count();
        progress.set_message(format!("{frames_done}/{} frames", s.frames.len()));
        if s.state.is_final() {
            break s;
        }
        tokio::time::sleep(Duration::from_millis(250)).await;
    };
    progress.finish_and_clear();
    match status.state {
        JobState::Done => {}
        JobState::Failed => anyhow::bail!(
            "job {} failed: {}",
            status.id,
            status.error.unwrap_or_default()
        ),
        _ => anyhow::bail!("job {} was {}", status.id, status.state.as_str()),
    }
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("creating {}", args.output.display()))?;
    for frame in status.frames.iter() {
        let bytes = client.frame_exr(status.id, frame).await?;
        let path = args.output.join(job::frame_file_name(frame));
        std::fs::write(&path, bytes).with_context(|| format!("writing {}", path.display()))?;
        crate::print(&format!("wrote {}\n", path.display()))?;
    }
    Ok(())
}

/// `tessera methods`: the registry.
pub fn methods() -> anyhow::Result<()> {
    let mut text = String::new();
    for m in tessera_render::method::methods() {
        text += &format!("{:<8} {}\n{:<8} spp: {}\n", m.name, m.summary, "", m.spp);
        for s in m.settings {
            text += &format!(
                "{:<8}   integrator.{}: {} — {}\n",
                "",
                s.name,
                s.kind.describe(),
                s.doc
            );
        }
    }
    crate::print(&text)
}
