//! The job store: jobs, frames, tasks, leases (attempts), passes, the artifact cache, workers
//! and bundles in SQLite.
//!
//! Everything the coordinator needs to resume lives here; task results, frame checkpoints and
//! artifacts are files beside it, and a task is `done` only once its result file is in place.
//! Leases are fenced: every grant is a row of `attempts` whose id is the lease token, and a
//! heartbeat, result or failure counts only if it carries the task's current token. Nothing in
//! the store knows one rendering method from another: tasks are (frame, step, index) with the
//! core's task description.

mod jobs;
mod ops;
mod passes;
mod sessions;
mod tasks;

use std::path::Path;
use std::sync::{Mutex, MutexGuard};

use rusqlite::{Connection, params};

pub use jobs::{Artifact, JobFilter, NewJob};
pub use ops::Blocklisting;
pub use passes::{CacheEntry, NewPass, PassStart};
pub use sessions::Session;
pub use tasks::{Completion, Gauges, Retry, RetryPolicy, StepKey};

use crate::job::TaskSpec;

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("job store: {0}")]
    Sql(#[from] rusqlite::Error),
    /// A row the store cannot read as what it should hold (written by another version, or
    /// edited by hand).
    #[error("job store: {0}")]
    Corrupt(String),
}

pub type Result<T> = std::result::Result<T, StoreError>;

/// The schema's version (SQLite's `user_version`): [`SCHEMA`] makes version 2, and each of
/// [`MIGRATIONS`] takes the store one version further. A store of a version before 2 or after
/// the last is refused.
const SCHEMA_VERSION: i64 = 2 + MIGRATIONS.len() as i64;

/// The migrations after version 2, in order: migration i takes version 2 + i to 3 + i.
const MIGRATIONS: &[&str] = &[
    // 3: farm operations — pausing, requeueing, worker tags and requirements, per-job worker
    // blocklists, draining, worker throughput and CPU, browser sessions.
    r#"
ALTER TABLE jobs ADD COLUMN require_tags TEXT NOT NULL DEFAULT '[]';
ALTER TABLE jobs ADD COLUMN started_ms INTEGER;
ALTER TABLE jobs ADD COLUMN requeued_ms INTEGER NOT NULL DEFAULT 0;
ALTER TABLE workers ADD COLUMN tags TEXT NOT NULL DEFAULT '[]';
ALTER TABLE workers ADD COLUMN draining INTEGER NOT NULL DEFAULT 0;
ALTER TABLE workers ADD COLUMN cpu REAL;
ALTER TABLE workers ADD COLUMN samples_done INTEGER NOT NULL DEFAULT 0;
ALTER TABLE workers ADD COLUMN busy_seconds REAL NOT NULL DEFAULT 0;
ALTER TABLE workers ADD COLUMN failures INTEGER NOT NULL DEFAULT 0;
CREATE INDEX IF NOT EXISTS tasks_job_queued ON tasks (job_id, id) WHERE state = 'queued';
CREATE INDEX IF NOT EXISTS jobs_state ON jobs (state, priority DESC, id);
CREATE TABLE IF NOT EXISTS blocklist (
    job_id INTEGER NOT NULL REFERENCES jobs(id),
    worker TEXT NOT NULL,
    failures INTEGER NOT NULL DEFAULT 0,
    blocked_ms INTEGER,
    last_error TEXT,
    PRIMARY KEY (job_id, worker)
);
CREATE TABLE IF NOT EXISTS sessions (
    id TEXT PRIMARY KEY,
    csrf TEXT NOT NULL,
    created_ms INTEGER NOT NULL,
    expires_ms INTEGER NOT NULL
);
"#,
];

const SCHEMA: &str = r#"
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
    method TEXT NOT NULL,
    decisions TEXT NOT NULL,
    error TEXT,
    planned_tasks INTEGER NOT NULL DEFAULT 0
);
CREATE TABLE IF NOT EXISTS frames (
    job_id INTEGER NOT NULL REFERENCES jobs(id),
    frame INTEGER NOT NULL,
    state TEXT NOT NULL,
    step INTEGER NOT NULL DEFAULT 0,
    tasks_total INTEGER NOT NULL DEFAULT 0,
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
    step INTEGER NOT NULL,
    idx INTEGER NOT NULL,
    kind TEXT NOT NULL,
    x0 INTEGER NOT NULL, y0 INTEGER NOT NULL, x1 INTEGER NOT NULL, y1 INTEGER NOT NULL,
    range_start INTEGER NOT NULL,
    range_end INTEGER NOT NULL,
    state TEXT NOT NULL,
    attempts INTEGER NOT NULL DEFAULT 0,
    lease INTEGER,
    worker TEXT,
    lease_expires_ms INTEGER,
    seconds REAL,
    result_bytes INTEGER,
    payload_bytes INTEGER,
    error TEXT
);
CREATE INDEX IF NOT EXISTS tasks_queue ON tasks (priority DESC, job_id, id) WHERE state = 'queued';
CREATE INDEX IF NOT EXISTS tasks_leased ON tasks (lease_expires_ms) WHERE state = 'leased';
CREATE INDEX IF NOT EXISTS tasks_step ON tasks (job_id, frame, step, idx);
CREATE TABLE IF NOT EXISTS attempts (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    task_id INTEGER NOT NULL REFERENCES tasks(id),
    worker TEXT NOT NULL,
    started_ms INTEGER NOT NULL,
    ended_ms INTEGER,
    outcome TEXT,
    error TEXT
);
CREATE INDEX IF NOT EXISTS attempts_task ON attempts (task_id);
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
    step INTEGER NOT NULL,
    name TEXT NOT NULL,
    key TEXT NOT NULL,
    state TEXT NOT NULL,
    tasks_total INTEGER NOT NULL DEFAULT 0,
    tasks_done INTEGER NOT NULL DEFAULT 0,
    summary TEXT,
    PRIMARY KEY (job_id, step)
);
CREATE TABLE IF NOT EXISTS cache (
    key TEXT PRIMARY KEY,
    name TEXT NOT NULL,
    path TEXT NOT NULL,
    bytes INTEGER NOT NULL,
    sha256 TEXT NOT NULL,
    job_id INTEGER NOT NULL,
    created_ms INTEGER NOT NULL,
    used_ms INTEGER NOT NULL
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

pub struct Store {
    conn: Mutex<Connection>,
}

fn task_spec(row: &rusqlite::Row, at: usize) -> rusqlite::Result<TaskSpec> {
    Ok(TaskSpec {
        kind: row.get(at)?,
        frame: row.get(at + 1)?,
        step: row.get(at + 2)?,
        index: row.get(at + 3)?,
        x0: row.get(at + 4)?,
        y0: row.get(at + 5)?,
        x1: row.get(at + 6)?,
        y1: row.get(at + 7)?,
        start: row.get(at + 8)?,
        end: row.get(at + 9)?,
    })
}

const SPEC_COLUMNS: &str = "kind, frame, step, idx, x0, y0, x1, y1, range_start, range_end";

fn json<T: serde::Serialize>(v: &T) -> String {
    serde_json::to_string(v).unwrap_or_default()
}

/// Reads a JSON column, or says which row and column could not be read and why.
fn from_json<T: serde::de::DeserializeOwned>(text: &str, what: &str) -> Result<T> {
    serde_json::from_str(text).map_err(|e| StoreError::Corrupt(format!("{what}: {e}: {text:?}")))
}

impl Store {
    /// Opens (or creates) the store at `path`; refuses a store of another schema version.
    pub fn open(path: &Path) -> Result<Store> {
        let conn = Connection::open(path)?;
        conn.busy_timeout(std::time::Duration::from_secs(10))?;
        conn.execute_batch(
            "PRAGMA journal_mode = WAL; PRAGMA synchronous = NORMAL; PRAGMA foreign_keys = ON;",
        )?;
        let version: i64 = conn.query_row("PRAGMA user_version", [], |r| r.get(0))?;
        let tables: i64 = conn.query_row(
            "SELECT COUNT(*) FROM sqlite_master WHERE type = 'table'",
            [],
            |r| r.get(0),
        )?;
        if tables > 0 && !(2..=SCHEMA_VERSION).contains(&version) {
            return Err(StoreError::Corrupt(format!(
                "{} has schema version {version}, this coordinator reads versions 2 to {SCHEMA_VERSION}; start with an empty data directory (or move this one away)",
                path.display()
            )));
        }
        let from = if tables > 0 { version } else { 2 };
        if tables == 0 {
            conn.execute_batch(SCHEMA)?;
        }
        // Each migration in one transaction with its version: a crash leaves either.
        for (i, m) in MIGRATIONS.iter().enumerate() {
            let to = 3 + i as i64;
            if from < to {
                conn.execute_batch(&format!("BEGIN; {m} PRAGMA user_version = {to}; COMMIT;"))?;
            }
        }
        conn.execute_batch(&format!("PRAGMA user_version = {SCHEMA_VERSION}"))?;
        Ok(Store {
            conn: Mutex::new(conn),
        })
    }

    fn conn(&self) -> MutexGuard<'_, Connection> {
        // A panic while holding the lock leaves SQLite consistent (transactions roll back).
        self.conn.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Moves the write-ahead log into the database and truncates it (after a job ends: the
    /// log would otherwise keep the size of its busiest moment).
    pub fn checkpoint(&self) -> Result<()> {
        self.conn()
            .query_row("PRAGMA wal_checkpoint(TRUNCATE)", [], |_| Ok(()))?;
        Ok(())
    }

    pub fn insert_bundle(&self, hash: &str, bytes: u64, now: i64) -> Result<()> {
        self.conn().execute(
            "INSERT OR IGNORE INTO bundles (hash, bytes, created_ms) VALUES (?1, ?2, ?3)",
            params![hash, bytes as i64, now],
        )?;
        Ok(())
    }

    pub fn bundle_exists(&self, hash: &str) -> Result<bool> {
        use rusqlite::OptionalExtension;
        Ok(self
            .conn()
            .query_row("SELECT 1 FROM bundles WHERE hash = ?1", [hash], |_| Ok(()))
            .optional()?
            .is_some())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::job::{FrameRange, RenderSettings};
    use crate::protocol::WorkerInfo;

    pub(crate) fn worker(id: &str) -> WorkerInfo {
        WorkerInfo::simulated(id)
    }

    pub(crate) fn task(frame: u32, index: u32) -> TaskSpec {
        TaskSpec::new("tile", frame, 0, index)
            .with_rect(tessera_render::Tile {
                x0: 0,
                y0: 0,
                x1: 1,
                y1: 1,
            })
            .with_range(0, 1)
    }

    /// A store with one job per priority given, each of `tasks` tasks in one frame.
    pub(crate) fn store(priorities: &[i32], tasks: u32) -> (tempfile::TempDir, Store, Vec<i64>) {
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
                        method: "path".into(),
                        decisions: vec![],
                        tasks: vec![(0..tasks).map(|i| task(1, i)).collect()],
                        passes: vec![],
                        planned_tasks: tasks as u64,
                        require_tags: vec![],
                    },
                    0,
                )
                .expect("job")
            })
            .collect();
        (dir, s, ids)
    }

    #[test]
    fn a_store_of_another_schema_version_is_refused() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("old.db");
        let conn = Connection::open(&path).expect("db");
        conn.execute_batch("CREATE TABLE jobs (id INTEGER); PRAGMA user_version = 1;")
            .expect("old schema");
        drop(conn);
        let e = Store::open(&path).err().expect("refused").to_string();
        assert!(
            e.contains("schema version 1") && e.contains("reads versions 2 to"),
            "{e}"
        );
        // An empty file is a new store.
        assert!(Store::open(&dir.path().join("new.db")).is_ok());
    }

    #[test]
    fn a_store_of_version_2_is_migrated_keeping_its_jobs() {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("v2.db");
        let conn = Connection::open(&path).expect("db");
        conn.execute_batch(SCHEMA).expect("version 2 schema");
        conn.execute_batch(
            "PRAGMA user_version = 2;
             INSERT INTO bundles (hash, bytes, created_ms) VALUES ('b', 1, 0);
             INSERT INTO jobs (name, state, priority, created_ms, bundle, scene, settings,
                first_frame, last_frame, width, height, spp, method, decisions)
             VALUES ('old', 'done', 0, 0, 'b', 'scene.json', '{}', 1, 1, 8, 8, 1, 'path', '[]');",
        )
        .expect("a job of version 2");
        drop(conn);
        let s = Store::open(&path).expect("migrated");
        let version: i64 = s
            .conn()
            .query_row("PRAGMA user_version", [], |r| r.get(0))
            .expect("version");
        assert_eq!(version, SCHEMA_VERSION);
        let jobs = s.jobs().expect("jobs");
        assert_eq!((jobs.len(), jobs[0].name.as_str()), (1, "old"));
        assert!(jobs[0].require_tags.is_empty() && jobs[0].started_ms.is_none());
        // Opening again changes nothing.
        drop(s);
        assert_eq!(
            Store::open(&path)
                .expect("again")
                .jobs()
                .expect("jobs")
                .len(),
            1
        );
    }

    #[test]
    fn a_job_whose_stored_settings_cannot_be_read_is_an_error_not_defaults() {
        let (_d, s, jobs) = store(&[0], 1);
        s.conn()
            .execute(
                "UPDATE jobs SET settings = '{\"spp\": \"many\"}' WHERE id = ?1",
                [jobs[0]],
            )
            .expect("edit");
        let e = s.job_source(jobs[0]).expect_err("refused").to_string();
        assert!(e.contains("settings of job") && e.contains("many"), "{e}");
        let e = s.job(jobs[0]).expect_err("refused").to_string();
        assert!(e.contains("settings of job"), "{e}");
        // A lease of its task fails the job with the reason rather than render defaults.
        assert!(s.lease(&worker("w"), 0, 1000).expect("lease").is_none());
        assert_eq!(
            s.job_state(jobs[0]).expect("q"),
            Some(crate::protocol::JobState::Failed)
        );
        let error: String = s
            .conn()
            .query_row("SELECT error FROM jobs WHERE id = ?1", [jobs[0]], |r| {
                r.get(0)
            })
            .expect("error");
        assert!(error.contains("settings of job"), "{error}");
    }
}
