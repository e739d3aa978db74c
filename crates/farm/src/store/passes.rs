//! Passes and the artifact cache in the store.
//!
//! A job that needs precomputation has one `passes` row per pass, in order, each with the key
//! of the artifact it makes. A pass whose key is cached (and allowed to be reused) starts
//! `reused`; otherwise the first pass to build is `running` with its tasks queued, later ones
//! `waiting`. Frames are queued when every pass is built or reused. Artifacts are files named
//! by key; `cache` says which job built each and when one was last used, for eviction.

use super::db::{Conn, Optional, params};

use super::{Result, Store};
use crate::job::TaskSpec;
use crate::protocol::{ArtifactRef, PassStatus};

/// How a pass of a new job starts.
#[derive(Debug, Clone, PartialEq)]
pub enum PassStart {
    /// Its artifact is cached: nothing to do.
    Reused,
    /// To build now, with these tasks.
    Build(Vec<TaskSpec>),
    /// To build after the passes before it (its tasks may read their artifacts).
    Waiting(Vec<TaskSpec>),
}

#[derive(Debug, Clone, PartialEq)]
pub struct NewPass {
    pub name: String,
    pub key: String,
    pub start: PassStart,
}

/// A cached artifact.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CacheEntry {
    pub key: String,
    /// The pass that builds it.
    pub name: String,
    /// Relative to the data directory.
    pub path: String,
    pub bytes: u64,
    pub sha256: String,
    /// The job that built it.
    pub job: i64,
}

impl Store {
    /// Inserts a new job's passes and the tasks of the one that builds first. Returns whether
    /// the frames can be queued at once (every pass reused).
    pub(super) fn insert_passes(tx: &Conn, job: i64, passes: &[NewPass]) -> Result<bool> {
        let mut building = false;
        for (step, p) in passes.iter().enumerate() {
            let (state, tasks) = match &p.start {
                PassStart::Reused => ("reused", None),
                PassStart::Build(t) | PassStart::Waiting(t) if !building => ("running", Some(t)),
                PassStart::Build(t) | PassStart::Waiting(t) => ("waiting", Some(t)),
            };
            tx.execute(
                "INSERT INTO passes (job_id, step, name, key, state, tasks_total) VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
                params![job, step as u32, p.name, p.key, state, tasks.map_or(0, |t| t.len() as i64)],
            )?;
            if let Some(tasks) = tasks {
                Self::insert_tasks(tx, job, tasks)?;
                if state == "waiting" {
                    tx.execute(
                        "UPDATE tasks SET state = 'waiting' WHERE job_id = ?1 AND frame = 0 AND step = ?2",
                        params![job, step as u32],
                    )?;
                }
            }
            building |= tasks.is_some();
        }
        Ok(!building)
    }

    /// The artifacts a task reads: those of the job's passes before it (a frame's task: all).
    pub(super) fn artifacts_for(tx: &Conn, job: i64, task: &TaskSpec) -> Result<Vec<ArtifactRef>> {
        let below = if task.is_pass() { task.step } else { u32::MAX };
        tx.query_map(
            "SELECT name, key FROM passes WHERE job_id = ?1 AND step < ?2 ORDER BY step",
            params![job, below],
            |r| {
                Ok(ArtifactRef {
                    pass: r.get(0)?,
                    key: r.get(1)?,
                })
            },
        )
    }

    /// The cached artifact with this key.
    pub fn cached(&self, key: &str) -> Result<Option<CacheEntry>> {
        Ok(self
            .conn()?
            .query_row(
                "SELECT key, name, path, bytes, sha256, job_id FROM cache WHERE key = ?1",
                params![key],
                |r| {
                    Ok(CacheEntry {
                        key: r.get(0)?,
                        name: r.get(1)?,
                        path: r.get(2)?,
                        bytes: r.get::<i64>(3)? as u64,
                        sha256: r.get(4)?,
                        job: r.get(5)?,
                    })
                },
            )
            .optional()?)
    }

    /// A pass's state (`running`, `waiting`, `built`, `reused`), if the job has that pass.
    pub fn pass_state(&self, job: i64, step: u32) -> Result<Option<String>> {
        Ok(self
            .conn()?
            .query_row(
                "SELECT state FROM passes WHERE job_id = ?1 AND step = ?2",
                params![job, step],
                |r| r.get(0),
            )
            .optional()?)
    }

    /// Notes that an artifact was used now (for least-recently-used eviction).
    pub fn touch(&self, key: &str, now: i64) -> Result<()> {
        self.conn()?.execute(
            "UPDATE cache SET used_ms = ?2 WHERE key = ?1",
            params![key, now],
        )?;
        Ok(())
    }

    /// A pass's artifact is written: cache it, mark the pass built, and queue what follows:
    /// the next pass that waits, or (`frames`, when none waits) every frame's first step.
    /// Returns whether frames were queued.
    pub fn pass_built(
        &self,
        job: i64,
        step: u32,
        entry: &CacheEntry,
        summary: &str,
        frames: &[Vec<TaskSpec>],
        now: i64,
    ) -> Result<bool> {
        self.db.write(|tx| {
            tx.execute(
                "INSERT INTO cache (key, name, path, bytes, sha256, job_id, created_ms, used_ms)
                 VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?7)
                 ON CONFLICT (key) DO UPDATE SET name = excluded.name, path = excluded.path,
                    bytes = excluded.bytes, sha256 = excluded.sha256, job_id = excluded.job_id,
                    created_ms = excluded.created_ms, used_ms = excluded.used_ms",
                params![
                    entry.key,
                    entry.name,
                    entry.path,
                    entry.bytes as i64,
                    entry.sha256,
                    job,
                    now
                ],
            )?;
            // A pass is built once: a second fold of it (a late request) queues nothing again.
            let changed = tx.execute(
                "UPDATE passes SET state = 'built', summary = ?3 WHERE job_id = ?1 AND step = ?2 AND state = 'running'",
                params![job, step, summary],
            )?;
            if changed == 0 {
                return Ok(false);
            }
            // Only a job still running gets more tasks.
            let running = Self::job_open(tx, job)?;
            let waiting: Option<u32> = tx
                .query_row(
                    "SELECT step FROM passes WHERE job_id = ?1 AND state = 'waiting' ORDER BY step LIMIT 1",
                    params![job],
                    |r| r.get(0),
                )
                .optional()?;
            let mut frames_queued = false;
            if running {
                match waiting {
                    Some(next) => {
                        tx.execute(
                            "UPDATE passes SET state = 'running' WHERE job_id = ?1 AND step = ?2",
                            params![job, next],
                        )?;
                        tx.execute(
                            "UPDATE tasks SET state = 'queued' WHERE job_id = ?1 AND frame = 0 AND step = ?2 AND state = 'waiting'",
                            params![job, next],
                        )?;
                    }
                    None => {
                        for tasks in frames {
                            Self::insert_tasks(tx, job, tasks)?;
                        }
                        frames_queued = true;
                    }
                }
            }
            Ok(frames_queued)
        })
    }

    /// Every cached artifact, least recently used first, with whether a job that has not ended
    /// reads it.
    pub fn cache_entries(&self) -> Result<Vec<(CacheEntry, bool)>> {
        let conn = self.conn()?;
        conn.query_map(
            "SELECT c.key, c.name, c.path, c.bytes, c.sha256, c.job_id,
                EXISTS (SELECT 1 FROM passes p JOIN jobs j ON j.id = p.job_id
                        WHERE p.key = c.key AND j.state IN ('queued', 'running', 'paused'))
             FROM cache c ORDER BY c.used_ms, c.created_ms",
            params![],
            |r| {
                Ok((
                    CacheEntry {
                        key: r.get(0)?,
                        name: r.get(1)?,
                        path: r.get(2)?,
                        bytes: r.get::<i64>(3)? as u64,
                        sha256: r.get(4)?,
                        job: r.get(5)?,
                    },
                    r.get(6)?,
                ))
            },
        )
    }

    /// Forgets a cached artifact (its file is the caller's to delete).
    pub fn uncache(&self, key: &str) -> Result<()> {
        self.conn()?
            .execute("DELETE FROM cache WHERE key = ?1", params![key])?;
        Ok(())
    }

    pub(super) fn job_passes(conn: &Conn, job: i64) -> Result<Vec<PassStatus>> {
        conn.query_map(
            "SELECT p.name, p.key, p.state, p.tasks_done, p.tasks_total, c.job_id, c.bytes, p.summary
             FROM passes p LEFT JOIN cache c ON c.key = p.key
             WHERE p.job_id = ?1 ORDER BY p.step",
            params![job],
            |r| {
                Ok(PassStatus {
                    name: r.get(0)?,
                    key: r.get(1)?,
                    state: r.get(2)?,
                    tasks_done: r.get::<i64>(3)? as u64,
                    tasks_total: r.get::<i64>(4)? as u64,
                    built_by: r.get(5)?,
                    bytes: r.get::<Option<i64>>(6)?.map(|b| b as u64),
                    summary: r.get(7)?,
                })
            },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{new_job, store, task};
    use super::*;
    use crate::job::FrameRange;

    /// A pass is built once: the fold of a late request for it (arriving after its artifact
    /// was written) must not queue the frames a second time.
    #[test]
    fn a_pass_built_twice_queues_its_frames_once() {
        let (_d, s, _) = store(&[], 0);
        let pass_task = TaskSpec::new("photons", 0, 0, 0).with_range(0, 10);
        let frame: Vec<TaskSpec> = (0..3).map(|i| task(1, i)).collect();
        let passes = vec![NewPass {
            name: "photons".into(),
            key: "k".into(),
            start: PassStart::Build(vec![pass_task]),
        }];
        let job = s
            .insert_job(
                &new_job(
                    FrameRange::single(1),
                    false,
                    "photon",
                    vec![frame.clone()],
                    passes,
                ),
                0,
            )
            .expect("job");
        assert_eq!(s.pass_state(job, 0).expect("q").as_deref(), Some("running"));
        // Its task done counts for the worker, without pixel samples (a pass has none).
        let w = super::super::tests::worker("w");
        let g = s
            .lease(&w, 0, 1000)
            .expect("lease")
            .expect("the pass's task");
        assert!(g.task.is_pass());
        s.complete(g.task_id, g.lease, 0.5, (1, 1), 1)
            .expect("complete");
        let status = &s.workers(1, 1000).expect("workers")[0];
        assert_eq!((status.tasks_done, status.samples_per_second), (1, None));
        let entry = CacheEntry {
            key: "k".into(),
            name: "photons".into(),
            path: "cache/k".into(),
            bytes: 1,
            sha256: "0".into(),
            job,
        };
        let frames = [frame];
        assert!(
            s.pass_built(job, 0, &entry, "built", &frames, 1)
                .expect("built")
        );
        assert!(
            !s.pass_built(job, 0, &entry, "built", &frames, 2)
                .expect("again")
        );
        assert_eq!(s.pass_state(job, 0).expect("q").as_deref(), Some("built"));
        let status = s.job(job).expect("q").expect("job");
        assert_eq!(status.tasks.total, 4, "{:?}", status.tasks);
    }
}
