//! The worker loop: lease a task, run it with its method's plan, heartbeat while it runs,
//! stream the result back. A job's bundle is downloaded, its scene built and its method
//! planned once per worker, not once per task; so are the artifacts and step inputs its tasks
//! read. Workers keep no state that matters: any worker may run any task, and a task may run
//! twice. Nothing here knows one rendering method from another.

use std::collections::HashMap;
use std::io::BufWriter;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

use anyhow::Context;
use tessera_render::Scene;
use tessera_render::method::{LoadFn, Loaded, Plan, Resources, TaskCtx};
use tessera_render::wire::Header;
use tessera_scene::SceneDesc;
use tokio::sync::OnceCell;

use crate::client::{Client, is_transient, status_of};
use crate::job;
use crate::protocol::{
    Failure, Heartbeat, LeaseGrant, LeaseRequest, WorkerInfo, result_over_limit,
};

#[derive(Debug, Clone)]
pub struct WorkerConfig {
    pub coordinator: String,
    pub token: String,
    pub name: String,
    /// Tasks rendered at once (one thread each; a task over the whole film uses every core).
    pub slots: u32,
    /// Exit when this process is no longer our parent (started by `serve --local-workers`).
    pub parent_pid: Option<u32>,
    /// What it offers (`--tags`); jobs may require some.
    pub tags: Vec<String>,
    /// Fault injection for tests of the farm: report every task as failed with this message
    /// instead of rendering it (a broken machine).
    pub fail_tasks_with: Option<String>,
    /// A private certificate authority (PEM) to trust for an `https://` coordinator.
    pub ca: Option<PathBuf>,
}

/// CPU use of this process between samples, from the kernel's accounting (Linux).
#[derive(Default)]
struct CpuMeter {
    last: Mutex<Option<(Instant, f64)>>,
}

impl CpuMeter {
    /// Seconds of CPU this process has used (user + system), where the platform tells it.
    fn used() -> Option<f64> {
        let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
        // Fields after the command name (which may hold spaces) in its parentheses.
        let rest = stat.rsplit_once(')')?.1;
        let fields: Vec<&str> = rest.split_whitespace().collect();
        let (utime, stime): (f64, f64) =
            (fields.get(11)?.parse().ok()?, fields.get(12)?.parse().ok()?);
        // The kernel counts in clock ticks of USER_HZ, 100 per second on Linux.
        Some((utime + stime) / 100.0)
    }

    /// Cores in use since the previous sample (none at the first).
    fn sample(&self) -> Option<f32> {
        let now = (Instant::now(), Self::used()?);
        let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
        let previous = last.replace(now);
        let (t0, c0) = previous?;
        let wall = now.0.duration_since(t0).as_secs_f64();
        (wall > 0.5).then(|| ((now.1 - c0) / wall) as f32)
    }
}

/// Jobs (scenes built) and downloads kept: the most recent few.
const KEPT: usize = 4;

/// Cells by key, least recently used first.
type Cells<K, T> = Mutex<Vec<(K, Arc<OnceCell<T>>)>>;
/// Values made once per process by key, least recently used first (blocking threads).
type Made<K> = Mutex<Vec<(K, Arc<OnceLock<Result<Loaded, String>>>)>>;

/// The entry for `key` in a small LRU list (created if missing).
fn entry<K: PartialEq, C: Default>(list: &Mutex<Vec<(K, Arc<C>)>>, key: K, keep: usize) -> Arc<C> {
    let mut list = list.lock().unwrap_or_else(|e| e.into_inner());
    match list.iter().position(|(k, _)| *k == key) {
        Some(i) => {
            let e = list.remove(i);
            let cell = e.1.clone();
            list.push(e);
            cell
        }
        None => {
            let cell = Arc::new(C::default());
            list.push((key, cell.clone()));
            if list.len() > keep {
                list.remove(0);
            }
            cell
        }
    }
}

/// The value for `key`, made by `init` once (concurrent callers wait for the first); a failed
/// `init` is forgotten, so the next caller tries again.
async fn cached<K, T, F, Fut>(list: &Cells<K, T>, key: K, init: F) -> anyhow::Result<T>
where
    K: PartialEq + Clone,
    T: Clone,
    F: FnOnce() -> Fut,
    Fut: std::future::Future<Output = anyhow::Result<T>>,
{
    let cell = entry(list, key.clone(), KEPT);
    match cell.get_or_try_init(init).await {
        Ok(v) => Ok(v.clone()),
        Err(e) => {
            list.lock()
                .unwrap_or_else(|e| e.into_inner())
                .retain(|(k, _)| *k != key);
            Err(e)
        }
    }
}

/// A job as a worker holds it: the scene with the job's settings, built, and its plan.
struct Prepared {
    desc: SceneDesc,
    scene: Scene,
    plan: Box<dyn Plan>,
}

struct Worker {
    config: WorkerConfig,
    cpu: CpuMeter,
    client: Client,
    id: String,
    host: String,
    scene_builds: AtomicU64,
    /// Where results are written before they are streamed out.
    tmp: PathBuf,
    jobs: Cells<i64, Arc<Prepared>>,
    /// Downloaded artifacts and step inputs (wire streams) by key.
    downloads: Cells<String, Arc<Vec<u8>>>,
    /// Artifacts and step inputs loaded from their streams, by key.
    loaded: Made<String>,
    /// Values shared by a step's tasks, by (job, frame, step, name).
    memos: Made<(i64, u32, u32, String)>,
}

/// What a task reads, for the core.
struct TaskResources<'a> {
    worker: &'a Worker,
    grant: &'a LeaseGrant,
    /// This task's downloads: artifacts by key, and the step's input.
    artifacts: HashMap<String, Arc<Vec<u8>>>,
    input: Option<(String, Arc<Vec<u8>>)>,
}

fn load_once(
    list: &Made<String>,
    key: &str,
    bytes: Option<&Arc<Vec<u8>>>,
    load: LoadFn,
) -> Result<Loaded, String> {
    let cell = entry(list, key.to_string(), KEPT);
    cell.get_or_init(|| {
        let bytes = bytes.ok_or_else(|| format!("{key} was not downloaded for this task"))?;
        load(&mut bytes.as_slice())
    })
    .clone()
}

impl Resources for TaskResources<'_> {
    fn artifact(&self, key: &str, load: LoadFn) -> Result<Loaded, String> {
        load_once(&self.worker.loaded, key, self.artifacts.get(key), load)
    }

    fn input(&self, load: LoadFn) -> Result<Loaded, String> {
        let (key, bytes) = self
            .input
            .as_ref()
            .ok_or("the task's step has no input (the coordinator sent none)")?;
        load_once(&self.worker.loaded, key, Some(bytes), load)
    }

    fn memo(
        &self,
        name: &str,
        make: &dyn Fn() -> Result<Loaded, String>,
    ) -> Result<Loaded, String> {
        let t = &self.grant.task;
        let key = (self.grant.job_id, t.frame, t.step, name.to_string());
        entry(&self.worker.memos, key, 2).get_or_init(make).clone()
    }
}

pub async fn run(config: WorkerConfig) -> anyhow::Result<()> {
    let client = Client::with_ca(&config.coordinator, &config.token, config.ca.as_deref())?;
    let host = hostname().unwrap_or_else(|| "unknown".into());
    let id = format!(
        "{}-{}",
        config.name,
        &crate::coordinator::random_token()?[..8]
    );
    let tmp = std::env::temp_dir().join(format!("tessera-worker-{id}"));
    std::fs::create_dir_all(&tmp).with_context(|| tmp.display().to_string())?;
    let worker = Arc::new(Worker {
        client,
        id,
        host,
        scene_builds: AtomicU64::new(0),
        tmp,
        jobs: Mutex::new(Vec::new()),
        downloads: Mutex::new(Vec::new()),
        loaded: Mutex::new(Vec::new()),
        memos: Mutex::new(Vec::new()),
        cpu: CpuMeter::default(),
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
        s.await??;
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

/// Runs `render` on a blocking thread; a panic in it is an error that says so.
async fn rendering(
    render: impl FnOnce() -> anyhow::Result<()> + Send + 'static,
) -> anyhow::Result<()> {
    tokio::task::spawn_blocking(move || {
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(render))
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
}

/// A failure no retry can mend: the job's own inputs are at fault.
#[derive(Debug)]
struct Permanent(String);

impl std::fmt::Display for Permanent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Permanent {}

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
            wire: tessera_render::wire::VERSION,
            tags: self.config.tags.clone(),
            cpu: self.cpu.sample(),
        }
    }

    /// Leases and runs tasks until the coordinator refuses this worker's build (409: another
    /// wire format), which waiting cannot mend: the worker then exits with that error.
    async fn slot(self: Arc<Self>, slot: u32) -> anyhow::Result<()> {
        loop {
            let req = LeaseRequest {
                worker: self.info(),
                wait_ms: 10_000,
            };
            let grant = match retrying("lease", Duration::MAX, || self.client.lease(&req)).await {
                Ok(Some(g)) => g,
                Ok(None) => continue,
                Err(e) if status_of(&e) == Some(reqwest::StatusCode::CONFLICT) => return Err(e),
                Err(e) => {
                    // A 4xx: our token or protocol is wrong; waiting will not fix it quickly.
                    tracing::error!(slot, error = %e, "cannot lease tasks");
                    tokio::time::sleep(Duration::from_secs(5)).await;
                    continue;
                }
            };
            self.clone().run_task(grant).await;
        }
    }

    /// The job's bundle, downloaded and its hash checked. One the coordinator does not have is
    /// a [`Permanent`] failure.
    async fn bundle(&self, grant: &LeaseGrant) -> anyhow::Result<Vec<u8>> {
        let bytes = retrying("bundle download", Duration::from_secs(600), || {
            self.client.download_bundle(&grant.bundle)
        })
        .await
        .map_err(|e| {
            if status_of(&e) == Some(reqwest::StatusCode::NOT_FOUND) {
                anyhow::Error::new(Permanent(format!("{e:#}")))
            } else {
                e
            }
        })?;
        let got = crate::bundle::hash(&bytes);
        anyhow::ensure!(
            got == grant.bundle,
            "the bundle downloaded for {} has the hash {got}: damaged in transit",
            grant.bundle
        );
        Ok(bytes)
    }

    /// The scene and plan of a job, loaded, built and planned once per worker. A bundle whose
    /// verified bytes do not load and plan is a [`Permanent`] failure: every worker would fail
    /// the same way.
    async fn prepared(&self, grant: &LeaseGrant) -> anyhow::Result<Arc<Prepared>> {
        cached(&self.jobs, grant.job_id, || async {
            let bytes = self.bundle(grant).await?;
            let (scene, settings, frames) =
                (grant.scene.clone(), grant.settings.clone(), grant.frames);
            let started = Instant::now();
            let prepared = tokio::task::spawn_blocking(move || -> anyhow::Result<Prepared> {
                let permanent = |e: String| anyhow::Error::new(Permanent(e));
                // Compiled as the coordinator compiled it: the same frames give the same
                // passes and artifact keys.
                let compiled = job::compile_bundled(
                    &bytes,
                    &scene,
                    &settings,
                    Some(frames),
                    job::Options::admitted(),
                )
                .map_err(permanent)?;
                Ok(Prepared {
                    scene: Scene::build(&compiled.job.desc),
                    desc: compiled.job.desc,
                    plan: compiled.plan,
                })
            })
            .await??;
            self.scene_builds.fetch_add(1, Relaxed);
            tracing::info!(
                job = grant.job_id,
                method = prepared.plan.method(),
                build_s = started.elapsed().as_secs_f64(),
                "scene loaded and built"
            );
            anyhow::Ok(Arc::new(prepared))
        })
        .await
    }

    /// A download (artifact or step input) by key, once per worker.
    async fn download(&self, key: String, path: String) -> anyhow::Result<Arc<Vec<u8>>> {
        cached(&self.downloads, key, || async {
            let bytes = retrying("download", Duration::from_secs(600), || {
                self.client.get_bytes(&path)
            })
            .await?;
            anyhow::Ok(Arc::new(bytes))
        })
        .await
    }

    /// Runs a task and writes its result to a file; returns the file.
    async fn execute(self: &Arc<Self>, grant: &LeaseGrant) -> anyhow::Result<PathBuf> {
        if let Some(message) = &self.config.fail_tasks_with {
            anyhow::bail!("{message}");
        }
        if job::is_pilot(&grant.task) {
            return self.measure(grant).await;
        }
        let prepared = self.prepared(grant).await.context("loading the scene")?;
        let mut artifacts = HashMap::new();
        for a in &grant.artifacts {
            let bytes = self
                .download(a.key.clone(), format!("/v1/artifacts/{}", a.key))
                .await
                .with_context(|| format!("downloading the {} artifact", a.pass))?;
            artifacts.insert(a.key.clone(), bytes);
        }
        let input = match &grant.input {
            Some(path) => Some((
                path.clone(),
                self.download(path.clone(), path.clone())
                    .await
                    .context("downloading the step's input")?,
            )),
            None => None,
        };
        let path = self
            .tmp
            .join(format!("{}-{}.tswf", grant.task_id, grant.lease));
        let worker = self.clone();
        let grant2 = grant.clone();
        let out = path.clone();
        let run = move || -> anyhow::Result<()> {
            let resources = TaskResources {
                worker: &worker,
                grant: &grant2,
                artifacts,
                input,
            };
            let ctx = TaskCtx {
                scene: &prepared.scene,
                desc: &prepared.desc,
                resources: &resources,
            };
            let plan = prepared.plan.as_ref();
            let spec = &grant2.task;
            let partial = plan.execute(&ctx, spec).map_err(anyhow::Error::msg)?;
            let schema = if spec.is_pass() {
                let passes = plan.passes();
                passes
                    .get(spec.step as usize)
                    .map(|p| p.schema())
                    .context("a pass task of a job without that pass")?
            } else {
                plan.schema()
            };
            let mut header = Header::new("result", &schema);
            header.task = Some(spec.clone());
            let file = std::fs::File::create(&out).with_context(|| out.display().to_string())?;
            partial.write_to(&header, &mut BufWriter::new(file))?;
            Ok(())
        };
        rendering(run).await?;
        Ok(path)
    }

    /// Runs a job's pilot task: measures `auto`'s candidates on the job's first frame with
    /// every core of this machine, and writes the choice to a file; returns the file.
    async fn measure(&self, grant: &LeaseGrant) -> anyhow::Result<PathBuf> {
        let bytes = self.bundle(grant).await.context("loading the scene")?;
        let path = self
            .tmp
            .join(format!("{}-{}.tswf", grant.task_id, grant.lease));
        let (out, grant) = (path.clone(), grant.clone());
        rendering(move || -> anyhow::Result<()> {
            let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
            let options = job::Options {
                choose: job::Choose::Measure { threads },
                ..job::Options::admitted()
            };
            let compiled = job::compile_bundled(
                &bytes,
                &grant.scene,
                &grant.settings,
                Some(grant.frames),
                options,
            )
            .map_err(|e| anyhow::Error::new(Permanent(e)))?;
            let choice = compiled
                .job
                .choice
                .as_ref()
                .context("the job's pilot measured nothing: it does not ask for auto")?;
            tracing::info!(job = grant.job_id, task = grant.task_id, method = %choice.method, spp = choice.spp, "auto chose");
            let file = std::fs::File::create(&out).with_context(|| out.display().to_string())?;
            job::write_choice(BufWriter::new(file), &grant.task, choice)
        })
        .await?;
        Ok(path)
    }

    async fn run_task(self: Arc<Self>, grant: LeaseGrant) {
        let (task, lease, job) = (grant.task_id, grant.lease, grant.job_id);
        let lost = Arc::new(AtomicBool::new(false));
        let beat = self.spawn_heartbeat(&grant, lost.clone());
        let start = Instant::now();
        let outcome = self.execute(&grant).await;
        let seconds = start.elapsed().as_secs_f64();
        beat.abort();
        if lost.load(Relaxed) {
            tracing::warn!(
                job,
                task,
                lease,
                "lease lost while rendering; result dropped"
            );
            if let Ok(path) = &outcome {
                let _ = std::fs::remove_file(path);
            }
            return;
        }
        let outcome = outcome.and_then(|path| match grant.max_result_bytes {
            Some(limit) => match std::fs::metadata(&path) {
                Ok(m) if m.len() > limit => {
                    let _ = std::fs::remove_file(&path);
                    anyhow::bail!("{}", result_over_limit(task, Some(m.len()), limit))
                }
                Ok(_) => Ok(path),
                Err(e) => anyhow::bail!("the result file {}: {e}", path.display()),
            },
            None => Ok(path),
        });
        match outcome {
            Ok(path) => {
                let upload = retrying("result upload", Duration::from_secs(600), || {
                    self.client.upload_result(task, lease, seconds, &path)
                })
                .await;
                let _ = std::fs::remove_file(&path);
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
            Err(e) => {
                let permanent = e.chain().any(|c| c.is::<Permanent>());
                self.report(task, lease, format!("{e:#}"), permanent).await
            }
        }
    }

    async fn report_failure(&self, task: i64, lease: i64, error: String) {
        self.report(task, lease, error, false).await
    }

    async fn report(&self, task: i64, lease: i64, error: String, permanent: bool) {
        tracing::error!(task, lease, error = %error, permanent, "task failed");
        let failure = Failure {
            lease,
            worker: self.id.clone(),
            error,
            permanent,
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
        self: &Arc<Self>,
        grant: &LeaseGrant,
        lost: Arc<AtomicBool>,
    ) -> tokio::task::JoinHandle<()> {
        let client = self.client.clone();
        let worker = self.clone();
        let mut hb = Heartbeat {
            lease: grant.lease,
            worker: self.id.clone(),
            cpu: None,
        };
        let (task, period) = (
            grant.task_id,
            Duration::from_millis((grant.lease_ms / 3).max(50)),
        );
        tokio::spawn(async move {
            loop {
                tokio::time::sleep(period).await;
                hb.cpu = worker.cpu.sample();
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
