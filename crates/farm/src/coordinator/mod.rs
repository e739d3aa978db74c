//! The coordinator: HTTP API, job store, scheduler, lease reaper, the fold of results into
//! frames and artifacts, disk reclamation, and the supervisor of local workers.
//!
//! Everything that must survive a restart is in the job store (SQLite in `DIR/tessera.db`, or
//! PostgreSQL) and the object store (by default the data directory; see [`crate::objects`]):
//! `bundles/HASH.tar`, `jobs/ID/results/TASK-LEASE.tswf` (a task's result until its frame or
//! pass is done), `jobs/ID/steps/FRAME-STEP.input` and `jobs/ID/steps/FRAME.state` (a frame's
//! checkpoint between steps), `jobs/ID/frame_NNNN.exr`, `cache/KEY.tswf` (pass artifacts).
//! `DIR/spool` is scratch. On start it folds on steps whose tasks all arrived before a
//! restart; leases granted before it keep running and expire as usual.

mod api;
mod auth;
mod disk;
mod error;
mod events;
mod fold;
mod metrics;
mod ops;
mod supervisor;
mod tasks;
pub mod timeouts;
mod users;
mod web;
mod work;

use std::collections::HashMap;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::Context;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use tessera_render::method::Plan;
use tessera_scene::SceneDesc;
use tokio::sync::Notify;

pub use error::{AppError, AppResult};

use crate::job::{self, FrameRange, Limits, RenderSettings};
use crate::protocol::Event;
use crate::store::{Retry, RetryPolicy, Store};
use fold::Folds;
use metrics::Metrics;

/// How long a coordinator joining a farm waits for its object store to show the identity the
/// job store records for its location (see `start`): the coordinator that recorded it writes
/// it a moment later.
const IDENTITY_PATIENCE: std::time::Duration = std::time::Duration::from_secs(5);

/// How a coordinator runs.
#[derive(Debug, Clone)]
pub struct Config {
    pub listen: SocketAddr,
    pub data: PathBuf,
    /// The job store: a PostgreSQL URL (`postgres://…`; coordinators sharing it are one
    /// farm), or `None` for the embedded SQLite in `data`.
    pub store: Option<String>,
    /// The object store: a directory or `s3://bucket/prefix` (coordinators sharing a job store
    /// share it), or `None` for `data`.
    pub objects: Option<String>,
    pub client_token: String,
    pub worker_token: String,
    /// A lease not renewed for this long expires.
    pub lease_ms: u64,
    /// Failures a task may have (on workers not blocklisted for its job) before its job
    /// fails.
    pub max_attempts: u32,
    /// Failures of a job's tasks on one worker that blocklist it for the job.
    pub blocklist_after: u32,
    pub limits: Limits,
    /// Largest scene bundle upload, bytes.
    pub max_upload: usize,
    /// Largest task result upload, bytes.
    pub max_result: u64,
    /// Worker processes to start and supervise.
    pub local_workers: u32,
    /// What local workers log (`RUST_LOG`; default: theirs).
    pub worker_log: Option<String>,
    /// The pass-artifact cache's size cap, bytes (least recently used artifacts go first).
    pub cache_max: u64,
    /// Finished, failed and cancelled jobs are deleted this long after they ended.
    pub retain: Option<Duration>,
    /// Serve HTTPS with this certificate chain and key (PEM files).
    pub tls: Option<(PathBuf, PathBuf)>,
    /// How long the server waits on a client's headers and body.
    pub timeouts: timeouts::Timeouts,
}

impl Config {
    pub fn new(
        listen: SocketAddr,
        data: PathBuf,
        client_token: String,
        worker_token: String,
    ) -> Self {
        Config {
            listen,
            data,
            store: None,
            objects: None,
            client_token,
            worker_token,
            lease_ms: 15_000,
            max_attempts: 3,
            blocklist_after: 3,
            limits: Limits::default(),
            max_upload: 512 << 20,
            max_result: 4 << 30,
            local_workers: 0,
            worker_log: None,
            cache_max: 8 << 30,
            retain: None,
            tls: None,
            timeouts: timeouts::Timeouts::default(),
        }
    }

    /// When failed tasks are retried and jobs fail.
    pub fn retry_policy(&self) -> RetryPolicy {
        RetryPolicy {
            max_attempts: self.max_attempts,
            blocklist_after: self.blocklist_after,
            alive_ms: 2 * self.lease_ms as i64,
        }
    }
}

/// Shared state of the running coordinator.
pub struct App {
    pub config: Config,
    pub store: Store,
    /// Bundles, results, checkpoints, frames and artifacts.
    pub objects: crate::objects::Objects,
    /// This coordinator among those sharing the store: the owner of its claims.
    pub id: String,
    metrics: Metrics,
    /// Woken when tasks are queued, for long-polling lease requests.
    work: Notify,
    /// Becomes true when the coordinator stops (ends long polls at once).
    stopping: tokio::sync::watch::Receiver<bool>,
    /// Jobs' scenes and plans, for folding.
    jobs: Mutex<HashMap<i64, Arc<JobPlan>>>,
    /// Frames and passes being folded.
    folds: Folds,
    /// To the fold thread.
    fold_requests: Mutex<std::sync::mpsc::Sender<fold::FoldRequest>>,
    /// What changed, for dashboards (`/v1/events`).
    events: tokio::sync::broadcast::Sender<Event>,
    /// Whether the reaper last found the job store unreachable.
    store_down: std::sync::atomic::AtomicBool,
    /// No lease expires before this (ms since the epoch): a lease period after the job store
    /// came back, so that workers whose heartbeats failed meanwhile can renew theirs.
    expire_after: std::sync::atomic::AtomicI64,
}

/// A job's scene with its settings applied, and its method's plan.
pub struct JobPlan {
    pub desc: SceneDesc,
    pub settings: RenderSettings,
    pub frames: FrameRange,
    pub plan: Box<dyn Plan>,
}

/// Milliseconds since the Unix epoch.
pub fn now_ms() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as i64)
}

/// What handlers share.
impl App {
    /// A worker is alive if seen within two lease periods.
    pub(super) fn alive_ms(&self) -> i64 {
        2 * self.config.lease_ms as i64
    }

    /// An object as a response body, streamed; `None` if there is none.
    pub(super) async fn send_object(
        &self,
        key: &str,
        content_type: &'static str,
    ) -> AppResult<Option<Response>> {
        let Some((len, stream)) = self.objects.stream(key).await? else {
            return Ok(None);
        };
        let body = axum::body::Body::from_stream(stream);
        Ok(Some(
            (
                [
                    (header::CONTENT_TYPE, content_type.to_string()),
                    (header::CONTENT_LENGTH, len.to_string()),
                ],
                body,
            )
                .into_response(),
        ))
    }
}

/// Where things live in the object store.
impl App {
    fn bundle_key(&self, hash: &str) -> String {
        format!("bundles/{hash}.tar")
    }
    fn job_prefix(&self, job: i64) -> String {
        format!("jobs/{job}")
    }
    fn result_key(&self, job: i64, task: i64, lease: i64) -> String {
        format!("jobs/{job}/results/{task}-{lease}.tswf")
    }
    /// What step `step` of frame `frame` reads besides the artifacts.
    fn input_key(&self, job: i64, frame: u32, step: u32) -> String {
        format!("jobs/{job}/steps/{frame}-{step}.input")
    }
    /// A frame's checkpoint between steps.
    fn checkpoint_key(&self, job: i64, frame: u32) -> String {
        format!("jobs/{job}/steps/{frame}.state")
    }
    /// A finished frame's EXR.
    fn frame_key(&self, job: i64, frame: u32) -> String {
        format!("jobs/{job}/{}", job::frame_file_name(frame))
    }
    /// A finished frame's PNG preview, beside its EXR.
    fn preview_key(&self, job: i64, frame: u32) -> String {
        self.frame_key(job, frame).replace(".exr", ".png")
    }
    /// A pass artifact with this key.
    fn artifact_key(&self, key: &str) -> String {
        format!("cache/{key}.tswf")
    }

    /// The cached artifact with this key, if its object is still there.
    fn cached(&self, key: &str) -> anyhow::Result<Option<crate::store::CacheEntry>> {
        match self.store.cached(key)? {
            Some(e) if self.objects.exists(&e.path)? => Ok(Some(e)),
            _ => Ok(None),
        }
    }

    /// A job's scene and plan, read from its bundle and planned once (cached).
    fn job_plan(&self, job: i64) -> anyhow::Result<Arc<JobPlan>> {
        if let Some(p) = self
            .jobs
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get(&job)
        {
            return Ok(p.clone());
        }
        let (hash, scene, settings, frames) = self
            .store
            .job_source(job)?
            .with_context(|| format!("job {job} is not in the store"))?;
        let bytes = self
            .objects
            .get(&self.bundle_key(&hash))?
            .with_context(|| format!("bundle {hash} of job {job} is not in the object store"))?;
        let compiled = job::compile_bundled(
            &bytes,
            &scene,
            &settings,
            Some(frames),
            job::Options::admitted(),
        )
        .map_err(anyhow::Error::msg)?;
        // Its plan from features alone is not the one it will run: none is kept.
        anyhow::ensure!(
            !compiled.awaits_choice(),
            "job {job} awaits auto's choice: its pilot has not run yet"
        );
        let p = Arc::new(JobPlan {
            desc: compiled.job.desc,
            settings,
            frames,
            plan: compiled.plan,
        });
        self.jobs
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(job, p.clone());
        Ok(p)
    }

    /// Forgets what is kept in memory for a job that ended.
    fn forget_job(&self, job: i64) {
        self.jobs
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(&job);
        self.folds.forget_job(job);
    }

    /// Takes back expired leases, once.
    fn reap(&self) {
        use std::sync::atomic::Ordering::Relaxed;
        let now = now_ms();
        if self.store_down.load(Relaxed) {
            if self.store.gauges().is_err() {
                return;
            }
            // Every heartbeat failed while the store was away: the leases that ran out then
            // were not given up by their workers.
            self.store_down.store(false, Relaxed);
            self.expire_after
                .store(now + self.config.lease_ms as i64, Relaxed);
            tracing::info!("job store reachable again: no lease expires for one lease period");
        }
        if now < self.expire_after.load(Relaxed) {
            self.tend_claims();
            return;
        }
        match self.store.expire(now, &self.config.retry_policy()) {
            Ok(expired) => {
                for (task, outcome) in expired {
                    self.metrics.count_expired();
                    match outcome {
                        Retry::JobFailed(msg) => tracing::warn!(task, error = %msg, "job failed"),
                        _ => tracing::warn!(task, "lease expired; task requeued"),
                    }
                    self.wake_workers();
                }
            }
            Err(e) => {
                self.store_down.store(true, Relaxed);
                tracing::error!(error = %e, "expiring leases");
                return;
            }
        }
        match self.store.fail_stranded(now, &self.config.retry_policy()) {
            Ok(failed) => {
                for (job, error) in failed {
                    tracing::warn!(job, error = %error, "job failed");
                    self.emit(Event::Job { id: job });
                }
            }
            Err(e) => tracing::error!(error = %e, "failing jobs no worker can run"),
        }
        self.tend_claims();
    }

    /// Wakes the workers waiting for a lease, here and (through the store) at every
    /// coordinator sharing it: work was queued, or a job may lease again.
    pub(super) fn wake_workers(&self) {
        self.work.notify_waiters();
        if let Err(e) = self.store.announce_work() {
            tracing::warn!(error = %e, "announcing work to the other coordinators");
        }
    }

    /// How long a claim lasts unless renewed (the reaper renews them several times a lease).
    fn claim_ms(&self) -> i64 {
        self.config.lease_ms.max(2000) as i64
    }

    /// Renews this coordinator's claims. With a shared store, also folds what it claims (the
    /// results that reached other coordinators) and the finished steps nobody folds (a
    /// coordinator that died left them).
    fn tend_claims(&self) {
        let held = match self.store.renew_claims(&self.id, now_ms(), self.claim_ms()) {
            Ok(held) => held,
            Err(e) => {
                tracing::error!(error = %e, "renewing claims");
                return;
            }
        };
        if !self.store.is_shared() {
            return;
        }
        for key in held.iter().filter_map(|n| fold::claimed_step(n)) {
            self.spawn_fold(key);
        }
        match self.store.finished_steps() {
            Ok(steps) => {
                for key in steps {
                    if !held.contains(&fold::claim_name(key)) {
                        self.spawn_fold(key);
                    }
                }
            }
            Err(e) => tracing::error!(error = %e, "looking for finished steps"),
        }
    }
}

fn store_listener(app: &std::sync::Weak<App>) {
    let Some(strong) = app.upgrade() else { return };
    let weak = app.clone();
    strong.store.on_work(Arc::new(move || {
        if let Some(app) = weak.upgrade() {
            app.work.notify_waiters();
        }
    }));
}

/// A running coordinator: its address, its state, and a way to stop it.
pub struct Running {
    pub addr: SocketAddr,
    pub app: Arc<App>,
    shutdown: tokio::sync::watch::Sender<bool>,
    server: tokio::task::JoinHandle<std::io::Result<()>>,
}

impl Running {
    /// Stops serving and the local workers, and waits for the server to finish.
    pub async fn stop(self) -> anyhow::Result<()> {
        let _ = self.shutdown.send(true);
        self.server.await??;
        Ok(())
    }

    /// Serves until the server stops (Ctrl-C or SIGTERM stop it gracefully).
    pub async fn wait(self) -> anyhow::Result<()> {
        let tx = self.shutdown.clone();
        tokio::spawn(async move {
            shutdown_signal().await;
            tracing::info!("shutting down");
            let _ = tx.send(true);
        });
        self.server.await??;
        Ok(())
    }
}

async fn shutdown_signal() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        if let Ok(mut term) = signal(SignalKind::terminate()) {
            tokio::select! {
                _ = tokio::signal::ctrl_c() => {}
                _ = term.recv() => {}
            }
            return;
        }
    }
    let _ = tokio::signal::ctrl_c().await;
}

/// Makes ring rustls's cryptography for this process (TLS for the coordinator and for
/// clients and workers); idempotent.
pub fn use_ring_for_tls() {
    let _ = rustls::crypto::ring::default_provider().install_default();
}

/// Opens the store, resumes unfinished work, binds and starts serving.
pub async fn start(config: Config) -> anyhow::Result<Running> {
    use_ring_for_tls();
    private_dir(&config.data)
        .with_context(|| format!("creating the data directory {}", config.data.display()))?;
    let store = match &config.store {
        Some(url) => Store::open_at(crate::store::Location::Postgres(url))
            .context("opening the job store (--store)")?,
        None => {
            // Sessions and CSRF tokens live in it: readable by this user alone (SQLite
            // gives its journal files the database's mode).
            let db = config.data.join("tessera.db");
            private_file(&db)
                .with_context(|| format!("creating the job store {}", db.display()))?;
            Store::open(&db).with_context(|| format!("opening the job store {}", db.display()))?
        }
    };
    let listener = tokio::net::TcpListener::bind(config.listen)
        .await
        .with_context(|| format!("cannot listen on {}", config.listen))?;
    let addr = listener.local_addr()?;
    let (shutdown, mut stop) = tokio::sync::watch::channel(false);
    let (fold_tx, fold_rx) = std::sync::mpsc::channel();
    if !store.is_shared() {
        // A store only this coordinator opens: the claims in it are its previous run's.
        store.forget_claims()?;
    }
    // Unique among the coordinators alive (no two listen on one host's address), and the
    // same after a restart, so that a restarted coordinator goes on with its own claims.
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_owned())
        .unwrap_or_else(|_| "coordinator".into());
    let id = format!("{host}/{addr}");
    tracing::info!(coordinator = %id, shared = store.is_shared(), "job store open");
    let objects = open_objects(&config, &id)?;
    objects.probe(&id)?;
    // A store without an id takes the one the job store records for its location, if another
    // coordinator is making it now, so that two first coordinators agree; that one writes it
    // into the store a moment after recording it, so the same store shows it, and a store
    // that never does is another one at the same path.
    let identity = objects.identity(|| {
        let candidate = random_token()?;
        let id = store.adopt_objects(&candidate, &objects.location)?;
        if id != candidate {
            objects.await_identity(&id, IDENTITY_PATIENCE)?;
        }
        Ok(id)
    })?;
    if let Some((recorded, location)) = store.check_objects(&identity, &objects.location)? {
        anyhow::bail!(
            "the object store {} (id {identity}) is not the one this farm's job store records: {location} (id {recorded}); coordinators sharing a job store must share its object store (--objects)",
            objects.location
        );
    }
    tracing::info!(objects = %objects.location, "object store writable");
    let app = Arc::new(App {
        stopping: shutdown.subscribe(),
        config,
        store,
        objects,
        id,
        metrics: Metrics::default(),
        work: Notify::new(),
        jobs: Mutex::new(HashMap::new()),
        folds: Folds::default(),
        fold_requests: Mutex::new(fold_tx),
        events: tokio::sync::broadcast::channel(events::CAPACITY).0,
        store_down: false.into(),
        expire_after: 0.into(),
    });
    fold::start_thread(&app, fold_rx)?;
    {
        // Work queued by another coordinator wakes the workers waiting here.
        let app = Arc::downgrade(&app);
        store_listener(&app);
    }

    // Resume: steps whose last task arrived just before a restart.
    for key in app.store.finished_steps()? {
        tracing::info!(
            job = key.job,
            frame = key.frame,
            step = key.step,
            "folding a step finished before the restart"
        );
        app.spawn_fold(key);
    }

    // The reaper: expired leases go back to the queue; old jobs go when they expire.
    {
        let app = app.clone();
        let mut stop = shutdown.subscribe();
        let period = Duration::from_millis((app.config.lease_ms / 4).clamp(100, 1000));
        tokio::spawn(async move {
            let mut last_sweep = std::time::Instant::now();
            loop {
                tokio::select! {
                    _ = tokio::time::sleep(period) => {
                        app.reap();
                        if last_sweep.elapsed() > Duration::from_secs(60) {
                            last_sweep = std::time::Instant::now();
                            let app = app.clone();
                            tokio::task::spawn_blocking(move || app.sweep_expired_jobs());
                        }
                    }
                    _ = stop.changed() => break,
                }
            }
        });
    }
    {
        let app = app.clone();
        tokio::task::spawn_blocking(move || app.sweep_expired_jobs());
    }
    if app.config.local_workers > 0 {
        supervisor::spawn(&app, addr, shutdown.subscribe());
    }
    let router = api::router(app.clone());
    let handle = axum_server::Handle::new();
    {
        let handle = handle.clone();
        tokio::spawn(async move {
            let _ = stop.changed().await;
            handle.graceful_shutdown(Some(Duration::from_secs(10)));
        });
    }
    let listener = listener.into_std()?;
    let timeouts = app.config.timeouts;
    let server = match app.config.tls.clone() {
        None => {
            let mut server = axum_server::from_tcp(listener)?.handle(handle);
            timeouts::configure(server.http_builder(), timeouts);
            tokio::spawn(async move { server.serve(router.into_make_service()).await })
        }
        Some((cert, key)) => {
            let tls = axum_server::tls_rustls::RustlsConfig::from_pem_file(&cert, &key)
                .await
                .with_context(|| {
                    format!(
                        "reading the TLS certificate {} and key {} (PEM)",
                        cert.display(),
                        key.display()
                    )
                })?;
            let mut server = axum_server::from_tcp_rustls(listener, tls)?.handle(handle);
            timeouts::configure(server.http_builder(), timeouts);
            tokio::spawn(async move { server.serve(router.into_make_service()).await })
        }
    };
    Ok(Running {
        addr,
        app,
        shutdown,
        server,
    })
}

/// The object store of `config`, with a spool directory of this coordinator's (`id`) in the
/// data directory, emptied: what a previous run left there was never stored.
fn open_objects(config: &Config, id: &str) -> anyhow::Result<crate::objects::Objects> {
    let spool = config.data.join("spool").join(id.replace(['/', ':'], "_"));
    if spool.is_dir() {
        std::fs::remove_dir_all(&spool)
            .with_context(|| format!("emptying the spool directory {}", spool.display()))?;
    }
    let location = match &config.objects {
        Some(l) => l.clone(),
        None => config.data.to_string_lossy().into_owned(),
    };
    crate::objects::Objects::open(&location, &spool)
}

/// Tokens from flags or the environment, or generated once and kept in `DIR/tokens.json` so a
/// restarted coordinator accepts the same workers and clients. Returns (client, worker, generated).
pub fn tokens(
    data: &Path,
    client: Option<String>,
    worker: Option<String>,
) -> anyhow::Result<(String, String, bool)> {
    if let (Some(c), Some(w)) = (&client, &worker) {
        return Ok((c.clone(), w.clone(), false));
    }
    let path = data.join("tokens.json");
    #[derive(serde::Serialize, serde::Deserialize)]
    struct Saved {
        client: String,
        worker: String,
    }
    let saved = match std::fs::read(&path) {
        Ok(bytes) => serde_json::from_slice::<Saved>(&bytes).with_context(|| {
            format!(
                "{}: expected {{\"client\": ..., \"worker\": ...}}",
                path.display()
            )
        })?,
        // Only a missing file means "none yet": a file that cannot be read is an error, not a
        // reason to issue new tokens that lock out every worker and client holding the old.
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            std::fs::create_dir_all(data)
                .with_context(|| format!("creating the data directory {}", data.display()))?;
            let saved = Saved {
                client: random_token()?,
                worker: random_token()?,
            };
            std::fs::write(&path, serde_json::to_vec_pretty(&saved)?)
                .with_context(|| format!("writing {}", path.display()))?;
            #[cfg(unix)]
            {
                use std::os::unix::fs::PermissionsExt;
                let _ = std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600));
            }
            saved
        }
        Err(e) => return Err(anyhow::anyhow!("reading {}: {e}", path.display())),
    };
    Ok((
        client.unwrap_or(saved.client),
        worker.unwrap_or(saved.worker),
        true,
    ))
}

/// Creates `dir` (and its parents) if need be; a directory this creates is readable by this
/// user alone.
fn private_dir(dir: &Path) -> std::io::Result<()> {
    let mut builder = std::fs::DirBuilder::new();
    builder.recursive(true);
    #[cfg(unix)]
    std::os::unix::fs::DirBuilderExt::mode(&mut builder, 0o700);
    builder.create(dir)
}

/// Creates `file` empty if it does not exist, and makes it readable and writable by this
/// user alone.
fn private_file(file: &Path) -> std::io::Result<()> {
    let mut options = std::fs::OpenOptions::new();
    options.create(true).append(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    options.open(file)?;
    #[cfg(unix)]
    std::fs::set_permissions(file, std::os::unix::fs::PermissionsExt::from_mode(0o600))?;
    Ok(())
}

/// 128 random bits from the OS, in hex.
pub fn random_token() -> anyhow::Result<String> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes).map_err(|e| anyhow::anyhow!("no OS randomness: {e}"))?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

#[cfg(test)]
mod tests {
    use super::tokens;

    #[test]
    fn tokens_are_generated_once_and_kept() {
        let dir = tempfile::tempdir().expect("temp dir");
        let data = dir.path().join("data");
        let (c, w, _) = tokens(&data, None, None).expect("generated");
        assert!(c != w && c.len() == 32, "{c} {w}");
        let (c2, w2, _) = tokens(&data, None, None).expect("kept");
        assert_eq!((c2, w2), (c, w));
    }

    /// A data directory that cannot be made, or a tokens file that cannot be read, is an error
    /// naming it: new tokens would lock out every worker and client holding the old ones.
    #[test]
    fn a_data_directory_or_tokens_file_that_cannot_be_used_is_named() {
        let dir = tempfile::tempdir().expect("temp dir");
        let file = dir.path().join("a-file");
        std::fs::write(&file, b"x").expect("file");
        let e = format!(
            "{:#}",
            tokens(&file.join("data"), None, None).expect_err("refused")
        );
        assert!(e.contains("a-file/data/tokens.json"), "{e}");
        let data = dir.path().join("data");
        std::fs::create_dir_all(data.join("tokens.json")).expect("a directory where the file goes");
        let e = format!("{:#}", tokens(&data, None, None).expect_err("refused"));
        assert!(e.contains("reading") && e.contains("tokens.json"), "{e}");
    }
}
