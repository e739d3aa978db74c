//! The worker loop: lease a task, render it with the core, heartbeat while it runs, upload the
//! result. Scenes are cached per job, so a job's bundle is downloaded and its BVH built once
//! per worker, not once per tile; so are the pass artifacts (photon maps, irradiance records)
//! a job's tasks name. Workers keep no state that matters: any worker may run any task, and a
//! task may run twice.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context;
use tokio::sync::OnceCell;

use crate::bundle::Bundle;
use crate::client::{Client, is_transient, status_of};
use crate::codec;
use crate::job::{self, FrameRange, Limits, PassKind, Prepared, TaskKind};
use crate::passes;
use crate::protocol::{Failure, Heartbeat, LeaseGrant, LeaseRequest, WorkerInfo};
use crate::sppm;
use tessera_render::Integrator;
use tessera_render::integrator::PhotonIntegrator;
use tessera_render::integrator::sppm::VisiblePoints;
use tessera_render::photon::PhotonMaps;

#[derive(Debug, Clone)]
pub struct WorkerConfig {
    pub coordinator: String,
    pub token: String,
    pub name: String,
    /// Tasks rendered at once (one thread each).
    pub slots: u32,
    /// Exit when this process is no longer our parent (started by `serve --local-workers`).
    pub parent_pid: Option<u32>,
}

/// Scenes kept, by job: the most recent few.
const CACHED_JOBS: usize = 4;

/// Cells by key, least recently used first.
type Cells<K, T> = Mutex<Vec<(K, Arc<OnceCell<T>>)>>;

/// The cell for `key` in a small LRU list of cells (created empty if missing).
fn cell_for<K: PartialEq, T>(list: &Cells<K, T>, key: K) -> Arc<OnceCell<T>> {
    let mut list = list.lock().unwrap_or_else(|e| e.into_inner());
    match list.iter().position(|(k, _)| *k == key) {
        Some(i) => {
            let entry = list.remove(i);
            let cell = entry.1.clone();
            list.push(entry);
            cell
        }
        None => {
            let cell = Arc::new(OnceCell::new());
            list.push((key, cell.clone()));
            if list.len() > CACHED_JOBS {
                list.remove(0);
            }
            cell
        }
    }
}

/// Forgets the cell for `key` (a failed initialisation is not cached).
fn forget<K: PartialEq, T>(list: &Cells<K, T>, key: &K) {
    list.lock()
        .unwrap_or_else(|e| e.into_inner())
        .retain(|(k, _)| k != key);
}

/// The value for `key` in a small LRU list of cells, made by `init` once (concurrent callers
/// wait for the first); a failed `init` is forgotten, so the next caller tries again.
async fn cached<K, T, F, Fut>(list: &Cells<K, T>, key: K, init: F) -> anyhow::Result<T>
where
    K: PartialEq + Clone,
    T: Clone,
    F: FnOnce() -> Fut,
    Fut: std::future::Future<Output = anyhow::Result<T>>,
{
    let cell = cell_for(list, key.clone());
    match cell.get_or_try_init(init).await {
        Ok(v) => Ok(v.clone()),
        Err(e) => {
            forget(list, &key);
            Err(e)
        }
    }
}

struct Worker {
    config: WorkerConfig,
    client: Client,
    id: String,
    host: String,
    scene_builds: AtomicU64,
    /// Scenes by job id, least recently used first; each built once (the cell).
    cache: Cells<i64, Arc<Prepared>>,
    /// Photon-mapping integrators by (job, artifact keys), built from downloaded artifacts.
    integrators: Cells<(i64, String), Arc<PhotonIntegrator>>,
    /// Decoded photon maps by artifact key.
    maps: Cells<String, Arc<PhotonMaps>>,
    /// Path tracers with a subsurface point cloud, by (job, artifact key).
    clouds: Cells<(i64, String), Arc<dyn Integrator>>,
    /// SPPM iterations' camera paths and radii by (job, frame, iteration): traced once per
    /// worker, read by each of the iteration's chunks it runs.
    sppm: Cells<(i64, u32, u32), Arc<SppmInputs>>,
}

/// What every task of one SPPM iteration reads.
struct SppmInputs {
    points: VisiblePoints,
    /// Squared gathering radius per pixel.
    r2: Vec<f32>,
}

/// What a task reads besides its scene.
enum Inputs {
    None,
    /// The photon-mapping integrator built from the job's artifacts.
    Photon(Arc<PhotonIntegrator>),
    /// The path tracer with the point cloud built from the job's artifact.
    Clouds(Arc<dyn Integrator>),
    Sppm(Arc<SppmInputs>),
}

pub async fn run(config: WorkerConfig) -> anyhow::Result<()> {
    let client = Client::new(&config.coordinator, &config.token)?;
    let host = hostname().unwrap_or_else(|| "unknown".into());
    let id = format!(
        "{}-{}",
        config.name,
        &crate::coordinator::random_token()?[..8]
    );
    let worker = Arc::new(Worker {
        client,
        id,
        host,
        scene_builds: AtomicU64::new(0),
        cache: Mutex::new(Vec::new()),
        integrators: Mutex::new(Vec::new()),
        maps: Mutex::new(Vec::new()),
        clouds: Mutex::new(Vec::new()),
        sppm: Mutex::new(Vec::new()),
        config,
    });
    tracing::info!(worker = %worker.id, coordinator = %worker.config.coordinator, slots = worker.config.slots, "worker started");
    if let Some(parent) = worker.config.parent_pid {
        watch_parent(parent);
    }
    let mut slots = Vec::new();
    for slot in 0..worker.config.slots.max(1) {
        let w = worker.clone();
        slots.push(tokio::spawn(async move { w.slot(slot).await }));
    }
    for s in slots {
        s.await?;
    }
    Ok(())
}

/// This machine's name, where the platform tells it.
pub fn hostname() -> Option<String> {
    std::fs::read_to_string("/etc/hostname")
        .ok()
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
}

#[cfg(unix)]
fn watch_parent(parent: u32) {
    std::thread::spawn(move || {
        loop {
            if std::os::unix::process::parent_id() != parent {
                tracing::warn!(
                    parent,
                    "the coordinator that started this worker is gone; exiting"
                );
                std::process::exit(0);
            }
            std::thread::sleep(Duration::from_millis(500));
        }
    });
}

#[cfg(not(unix))]
fn watch_parent(_parent: u32) {}

/// Runs one task: a tile with the job's integrator (the photon one when given), a pass, or an
/// SPPM chunk.
fn run_spec(prepared: &Prepared, inputs: &Inputs, spec: &job::TaskSpec) -> Result<Vec<u8>, String> {
    let photon = match inputs {
        Inputs::Photon(p) => Some(p.as_ref()),
        _ => None,
    };
    match spec.kind {
        TaskKind::Sppm => {
            let Inputs::Sppm(i) = inputs else {
                return Err("an sppm task without its iteration's radii".into());
            };
            Ok(sppm::encode_output(&sppm::execute(
                prepared, &i.points, &i.r2, spec,
            )?))
        }
        TaskKind::Bdpt => {
            let (sums, stats) = crate::bdpt::execute(prepared, spec)?;
            Ok(crate::bdpt::encode_output(&sums, &stats))
        }
        TaskKind::Tile => {
            let integrator: &dyn tessera_render::Integrator = match (photon, inputs) {
                (Some(p), _) => p,
                (None, Inputs::Clouds(i)) => i.as_ref(),
                (None, _) => prepared
                    .integrator()
                    .ok_or("a tile task without its pass artifacts")?,
            };
            let camera = prepared.camera(spec.frame);
            Ok(codec::encode(
                &prepared.execute_using(integrator, &camera, spec),
            ))
        }
        _ => Ok(passes::encode_output(&passes::execute(
            prepared, photon, spec,
        )?)),
    }
}

/// Retries `f` while the coordinator is unreachable or answers 5xx, backing off up to 5 s,
/// for at most `patience`.
async fn retrying<T, F, Fut>(what: &str, patience: Duration, mut f: F) -> anyhow::Result<T>
where
    F: FnMut() -> Fut,
    Fut: std::future::Future<Output = anyhow::Result<T>>,
{
    let start = Instant::now();
    let mut delay = Duration::from_millis(100);
    loop {
        match f().await {
            Ok(v) => return Ok(v),
            Err(e) if is_transient(&e) && start.elapsed() < patience => {
                tracing::warn!(error = %e, retry_in_ms = delay.as_millis() as u64, "{what}: coordinator unavailable");
                tokio::time::sleep(delay).await;
                delay = (delay * 2).min(Duration::from_secs(5));
            }
            Err(e) => return Err(e),
        }
    }
}

impl Worker {
    fn info(&self) -> WorkerInfo {
        WorkerInfo {
            id: self.id.clone(),
            name: self.config.name.clone(),
            host: self.host.clone(),
            pid: std::process::id(),
            slots: self.config.slots,
            scene_builds: self.scene_builds.load(Relaxed),
            version: env!("CARGO_PKG_VERSION").into(),
        }
    }

    async fn slot(self: Arc<Self>, slot: u32) {
        loop {
            let req = LeaseRequest {
                worker: self.info(),
                wait_ms: 10_000,
            };
            let grant = match retrying("lease", Duration::MAX, || self.client.lease(&req)).await {
                Ok(Some(g)) => g,
                Ok(None) => continue,
                Err(e) => {
                    // A 4xx: our token or protocol is wrong; waiting will not fix it quickly.
                    tracing::error!(slot, error = %e, "cannot lease tasks");
                    tokio::time::sleep(Duration::from_secs(5)).await;
                    continue;
                }
            };
            self.run_task(grant).await;
        }
    }

    /// The scene of a job, loaded and built once per worker.
    async fn prepared(&self, grant: &LeaseGrant) -> anyhow::Result<Arc<Prepared>> {
        cached(&self.cache, grant.job_id, || async {
            let bytes = retrying("bundle download", Duration::from_secs(600), || {
                self.client.download_bundle(&grant.bundle)
            })
            .await?;
            // Pass tasks of photon maps have no frame: any of the job's frames will do
            // to check the settings.
            let (scene, settings, frame) = (
                grant.scene.clone(),
                grant.settings.clone(),
                grant.task.frame.max(1),
            );
            let prepared = tokio::task::spawn_blocking(move || -> anyhow::Result<Prepared> {
                let bundle = Bundle::from_tar(&bytes).map_err(anyhow::Error::msg)?;
                let mut desc = bundle.load(&scene)?;
                job::apply(
                    &mut desc,
                    &settings,
                    FrameRange::single(frame),
                    &Limits::default(),
                )
                .map_err(anyhow::Error::msg)?;
                Ok(Prepared::scene_only(desc))
            })
            .await??;
            self.scene_builds.fetch_add(1, Relaxed);
            tracing::info!(
                job = grant.job_id,
                build_s = prepared.build_seconds,
                "scene loaded and built"
            );
            anyhow::Ok(Arc::new(prepared))
        })
        .await
    }

    async fn download(&self, key: &str) -> anyhow::Result<Vec<u8>> {
        retrying("artifact download", Duration::from_secs(600), || {
            self.client.download_artifact(key)
        })
        .await
    }

    /// The photon maps with this key, downloaded and decoded once per worker (the record and
    /// the tile stage of a job both read them).
    async fn photon_maps(&self, key: &str) -> anyhow::Result<Arc<PhotonMaps>> {
        cached(&self.maps, key.to_string(), || async {
            let bytes = self.download(key).await?;
            let maps = tokio::task::spawn_blocking(move || passes::decode_maps(&bytes))
                .await?
                .map_err(anyhow::Error::msg)?;
            anyhow::Ok(Arc::new(maps))
        })
        .await
    }

    /// The photon-mapping integrator of a task's artifacts (maps, and records for tiles),
    /// downloaded and decoded once per worker.
    async fn photon_integrator(
        &self,
        grant: &LeaseGrant,
        prepared: &Arc<Prepared>,
    ) -> anyhow::Result<Arc<PhotonIntegrator>> {
        let keys: Vec<&str> = grant.artifacts.iter().map(|a| a.key.as_str()).collect();
        let id = (grant.job_id, keys.join(","));
        cached(&self.integrators, id.clone(), || async {
            let (mut maps, mut records) = (None, None);
            for a in &grant.artifacts {
                match a.kind {
                    PassKind::Photons => maps = Some(self.photon_maps(&a.key).await?),
                    PassKind::Records => records = Some(self.download(&a.key).await?),
                    PassKind::Subsurface => {}
                }
            }
            let prepared = prepared.clone();
            let integ = tokio::task::spawn_blocking(move || -> anyhow::Result<_> {
                let maps = maps.context("the task names no photon-map artifact")?;
                let records = records
                    .map(|b| passes::decode_records(&b))
                    .transpose()
                    .map_err(anyhow::Error::msg)?;
                passes::integrator(&prepared, maps, records).map_err(anyhow::Error::msg)
            })
            .await??;
            tracing::info!(job = grant.job_id, artifacts = %id.1, "pass artifacts loaded");
            anyhow::Ok(Arc::new(integ))
        })
        .await
    }

    /// The path tracer of a tile task whose job has a subsurface point-cloud artifact,
    /// downloaded and built once per worker.
    async fn cloud_integrator(
        &self,
        grant: &LeaseGrant,
        prepared: &Arc<Prepared>,
    ) -> anyhow::Result<Arc<dyn Integrator>> {
        let key = grant
            .artifacts
            .iter()
            .find(|a| a.kind == PassKind::Subsurface)
            .context("the task names no point-cloud artifact")?
            .key
            .clone();
        cached(&self.clouds, (grant.job_id, key.clone()), || async {
            let bytes = self.download(&key).await?;
            let prepared = prepared.clone();
            let integ = tokio::task::spawn_blocking(move || {
                crate::subsurface::integrator(&prepared, &bytes)
            })
            .await?
            .map_err(anyhow::Error::msg)?;
            tracing::info!(job = grant.job_id, artifact = %key, "point cloud loaded");
            anyhow::Ok(Arc::<dyn Integrator>::from(integ))
        })
        .await
    }

    /// An SPPM iteration's radii (downloaded; the initial ones for iteration 0) and camera
    /// paths (traced here), once per worker.
    async fn sppm_inputs(
        &self,
        grant: &LeaseGrant,
        prepared: &Arc<Prepared>,
    ) -> anyhow::Result<Arc<SppmInputs>> {
        let (frame, t) = (grant.task.frame, grant.task.sample_start);
        let id = (grant.job_id, frame, t);
        cached(&self.sppm, id, || async {
            let pixels = prepared.desc.film.width * prepared.desc.film.height;
            let radii = if t == 0 {
                None
            } else {
                Some(
                    retrying("sppm radii download", Duration::from_secs(600), || {
                        self.client.download_sppm_radii(grant.job_id, frame, t)
                    })
                    .await?,
                )
            };
            let prepared = prepared.clone();
            let inputs = tokio::task::spawn_blocking(move || -> anyhow::Result<_> {
                let r2 = match radii {
                    Some(b) => sppm::decode_radii(&b, pixels),
                    None => sppm::initial_radii(&prepared),
                }
                .map_err(anyhow::Error::msg)?;
                let points =
                    sppm::visible_points(&prepared, frame, t).map_err(anyhow::Error::msg)?;
                Ok(SppmInputs { points, r2 })
            })
            .await??;
            tracing::debug!(
                job = grant.job_id,
                frame,
                iteration = t,
                "sppm camera paths traced"
            );
            anyhow::Ok(Arc::new(inputs))
        })
        .await
    }

    async fn run_task(&self, grant: LeaseGrant) {
        let (task, lease, job) = (grant.task_id, grant.lease, grant.job_id);
        let lost = Arc::new(AtomicBool::new(false));
        let beat = self.spawn_heartbeat(&grant, lost.clone());
        let start = Instant::now();
        let outcome = async {
            let prepared = self.prepared(&grant).await.context("loading the scene")?;
            let spec = grant.task;
            let inputs = if spec.kind == TaskKind::Sppm {
                Inputs::Sppm(
                    self.sppm_inputs(&grant, &prepared)
                        .await
                        .context("tracing the sppm iteration's camera paths")?,
                )
            } else if spec.kind == TaskKind::Tile
                && grant
                    .artifacts
                    .iter()
                    .any(|a| a.kind == PassKind::Subsurface)
            {
                Inputs::Clouds(
                    self.cloud_integrator(&grant, &prepared)
                        .await
                        .context("loading the point cloud")?,
                )
            } else if spec.kind == TaskKind::Records
                || (spec.kind == TaskKind::Tile && !grant.artifacts.is_empty())
            {
                Inputs::Photon(
                    self.photon_integrator(&grant, &prepared)
                        .await
                        .context("loading the pass artifacts")?,
                )
            } else {
                Inputs::None
            };
            tokio::task::spawn_blocking(move || {
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    run_spec(&prepared, &inputs, &spec)
                }))
            })
            .await?
            .map_err(|panic| {
                let what = panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_else(|| "unknown panic".into());
                anyhow::anyhow!("the renderer panicked: {what}")
            })?
            .map_err(anyhow::Error::msg)
        }
        .await;
        let seconds = start.elapsed().as_secs_f64();
        beat.abort();
        if lost.load(Relaxed) {
            tracing::warn!(
                job,
                task,
                lease,
                "lease lost while rendering; result dropped"
            );
            return;
        }
        match outcome {
            Ok(bytes) => {
                let upload = retrying("result upload", Duration::from_secs(600), || {
                    self.client
                        .upload_result(task, lease, seconds, bytes.clone())
                })
                .await;
                match upload {
                    Ok(()) => tracing::info!(job, task, lease, seconds, "task done"),
                    Err(e) if status_of(&e) == Some(reqwest::StatusCode::CONFLICT) => {
                        tracing::warn!(job, task, lease, error = %e, "result not accepted: lease no longer current")
                    }
                    Err(e) => {
                        self.report_failure(task, lease, format!("uploading the result: {e:#}"))
                            .await
                    }
                }
            }
            Err(e) => self.report_failure(task, lease, format!("{e:#}")).await,
        }
    }

    async fn report_failure(&self, task: i64, lease: i64, error: String) {
        tracing::error!(task, lease, error = %error, "task failed");
        let failure = Failure {
            lease,
            worker: self.id.clone(),
            error,
        };
        if let Err(e) = retrying("failure report", Duration::from_secs(60), || {
            self.client.fail(task, &failure)
        })
        .await
        {
            tracing::warn!(task, error = %e, "could not report the failure; the lease will expire");
        }
    }

    /// Renews the lease every third of its period until aborted; sets `lost` on a 409.
    fn spawn_heartbeat(
        &self,
        grant: &LeaseGrant,
        lost: Arc<AtomicBool>,
    ) -> tokio::task::JoinHandle<()> {
        let client = self.client.clone();
        let hb = Heartbeat {
            lease: grant.lease,
            worker: self.id.clone(),
        };
        let (task, period) = (
            grant.task_id,
            Duration::from_millis((grant.lease_ms / 3).max(50)),
        );
        tokio::spawn(async move {
            loop {
                tokio::time::sleep(period).await;
                match client.heartbeat(task, &hb).await {
                    Ok(()) => {}
                    Err(e) if status_of(&e) == Some(reqwest::StatusCode::CONFLICT) => {
                        lost.store(true, Relaxed);
                        return;
                    }
                    Err(e) => tracing::warn!(task, error = %e, "heartbeat failed; retrying"),
                }
            }
        })
    }
}
