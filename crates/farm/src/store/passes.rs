//! Passes and the artifact cache in the store.
//!
//! A job that needs precomputation has one `passes` row per pass (photon maps, then the
//! irradiance cache), each with the key of the artifact it makes. A pass whose key is in the
//! `cache` table (and allowed to be reused) starts `reused`; otherwise the first pass to build
//! is `running` with its tasks queued, later ones `waiting`. Tile tasks are queued when every
//! pass is built or reused. Artifacts are files named by key; `cache` says which job built each.

use rusqlite::{OptionalExtension, Transaction, params};

use super::{Result, Store};
use crate::job::{PassKind, TaskKind, TaskSpec};
use crate::protocol::{ArtifactRef, PassStatus};

/// How a pass of a new job starts.
#[derive(Debug, Clone, PartialEq)]
pub enum PassStart {
    /// Its artifact is cached: nothing to do.
    Reused,
    /// To build now, with these tasks.
    Build(Vec<TaskSpec>),
    /// To build after the passes before it (its tasks need their artifacts).
    Waiting,
}

#[derive(Debug, Clone, PartialEq)]
pub struct NewPass {
    pub kind: PassKind,
    pub key: String,
    pub start: PassStart,
}

/// A cached artifact.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CacheEntry {
    pub key: String,
    pub kind: PassKind,
    /// Relative to the data directory.
    pub path: String,
    pub bytes: u64,
    pub sha256: String,
    /// The job that built it.
    pub job: i64,
}

/// What follows a finished pass.
#[derive(Debug, Clone, PartialEq)]
pub enum NextStage {
    /// The next pass, with its tasks.
    Pass(PassKind, Vec<TaskSpec>),
    /// The tile tasks of every frame.
    Tiles(Vec<TaskSpec>),
}

impl Store {
    /// Inserts a new job's passes and the tasks of those that build now. Returns whether the
    /// tile tasks can be queued at once (every pass reused).
    pub(super) fn insert_passes(tx: &Transaction, job: i64, passes: &[NewPass]) -> Result<bool> {
        let mut all_reused = true;
        for p in passes {
            let (state, total) = match &p.start {
                PassStart::Reused => ("reused", 0),
                PassStart::Build(tasks) => ("running", tasks.len()),
                PassStart::Waiting => ("waiting", 0),
            };
            tx.execute(
                "INSERT INTO passes (job_id, kind, key, state, tasks_total) VALUES (?1, ?2, ?3, ?4, ?5)",
                params![job, p.kind.as_str(), p.key, state, total as i64],
            )?;
            if let PassStart::Build(tasks) = &p.start {
                Self::insert_tasks(tx, job, tasks)?;
                all_reused = false;
            }
            if p.start == PassStart::Waiting {
                all_reused = false;
            }
        }
        Ok(all_reused)
    }

    /// The artifacts a task of `kind` reads: the keys of the job's passes before its stage.
    pub(super) fn artifacts_for(
        tx: &Transaction,
        job: i64,
        kind: TaskKind,
    ) -> Result<Vec<ArtifactRef>> {
        let wanted: &[PassKind] = match kind {
            TaskKind::GlobalPhotons
            | TaskKind::CausticPhotons
            | TaskKind::Sppm
            | TaskKind::Bdpt
            | TaskKind::SubsurfacePoints => &[],
            TaskKind::Records => &[PassKind::Photons],
            TaskKind::Tile => &[PassKind::Photons, PassKind::Records, PassKind::Subsurface],
        };
        let mut out = Vec::new();
        for &pass in wanted {
            let key: Option<String> = tx
                .query_row(
                    "SELECT key FROM passes WHERE job_id = ?1 AND kind = ?2",
                    params![job, pass.as_str()],
                    |r| r.get(0),
                )
                .optional()?;
            if let Some(key) = key {
                out.push(ArtifactRef { kind: pass, key });
            }
        }
        Ok(out)
    }

    /// The cached artifact with this key.
    pub fn cached(&self, key: &str) -> Result<Option<CacheEntry>> {
        self.conn()
            .query_row(
                "SELECT key, kind, path, bytes, sha256, job_id FROM cache WHERE key = ?1",
                [key],
                |r| {
                    Ok(CacheEntry {
                        key: r.get(0)?,
                        kind: PassKind::parse(&r.get::<_, String>(1)?).unwrap_or(PassKind::Photons),
                        path: r.get(2)?,
                        bytes: r.get::<_, i64>(3)? as u64,
                        sha256: r.get(4)?,
                        job: r.get(5)?,
                    })
                },
            )
            .optional()
    }

    /// Done tasks of a pass in merge order: (task id, lease, spec).
    pub fn pass_results(&self, job: i64, pass: PassKind) -> Result<Vec<(i64, i64, TaskSpec)>> {
        let kinds: &[TaskKind] = match pass {
            PassKind::Photons => &[TaskKind::GlobalPhotons, TaskKind::CausticPhotons],
            PassKind::Records => &[TaskKind::Records],
            PassKind::Subsurface => &[TaskKind::SubsurfacePoints],
        };
        let conn = self.conn();
        let mut stmt = conn.prepare(&format!(
            "SELECT id, lease, {} FROM tasks
             WHERE job_id = ?1 AND state = 'done' AND kind IN (?2, ?3)
             ORDER BY tile_index",
            super::SPEC_COLUMNS
        ))?;
        let (a, b) = (kinds[0].as_str(), kinds[kinds.len() - 1].as_str());
        stmt.query_map(params![job, a, b], |r| {
            Ok((r.get(0)?, r.get(1)?, super::task_spec(r, 2)?))
        })?
        .collect()
    }

    /// A pass's artifact is written: cache it, mark the pass built, and queue what follows.
    pub fn pass_built(
        &self,
        job: i64,
        pass: PassKind,
        entry: &CacheEntry,
        next: &NextStage,
        now: i64,
    ) -> Result<()> {
        let mut conn = self.conn();
        let tx = conn.transaction()?;
        tx.execute(
            "INSERT OR REPLACE INTO cache (key, kind, path, bytes, sha256, job_id, created_ms)
             VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)",
            params![
                entry.key,
                entry.kind.as_str(),
                entry.path,
                entry.bytes as i64,
                entry.sha256,
                job,
                now
            ],
        )?;
        tx.execute(
            "UPDATE passes SET state = 'built' WHERE job_id = ?1 AND kind = ?2",
            params![job, pass.as_str()],
        )?;
        // Only a job still running gets more tasks.
        let running: bool = tx
            .prepare("SELECT 1 FROM jobs WHERE id = ?1 AND state IN ('queued', 'running')")?
            .exists([job])?;
        if running {
            match next {
                NextStage::Pass(kind, tasks) => {
                    tx.execute(
                        "UPDATE passes SET state = 'running', tasks_total = ?3
                         WHERE job_id = ?1 AND kind = ?2",
                        params![job, kind.as_str(), tasks.len() as i64],
                    )?;
                    Self::insert_tasks(&tx, job, tasks)?;
                }
                NextStage::Tiles(tasks) => Self::insert_tasks(&tx, job, tasks)?,
            }
        }
        tx.commit()
    }

    /// Passes whose tasks are all done but whose artifact was not written (a restart in
    /// between): (job, pass).
    pub fn unfinished_passes(&self) -> Result<Vec<(i64, PassKind)>> {
        let conn = self.conn();
        let mut stmt = conn.prepare(
            "SELECT p.job_id, p.kind FROM passes p JOIN jobs j ON j.id = p.job_id
             WHERE p.state = 'running' AND p.tasks_done = p.tasks_total
               AND j.state IN ('queued', 'running')
             ORDER BY p.job_id, p.kind",
        )?;
        stmt.query_map([], |r| {
            Ok((
                r.get(0)?,
                PassKind::parse(&r.get::<_, String>(1)?).unwrap_or(PassKind::Photons),
            ))
        })?
        .collect()
    }

    pub(super) fn job_passes(conn: &rusqlite::Connection, job: i64) -> Result<Vec<PassStatus>> {
        let mut stmt = conn.prepare(
            "SELECT p.kind, p.key, p.state, p.tasks_done, p.tasks_total, c.job_id, c.bytes
             FROM passes p LEFT JOIN cache c ON c.key = p.key
             WHERE p.job_id = ?1 ORDER BY p.rowid",
        )?;
        stmt.query_map([job], |r| {
            Ok(PassStatus {
                kind: PassKind::parse(&r.get::<_, String>(0)?).unwrap_or(PassKind::Photons),
                key: r.get(1)?,
                state: r.get(2)?,
                tasks_done: r.get::<_, i64>(3)? as u64,
                tasks_total: r.get::<_, i64>(4)? as u64,
                built_by: r.get(5)?,
                bytes: r.get::<_, Option<i64>>(6)?.map(|b| b as u64),
            })
        })?
        .collect()
    }
}
