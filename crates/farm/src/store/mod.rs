//! The job store: jobs, frames, tasks, leases (attempts), passes, the artifact cache, workers
//! and bundles, in the embedded SQLite (one coordinator) or in PostgreSQL (any number of
//! coordinators sharing it); see [`db`].
//!
//! Everything the coordinator needs to resume lives here; task results, frame checkpoints and
//! artifacts are files beside it, and a task is `done` only once its result file is in place.
//! Leases are fenced: every grant is a row of `attempts` whose id is the lease token, and a
//! heartbeat, result or failure counts only if it carries the task's current token. Nothing in
//! the store knows one rendering method from another: tasks are (frame, step, index) with the
//! core's task description.

mod claims;
pub(crate) mod db;
mod jobs;
mod ops;
mod passes;
mod sessions;
mod tasks;
mod users;

use std::path::Path;

use db::{Conn, Db, Dialect, Optional, params};

pub use claims::Claim;
pub use jobs::{Artifact, JobFilter, NewJob, Work};
pub use ops::Blocklisting;
pub use passes::{CacheEntry, NewPass, PassStart};
pub use sessions::Session;
pub use tasks::{Completion, Gauges, Retry, RetryPolicy, StepKey};
pub use users::token_hash;

use crate::job::TaskSpec;

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("job store: {0}")]
    Sql(#[from] rusqlite::Error),
    #[error("job store: {}", describe(.0))]
    Postgres(#[from] tokio_postgres::Error),
    #[error("cannot connect to the job store, the {place}: {}", describe(.source))]
    Connect {
        place: String,
        source: tokio_postgres::Error,
    },
    /// A statement PostgreSQL refused or could not run.
    #[error("job store: {} in `{sql}`", describe(.source))]
    Statement {
        sql: String,
        source: tokio_postgres::Error,
    },
    /// The store's configuration or connection (not a statement) failed.
    #[error("job store: {0}")]
    Config(String),
    /// A query that must return a row returned none.
    #[error("job store: no such row")]
    NoRow,
    /// A row the store cannot read as what it should hold (written by another version, or
    /// edited by hand).
    #[error("job store: {0}")]
    Corrupt(String),
}

pub type Result<T> = std::result::Result<T, StoreError>;

impl StoreError {
    /// A statement's error, naming the statement by its first line.
    fn statement(sql: &str, source: tokio_postgres::Error) -> StoreError {
        StoreError::Statement {
            sql: sql.lines().next().unwrap_or("").trim().to_owned(),
            source,
        }
    }
}

/// A PostgreSQL error with what the server said (its message, detail and hint), or the
/// client's error and its cause.
fn describe(e: &tokio_postgres::Error) -> String {
    if let Some(db) = e.as_db_error() {
        let mut s = format!("{} ({})", db.message(), db.code().code());
        if let Some(d) = db.detail() {
            s += &format!("; {d}");
        }
        if let Some(h) = db.hint() {
            s += &format!("; hint: {h}");
        }
        return s;
    }
    match std::error::Error::source(e) {
        Some(cause) => format!("{e}: {cause}"),
        None => e.to_string(),
    }
}

/// The schema's version (SQLite's `user_version`, PostgreSQL's table `tessera_schema`):
/// [`SCHEMA`] makes version 2, and each of [`MIGRATIONS`] takes the store one version further,
/// on either database ([`Dialect::ddl`]). A store of a version before 2 or after the last is
/// refused.
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
    // 4: claims — work one coordinator of several does alone (see `claims`).
    r#"
CREATE TABLE IF NOT EXISTS claims (
    name TEXT PRIMARY KEY,
    owner TEXT NOT NULL,
    expires_ms INTEGER NOT NULL
);
"#,
    // 5: facts of the farm as a whole (the identity of its object store).
    r#"
CREATE TABLE IF NOT EXISTS farm (
    key TEXT PRIMARY KEY,
    value TEXT NOT NULL
);
"#,
    // 6: users and their roles, per-worker tokens (kept as hashes), who submitted each job,
    // whose each dashboard session is.
    r#"
CREATE TABLE IF NOT EXISTS users (
    name TEXT PRIMARY KEY,
    role TEXT NOT NULL,
    token_hash TEXT NOT NULL UNIQUE,
    created_ms INTEGER NOT NULL,
    revoked_ms INTEGER
);
ALTER TABLE jobs ADD COLUMN submitter TEXT;
ALTER TABLE sessions ADD COLUMN user_name TEXT NOT NULL DEFAULT 'admin';
ALTER TABLE sessions ADD COLUMN role TEXT NOT NULL DEFAULT 'admin';
"#,
    // 7: jobs queued with `auto`'s pilot, planned when a worker has measured it.
    r#"
ALTER TABLE jobs ADD COLUMN measuring INTEGER NOT NULL DEFAULT 0;
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
    db: Db,
}

/// The PostgreSQL channel of [`Store::announce_work`].
const WORK_CHANNEL: &str = "tessera_work";

/// The PostgreSQL advisory lock held while a coordinator creates or migrates the schema.
const MIGRATION_LOCK: i64 = 0x7465_7373_6572_6101;

fn task_spec(row: &db::Row, at: usize) -> Result<TaskSpec> {
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

/// The store a test coordinator whose data directory is `data` uses: when the environment
/// variable `TESSERA_TEST_POSTGRES` names a PostgreSQL database (CI's second run of the
/// suite), a schema of it named after `data` (made when the store opens; the same directory
/// gives the same schema, so a restarted coordinator finds its jobs); else `None`, the
/// embedded SQLite in `data`.
pub fn test_store_url(data: &Path) -> Option<String> {
    use sha2::Digest;
    let base = std::env::var("TESSERA_TEST_POSTGRES").ok()?;
    let hash = sha2::Sha256::digest(data.to_string_lossy().as_bytes());
    let schema: String = hash[..8].iter().map(|b| format!("{b:02x}")).collect();
    let sep = if base.contains('?') { '&' } else { '?' };
    Some(format!("{base}{sep}options=-csearch_path%3Dt_{schema}"))
}

/// Where the store lives: `postgres://…` (or `postgresql://…`) is PostgreSQL, anything else
/// a path for the embedded SQLite.
pub enum Location<'a> {
    Sqlite(&'a Path),
    Postgres(&'a str),
}

impl Store {
    /// Opens (or creates) the embedded store at `path`; refuses a store of another schema
    /// version.
    pub fn open(path: &Path) -> Result<Store> {
        Store::open_at(Location::Sqlite(path))
    }

    /// Opens (or creates, or migrates) the store at `at`; refuses a store of another schema
    /// version.
    pub fn open_at(at: Location) -> Result<Store> {
        let (db, place) = match at {
            Location::Sqlite(path) => {
                let conn = rusqlite::Connection::open(path)?;
                conn.busy_timeout(std::time::Duration::from_secs(10))?;
                conn.execute_batch(
                    "PRAGMA journal_mode = WAL; PRAGMA synchronous = NORMAL; PRAGMA foreign_keys = ON;",
                )?;
                (Db::sqlite(conn), path.display().to_string())
            }
            Location::Postgres(url) => (Db::postgres(url)?, "the PostgreSQL store".to_owned()),
        };
        let conn = db.conn()?;
        let dialect = conn.dialect();
        if dialect == Dialect::Postgres {
            // One coordinator at a time creates or migrates a shared store; the lock is the
            // session's, so it ends with the connection if this process dies.
            conn.execute_batch(&format!("SELECT pg_advisory_lock({MIGRATION_LOCK})"))?;
        }
        let migrated = Self::migrate(&conn, &place);
        if dialect == Dialect::Postgres {
            conn.execute_batch(&format!("SELECT pg_advisory_unlock({MIGRATION_LOCK})"))?;
        }
        migrated?;
        drop(conn);
        Ok(Store { db })
    }

    /// Brings the schema to [`SCHEMA_VERSION`], each migration in one transaction with its
    /// version (a crash leaves either).
    fn migrate(conn: &Conn, place: &str) -> Result<()> {
        let dialect = conn.dialect();
        let (tables, version): (i64, i64) = match dialect {
            Dialect::Sqlite => (
                conn.query_row(
                    "SELECT COUNT(*) FROM sqlite_master WHERE type = 'table'",
                    params![],
                    |r| r.get(0),
                )?,
                conn.query_row("PRAGMA user_version", params![], |r| r.get(0))?,
            ),
            Dialect::Postgres => {
                // A search_path naming a schema that does not exist yet: make it (a farm of its
                // own in a shared database).
                let schema: Option<String> =
                    conn.query_row("SELECT current_schema()", params![], |r| r.get(0))?;
                if schema.is_none() {
                    let path: String =
                        conn.query_row("SHOW search_path", params![], |r| r.get(0))?;
                    let first = path
                        .split(',')
                        .next()
                        .unwrap_or("")
                        .trim()
                        .trim_matches('"');
                    if first.is_empty() || first.starts_with('$') {
                        return Err(StoreError::Config(format!(
                            "{place}: the search_path {path:?} names no schema to create the tables in"
                        )));
                    }
                    conn.execute_batch(&format!(
                        "CREATE SCHEMA IF NOT EXISTS \"{}\"",
                        first.replace('"', "")
                    ))?;
                }
                conn.execute_batch(
                    "CREATE TABLE IF NOT EXISTS tessera_schema (version BIGINT NOT NULL)",
                )?;
                let version: Option<i64> =
                    conn.query_row("SELECT MAX(version) FROM tessera_schema", params![], |r| {
                        r.get(0)
                    })?;
                let tables: i64 = conn.query_row(
                    "SELECT COUNT(*) FROM information_schema.tables
                     WHERE table_schema = current_schema() AND table_name = 'jobs'",
                    params![],
                    |r| r.get(0),
                )?;
                (tables, version.unwrap_or(0))
            }
        };
        if tables > 0 && !(2..=SCHEMA_VERSION).contains(&version) {
            return Err(StoreError::Corrupt(format!(
                "{place} has schema version {version}, this coordinator reads versions 2 to {SCHEMA_VERSION}; start with an empty data directory or database (or move this one away)"
            )));
        }
        let set_version = |to: i64| match dialect {
            Dialect::Sqlite => format!("PRAGMA user_version = {to};"),
            Dialect::Postgres => {
                format!("DELETE FROM tessera_schema; INSERT INTO tessera_schema VALUES ({to});")
            }
        };
        if tables == 0 {
            conn.execute_batch(&format!(
                "BEGIN; {} {} COMMIT;",
                dialect.ddl(SCHEMA),
                set_version(2)
            ))?;
        }
        let from = if tables > 0 { version } else { 2 };
        for (i, m) in MIGRATIONS.iter().enumerate() {
            let to = 3 + i as i64;
            if from < to {
                conn.execute_batch(&format!(
                    "BEGIN; {} {} COMMIT;",
                    dialect.ddl(m),
                    set_version(to)
                ))?;
            }
        }
        Ok(())
    }

    /// Records the identity of the object store (`id`, found at `location`) the first
    /// coordinator used, and checks every later one's against it: coordinators sharing a job
    /// store must share its objects (bundles, results, frames). Returns the recorded id and
    /// location where they differ.
    pub fn check_objects(&self, id: &str, location: &str) -> Result<Option<(String, String)>> {
        self.db.write(|tx| {
            let get = |key: &str| -> Result<Option<String>> {
                tx.query_row("SELECT value FROM farm WHERE key = ?1", params![key], |r| {
                    r.get(0)
                })
                .optional()
            };
            match get("objects_id")? {
                Some(recorded) if recorded != id => Ok(Some((
                    recorded,
                    get("objects_location")?.unwrap_or_default(),
                ))),
                Some(_) => Ok(None),
                None => {
                    for (key, value) in [("objects_id", id), ("objects_location", location)] {
                        tx.execute(
                            "INSERT INTO farm (key, value) VALUES (?1, ?2)",
                            params![key, value],
                        )?;
                    }
                    Ok(None)
                }
            }
        })
    }

    /// The id for an object store at `location` that holds none yet: the one this job store
    /// records for that location (another coordinator made it first), else `candidate`,
    /// recorded now. One transaction, so coordinators starting together agree.
    pub fn adopt_objects(&self, candidate: &str, location: &str) -> Result<String> {
        self.db.write(|tx| {
            let get = |key: &str| -> Result<Option<String>> {
                tx.query_row("SELECT value FROM farm WHERE key = ?1", params![key], |r| {
                    r.get(0)
                })
                .optional()
            };
            match (get("objects_id")?, get("objects_location")?) {
                (Some(id), Some(at)) if at == location => Ok(id),
                (Some(_), _) => Ok(candidate.to_string()),
                (None, _) => {
                    for (key, value) in [("objects_id", candidate), ("objects_location", location)]
                    {
                        tx.execute(
                            "INSERT INTO farm (key, value) VALUES (?1, ?2)",
                            params![key, value],
                        )?;
                    }
                    Ok(candidate.to_string())
                }
            }
        })
    }

    /// Calls `on` when any coordinator sharing the store queues work ([`Store::announce_work`]).
    pub fn on_work(&self, on: std::sync::Arc<dyn Fn() + Send + Sync>) {
        self.db.listen(WORK_CHANNEL, on);
    }

    /// Tells the coordinators sharing the store that work was queued (their workers waiting
    /// for a lease look again).
    pub fn announce_work(&self) -> Result<()> {
        if self.is_shared() {
            self.conn()?
                .execute_batch(&format!("NOTIFY {WORK_CHANNEL}"))?;
        }
        Ok(())
    }

    /// Whether other coordinators may share this store (PostgreSQL).
    pub fn is_shared(&self) -> bool {
        self.db.dialect() == Dialect::Postgres
    }

    /// A connection for statements outside a transaction of their own.
    fn conn(&self) -> Result<Conn<'_>> {
        self.db.conn()
    }

    /// The store's size, bytes: SQLite's pages (its write-ahead log not counted), or on
    /// PostgreSQL the tables of the store's schema with their indexes and TOAST.
    pub fn size_bytes(&self) -> Result<i64> {
        let sql = match self.db.dialect() {
            Dialect::Sqlite => {
                "SELECT page_count * page_size FROM pragma_page_count(), pragma_page_size()"
            }
            Dialect::Postgres => {
                "SELECT COALESCE(SUM(pg_total_relation_size(c.oid)), 0)::BIGINT FROM pg_class c
                 JOIN pg_namespace n ON n.oid = c.relnamespace
                 WHERE n.nspname = current_schema() AND c.relkind = 'r'"
            }
        };
        self.conn()?.query_row(sql, params![], |r| r.get(0))
    }

    /// Moves SQLite's write-ahead log into the database and truncates it (after a job ends:
    /// the log would otherwise keep the size of its busiest moment); nothing on PostgreSQL.
    pub fn checkpoint(&self) -> Result<()> {
        let conn = self.db.conn()?;
        if conn.dialect() == Dialect::Sqlite {
            conn.query_row("PRAGMA wal_checkpoint(TRUNCATE)", params![], |_| Ok(()))?;
        }
        Ok(())
    }

    pub fn insert_bundle(&self, hash: &str, bytes: u64, now: i64) -> Result<()> {
        self.db.conn()?.execute(
            "INSERT INTO bundles (hash, bytes, created_ms) VALUES (?1, ?2, ?3)
             ON CONFLICT (hash) DO NOTHING",
            params![hash, bytes as i64, now],
        )?;
        Ok(())
    }

    pub fn bundle_exists(&self, hash: &str) -> Result<bool> {
        Ok(self
            .db
            .conn()?
            .query_row(
                "SELECT 1 FROM bundles WHERE hash = ?1",
                params![hash],
                |_| Ok(()),
            )
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

    /// A job of bundle `b` over `frames`, at priority 0, that runs `tasks` with `passes`
    /// first (or awaits `auto`'s choice, `measuring`, with `tasks` its pilot).
    pub(crate) fn new_job(
        frames: FrameRange,
        measuring: bool,
        method: &str,
        tasks: Vec<Vec<TaskSpec>>,
        passes: Vec<NewPass>,
    ) -> NewJob {
        let planned = tasks
            .iter()
            .chain(passes.iter().filter_map(|p| match &p.start {
                PassStart::Build(t) | PassStart::Waiting(t) => Some(t),
                PassStart::Reused => None,
            }));
        NewJob {
            name: "j".into(),
            priority: 0,
            bundle: "b".into(),
            scene: "scene.json".into(),
            frames,
            width: 1,
            height: 1,
            require_tags: vec![],
            submitter: None,
            measuring,
            work: Work {
                settings: RenderSettings::default(),
                spp: 1,
                method: method.into(),
                decisions: vec![],
                planned_tasks: planned.map(|t| t.len() as u64).sum(),
                tasks,
                passes,
            },
        }
    }

    /// A store with one job per priority given, each of `tasks` tasks in one frame.
    pub(crate) fn store(priorities: &[i32], tasks: u32) -> (tempfile::TempDir, Store, Vec<i64>) {
        let dir = tempfile::tempdir().expect("temp dir");
        let s = open_test(dir.path());
        s.insert_bundle("b", 1, 0).expect("bundle");
        let ids = priorities
            .iter()
            .map(|&priority| {
                let tasks = vec![(0..tasks).map(|i| task(1, i)).collect()];
                let job = NewJob {
                    priority,
                    ..new_job(FrameRange::single(1), false, "path", tasks, vec![])
                };
                s.insert_job(&job, 0).expect("job")
            })
            .collect();
        (dir, s, ids)
    }

    /// Where a test's store lives: a new schema of the PostgreSQL database that
    /// `TESSERA_TEST_POSTGRES` names (CI's second run of the suite), else a SQLite file in
    /// `dir`.
    fn test_location(dir: &Path) -> (Option<String>, std::path::PathBuf) {
        (test_store_url(dir), dir.join("t.db"))
    }

    pub(crate) fn open_test(dir: &Path) -> Store {
        match test_location(dir) {
            (Some(url), _) => Store::open_at(Location::Postgres(&url)).expect("open"),
            (None, path) => Store::open(&path).expect("open"),
        }
    }

    /// The database of a test's store without the store: for writing what another version
    /// left behind.
    fn raw(at: &(Option<String>, std::path::PathBuf)) -> Db {
        match at {
            (Some(url), _) => {
                let db = Db::postgres(url).expect("connect");
                let c = db.conn().expect("conn");
                let path: String = c
                    .query_row("SHOW search_path", params![], |r| r.get(0))
                    .expect("search_path");
                c.execute_batch(&format!("CREATE SCHEMA IF NOT EXISTS {path}"))
                    .expect("schema");
                drop(c);
                db
            }
            (None, path) => Db::sqlite(rusqlite::Connection::open(path).expect("db")),
        }
    }

    fn reopen(at: &(Option<String>, std::path::PathBuf)) -> Result<Store> {
        match at {
            (Some(url), _) => Store::open_at(Location::Postgres(url)),
            (None, path) => Store::open(path),
        }
    }

    fn set_version(c: &Conn, v: i64) {
        let sql = match c.dialect() {
            Dialect::Sqlite => format!("PRAGMA user_version = {v}"),
            Dialect::Postgres => format!(
                "CREATE TABLE IF NOT EXISTS tessera_schema (version BIGINT NOT NULL);
                 DELETE FROM tessera_schema; INSERT INTO tessera_schema VALUES ({v})"
            ),
        };
        c.execute_batch(&sql).expect("version");
    }

    #[test]
    fn the_store_size_counts_its_tables_and_grows_with_jobs() {
        let (_dir, small, _) = store(&[0], 1);
        let (_dir2, big, _) = store(&[0; 20], 500);
        let (a, b) = (
            small.size_bytes().expect("size"),
            big.size_bytes().expect("size"),
        );
        // At least a page per table, and 10,000 tasks take more room than one.
        assert!(a >= 4096, "{a}");
        assert!(b > a + 10_000 * 50, "{a} then {b}");
    }

    #[test]
    fn a_store_of_another_schema_version_is_refused() {
        let dir = tempfile::tempdir().expect("temp dir");
        for (old, v) in [(true, 1), (false, SCHEMA_VERSION + 1)] {
            let at = test_location(&dir.path().join(format!("v{v}")));
            std::fs::create_dir_all(dir.path().join(format!("v{v}"))).expect("dir");
            let db = raw(&at);
            let c = db.conn().expect("conn");
            if old {
                c.execute_batch("CREATE TABLE jobs (id INTEGER)")
                    .expect("old schema");
            } else {
                c.execute_batch(&c.dialect().ddl(SCHEMA)).expect("schema");
            }
            set_version(&c, v);
            drop(c);
            drop(db);
            let e = reopen(&at).err().expect("refused").to_string();
            assert!(
                e.contains(&format!("schema version {v}")) && e.contains("reads versions 2 to"),
                "{e}"
            );
        }
        // An empty store is a new store.
        let fresh = dir.path().join("new");
        std::fs::create_dir_all(&fresh).expect("dir");
        assert!(reopen(&test_location(&fresh)).is_ok());
    }

    #[test]
    fn a_store_of_version_2_is_migrated_keeping_its_jobs() {
        let dir = tempfile::tempdir().expect("temp dir");
        let at = test_location(dir.path());
        let db = raw(&at);
        let c = db.conn().expect("conn");
        c.execute_batch(&c.dialect().ddl(SCHEMA))
            .expect("version 2 schema");
        set_version(&c, 2);
        c.execute_batch(
            "INSERT INTO bundles (hash, bytes, created_ms) VALUES ('b', 1, 0);
             INSERT INTO jobs (name, state, priority, created_ms, bundle, scene, settings,
                first_frame, last_frame, width, height, spp, method, decisions)
             VALUES ('old', 'done', 0, 0, 'b', 'scene.json', '{}', 1, 1, 8, 8, 1, 'path', '[]');",
        )
        .expect("a job of version 2");
        drop(c);
        drop(db);
        let s = reopen(&at).expect("migrated");
        let c = s.conn().expect("conn");
        let version: i64 = match c.dialect() {
            Dialect::Sqlite => c.query_row("PRAGMA user_version", params![], |r| r.get(0)),
            Dialect::Postgres => {
                c.query_row("SELECT MAX(version) FROM tessera_schema", params![], |r| {
                    r.get(0)
                })
            }
        }
        .expect("version");
        drop(c);
        assert_eq!(version, SCHEMA_VERSION);
        let jobs = s.jobs().expect("jobs");
        assert_eq!((jobs.len(), jobs[0].name.as_str()), (1, "old"));
        assert!(jobs[0].require_tags.is_empty() && jobs[0].started_ms.is_none());
        // Opening again changes nothing.
        drop(s);
        assert_eq!(reopen(&at).expect("again").jobs().expect("jobs").len(), 1);
    }

    #[test]
    fn a_job_whose_stored_settings_cannot_be_read_is_an_error_not_defaults() {
        let (_d, s, jobs) = store(&[0], 1);
        s.conn()
            .expect("conn")
            .execute(
                "UPDATE jobs SET settings = '{\"spp\": \"many\"}' WHERE id = ?1",
                params![jobs[0]],
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
            .expect("conn")
            .query_row(
                "SELECT error FROM jobs WHERE id = ?1",
                params![jobs[0]],
                |r| r.get(0),
            )
            .expect("error");
        assert!(error.contains("settings of job"), "{error}");
    }
}
