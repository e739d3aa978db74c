//! The wire protocol: JSON bodies of the coordinator's HTTP API under `/v1`, shared by the
//! coordinator, workers and clients, and described in the OpenAPI document.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::job::{FrameRange, RenderSettings, TaskSpec};

/// An error, as every 4xx/5xx response carries it.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct ErrorBody {
    /// What went wrong and what was expected.
    pub error: String,
}

/// A stored scene bundle.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct BundleInfo {
    /// SHA-256 of the tar archive, hex: the bundle's address.
    pub hash: String,
    pub bytes: u64,
    /// The files it holds.
    pub files: Vec<String>,
}

/// A job to submit.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct JobRequest {
    /// Hash of an uploaded bundle (`POST /v1/bundles`).
    pub bundle: String,
    /// The scene file inside the bundle.
    #[serde(default = "default_scene")]
    pub scene: String,
    /// A name to show (default: the scene's name).
    #[serde(default)]
    pub name: Option<String>,
    /// Frames to render (default: every frame of the scene's camera path, or frame 1).
    #[serde(default)]
    pub frames: Option<FrameRange>,
    #[serde(default)]
    pub settings: RenderSettings,
    /// Higher runs first; equal priorities run oldest first.
    #[serde(default)]
    pub priority: i32,
    /// Tags a worker must have to run the job's tasks (`tessera worker --tags`).
    #[serde(default)]
    pub require_tags: Vec<String>,
}

fn default_scene() -> String {
    "scene.json".into()
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum JobState {
    Queued,
    Running,
    /// Held by a user: no new leases; leased tasks finish.
    Paused,
    Done,
    Failed,
    Cancelled,
}

impl JobState {
    pub const ALL: [JobState; 6] = [
        JobState::Queued,
        JobState::Running,
        JobState::Paused,
        JobState::Done,
        JobState::Failed,
        JobState::Cancelled,
    ];
    pub fn as_str(self) -> &'static str {
        match self {
            JobState::Queued => "queued",
            JobState::Running => "running",
            JobState::Paused => "paused",
            JobState::Done => "done",
            JobState::Failed => "failed",
            JobState::Cancelled => "cancelled",
        }
    }
    pub fn parse(s: &str) -> JobState {
        match s {
            "running" => JobState::Running,
            "paused" => JobState::Paused,
            "done" => JobState::Done,
            "failed" => JobState::Failed,
            "cancelled" => JobState::Cancelled,
            _ => JobState::Queued,
        }
    }
    pub fn is_final(self) -> bool {
        matches!(
            self,
            JobState::Done | JobState::Failed | JobState::Cancelled
        )
    }
}

/// Task counts by state.
#[derive(Debug, Clone, Default, Serialize, Deserialize, ToSchema)]
pub struct TaskCounts {
    /// Tasks queued so far, in any state.
    pub total: u64,
    /// Tasks the job is expected to have in all, counting those not queued yet (tiles after
    /// the passes, SPPM iterations after the running one); adaptive rounds may add more.
    #[serde(default)]
    pub planned: u64,
    pub queued: u64,
    pub leased: u64,
    pub done: u64,
    pub failed: u64,
    pub cancelled: u64,
}

/// One frame of a job.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct FrameStatus {
    pub frame: u32,
    /// queued, running, done.
    pub state: String,
    /// The step it is at (an adaptive round, an SPPM iteration).
    pub step: u32,
    pub tasks_done: u64,
    pub tasks_total: u64,
    /// Where to download the finished EXR (relative URL), once done.
    pub exr: Option<String>,
    /// SHA-256 of the finished EXR.
    pub exr_sha256: Option<String>,
    /// Adaptive sampling: the relMSE the finished frame estimates for itself.
    pub estimated_rel_mse: Option<f64>,
}

/// A job and its progress.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct JobStatus {
    pub id: i64,
    pub name: String,
    pub state: JobState,
    pub priority: i32,
    /// Milliseconds since the Unix epoch.
    pub created_ms: i64,
    pub finished_ms: Option<i64>,
    pub bundle: String,
    pub scene: String,
    /// The rendering method that runs (for `auto`, the one it chose).
    pub method: String,
    pub frames: FrameRange,
    pub settings: RenderSettings,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub tasks: TaskCounts,
    /// Leases granted for this job's tasks (more than tasks.total when some were retried).
    pub attempts: u64,
    /// Fraction of tasks done, 0 to 1.
    pub progress: f64,
    pub frame_status: Vec<FrameStatus>,
    /// Why the job failed: the worker's error.
    pub error: Option<String>,
    /// What the core decided to do for this scene.
    pub decisions: Vec<String>,
    /// Precomputation passes (photon maps, irradiance cache): built here or reused.
    #[serde(default)]
    pub passes: Vec<PassStatus>,
    /// Tags a worker must have to run its tasks.
    #[serde(default)]
    pub require_tags: Vec<String>,
    /// When its first task was leased (ms since the epoch).
    #[serde(default)]
    pub started_ms: Option<i64>,
    /// Workers that may not run its tasks any more, having failed them too often.
    #[serde(default)]
    pub blocklist: Vec<Blocklisted>,
    /// Who submitted it (the name of the token's user; `admin` for the coordinator's own
    /// client token).
    #[serde(default)]
    pub submitter: Option<String>,
    /// Whether `auto`'s pilot, a task a worker runs, has yet to choose the method: until then
    /// `method` is `auto` and the job's passes and frames are not planned.
    #[serde(default)]
    pub measuring: bool,
}

/// A worker blocklisted for a job.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct Blocklisted {
    pub worker: String,
    /// Failures of the job's tasks on it.
    pub failures: u32,
    pub since_ms: i64,
    /// Its last failure's message.
    pub last_error: Option<String>,
}

/// A page of jobs, newest first.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct JobList {
    /// Jobs matching the filter, in all pages.
    pub total: u64,
    /// Jobs matching the filter by state, in all pages.
    pub by_state: std::collections::BTreeMap<String, u64>,
    /// This page (without per-frame detail, passes or decisions).
    pub jobs: Vec<JobStatus>,
}

/// Changes to a job (`PATCH /v1/jobs/{id}`).
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct JobPatch {
    /// A new priority: higher runs first (its queued tasks move with it).
    #[serde(default)]
    pub priority: Option<i32>,
}

/// One lease of a task and how it ended.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct AttemptStatus {
    /// The lease token.
    pub id: i64,
    pub task_id: i64,
    pub frame: u32,
    pub step: u32,
    pub kind: String,
    pub index: u32,
    pub worker: String,
    pub started_ms: i64,
    pub ended_ms: Option<i64>,
    /// done, failed, expired, stale, unreadable; none while it runs.
    pub outcome: Option<String>,
    pub error: Option<String>,
}

/// Something changed (`GET /v1/events`, server-sent events): what to look at again.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Event {
    /// A job was submitted, changed state or made progress.
    Job { id: i64 },
    /// A job was deleted.
    JobDeleted { id: i64 },
    /// A worker was seen, changed or was blocklisted.
    Worker { id: String },
}

/// A pass of a job and the artifact it makes or reuses.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct PassStatus {
    /// The pass's name (`photons`, `irradiance_cache`, `subsurface`).
    pub name: String,
    /// The artifact's key: a hash of everything that determines it.
    pub key: String,
    /// `reused` (an artifact with this key was cached), `waiting`, `running` or `built`.
    pub state: String,
    pub tasks_done: u64,
    pub tasks_total: u64,
    /// The job that built the artifact (this one, if built here), once it exists.
    pub built_by: Option<i64>,
    /// Size of the artifact, bytes.
    pub bytes: Option<u64>,
    /// What the pass built (counts, sizes), once built.
    pub summary: Option<String>,
}

/// An artifact a task reads (download with `GET /v1/artifacts/{key}`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct ArtifactRef {
    /// The pass that builds it.
    pub pass: String,
    pub key: String,
}

/// One task of a job.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct TaskStatus {
    pub id: i64,
    #[serde(flatten)]
    pub spec: TaskSpec,
    /// queued, leased, done, failed, cancelled.
    pub state: String,
    /// Leases granted so far.
    pub attempts: u32,
    pub worker: Option<String>,
    /// Seconds the accepted result took to render.
    pub seconds: Option<f64>,
    /// Bytes of the accepted result as uploaded (compressed), and of its payload before
    /// compression.
    pub result_bytes: Option<u64>,
    pub payload_bytes: Option<u64>,
    pub error: Option<String>,
}

/// Who a worker is; sent with every lease request.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct WorkerInfo {
    /// Unique per worker process.
    pub id: String,
    pub name: String,
    pub host: String,
    /// Its process id on that host.
    pub pid: u32,
    /// Tasks it runs at once.
    pub slots: u32,
    /// Scenes it has loaded and built (its cache misses).
    pub scene_builds: u64,
    pub version: String,
    /// The wire format it writes task results in (`tessera_render::wire::VERSION`): a
    /// coordinator leases tasks only to workers of its own (0 from a worker that does not say).
    #[serde(default)]
    pub wire: u16,
    /// What it offers (`tessera worker --tags`); jobs may require some.
    #[serde(default)]
    pub tags: Vec<String>,
    /// Its process's CPU use since its last report, in cores.
    #[serde(default)]
    pub cpu: Option<f32>,
}

impl WorkerInfo {
    /// A worker of this process called `id`, one slot, no tags (simulated workers: tests,
    /// benchmarks).
    pub fn simulated(id: &str) -> Self {
        WorkerInfo {
            id: id.into(),
            name: id.into(),
            host: "simulated".into(),
            pid: std::process::id(),
            slots: 1,
            scene_builds: 0,
            version: env!("CARGO_PKG_VERSION").into(),
            wire: tessera_render::wire::VERSION,
            tags: Vec::new(),
            cpu: None,
        }
    }
}

/// A request for work.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct LeaseRequest {
    pub worker: WorkerInfo,
    /// How long to wait for a task when none is queued (long poll), ms; at most 20000.
    #[serde(default)]
    pub wait_ms: u64,
}

/// A task leased to a worker.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct LeaseGrant {
    pub task_id: i64,
    /// The fence token: results and heartbeats must carry it.
    pub lease: i64,
    /// Renew (heartbeat) before this many ms pass.
    pub lease_ms: u64,
    pub job_id: i64,
    pub bundle: String,
    pub scene: String,
    pub settings: RenderSettings,
    /// The job's frames: a method plans its passes from all of them (the irradiance cache's
    /// keyframes), so a worker plans the job with the same range as the coordinator did.
    pub frames: FrameRange,
    pub task: TaskSpec,
    /// Artifacts the task reads, by key.
    #[serde(default)]
    pub artifacts: Vec<ArtifactRef>,
    /// Where to download what the task's step reads besides the artifacts (relative URL), if
    /// the step has an input.
    #[serde(default)]
    pub input: Option<String>,
    /// The largest result this coordinator accepts (`serve --max-result-mib`), in bytes: a
    /// worker refuses a larger one itself rather than upload it to be refused.
    #[serde(default)]
    pub max_result_bytes: Option<u64>,
}

/// A size in the unit that reads best: `4 GiB`, `512 MiB`, `64 KiB`, `100 bytes`.
pub fn human_size(bytes: u64) -> String {
    match bytes {
        b if b >= 1 << 30 && b % (1 << 30) == 0 => format!("{} GiB", b >> 30),
        b if b >= 1 << 20 => format!("{} MiB", b >> 20),
        b if b >= 1 << 10 => format!("{} KiB", b >> 10),
        b => format!("{b} bytes"),
    }
}

/// What a result over the coordinator's limit is told, by the coordinator or by the worker
/// that checks first: which limit, the size where known, and how to raise it.
pub fn result_over_limit(task: i64, bytes: Option<u64>, limit: u64) -> String {
    let of = bytes.map_or(String::new(), |b| format!(" ({b} bytes)"));
    format!(
        "result of task {task}{of} is over this coordinator's limit of {} per task result; raise it with `tessera serve --max-result-mib`, or cut the job finer (--samples-per-task, --tile)",
        human_size(limit)
    )
}

/// A worker renewing its lease.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Heartbeat {
    pub lease: i64,
    pub worker: String,
    /// The worker process's CPU use since its last report, in cores.
    #[serde(default)]
    pub cpu: Option<f32>,
}

/// A worker giving up a task.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Failure {
    pub lease: i64,
    pub worker: String,
    pub error: String,
    /// No retry can mend it: the job's own inputs are at fault (its bundle is not in the
    /// object store, its scene does not load or plan from the bundle's verified bytes), so
    /// the job fails at once with this error.
    #[serde(default)]
    pub permanent: bool,
}

/// A worker as the coordinator sees it.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct WorkerStatus {
    pub id: String,
    pub name: String,
    pub host: String,
    pub pid: u32,
    pub slots: u32,
    pub version: String,
    pub first_seen_ms: i64,
    pub last_seen_ms: i64,
    /// Seen within the last few lease periods.
    pub alive: bool,
    pub scene_builds: u64,
    pub tasks_done: u64,
    /// Tasks it holds a lease on now.
    pub leased_tasks: Vec<i64>,
    pub tags: Vec<String>,
    /// Finishing what it holds and taking nothing more.
    pub draining: bool,
    /// CPU use of its process at its last report, in cores.
    pub cpu: Option<f32>,
    /// Pixel samples (pixels × samples of its tile tasks) per second of task time.
    pub samples_per_second: Option<f64>,
    /// Task failures it reported.
    pub failures: u64,
    /// Jobs it is blocklisted for.
    pub blocklisted_for: Vec<i64>,
}

/// A rendering method, as the registry lists it.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct MethodStatus {
    pub name: String,
    pub summary: String,
    /// What `spp` counts for it.
    pub spp: String,
    /// Scene settings (`integrator.…`) it reads besides spp, depth and seed.
    pub settings: Vec<SettingStatus>,
}

/// A scene setting a method reads.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct SettingStatus {
    /// Its path under `integrator` (`photon_map.alpha`).
    pub name: String,
    /// The values it admits (`a fraction in (0, 1)`).
    pub values: String,
    /// What it sets, and what is chosen where the scene leaves it out.
    pub doc: String,
}

/// Checks a list of worker tags: at most 32, each 1 to 64 letters, digits, `-`, `_` or `.`.
pub fn check_tags(tags: &[String], field: &str) -> Result<(), String> {
    if tags.len() > 32 {
        return Err(format!(
            "{field}: expected at most 32 tags, got {}",
            tags.len()
        ));
    }
    for t in tags {
        let ok = !t.is_empty()
            && t.len() <= 64
            && t.chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'));
        if !ok {
            return Err(format!(
                "{field}: expected tags of 1 to 64 letters, digits, '-', '_' or '.', got \"{t}\""
            ));
        }
    }
    Ok(())
}

/// What a token may do (see docs/src/farm/roles.md, the route-by-role table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum Role {
    /// Everything a person does: every job, the farm's workers, its users.
    Admin,
    /// Submits jobs; steers and downloads its own; reads everything.
    Artist,
    /// Reads: jobs, their progress and previews, workers.
    Viewer,
    /// A worker: leases tasks and uploads their results.
    Worker,
}

impl Role {
    pub const ALL: [Role; 4] = [Role::Admin, Role::Artist, Role::Viewer, Role::Worker];

    pub fn as_str(self) -> &'static str {
        match self {
            Role::Admin => "admin",
            Role::Artist => "artist",
            Role::Viewer => "viewer",
            Role::Worker => "worker",
        }
    }

    pub fn parse(s: &str) -> Option<Role> {
        Role::ALL.into_iter().find(|r| r.as_str() == s)
    }
}

/// A user (or a worker) with a token of its own.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct User {
    pub name: String,
    pub role: Role,
    /// Milliseconds since the Unix epoch.
    pub created_ms: i64,
    /// When its token was revoked; it is refused from then on.
    pub revoked_ms: Option<i64>,
}

/// A user to add (`POST /v1/users`).
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct NewUser {
    /// 1 to 64 letters, digits, `-`, `_` or `.`; for a worker, the name it runs under
    /// (`tessera worker --name`).
    pub name: String,
    pub role: Role,
}

/// A user just added, with its token: shown once, kept only as a hash.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
pub struct AddedUser {
    pub user: User,
    pub token: String,
}

/// Checks a user's name: 1 to 64 letters, digits, `-`, `_` or `.`.
pub fn check_user_name(name: &str) -> Result<(), String> {
    let ok = !name.is_empty()
        && name.len() <= 64
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'));
    match ok {
        true => Ok(()),
        false => Err(format!(
            "name: expected 1 to 64 letters, digits, '-', '_' or '.', got \"{name}\""
        )),
    }
}
