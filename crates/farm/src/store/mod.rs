//! The job store: jobs, frames, tasks, leases (attempts), workers and bundles in SQLite.
//!
//! Everything the coordinator needs to resume lives here; tile results are files beside it,
//! named by task and lease, and a task is `done` only once its file is in place. Leases are
//! fenced: every grant is a row of `attempts` whose id is the lease token, and a heartbeat,
//! result or failure counts only if it carries the task's current token.

mod passes;

use std::path::Path;
use std::sync::{Mutex, MutexGuard};

use rusqlite::{Connection, OptionalExtension, Transaction, params};

pub use passes::{CacheEntry, NewPass, NextStage, PassStart};

use crate::job::{FrameRange, PassKind, RenderSettings, TaskKind, TaskSpec};
use crate::protocol::{
    FrameStatus, JobState, JobStatus, LeaseGrant, TaskCounts, TaskStatus, WorkerInfo, WorkerStatus,
};

pub type Result<T> = std::result::Result<T, rusqlite::Error>;

const SCHEMA: &str = r#"
PRAGMA journal_mode = WAL;
PRAGMA synchronous = NORMAL;
PRAGMA foreign_keys = ON;
CREATE TABLE IF NOT EXISTS bundles (
    hash TEXT PRIMARY KEY,
    bytes INTEGER NOT NULL,
    created_ms INTEGER NOT NULL
);
CREATE TABLE IF NOT EXISTS jobs (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    name TEXT NOT NULL,
    state TEXT NOT NULL,
    priority INTEGER NOT NULL,
    created_ms INTEGER NOT NULL,
    finished_ms INTEGER,
    bundle TEXT NOT NULL REFERENCES bundles(hash),
    scene TEXT NOT NULL,
    settings TEXT NOT NULL,
    first_frame INTEGER NOT NULL,
    last_frame INTEGER NOT NULL,
    width INTEGER NOT NULL,
    height INTEGER NOT NULL,
    spp INTEGER NOT NULL,
    decisions TEXT NOT NULL,
    error TEXT,
    planned_tasks INTEGER NOT NULL DEFAULT 0
);
CREATE TABLE IF NOT EXISTS frames (
    job_id INTEGER NOT NULL REFERENCES jobs(id),
    frame INTEGER NOT NULL,
    state TEXT NOT NULL,
    tasks_total INTEGER NOT NULL,
    tasks_done INTEGER NOT NULL DEFAULT 0,
    finished_ms INTEGER,
    estimated_rel_mse REAL,
    PRIMARY KEY (job_id, frame)
);
CREATE TABLE IF NOT EXISTS tasks (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    job_id INTEGER NOT NULL REFERENCES jobs(id),
    priority INTEGER NOT NULL,
    frame INTEGER NOT NULL,
    tile_index INTEGER NOT NULL,
    x0 INTEGER NOT NULL, y0 INTEGER NOT NULL, x1 INTEGER NOT NULL, y1 INTEGER NOT NULL,
    sample_start INTEGER NOT NULL,
    sample_end INTEGER NOT NULL,
    kind TEXT NOT NULL DEFAULT 'tile',
    state TEXT NOT NULL,
    attempts INTEGER NOT NULL DEFAULT 0,
    lease INTEGER,
    worker TEXT,
    lease_expires_ms INTEGER,
    seconds REAL,
    error TEXT
);
CREATE INDEX IF NOT EXISTS tasks_queue ON tasks (priority DESC, job_id, id) WHERE state = 'queued';
CREATE INDEX IF NOT EXISTS tasks_leased ON tasks (lease_expires_ms) WHERE state = 'leased';
CREATE INDEX IF NOT EXISTS tasks_frame ON tasks (job_id, frame, tile_index, sample_start);
CREATE TABLE IF NOT EXISTS attempts (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    task_id INTEGER NOT NULL REFERENCES tasks(id),
    worker TEXT NOT NULL,
    started_ms INTEGER NOT NULL,
    ended_ms INTEGER,
    outcome TEXT,
    error TEXT
);
CREATE TABLE IF NOT EXISTS artifacts (
    job_id INTEGER NOT NULL REFERENCES jobs(id),
    frame INTEGER NOT NULL,
    kind TEXT NOT NULL,
    path TEXT NOT NULL,
    bytes INTEGER NOT NULL,
    sha256 TEXT NOT NULL,
    created_ms INTEGER NOT NULL,
    PRIMARY KEY (job_id, frame, kind)
);
CREATE TABLE IF NOT EXISTS passes (
    job_id INTEGER NOT NULL REFERENCES jobs(id),
    kind TEXT NOT NULL,
    key TEXT NOT NULL,
    state TEXT NOT NULL,
    tasks_total INTEGER NOT NULL DEFAULT 0,
    tasks_done INTEGER NOT NULL DEFAULT 0,
    PRIMARY KEY (job_id, kind)
);
CREATE TABLE IF NOT EXISTS cache (
    key TEXT PRIMARY KEY,
    kind TEXT NOT NULL,
    path TEXT NOT NULL,
    bytes INTEGER NOT NULL,
    sha256 TEXT NOT NULL,
    job_id INTEGER NOT NULL,
    created_ms INTEGER NOT NULL
);
CREATE TABLE IF NOT EXISTS workers (
    id TEXT PRIMARY KEY,
    name TEXT NOT NULL,
    host TEXT NOT NULL,
    pid INTEGER NOT NULL,
    slots INTEGER NOT NULL,
    version TEXT NOT NULL,
    first_seen_ms INTEGER NOT NULL,
    last_seen_ms INTEGER NOT NULL,
    scene_builds INTEGER NOT NULL,
    tasks_done INTEGER NOT NULL DEFAULT 0
);
"#;

/// A job ready to insert: its row and the tasks of every frame.
pub struct NewJob {
    pub name: String,
    pub priority: i32,
    pub bundle: String,
    pub scene: String,
    pub settings: RenderSettings,
    pub frames: FrameRange,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub decisions: Vec<String>,
    /// Tile tasks of each frame, in stitch order: queued at once, or when the passes are done.
    pub tasks: Vec<Vec<TaskSpec>>,
    /// Precomputation passes, in order (empty for integrators without any).
    pub passes: Vec<NewPass>,
    /// Tasks expected in all (for progress), counting those queued later.
    pub planned_tasks: u64,
}

/// What became of a result.
#[derive(Debug, PartialEq, Eq)]
pub enum Completion {
    /// The lease was not current (expired and reassigned, or the job ended): dropped.
    Stale,
    /// Accepted; `Some(frame)` when it was the last task of that frame, `Some(pass)` when
    /// the last task of that pass.
    Accepted {
        frame_complete: Option<u32>,
        pass_complete: Option<PassKind>,
    },
}

/// What became of a failure report or an expired lease.
#[derive(Debug, PartialEq, Eq)]
pub enum Retry {
    Stale,
    Requeued,
    /// Out of attempts: the job failed with this error.
    JobFailed(String),
}

/// A file the coordinator produced for a frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Artifact {
    /// `exr` or `png`.
    pub kind: String,
    /// Relative to the data directory.
    pub path: String,
    pub bytes: u64,
    pub sha256: String,
}

/// Queue gauges for `/metrics` and `/healthz`.
pub struct Gauges {
    pub queued: u64,
    pub leased: u64,
    /// Jobs by state.
    pub jobs: Vec<(String, u64)>,
}

pub struct Store {
    conn: Mutex<Connection>,
}

fn task_spec(row: &rusqlite::Row, at: usize) -> Result<TaskSpec> {
    Ok(TaskSpec {
        kind: TaskKind::parse(&row.get::<_, String>(at)?),
        frame: row.get(at + 1)?,
        tile_index: row.get(at + 2)?,
        x0: row.get(at + 3)?,
        y0: row.get(at + 4)?,
        x1: row.get(at + 5)?,
        y1: row.get(at + 6)?,
        sample_start: row.get(at + 7)?,
        sample_end: row.get(at + 8)?,
    })
}

const SPEC_COLUMNS: &str = "kind, frame, tile_index, x0, y0, x1, y1, sample_start, sample_end";

fn json<T: serde::Serialize>(v: &T) -> String {
    serde_json::to_string(v).unwrap_or_default()
}

impl Store {
    /// Opens (or creates) the store at `path`.
    pub fn open(path: &Path) -> Result<Store> {
        let conn = Connection::open(path)?;
        conn.busy_timeout(std::time::Duration::from_secs(10))?;
        conn.execute_batch(SCHEMA)?;
        // Stores made before tasks had kinds.
        let has_kind: bool = conn
            .prepare("SELECT 1 FROM pragma_table_info('tasks') WHERE name = 'kind'")?
            .exists([])?;
        if !has_kind {
            conn.execute_batch("ALTER TABLE tasks ADD COLUMN kind TEXT NOT NULL DEFAULT 'tile'")?;
        }
        // Stores made before jobs said how many tasks they plan.
        let has_planned: bool = conn
            .prepare("SELECT 1 FROM pragma_table_info('jobs') WHERE name = 'planned_tasks'")?
            .exists([])?;
        if !has_planned {
            conn.execute_batch(
                "ALTER TABLE jobs ADD COLUMN planned_tasks INTEGER NOT NULL DEFAULT 0",
            )?;
        }
        Ok(Store {
            conn: Mutex::new(conn),
        })
    }

    fn conn(&self) -> MutexGuard<'_, Connection> {
        // A panic while holding the lock leaves SQLite consistent (transactions roll back).
        self.conn.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub fn insert_bundle(&self, hash: &str, bytes: u64, now: i64) -> Result<()> {
        self.conn().execute(
            "INSERT OR IGNORE INTO bundles (hash, bytes, created_ms) VALUES (?1, ?2, ?3)",
            params![hash, bytes as i64, now],
        )?;
        Ok(())
    }

    pub fn bundle_exists(&self, hash: &str) -> Result<bool> {
        self.conn()
            .query_row("SELECT 1 FROM bundles WHERE hash = ?1", [hash], |_| Ok(()))
            .optional()
            .map(|r| r.is_some())
    }

    pub fn insert_job(&self, job: &NewJob, now: i64) -> Result<i64> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        tx.execute(
            "INSERT INTO jobs (name, state, priority, created_ms, bundle, scene, settings,
                first_frame, last_frame, width, height, spp, decisions, planned_tasks)
             VALUES (?1, 'queued', ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13)",
            params![
                job.name,
                job.priority,
                now,
                job.bundle,
                job.scene,
                json(&job.settings),
                job.frames.first,
                job.frames.last,
                job.width,
                job.height,
                job.spp,
                json(&job.decisions),
                job.planned_tasks as i64,
            ],
        )?;
        let id = tx.last_insert_rowid();
        {
            let mut frame = tx.prepare(
                "INSERT INTO frames (job_id, frame, state, tasks_total) VALUES (?1, ?2, 'queued', ?3)",
            )?;
            for (f, tasks) in job.frames.iter().zip(&job.tasks) {
                frame.execute(params![id, f, tasks.len() as i64])?;
            }
        }
        let tiles_now = Self::insert_passes(&tx, id, &job.passes)?;
        if tiles_now {
            Self::insert_tasks(&tx, id, job.tasks.iter().flatten())?;
        }
        tx.commit()?;
        Ok(id)
    }

    /// Queues tasks of a job (at the job's priority, copied for the queue index).
    fn insert_tasks<'a>(
        tx: &Transaction,
        job: i64,
        tasks: impl IntoIterator<Item = &'a TaskSpec>,
    ) -> Result<()> {
        let mut insert = tx.prepare(
            "INSERT INTO tasks (job_id, priority, frame, tile_index, x0, y0, x1, y1,
                sample_start, sample_end, kind, state)
             SELECT ?1, priority, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, 'queued' FROM jobs WHERE id = ?1",
        )?;
        for t in tasks {
            insert.execute(params![
                job,
                t.frame,
                t.tile_index,
                t.x0,
                t.y0,
                t.x1,
                t.y1,
                t.sample_start,
                t.sample_end,
                t.kind.as_str()
            ])?;
        }
        Ok(())
    }

    fn upsert_worker(tx: &Transaction, w: &WorkerInfo, now: i64) -> Result<()> {
        tx.execute(
            "INSERT INTO workers (id, name, host, pid, slots, version, first_seen_ms, last_seen_ms, scene_builds)
             VALUES (?1, ?2, ?3, ?8, ?4, ?5, ?6, ?6, ?7)
             ON CONFLICT (id) DO UPDATE SET last_seen_ms = ?6, scene_builds = ?7, slots = ?4",
            params![w.id, w.name, w.host, w.slots, w.version, now, w.scene_builds as i64, w.pid],
        )?;
        Ok(())
    }

    /// Grants the next task (priority, then job age, then frame and tile order) to `worker`.
    pub fn lease(
        &self,
        worker: &WorkerInfo,
        now: i64,
        lease_ms: u64,
    ) -> Result<Option<LeaseGrant>> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        Self::upsert_worker(&tx, worker, now)?;
        let next: Option<(i64, i64)> = tx
            .query_row(
                "SELECT id, job_id FROM tasks WHERE state = 'queued'
                 ORDER BY priority DESC, job_id, id LIMIT 1",
                [],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .optional()?;
        let Some((task_id, job_id)) = next else {
            tx.commit()?;
            return Ok(None);
        };
        tx.execute(
            "INSERT INTO attempts (task_id, worker, started_ms) VALUES (?1, ?2, ?3)",
            params![task_id, worker.id, now],
        )?;
        let lease = tx.last_insert_rowid();
        tx.execute(
            "UPDATE tasks SET state = 'leased', attempts = attempts + 1, lease = ?2, worker = ?3,
                lease_expires_ms = ?4 WHERE id = ?1",
            params![task_id, lease, worker.id, now + lease_ms as i64],
        )?;
        tx.execute(
            "UPDATE jobs SET state = 'running' WHERE id = ?1 AND state = 'queued'",
            [job_id],
        )?;
        let mut grant = tx.query_row(
            &format!(
                "SELECT j.bundle, j.scene, j.settings, {SPEC_COLUMNS}
                 FROM tasks t JOIN jobs j ON j.id = t.job_id WHERE t.id = ?1"
            ),
            [task_id],
            |r| {
                Ok(LeaseGrant {
                    task_id,
                    lease,
                    lease_ms,
                    job_id,
                    bundle: r.get(0)?,
                    scene: r.get(1)?,
                    settings: serde_json::from_str(&r.get::<_, String>(2)?).unwrap_or_default(),
                    task: task_spec(r, 3)?,
                    artifacts: Vec::new(),
                })
            },
        )?;
        grant.artifacts = Self::artifacts_for(&tx, job_id, grant.task.kind)?;
        tx.commit()?;
        Ok(Some(grant))
    }

    /// Renews a lease; false if it is no longer the task's current lease.
    pub fn heartbeat(
        &self,
        task: i64,
        lease: i64,
        worker: &str,
        now: i64,
        lease_ms: u64,
    ) -> Result<bool> {
        let conn = self.conn();
        conn.execute(
            "UPDATE workers SET last_seen_ms = ?2 WHERE id = ?1",
            params![worker, now],
        )?;
        let n = conn.execute(
            "UPDATE tasks SET lease_expires_ms = ?3
             WHERE id = ?1 AND lease = ?2 AND state = 'leased'",
            params![task, lease, now + lease_ms as i64],
        )?;
        Ok(n == 1)
    }

    /// The task a lease is for, if the lease is current: (job, spec).
    pub fn current_lease(&self, task: i64, lease: i64) -> Result<Option<(i64, TaskSpec)>> {
        self.conn()
            .query_row(
                &format!(
                    "SELECT job_id, {SPEC_COLUMNS} FROM tasks
                     WHERE id = ?1 AND lease = ?2 AND state = 'leased'"
                ),
                params![task, lease],
                |r| Ok((r.get(0)?, task_spec(r, 1)?)),
            )
            .optional()
    }

    /// Marks a task done with its result (already on disk), if the lease is still current.
    pub fn complete(&self, task: i64, lease: i64, seconds: f64, now: i64) -> Result<Completion> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        let n = tx.execute(
            "UPDATE tasks SET state = 'done', seconds = ?3, lease_expires_ms = NULL
             WHERE id = ?1 AND lease = ?2 AND state = 'leased'",
            params![task, lease, seconds],
        )?;
        if n == 0 {
            tx.execute(
                "UPDATE attempts SET ended_ms = ?2, outcome = 'stale' WHERE id = ?1 AND outcome IS NULL",
                params![lease, now],
            )?;
            tx.commit()?;
            return Ok(Completion::Stale);
        }
        tx.execute(
            "UPDATE attempts SET ended_ms = ?2, outcome = 'done' WHERE id = ?1",
            params![lease, now],
        )?;
        tx.execute(
            "UPDATE workers SET tasks_done = tasks_done + 1, last_seen_ms = ?2
             WHERE id = (SELECT worker FROM attempts WHERE id = ?1)",
            params![lease, now],
        )?;
        let (job, frame, kind): (i64, u32, String) = tx.query_row(
            "SELECT job_id, frame, kind FROM tasks WHERE id = ?1",
            [task],
            |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)),
        )?;
        if let Some(pass) = TaskKind::parse(&kind).pass() {
            let (done, total): (i64, i64) = tx.query_row(
                "UPDATE passes SET tasks_done = tasks_done + 1
                 WHERE job_id = ?1 AND kind = ?2 RETURNING tasks_done, tasks_total",
                params![job, pass.as_str()],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )?;
            tx.commit()?;
            return Ok(Completion::Accepted {
                frame_complete: None,
                pass_complete: (done == total).then_some(pass),
            });
        }
        let (done, total): (i64, i64) = tx.query_row(
            "UPDATE frames SET tasks_done = tasks_done + 1, state = 'running'
             WHERE job_id = ?1 AND frame = ?2 RETURNING tasks_done, tasks_total",
            params![job, frame],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )?;
        tx.commit()?;
        Ok(Completion::Accepted {
            frame_complete: (done == total).then_some(frame),
            pass_complete: None,
        })
    }

    /// Ends an attempt that failed (`outcome` "failed") or whose lease expired ("expired"):
    /// requeues the task, or fails the job once the task has had `max_attempts` leases.
    fn retry(
        tx: &Transaction,
        task: i64,
        lease: i64,
        outcome: &str,
        error: &str,
        now: i64,
        max_attempts: u32,
    ) -> Result<Retry> {
        let row: Option<(i64, u32, u32, u32, String)> = tx
            .query_row(
                "SELECT t.job_id, t.attempts, t.frame, t.tile_index, COALESCE(a.worker, '')
                 FROM tasks t LEFT JOIN attempts a ON a.id = t.lease
                 WHERE t.id = ?1 AND t.lease = ?2 AND t.state = 'leased'",
                params![task, lease],
                |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?)),
            )
            .optional()?;
        let Some((job, attempts, frame, tile, worker)) = row else {
            return Ok(Retry::Stale);
        };
        tx.execute(
            "UPDATE attempts SET ended_ms = ?2, outcome = ?3, error = ?4 WHERE id = ?1",
            params![lease, now, outcome, error],
        )?;
        if attempts < max_attempts {
            tx.execute(
                "UPDATE tasks SET state = 'queued', lease = NULL, worker = NULL,
                    lease_expires_ms = NULL, error = ?2 WHERE id = ?1",
                params![task, error],
            )?;
            return Ok(Retry::Requeued);
        }
        let message = format!(
            "task {task} (frame {frame}, tile {tile}) failed {attempts} times; last attempt on worker {worker}: {error}"
        );
        tx.execute(
            "UPDATE tasks SET state = 'failed', lease_expires_ms = NULL, error = ?2 WHERE id = ?1",
            params![task, error],
        )?;
        Self::end_job(tx, job, "failed", Some(&message), now)?;
        Ok(Retry::JobFailed(message))
    }

    /// A worker reports that it could not render a task.
    pub fn fail(
        &self,
        task: i64,
        lease: i64,
        error: &str,
        now: i64,
        max_attempts: u32,
    ) -> Result<Retry> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        let r = Self::retry(&tx, task, lease, "failed", error, now, max_attempts)?;
        tx.commit()?;
        Ok(r)
    }

    /// Takes back every lease that expired before `now`. Returns what became of each.
    pub fn expire(&self, now: i64, max_attempts: u32) -> Result<Vec<(i64, Retry)>> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        let expired: Vec<(i64, i64)> = tx
            .prepare(
                "SELECT id, lease FROM tasks WHERE state = 'leased' AND lease_expires_ms < ?1",
            )?
            .query_map([now], |r| Ok((r.get(0)?, r.get(1)?)))?
            .collect::<Result<_>>()?;
        let mut out = Vec::with_capacity(expired.len());
        for (task, lease) in expired {
            let r = Self::retry(
                &tx,
                task,
                lease,
                "expired",
                "the lease expired: the worker stopped renewing it (died, hung or lost the network)",
                now,
                max_attempts,
            )?;
            out.push((task, r));
        }
        tx.commit()?;
        Ok(out)
    }

    /// Ends a job that has not ended (`cancelled` or `failed`, with an error), cancelling its
    /// open tasks; false if it had ended.
    fn end_job(
        tx: &Transaction,
        job: i64,
        state: &str,
        error: Option<&str>,
        now: i64,
    ) -> Result<bool> {
        let n = tx.execute(
            "UPDATE jobs SET state = ?2, error = COALESCE(?3, error), finished_ms = ?4
             WHERE id = ?1 AND state IN ('queued', 'running')",
            params![job, state, error, now],
        )?;
        if n == 1 {
            tx.execute(
                "UPDATE tasks SET state = 'cancelled', lease_expires_ms = NULL
                 WHERE job_id = ?1 AND state IN ('queued', 'leased')",
                [job],
            )?;
        }
        Ok(n == 1)
    }

    /// Cancels a job that has not ended; false if it had.
    pub fn cancel(&self, job: i64, now: i64) -> Result<bool> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        let ended = Self::end_job(&tx, job, "cancelled", None, now)?;
        tx.commit()?;
        Ok(ended)
    }

    /// Fails a job that has not ended (a stitch that could not be written, say).
    pub fn fail_job(&self, job: i64, error: &str, now: i64) -> Result<()> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        Self::end_job(&tx, job, "failed", Some(error), now)?;
        tx.commit()
    }

    /// Adds a round of tasks to a frame (adaptive sampling).
    pub fn add_tasks(&self, job: i64, frame: u32, tasks: &[TaskSpec]) -> Result<()> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        Self::insert_tasks(&tx, job, tasks)?;
        tx.execute(
            "UPDATE frames SET tasks_total = tasks_total + ?3 WHERE job_id = ?1 AND frame = ?2",
            params![job, frame, tasks.len() as i64],
        )?;
        tx.commit()
    }

    /// Done tasks of a frame in stitch order: (task id, lease, spec).
    pub fn frame_results(
        &self,
        job: i64,
        frame: u32,
        kind: TaskKind,
    ) -> Result<Vec<(i64, i64, TaskSpec)>> {
        let conn = self.conn();
        let mut stmt = conn.prepare(&format!(
            "SELECT id, lease, {SPEC_COLUMNS} FROM tasks
             WHERE job_id = ?1 AND frame = ?2 AND state = 'done' AND kind = ?3
             ORDER BY tile_index, sample_start"
        ))?;
        stmt.query_map(params![job, frame, kind.as_str()], |r| {
            Ok((r.get(0)?, r.get(1)?, task_spec(r, 2)?))
        })?
        .collect()
    }

    /// A job's film size (width, height).
    pub fn film_size(&self, job: i64) -> Result<Option<(u32, u32)>> {
        self.conn()
            .query_row("SELECT width, height FROM jobs WHERE id = ?1", [job], |r| {
                Ok((r.get(0)?, r.get(1)?))
            })
            .optional()
    }

    /// Done tasks of iteration `t` of an SPPM frame in fold (chunk) order: (task id, lease,
    /// spec).
    pub fn sppm_results(&self, job: i64, frame: u32, t: u32) -> Result<Vec<(i64, i64, TaskSpec)>> {
        let conn = self.conn();
        let mut stmt = conn.prepare(&format!(
            "SELECT id, lease, {SPEC_COLUMNS} FROM tasks
             WHERE job_id = ?1 AND frame = ?2 AND state = 'done' AND kind = 'sppm'
               AND sample_start = ?3
             ORDER BY tile_index"
        ))?;
        stmt.query_map(params![job, frame, t], |r| {
            Ok((r.get(0)?, r.get(1)?, task_spec(r, 2)?))
        })?
        .collect()
    }

    /// Marks a stitched frame done with its files (kind, path relative to the data
    /// directory, bytes, SHA-256), and the job done when it was its last frame.
    /// Returns whether the job is now done.
    pub fn frame_stitched(
        &self,
        job: i64,
        frame: u32,
        files: &[Artifact],
        estimated_rel_mse: Option<f64>,
        now: i64,
    ) -> Result<bool> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        for a in files {
            tx.execute(
                "INSERT OR REPLACE INTO artifacts (job_id, frame, kind, path, bytes, sha256, created_ms)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
                params![job, frame, a.kind, a.path, a.bytes as i64, a.sha256, now],
            )?;
        }
        tx.execute(
            "UPDATE frames SET state = 'done', finished_ms = ?3, estimated_rel_mse = ?4
             WHERE job_id = ?1 AND frame = ?2",
            params![job, frame, now, estimated_rel_mse],
        )?;
        let left: i64 = tx.query_row(
            "SELECT COUNT(*) FROM frames WHERE job_id = ?1 AND state != 'done'",
            [job],
            |r| r.get(0),
        )?;
        let done = left == 0
            && tx.execute(
                "UPDATE jobs SET state = 'done', finished_ms = ?2
                 WHERE id = ?1 AND state IN ('queued', 'running')",
                params![job, now],
            )? == 1;
        tx.commit()?;
        Ok(done)
    }

    /// Frames whose tasks are all done but that were not stitched (a restart in between).
    pub fn unstitched_frames(&self) -> Result<Vec<(i64, u32)>> {
        let conn = self.conn();
        let mut stmt = conn.prepare(
            "SELECT f.job_id, f.frame FROM frames f JOIN jobs j ON j.id = f.job_id
             WHERE f.state != 'done' AND f.tasks_done = f.tasks_total AND f.tasks_total > 0
               AND j.state IN ('queued', 'running')
             ORDER BY f.job_id, f.frame",
        )?;
        stmt.query_map([], |r| Ok((r.get(0)?, r.get(1)?)))?
            .collect()
    }

    /// (bundle, scene, settings, frames) of a job.
    pub fn job_source(
        &self,
        job: i64,
    ) -> Result<Option<(String, String, RenderSettings, FrameRange)>> {
        self.conn()
            .query_row(
                "SELECT bundle, scene, settings, first_frame, last_frame FROM jobs WHERE id = ?1",
                [job],
                |r| {
                    Ok((
                        r.get(0)?,
                        r.get(1)?,
                        serde_json::from_str(&r.get::<_, String>(2)?).unwrap_or_default(),
                        FrameRange {
                            first: r.get(3)?,
                            last: r.get(4)?,
                        },
                    ))
                },
            )
            .optional()
    }

    pub fn job(&self, id: i64) -> Result<Option<JobStatus>> {
        Ok(self.jobs_where("WHERE j.id = ?1", [id], true)?.pop())
    }

    /// Every job, newest first, without per-frame detail.
    pub fn jobs(&self) -> Result<Vec<JobStatus>> {
        self.jobs_where("", [], false)
    }

    fn jobs_where<P: rusqlite::Params>(
        &self,
        filter: &str,
        p: P,
        frames: bool,
    ) -> Result<Vec<JobStatus>> {
        let conn = self.conn();
        let mut stmt = conn.prepare(&format!(
            "SELECT j.id, j.name, j.state, j.priority, j.created_ms, j.finished_ms, j.bundle, j.scene,
                j.settings, j.first_frame, j.last_frame, j.width, j.height, j.spp, j.decisions, j.error,
                COUNT(t.id),
                SUM(t.state = 'queued'), SUM(t.state = 'leased'), SUM(t.state = 'done'),
                SUM(t.state = 'failed'), SUM(t.state = 'cancelled'), SUM(t.attempts),
                j.planned_tasks
             FROM jobs j LEFT JOIN tasks t ON t.job_id = j.id {filter}
             GROUP BY j.id ORDER BY j.id DESC"
        ))?;
        let mut jobs: Vec<JobStatus> = stmt
            .query_map(p, |r| {
                let count = |i: usize| -> Result<u64> {
                    Ok(r.get::<_, Option<i64>>(i)?.unwrap_or(0) as u64)
                };
                let tasks = TaskCounts {
                    total: count(16)?,
                    queued: count(17)?,
                    leased: count(18)?,
                    done: count(19)?,
                    failed: count(20)?,
                    cancelled: count(21)?,
                    planned: count(23)?,
                };
                let expected = tasks.total.max(tasks.planned);
                Ok(JobStatus {
                    id: r.get(0)?,
                    name: r.get(1)?,
                    state: JobState::parse(&r.get::<_, String>(2)?),
                    priority: r.get(3)?,
                    created_ms: r.get(4)?,
                    finished_ms: r.get(5)?,
                    bundle: r.get(6)?,
                    scene: r.get(7)?,
                    settings: serde_json::from_str(&r.get::<_, String>(8)?).unwrap_or_default(),
                    frames: FrameRange {
                        first: r.get(9)?,
                        last: r.get(10)?,
                    },
                    width: r.get(11)?,
                    height: r.get(12)?,
                    spp: r.get(13)?,
                    decisions: serde_json::from_str(&r.get::<_, String>(14)?).unwrap_or_default(),
                    error: r.get(15)?,
                    progress: if expected == 0 {
                        0.0
                    } else {
                        tasks.done as f64 / expected as f64
                    },
                    attempts: count(22)?,
                    tasks,
                    frame_status: Vec::new(),
                    passes: Vec::new(),
                })
            })?
            .collect::<Result<_>>()?;
        if frames {
            let mut stmt = conn.prepare(
                "SELECT f.frame, f.state, f.tasks_done, f.tasks_total, a.sha256, f.estimated_rel_mse FROM frames f
                 LEFT JOIN artifacts a ON a.job_id = f.job_id AND a.frame = f.frame AND a.kind = 'exr'
                 WHERE f.job_id = ?1 ORDER BY f.frame",
            )?;
            for job in jobs.iter_mut() {
                job.passes = Self::job_passes(&conn, job.id)?;
                job.frame_status = stmt
                    .query_map([job.id], |r| {
                        let frame: u32 = r.get(0)?;
                        let state: String = r.get(1)?;
                        Ok(FrameStatus {
                            frame,
                            exr: (state == "done")
                                .then(|| format!("/v1/jobs/{}/frames/{frame}/exr", job.id)),
                            state,
                            tasks_done: r.get::<_, i64>(2)? as u64,
                            tasks_total: r.get::<_, i64>(3)? as u64,
                            exr_sha256: r.get(4)?,
                            estimated_rel_mse: r.get(5)?,
                        })
                    })?
                    .collect::<Result<_>>()?;
            }
        }
        Ok(jobs)
    }

    pub fn tasks(&self, job: i64) -> Result<Vec<TaskStatus>> {
        let conn = self.conn();
        let mut stmt = conn.prepare(&format!(
            "SELECT id, state, attempts, worker, seconds, error, {SPEC_COLUMNS}
             FROM tasks WHERE job_id = ?1 ORDER BY id"
        ))?;
        stmt.query_map([job], |r| {
            Ok(TaskStatus {
                id: r.get(0)?,
                state: r.get(1)?,
                attempts: r.get(2)?,
                worker: r.get(3)?,
                seconds: r.get(4)?,
                error: r.get(5)?,
                spec: task_spec(r, 6)?,
            })
        })?
        .collect()
    }

    /// Whether a job exists.
    pub fn job_exists(&self, job: i64) -> Result<bool> {
        self.conn()
            .query_row("SELECT 1 FROM jobs WHERE id = ?1", [job], |_| Ok(()))
            .optional()
            .map(|r| r.is_some())
    }

    /// A frame's state (queued, running, done), if the job has that frame.
    pub fn frame_state(&self, job: i64, frame: u32) -> Result<Option<String>> {
        self.conn()
            .query_row(
                "SELECT state FROM frames WHERE job_id = ?1 AND frame = ?2",
                params![job, frame],
                |r| r.get(0),
            )
            .optional()
    }

    /// Workers, most recently seen first; alive if seen within `alive_ms`.
    pub fn workers(&self, now: i64, alive_ms: i64) -> Result<Vec<WorkerStatus>> {
        let conn = self.conn();
        let mut stmt = conn.prepare(
            "SELECT w.id, w.name, w.host, w.slots, w.version, w.first_seen_ms, w.last_seen_ms,
                w.scene_builds, w.tasks_done, w.pid,
                (SELECT group_concat(t.id) FROM tasks t WHERE t.worker = w.id AND t.state = 'leased')
             FROM workers w ORDER BY w.last_seen_ms DESC",
        )?;
        stmt.query_map([], |r| {
            let last: i64 = r.get(6)?;
            let leased: Option<String> = r.get(10)?;
            Ok(WorkerStatus {
                id: r.get(0)?,
                name: r.get(1)?,
                host: r.get(2)?,
                pid: r.get(9)?,
                slots: r.get(3)?,
                version: r.get(4)?,
                first_seen_ms: r.get(5)?,
                last_seen_ms: last,
                alive: now - last <= alive_ms,
                scene_builds: r.get::<_, i64>(7)? as u64,
                tasks_done: r.get::<_, i64>(8)? as u64,
                leased_tasks: leased
                    .unwrap_or_default()
                    .split(',')
                    .filter_map(|s| s.parse().ok())
                    .collect(),
            })
        })?
        .collect()
    }

    /// Tasks queued and leased over all jobs, and jobs by state.
    pub fn gauges(&self) -> Result<Gauges> {
        let conn = self.conn();
        let (queued, leased): (i64, i64) = conn.query_row(
            "SELECT (SELECT COUNT(*) FROM tasks WHERE state = 'queued'),
                    (SELECT COUNT(*) FROM tasks WHERE state = 'leased')",
            [],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )?;
        let mut stmt = conn.prepare("SELECT state, COUNT(*) FROM jobs GROUP BY state")?;
        let jobs = stmt
            .query_map([], |r| Ok((r.get(0)?, r.get::<_, i64>(1)? as u64)))?
            .collect::<Result<_>>()?;
        Ok(Gauges {
            queued: queued as u64,
            leased: leased as u64,
            jobs,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn worker(id: &str) -> WorkerInfo {
        WorkerInfo {
            id: id.into(),
            name: id.into(),
            host: "test".into(),
            pid: 1,
            slots: 1,
            scene_builds: 0,
            version: "test".into(),
        }
    }

    fn task(frame: u32, tile_index: u32) -> TaskSpec {
        TaskSpec {
            kind: TaskKind::Tile,
            frame,
            tile_index,
            x0: 0,
            y0: 0,
            x1: 1,
            y1: 1,
            sample_start: 0,
            sample_end: 1,
        }
    }

    /// A store with one job per priority given, each of `tasks` tasks in one frame.
    fn store(priorities: &[i32], tasks: u32) -> (tempfile::TempDir, Store, Vec<i64>) {
        let dir = tempfile::tempdir().expect("temp dir");
        let s = Store::open(&dir.path().join("t.db")).expect("open");
        s.insert_bundle("b", 1, 0).expect("bundle");
        let ids = priorities
            .iter()
            .map(|&priority| {
                s.insert_job(
                    &NewJob {
                        name: "j".into(),
                        priority,
                        bundle: "b".into(),
                        scene: "scene.json".into(),
                        settings: RenderSettings::default(),
                        frames: FrameRange::single(1),
                        width: 1,
                        height: 1,
                        spp: 1,
                        decisions: vec![],
                        tasks: vec![(0..tasks).map(|i| task(1, i)).collect()],
                        passes: vec![],
                        planned_tasks: tasks as u64,
                    },
                    0,
                )
                .expect("job")
            })
            .collect();
        (dir, s, ids)
    }

    #[test]
    fn leases_go_by_priority_then_age_then_task_order() {
        let (_d, s, jobs) = store(&[0, 5, 5], 2);
        let order: Vec<(i64, u32)> = (0..6)
            .map(|_| {
                let g = s
                    .lease(&worker("w"), 0, 1000)
                    .expect("lease")
                    .expect("a task");
                (g.job_id, g.task.tile_index)
            })
            .collect();
        let (low, high_old, high_new) = (jobs[0], jobs[1], jobs[2]);
        assert_eq!(
            order,
            [
                (high_old, 0),
                (high_old, 1),
                (high_new, 0),
                (high_new, 1),
                (low, 0),
                (low, 1)
            ]
        );
        assert!(s.lease(&worker("w"), 0, 1000).expect("lease").is_none());
    }

    #[test]
    fn a_stale_lease_cannot_heartbeat_or_complete_after_reassignment() {
        let (_d, s, jobs) = store(&[0], 1);
        let first = s.lease(&worker("a"), 0, 100).expect("lease").expect("task");
        // The lease expires and the task goes to another worker.
        assert_eq!(s.expire(50, 3).expect("expire"), vec![]);
        assert_eq!(
            s.expire(101, 3).expect("expire"),
            vec![(first.task_id, Retry::Requeued)]
        );
        let second = s
            .lease(&worker("b"), 102, 100)
            .expect("lease")
            .expect("task");
        assert_eq!(second.task_id, first.task_id);
        assert_ne!(second.lease, first.lease);
        assert!(
            !s.heartbeat(first.task_id, first.lease, "a", 103, 100)
                .expect("hb")
        );
        assert!(
            s.current_lease(first.task_id, first.lease)
                .expect("q")
                .is_none()
        );
        assert_eq!(
            s.complete(first.task_id, first.lease, 1.0, 104).expect("c"),
            Completion::Stale
        );
        // The current holder completes; its frame is then complete.
        assert!(
            s.heartbeat(second.task_id, second.lease, "b", 105, 100)
                .expect("hb")
        );
        assert_eq!(
            s.complete(second.task_id, second.lease, 1.0, 106)
                .expect("c"),
            Completion::Accepted {
                frame_complete: Some(1),
                pass_complete: None,
            }
        );
        assert_eq!(
            s.complete(second.task_id, second.lease, 1.0, 107)
                .expect("c"),
            Completion::Stale
        );
        let job = s.job(jobs[0]).expect("q").expect("job");
        assert_eq!((job.tasks.done, job.attempts), (1, 2));
        assert_eq!(
            s.frame_results(jobs[0], 1, TaskKind::Tile)
                .expect("q")
                .len(),
            1
        );
        // A later round (adaptive sampling) reopens the frame until its tasks are done too.
        s.add_tasks(
            jobs[0],
            1,
            &[TaskSpec {
                sample_start: 1,
                sample_end: 2,
                ..task(1, 0)
            }],
        )
        .expect("add");
        let g = s
            .lease(&worker("b"), 110, 100)
            .expect("lease")
            .expect("the new round");
        assert_eq!((g.task.sample_start, g.task.sample_end), (1, 2));
        assert_eq!(
            s.complete(g.task_id, g.lease, 1.0, 111).expect("c"),
            Completion::Accepted {
                frame_complete: Some(1),
                pass_complete: None,
            }
        );
        assert_eq!(
            s.frame_results(jobs[0], 1, TaskKind::Tile)
                .expect("q")
                .len(),
            2
        );
    }

    #[test]
    fn a_task_failing_max_attempts_times_fails_its_job_with_the_error() {
        let (_d, s, jobs) = store(&[0], 2);
        for attempt in 1..=3 {
            let g = s
                .lease(&worker("w"), 0, 1000)
                .expect("lease")
                .expect("task");
            assert_eq!(g.task.tile_index, 0, "the failed task is retried first");
            let r = s
                .fail(g.task_id, g.lease, &format!("boom {attempt}"), 1, 3)
                .expect("fail");
            if attempt < 3 {
                assert_eq!(r, Retry::Requeued);
            } else {
                assert!(
                    matches!(&r, Retry::JobFailed(m) if m.contains("boom 3") && m.contains("3 times")),
                    "{r:?}"
                );
            }
        }
        let job = s.job(jobs[0]).expect("q").expect("job");
        assert_eq!(job.state, JobState::Failed);
        assert!(
            job.error
                .as_deref()
                .unwrap_or("")
                .contains("worker w: boom 3"),
            "{:?}",
            job.error
        );
        assert_eq!((job.tasks.failed, job.tasks.cancelled), (1, 1));
        assert!(s.lease(&worker("w"), 2, 1000).expect("lease").is_none());
    }
}
