//! The coordinator: HTTP API, job store, scheduler, lease reaper, stitcher and the
//! supervisor of local workers.
//!
//! Everything that must survive a restart is in the SQLite store and the data directory
//! (`DIR/tessera.db`, `DIR/bundles/HASH.tar`, `DIR/jobs/ID/tiles/TASK-LEASE.tsum`,
//! `DIR/jobs/ID/frame_NNNN.exr`). On start it stitches frames whose tiles all arrived before a
//! restart; leases granted before it keep running and expire as usual.

mod api;
mod error;
mod metrics;
mod supervisor;

use std::collections::HashMap;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering::Relaxed;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::Context;
use tessera_render::integrator::sppm::SppmSettings;
use tessera_scene::SceneDesc;
use tokio::sync::Notify;

pub use error::{AppError, AppResult};

use crate::bdpt;
use crate::bundle::Bundle;
use crate::codec;
use crate::job::{
    self, FrameRange, Limits, PassKind, RenderSettings, TaskKind, TaskOutput, TaskSpec,
};
use crate::passes::{self, PassOutput, PassPlan};
use crate::progressive::{self, Adaptive, Round, next_round};
use crate::sppm;
use crate::store::{Artifact, Retry, Store};
use crate::store::{CacheEntry, NextStage};
use metrics::Metrics;

/// How a coordinator runs.
#[derive(Debug, Clone)]
pub struct Config {
    pub listen: SocketAddr,
    pub data: PathBuf,
    pub client_token: String,
    pub worker_token: String,
    /// A lease not renewed for this long expires.
    pub lease_ms: u64,
    /// Leases a task may have before its job fails.
    pub max_attempts: u32,
    pub limits: Limits,
    /// Largest scene bundle upload, bytes.
    pub max_upload: usize,
    /// Worker processes to start and supervise.
    pub local_workers: u32,
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
            client_token,
            worker_token,
            lease_ms: 15_000,
            max_attempts: 3,
            limits: Limits::default(),
            max_upload: 512 << 20,
            local_workers: 0,
        }
    }
}

/// Shared state of the running coordinator.
pub struct App {
    pub config: Config,
    pub store: Store,
    metrics: Metrics,
    /// Woken when tasks are queued, for long-polling lease requests.
    work: Notify,
    /// Becomes true when the coordinator stops (ends long polls at once).
    stopping: tokio::sync::watch::Receiver<bool>,
    /// Scene descriptions of jobs (with their settings applied), for stitching.
    descs: Mutex<HashMap<i64, Arc<JobScene>>>,
}

/// A job's scene with its settings applied, the adaptive rule they ask for, and its passes.
struct JobScene {
    desc: SceneDesc,
    settings: RenderSettings,
    frames: FrameRange,
    adaptive: Option<Adaptive>,
    plan: Option<PassPlan>,
    /// SPPM's settings, for an SPPM job.
    sppm: Option<SppmSettings>,
    /// A BDPT job: frames are sample ranges over the whole film (see `crate::bdpt`).
    bdpt: bool,
}

/// Writes `path` whole or not at all (a temporary file renamed over it), creating its
/// directory.
fn replace_file(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).with_context(|| dir.display().to_string())?;
    }
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, bytes).with_context(|| tmp.display().to_string())?;
    std::fs::rename(&tmp, path).with_context(|| path.display().to_string())
}

/// Milliseconds since the Unix epoch.
pub fn now_ms() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_millis() as i64)
}

impl App {
    fn bundle_path(&self, hash: &str) -> PathBuf {
        self.config.data.join("bundles").join(format!("{hash}.tar"))
    }
    fn job_dir(&self, job: i64) -> PathBuf {
        self.config.data.join("jobs").join(job.to_string())
    }
    fn tile_path(&self, job: i64, task: i64, lease: i64) -> PathBuf {
        self.job_dir(job)
            .join("tiles")
            .join(format!("{task}-{lease}.tsum"))
    }
    fn frame_path(&self, job: i64, frame: u32) -> PathBuf {
        self.job_dir(job).join(job::frame_file_name(frame))
    }
    /// `path` relative to the data directory, as the store records files.
    fn relative(&self, path: &Path) -> String {
        path.strip_prefix(&self.config.data)
            .unwrap_or(path)
            .to_string_lossy()
            .into_owned()
    }
    /// Where a pass artifact with this key lives.
    fn artifact_path(&self, key: &str) -> PathBuf {
        self.config.data.join("cache").join(format!("{key}.bin"))
    }

    /// The cached artifact with this key, if its file is still there.
    fn cached(&self, key: &str) -> crate::store::Result<Option<CacheEntry>> {
        Ok(self
            .store
            .cached(key)?
            .filter(|e| self.config.data.join(&e.path).is_file()))
    }

    /// The scene of a job with its settings applied, read from its bundle once (cached).
    fn job_scene(&self, job: i64) -> anyhow::Result<Arc<JobScene>> {
        if let Some(d) = self
            .descs
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get(&job)
        {
            return Ok(d.clone());
        }
        let (hash, scene, settings, frames) = self
            .store
            .job_source(job)?
            .with_context(|| format!("job {job} is not in the store"))?;
        let bytes = std::fs::read(self.bundle_path(&hash))
            .with_context(|| format!("bundle {hash} of job {job}"))?;
        let bundle = Bundle::from_tar(&bytes).map_err(anyhow::Error::msg)?;
        let mut desc = bundle.load(&scene)?;
        job::apply(&mut desc, &settings, frames, &Limits::default()).map_err(anyhow::Error::msg)?;
        let analysis = tessera_render::analysis::analyze(&desc);
        let scene = Arc::new(JobScene {
            adaptive: job::adaptive_rule(&desc, &settings),
            plan: passes::plan(&desc, &analysis, frames),
            sppm: (analysis.integrator == tessera_scene::IntegratorKind::Sppm)
                .then(|| sppm::settings(&desc).1),
            bdpt: bdpt::film_tasks(analysis.integrator),
            desc,
            settings,
            frames,
        });
        self.descs
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(job, scene.clone());
        Ok(scene)
    }

    /// Decodes the accepted results of a frame so far, in stitch order.
    fn frame_outputs(&self, job: i64, frame: u32) -> anyhow::Result<Vec<TaskOutput>> {
        self.decode_results(job, frame, TaskKind::Tile, codec::decode)
    }

    /// Decodes the accepted results of a frame's tasks of `kind` so far, in stitch order.
    fn decode_results<T>(
        &self,
        job: i64,
        frame: u32,
        kind: TaskKind,
        decode: impl Fn(&[u8], &TaskSpec) -> Result<T, String>,
    ) -> anyhow::Result<Vec<T>> {
        let results = self.store.frame_results(job, frame, kind)?;
        results
            .iter()
            .map(|(task, lease, spec)| {
                let path = self.tile_path(job, *task, *lease);
                let bytes = std::fs::read(&path).with_context(|| path.display().to_string())?;
                decode(&bytes, spec).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
            })
            .collect()
    }

    /// A BDPT frame from the sample ranges accepted so far: the image and its counters, and
    /// how many of the frame's tasks they are.
    fn bdpt_frame(
        &self,
        job: i64,
        frame: u32,
        desc: &SceneDesc,
    ) -> anyhow::Result<(tessera_render::Image, tessera_render::RayStats, usize)> {
        let outputs = self.decode_results(job, frame, TaskKind::Bdpt, bdpt::decode_output)?;
        let (sums, stats) = bdpt::merge(&outputs, desc);
        let image = sums.image(job::camera(desc, frame).exposure);
        Ok((image, stats, outputs.len()))
    }

    /// A frame's tasks are all done (blocking): an adaptive frame may need another round of
    /// tasks (the same choice `tessera render` makes, from the same sums); otherwise the frame
    /// is stitched and its EXR and PNG written. Returns whether the job is now done.
    fn finish_frame(&self, job: i64, frame: u32) -> anyhow::Result<bool> {
        let scene = self.job_scene(job)?;
        if let Some(s) = &scene.sppm {
            return self.finish_sppm_iteration(job, frame, &scene.desc, s);
        }
        if scene.bdpt {
            let (image, stats, done) = self.bdpt_frame(job, frame, &scene.desc)?;
            let planned = bdpt::tasks(&scene.desc, &scene.settings, frame).len();
            anyhow::ensure!(
                done == planned,
                "bdpt frame {frame}: {done} of its {planned} tasks done"
            );
            return self.write_frame(job, frame, &scene.desc, &image, &stats, &[], None);
        }
        let desc = &scene.desc;
        let outputs = self.frame_outputs(job, frame)?;
        let (tiles, stats) = job::merge_tiles(&outputs);
        let image = tessera_render::Image::from_tiles(desc.film.width, desc.film.height, &tiles);
        let mut extra = Vec::new();
        let mut estimate = None;
        if let Some(rule) = &scene.adaptive {
            let pixels = desc.film.width as f64 * desc.film.height as f64;
            match next_round(&tiles, pixels, rule, std::time::Duration::ZERO) {
                Round::Render(plan) => {
                    let tasks: Vec<TaskSpec> = plan
                        .iter()
                        .map(|&(i, end)| {
                            let t = &tiles[i];
                            TaskSpec {
                                kind: job::TaskKind::Tile,
                                frame,
                                tile_index: i as u32,
                                x0: t.tile.x0,
                                y0: t.tile.y0,
                                x1: t.tile.x1,
                                y1: t.tile.y1,
                                sample_start: t.samples.end,
                                sample_end: end,
                            }
                        })
                        .collect();
                    self.store.add_tasks(job, frame, &tasks)?;
                    tracing::info!(job, frame, tasks = tasks.len(), "adaptive round queued");
                    self.work.notify_waiters();
                    return Ok(false);
                }
                Round::Stop(reason) => {
                    let e = tessera_render::metrics::estimated_rel_mse(&image);
                    extra = progressive::adaptive_metadata(e, &tiles, reason, rule);
                    estimate = Some(e);
                }
            }
        }
        self.write_frame(job, frame, desc, &image, &stats, &extra, estimate)
    }

    /// An SPPM frame's iteration is done (blocking): fold its tasks' sums into the frame's
    /// state, then queue the next iteration (with its radii) or write the frame. A restart
    /// between any two steps repeats only what was not written.
    fn finish_sppm_iteration(
        &self,
        job: i64,
        frame: u32,
        desc: &SceneDesc,
        s: &SppmSettings,
    ) -> anyhow::Result<bool> {
        let state_path = self.sppm_path(job, frame, "state");
        let mut state = match std::fs::read(&state_path) {
            Ok(bytes) => sppm::decode_state(&bytes)
                .map_err(|e| anyhow::anyhow!("{}: {e}", state_path.display()))?,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => sppm::FrameState::new(desc, s),
            Err(e) => return Err(e).context(state_path.display().to_string()),
        };
        let t = state.state.iterations;
        let pixels = desc.film.width * desc.film.height;
        let results = self.store.sppm_results(job, frame, t)?;
        if !results.is_empty() {
            let outputs = results
                .iter()
                .map(|(task, lease, spec)| {
                    let path = self.tile_path(job, *task, *lease);
                    let bytes = std::fs::read(&path).with_context(|| path.display().to_string())?;
                    sppm::decode_output(&bytes, spec, pixels)
                        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
                })
                .collect::<anyhow::Result<Vec<_>>>()?;
            anyhow::ensure!(
                outputs.len() == sppm::iteration_tasks(desc, frame, t).len(),
                "sppm iteration {t} of frame {frame}: {} of its tasks done",
                outputs.len()
            );
            state.fold(&outputs, s.alpha).map_err(anyhow::Error::msg)?;
            replace_file(&state_path, &sppm::encode_state(&state))?;
            // The previous iteration's radii are read by nobody now.
            let _ = std::fs::remove_file(self.sppm_path(job, frame, &format!("{t}.radii")));
        }
        let t = state.state.iterations;
        if t < s.iterations {
            let radii = self.sppm_path(job, frame, &format!("{t}.radii"));
            replace_file(&radii, &sppm::encode_radii(&state.state.radii2()))?;
            let tasks = sppm::iteration_tasks(desc, frame, t);
            self.store.add_tasks(job, frame, &tasks)?;
            tracing::debug!(
                job,
                frame,
                iteration = t,
                tasks = tasks.len(),
                "sppm iteration queued"
            );
            self.work.notify_waiters();
            return Ok(false);
        }
        let exposure = job::camera(desc, frame).exposure;
        let image = state.state.image(exposure);
        let done = self.write_frame(
            job,
            frame,
            desc,
            &image,
            &state.stats,
            &sppm::metadata(s),
            None,
        )?;
        let _ = std::fs::remove_file(&state_path);
        Ok(done)
    }

    /// An SPPM frame's estimate after the iterations folded so far (black before the first).
    fn sppm_preview(
        &self,
        job: i64,
        frame: u32,
        desc: &SceneDesc,
    ) -> anyhow::Result<tessera_render::Image> {
        let path = self.sppm_path(job, frame, "state");
        Ok(match std::fs::read(&path) {
            Ok(bytes) => sppm::decode_state(&bytes)
                .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?
                .state
                .image(job::camera(desc, frame).exposure),
            Err(_) => tessera_render::Image::new(desc.film.width, desc.film.height),
        })
    }

    /// Where an SPPM frame's state (`what` = "state") or radii ("T.radii") live.
    fn sppm_path(&self, job: i64, frame: u32, what: &str) -> PathBuf {
        self.job_dir(job)
            .join("sppm")
            .join(format!("{frame}.{what}"))
    }

    /// Writes a frame's EXR and PNG, records them and marks the frame done. Returns whether
    /// the job is now done.
    #[allow(clippy::too_many_arguments)]
    fn write_frame(
        &self,
        job: i64,
        frame: u32,
        desc: &SceneDesc,
        image: &tessera_render::Image,
        stats: &tessera_render::RayStats,
        extra: &[(String, String)],
        estimate: Option<f64>,
    ) -> anyhow::Result<bool> {
        let path = self.frame_path(job, frame);
        let tmp = path.with_extension("tmp.exr");
        job::write_frame(&tmp, desc, frame, image, stats, extra)?;
        std::fs::rename(tmp.with_extension("png"), path.with_extension("png"))?;
        std::fs::rename(&tmp, &path)?;
        let mut files = Vec::new();
        for (kind, file) in [("exr", path.clone()), ("png", path.with_extension("png"))] {
            let bytes = std::fs::read(&file)?;
            files.push(Artifact {
                kind: kind.into(),
                path: self.relative(&file),
                bytes: bytes.len() as u64,
                sha256: crate::bundle::hash(&bytes),
            });
        }
        self.metrics.frames_stitched.fetch_add(1, Relaxed);
        let job_done = self
            .store
            .frame_stitched(job, frame, &files, estimate, now_ms())?;
        tracing::info!(job, frame, path = %path.display(), job_done, "frame stitched");
        if job_done {
            self.descs
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .remove(&job);
        }
        Ok(job_done)
    }

    /// A pass's tasks are all done (blocking): merge their outputs in order into the artifact,
    /// write it under its key, and queue what follows (the next pass, or every frame's tiles).
    fn finish_pass(&self, job: i64, pass: PassKind) -> anyhow::Result<()> {
        let scene = self.job_scene(job)?;
        let mut outputs = Vec::new();
        for (task, lease, spec) in self.store.pass_results(job, pass)? {
            let path = self.tile_path(job, task, lease);
            let bytes = std::fs::read(&path).with_context(|| path.display().to_string())?;
            let out = passes::decode_output(&bytes, &spec)
                .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
            outputs.push((spec.kind, out));
        }
        let plan = || {
            scene
                .plan
                .as_ref()
                .with_context(|| format!("job {job} has a {} pass but no pass plan", pass.as_str()))
        };
        let (key, bytes) = match pass {
            PassKind::Photons => {
                let plan = plan()?;
                let maps = passes::merge_photons(
                    &scene.desc,
                    &plan.settings,
                    outputs.iter().filter_map(|(k, o)| match o {
                        PassOutput::Photons(p) => Some((*k, p.as_slice())),
                        _ => None,
                    }),
                );
                (plan.photons_key.clone(), passes::encode_maps(&maps))
            }
            PassKind::Records => {
                let records: Vec<_> = outputs
                    .iter()
                    .flat_map(|(_, o)| match o {
                        PassOutput::Records(r) => r.as_slice(),
                        _ => &[],
                    })
                    .copied()
                    .collect();
                let key = plan()?
                    .records_key
                    .clone()
                    .context("a records pass without a records key")?;
                (key, passes::encode_records(&records))
            }
            PassKind::Subsurface => {
                let e: Vec<_> = outputs
                    .iter()
                    .flat_map(|(_, o)| match o {
                        PassOutput::Irradiance(e) => e.as_slice(),
                        _ => &[],
                    })
                    .copied()
                    .collect();
                (
                    crate::subsurface::key(&scene.desc),
                    crate::subsurface::encode(&e),
                )
            }
        };
        let path = self.artifact_path(&key);
        // Jobs that build the same key at once (reuse disabled) write their own temporary
        // file; the renames replace one identical artifact with another.
        let tmp = path.with_extension(format!("{job}.tmp"));
        std::fs::write(&tmp, &bytes).with_context(|| tmp.display().to_string())?;
        std::fs::rename(&tmp, &path)?;
        let entry = CacheEntry {
            key: key.clone(),
            kind: pass,
            path: self.relative(&path),
            bytes: bytes.len() as u64,
            sha256: crate::bundle::hash(&bytes),
            job,
        };
        let records = scene.plan.as_ref().filter(|p| p.records_key.is_some());
        let next = if let (PassKind::Photons, Some(plan)) = (pass, records) {
            NextStage::Pass(PassKind::Records, plan.record_tasks(&scene.desc))
        } else {
            NextStage::Tiles(
                scene
                    .frames
                    .iter()
                    .flat_map(|f| job::plan_frame(&scene.desc, &scene.settings, f))
                    .collect(),
            )
        };
        self.store.pass_built(job, pass, &entry, &next, now_ms())?;
        tracing::info!(job, pass = pass.as_str(), key = %key, bytes = bytes.len(), "pass artifact built");
        self.work.notify_waiters();
        Ok(())
    }

    /// Finishes a pass in the background; a failure fails the job with its reason.
    fn spawn_finish_pass(self: &Arc<Self>, job: i64, pass: PassKind) {
        let app = self.clone();
        tokio::task::spawn_blocking(move || {
            if let Err(e) = app.finish_pass(job, pass) {
                let message = format!("merging the {} pass: {e:#}", pass.as_str());
                tracing::error!(job, error = %message, "pass failed");
                let _ = app.store.fail_job(job, &message, now_ms());
            }
        });
    }

    /// Finishes a frame in the background; a failure (disk full, say) fails the job with its
    /// reason.
    fn spawn_finish_frame(self: &Arc<Self>, job: i64, frame: u32) {
        let app = self.clone();
        tokio::task::spawn_blocking(move || {
            if let Err(e) = app.finish_frame(job, frame) {
                let message = format!("stitching frame {frame}: {e:#}");
                tracing::error!(job, frame, error = %message, "stitch failed");
                let _ = app.store.fail_job(job, &message, now_ms());
            }
        });
    }

    /// Takes back expired leases, once.
    fn reap(&self) {
        match self.store.expire(now_ms(), self.config.max_attempts) {
            Ok(expired) => {
                for (task, outcome) in expired {
                    self.metrics.expired.fetch_add(1, Relaxed);
                    match outcome {
                        Retry::JobFailed(msg) => tracing::warn!(task, error = %msg, "job failed"),
                        _ => tracing::warn!(task, "lease expired; task requeued"),
                    }
                    self.work.notify_waiters();
                }
            }
            Err(e) => tracing::error!(error = %e, "expiring leases"),
        }
    }
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

/// Opens the store, resumes unfinished work, binds and starts serving.
pub async fn start(config: Config) -> anyhow::Result<Running> {
    for dir in ["bundles", "jobs", "cache"] {
        std::fs::create_dir_all(config.data.join(dir))
            .with_context(|| format!("creating {}", config.data.join(dir).display()))?;
    }
    let db = config.data.join("tessera.db");
    let store =
        Store::open(&db).with_context(|| format!("opening the job store {}", db.display()))?;
    let listener = tokio::net::TcpListener::bind(config.listen)
        .await
        .with_context(|| format!("cannot listen on {}", config.listen))?;
    let addr = listener.local_addr()?;
    let (shutdown, mut stop) = tokio::sync::watch::channel(false);
    let app = Arc::new(App {
        stopping: shutdown.subscribe(),
        config,
        store,
        metrics: Metrics::default(),
        work: Notify::new(),
        descs: Mutex::new(HashMap::new()),
    });

    // Resume: passes and frames whose last task arrived just before a restart.
    for (job, pass) in app.store.unfinished_passes()? {
        tracing::info!(
            job,
            pass = pass.as_str(),
            "merging a pass finished before the restart"
        );
        app.spawn_finish_pass(job, pass);
    }
    for (job, frame) in app.store.unstitched_frames()? {
        tracing::info!(job, frame, "stitching a frame finished before the restart");
        app.spawn_finish_frame(job, frame);
    }

    // The reaper: expired leases go back to the queue.
    {
        let app = app.clone();
        let mut stop = shutdown.subscribe();
        let period = Duration::from_millis((app.config.lease_ms / 4).clamp(100, 1000));
        tokio::spawn(async move {
            loop {
                tokio::select! {
                    _ = tokio::time::sleep(period) => app.reap(),
                    _ = stop.changed() => break,
                }
            }
        });
    }
    if app.config.local_workers > 0 {
        supervisor::spawn(&app, addr, shutdown.subscribe());
    }
    let router = api::router(app.clone());
    let server = tokio::spawn(async move {
        axum::serve(listener, router)
            .with_graceful_shutdown(async move {
                let _ = stop.changed().await;
            })
            .await
    });
    Ok(Running {
        addr,
        app,
        shutdown,
        server,
    })
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
        Err(_) => {
            std::fs::create_dir_all(data)?;
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
    };
    Ok((
        client.unwrap_or(saved.client),
        worker.unwrap_or(saved.worker),
        true,
    ))
}

/// 128 random bits from the OS, in hex.
pub fn random_token() -> anyhow::Result<String> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes).map_err(|e| anyhow::anyhow!("no OS randomness: {e}"))?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}
