//! Jobs in the store: inserting them with their first tasks, their status, their frames'
//! outputs, and deleting them.

use std::collections::HashMap;

use super::db::{Conn, Optional, ToValue, Value, params};

use super::passes::NewPass;
use super::{Result, SPEC_COLUMNS, Store, StoreError, from_json, json, task_spec};
use crate::job::{FrameRange, RenderSettings, TaskSpec};
use crate::protocol::{
    AttemptStatus, FrameStatus, JobState, JobStatus, TaskCounts, TaskStatus, WorkerStatus,
};

/// A job ready to insert: its row and what it runs first.
pub struct NewJob {
    pub name: String,
    pub priority: i32,
    pub bundle: String,
    pub scene: String,
    pub frames: FrameRange,
    pub width: u32,
    pub height: u32,
    /// Tags a worker must have to run its tasks.
    pub require_tags: Vec<String>,
    /// Who submitted it (the token's user).
    pub submitter: Option<String>,
    /// Whether it awaits `auto`'s choice: then `work.tasks` is its pilot alone, and the rest
    /// is planned when the pilot is done ([`Store::measured`]).
    pub measuring: bool,
    pub work: Work,
}

/// What a job runs, as planned: inserted with the job, or when its pilot is done.
pub struct Work {
    /// The job's settings, with `auto`'s choice where one was measured.
    pub settings: RenderSettings,
    pub spp: u32,
    /// The method that runs.
    pub method: String,
    pub decisions: Vec<String>,
    /// Each frame's first step, in fold order: queued at once, or when the passes are done.
    pub tasks: Vec<Vec<TaskSpec>>,
    /// Precomputation passes, in order.
    pub passes: Vec<NewPass>,
    /// Tasks expected in all (for progress), counting those queued later.
    pub planned_tasks: u64,
}

/// Jobs by state: (state, count).
pub type StateCounts = Vec<(String, u64)>;

/// Which jobs a list shows, and which page of them.
#[derive(Debug, Clone, Default)]
pub struct JobFilter {
    /// Only jobs in these states (all if empty).
    pub states: Vec<JobState>,
    /// Only jobs whose name contains this (case-insensitive).
    pub name: Option<String>,
    pub offset: u64,
    /// At most this many (all if `None`).
    pub limit: Option<u64>,
    /// In the order the queue serves them (priority, then age) instead of newest first.
    pub queue_order: bool,
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

impl Store {
    pub fn insert_job(&self, job: &NewJob, now: i64) -> Result<i64> {
        self.db.write(|tx| {
            let id: i64 = tx.query_row(
                "INSERT INTO jobs (name, state, priority, created_ms, bundle, scene, settings,
                first_frame, last_frame, width, height, spp, method, decisions, planned_tasks,
                require_tags, submitter, measuring)
             VALUES (?1, 'queued', ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17)
             RETURNING id",
                params![
                    job.name,
                    job.priority,
                    now,
                    job.bundle,
                    job.scene,
                    json(&job.work.settings),
                    job.frames.first,
                    job.frames.last,
                    job.width,
                    job.height,
                    job.work.spp,
                    job.work.method,
                    json(&job.work.decisions),
                    job.work.planned_tasks as i64,
                    Self::tags_json(&job.require_tags),
                    job.submitter,
                    job.measuring,
                ],
                |r| r.get(0),
            )?;
            for f in job.frames.iter() {
                tx.execute(
                    "INSERT INTO frames (job_id, frame, state) VALUES (?1, ?2, 'queued')",
                    params![id, f],
                )?;
            }
            Self::insert_work(tx, id, &job.work)?;
            Ok(id)
        })
    }

    /// Plans a job that awaited `auto`'s choice, as `planned` says: once, however many coordinators fold its pilot, and only while the
    /// job is open. Returns whether this call planned it.
    pub fn measured(&self, job: i64, planned: &Work) -> Result<bool> {
        self.db.write(|tx| {
            let changed = tx.execute(
                "UPDATE jobs SET measuring = 0, settings = ?2, method = ?3, spp = ?4, decisions = ?5,
                    planned_tasks = planned_tasks + ?6
                 WHERE id = ?1 AND measuring = 1 AND state IN ('queued', 'running', 'paused')",
                params![
                    job,
                    json(&planned.settings),
                    planned.method,
                    planned.spp,
                    json(&planned.decisions),
                    planned.planned_tasks as i64,
                ],
            )?;
            if changed == 0 {
                return Ok(false);
            }
            Self::insert_work(tx, job, planned)?;
            Ok(true)
        })
    }

    /// Inserts a job's passes, and its frames' first steps where no pass is to be built first.
    fn insert_work(tx: &Conn, job: i64, work: &Work) -> Result<()> {
        if Self::insert_passes(tx, job, &work.passes)? {
            for tasks in &work.tasks {
                Self::insert_tasks(tx, job, tasks)?;
            }
        }
        Ok(())
    }

    /// Queues tasks of a job (at the job's priority, copied for the queue index) and counts
    /// frame tasks in their frames.
    pub(super) fn insert_tasks(tx: &Conn, job: i64, tasks: &[TaskSpec]) -> Result<()> {
        let insert = format!(
            "INSERT INTO tasks (job_id, priority, {SPEC_COLUMNS}, state)
             SELECT ?1, priority, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, 'queued'
             FROM jobs WHERE id = ?1"
        );
        for t in tasks {
            tx.execute(
                &insert,
                params![
                    job, t.kind, t.frame, t.step, t.index, t.x0, t.y0, t.x1, t.y1, t.start, t.end
                ],
            )?;
            if !t.is_pass() {
                tx.execute(
                    "UPDATE frames SET tasks_total = tasks_total + 1 WHERE job_id = ?1 AND frame = ?2",
                    params![job, t.frame],
                )?;
            }
        }
        Ok(())
    }

    /// (bundle, scene, settings, frames) of a job; an error if its settings cannot be read.
    pub fn job_source(
        &self,
        job: i64,
    ) -> Result<Option<(String, String, RenderSettings, FrameRange)>> {
        let row: Option<(String, String, String, u32, u32)> = self
            .conn()?
            .query_row(
                "SELECT bundle, scene, settings, first_frame, last_frame FROM jobs WHERE id = ?1",
                params![job],
                |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?)),
            )
            .optional()?;
        let Some((bundle, scene, settings, first, last)) = row else {
            return Ok(None);
        };
        let settings = from_json(&settings, &format!("settings of job {job}"))?;
        Ok(Some((bundle, scene, settings, FrameRange { first, last })))
    }

    pub fn job(&self, id: i64) -> Result<Option<JobStatus>> {
        Ok(self
            .jobs_where("WHERE id = ?1", vec![Value::Int(id)], true, "id DESC")?
            .pop())
    }

    /// Every job, newest first, without per-frame detail.
    pub fn jobs(&self) -> Result<Vec<JobStatus>> {
        Ok(self.job_page(&JobFilter::default())?.0)
    }

    /// A page of the jobs `filter` selects, newest first, without per-frame detail,
    /// passes or decisions; how many it selects in all, by state.
    pub fn job_page(&self, filter: &JobFilter) -> Result<(Vec<JobStatus>, StateCounts)> {
        let mut clauses = Vec::new();
        let mut values: Vec<Value> = Vec::new();
        if let Some(name) = &filter.name {
            values.push(Value::Text(format!(
                "%{}%",
                name.replace('\\', "\\\\")
                    .replace('%', "\\%")
                    .replace('_', "\\_")
            )));
            // Case-insensitive on both databases (PostgreSQL's LIKE is not).
            clauses.push(format!(
                "LOWER(name) LIKE LOWER(?{}) ESCAPE '\\'",
                values.len()
            ));
        }
        let by_state: Vec<(String, u64)> = {
            let conn = self.conn()?;
            let where_ = if clauses.is_empty() {
                String::new()
            } else {
                format!("WHERE {}", clauses.join(" AND "))
            };
            conn.query_map(
                &format!("SELECT state, COUNT(*) FROM jobs {where_} GROUP BY state"),
                &refs(&values),
                |r| Ok((r.get(0)?, r.get::<i64>(1)? as u64)),
            )?
        };
        if !filter.states.is_empty() {
            let list: Vec<String> = filter
                .states
                .iter()
                .map(|s| format!("'{}'", s.as_str()))
                .collect();
            clauses.push(format!("state IN ({})", list.join(", ")));
        }
        let mut where_ = if clauses.is_empty() {
            String::new()
        } else {
            format!("WHERE {}", clauses.join(" AND "))
        };
        let order = if filter.queue_order {
            "priority DESC, id ASC"
        } else {
            "id DESC"
        };
        where_ += &format!(
            " ORDER BY {order} LIMIT {} OFFSET {}",
            filter.limit.map_or(i64::MAX, |l| l as i64),
            filter.offset
        );
        Ok((self.jobs_where(&where_, values, false, order)?, by_state))
    }

    /// Jobs whose rows `filter` (a WHERE, ORDER and LIMIT on `jobs`) selects, in `order` (of
    /// `jobs`' columns, as the filter's), with their task counts; with `frames`, also their
    /// frames, passes, decisions and blocklist.
    fn jobs_where(
        &self,
        filter: &str,
        values: Vec<Value>,
        frames: bool,
        order: &str,
    ) -> Result<Vec<JobStatus>> {
        let order = order
            .split(", ")
            .map(|o| format!("j.{o}"))
            .collect::<Vec<_>>()
            .join(", ");
        let conn = self.conn()?;
        let count_state = |s: &str| format!("SUM(CASE WHEN state = '{s}' THEN 1 ELSE 0 END)");
        let rows: Vec<(JobStatus, String, String, String)> = conn.query_map(
            &format!(
                "SELECT j.id, j.name, j.state, j.priority, j.created_ms, j.finished_ms, j.bundle, j.scene,
                    j.settings, j.first_frame, j.last_frame, j.width, j.height, j.spp, j.decisions, j.error,
                    t.total, t.queued, t.leased, t.done, t.failed, t.cancelled, t.attempts,
                    j.planned_tasks, j.method, j.require_tags, j.started_ms, j.submitter, j.measuring
                 FROM (SELECT * FROM jobs {filter}) j
                 LEFT JOIN (SELECT job_id, COUNT(*) AS total, {} AS queued, {} AS leased,
                                {} AS done, {} AS failed, {} AS cancelled, SUM(attempts) AS attempts
                            FROM tasks WHERE job_id IN (SELECT id FROM jobs {filter})
                            GROUP BY job_id) t ON t.job_id = j.id
                 ORDER BY {order}",
                count_state("queued"),
                count_state("leased"),
                count_state("done"),
                count_state("failed"),
                count_state("cancelled"),
            ),
            &refs(&values),
            |r| {
                let count = |i: usize| -> Result<u64> {
                    Ok(r.get::<Option<i64>>(i)?.unwrap_or(0) as u64)
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
                let status = JobStatus {
                    id: r.get(0)?,
                    name: r.get(1)?,
                    state: JobState::parse(&r.get::<String>(2)?),
                    priority: r.get(3)?,
                    created_ms: r.get(4)?,
                    finished_ms: r.get(5)?,
                    bundle: r.get(6)?,
                    scene: r.get(7)?,
                    method: r.get(24)?,
                    settings: RenderSettings::default(),
                    frames: FrameRange {
                        first: r.get(9)?,
                        last: r.get(10)?,
                    },
                    width: r.get(11)?,
                    height: r.get(12)?,
                    spp: r.get(13)?,
                    decisions: Vec::new(),
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
                    require_tags: Vec::new(),
                    started_ms: r.get(26)?,
                    blocklist: Vec::new(),
                    submitter: r.get(27)?,
                    measuring: r.get(28)?,
                };
                Ok((status, r.get(8)?, r.get(14)?, r.get(25)?))
            },
        )?;
        let mut jobs = Vec::with_capacity(rows.len());
        for (mut job, settings, decisions, tags) in rows {
            job.settings = from_json(&settings, &format!("settings of job {}", job.id))?;
            job.require_tags = from_json(&tags, &format!("require_tags of job {}", job.id))?;
            if frames {
                job.decisions = from_json(&decisions, &format!("decisions of job {}", job.id))?;
            }
            jobs.push(job);
        }
        if frames {
            for job in jobs.iter_mut() {
                job.passes = Self::job_passes(&conn, job.id)?;
                job.blocklist = Self::blocklist_of(&conn, job.id)?;
                job.frame_status = conn.query_map(
                    "SELECT f.frame, f.state, f.tasks_done, f.tasks_total, a.sha256, f.estimated_rel_mse, f.step
                     FROM frames f
                     LEFT JOIN artifacts a ON a.job_id = f.job_id AND a.frame = f.frame AND a.kind = 'exr'
                     WHERE f.job_id = ?1 ORDER BY f.frame",
                    params![job.id],
                    |r| {
                        let frame: u32 = r.get(0)?;
                        let state: String = r.get(1)?;
                        Ok(FrameStatus {
                            frame,
                            exr: (state == "done")
                                .then(|| format!("/v1/jobs/{}/frames/{frame}/exr", job.id)),
                            state,
                            step: r.get(6)?,
                            tasks_done: r.get::<i64>(2)? as u64,
                            tasks_total: r.get::<i64>(3)? as u64,
                            exr_sha256: r.get(4)?,
                            estimated_rel_mse: r.get(5)?,
                        })
                    },
                )?;
            }
        }
        Ok(jobs)
    }

    /// A job's tasks, or those of one frame (0: its passes' tasks).
    pub fn tasks(&self, job: i64, frame: Option<u32>) -> Result<Vec<TaskStatus>> {
        let conn = self.conn()?;
        conn.query_map(
            &format!(
                "SELECT id, state, attempts, worker, seconds, error, result_bytes, payload_bytes, {SPEC_COLUMNS}
                 FROM tasks WHERE job_id = ?1 AND (CAST(?2 AS BIGINT) IS NULL OR frame = ?2) ORDER BY id"
            ),
            params![job, frame],
            |r| {
                Ok(TaskStatus {
                    id: r.get(0)?,
                    state: r.get(1)?,
                    attempts: r.get(2)?,
                    worker: r.get(3)?,
                    seconds: r.get(4)?,
                    error: r.get(5)?,
                    result_bytes: r.get::<Option<i64>>(6)?.map(|b| b as u64),
                    payload_bytes: r.get::<Option<i64>>(7)?.map(|b| b as u64),
                    spec: task_spec(r, 8)?,
                })
            },
        )
    }

    /// A job's attempts (leases), newest first: failures first if `failures_first`; at most
    /// `limit`.
    pub fn attempts(
        &self,
        job: i64,
        failures_first: bool,
        limit: u64,
    ) -> Result<Vec<AttemptStatus>> {
        let conn = self.conn()?;
        let order = if failures_first {
            "CASE WHEN a.outcome IN ('failed', 'expired', 'unreadable') THEN 1 ELSE 0 END DESC, a.id DESC"
        } else {
            "a.id DESC"
        };
        conn.query_map(
            &format!(
                "SELECT a.id, a.task_id, t.frame, t.step, t.kind, t.idx, a.worker, a.started_ms,
                    a.ended_ms, a.outcome, a.error
                 FROM attempts a JOIN tasks t ON t.id = a.task_id
                 WHERE t.job_id = ?1 ORDER BY {order} LIMIT ?2"
            ),
            params![job, limit as i64],
            |r| {
                Ok(AttemptStatus {
                    id: r.get(0)?,
                    task_id: r.get(1)?,
                    frame: r.get(2)?,
                    step: r.get(3)?,
                    kind: r.get(4)?,
                    index: r.get(5)?,
                    worker: r.get(6)?,
                    started_ms: r.get(7)?,
                    ended_ms: r.get(8)?,
                    outcome: r.get(9)?,
                    error: r.get(10)?,
                })
            },
        )
    }

    /// Whether a job exists.
    pub fn job_exists(&self, job: i64) -> Result<bool> {
        Ok(self
            .conn()?
            .query_row("SELECT 1 FROM jobs WHERE id = ?1", params![job], |_| Ok(()))
            .optional()?
            .is_some())
    }

    /// A job's state, if it exists.
    pub fn job_state(&self, job: i64) -> Result<Option<JobState>> {
        Ok(self
            .conn()?
            .query_row("SELECT state FROM jobs WHERE id = ?1", params![job], |r| {
                r.get::<String>(0)
            })
            .optional()?
            .map(|s| JobState::parse(&s)))
    }

    /// A frame's state (queued, running, done), if the job has that frame.
    pub fn frame_state(&self, job: i64, frame: u32) -> Result<Option<String>> {
        Ok(self
            .conn()?
            .query_row(
                "SELECT state FROM frames WHERE job_id = ?1 AND frame = ?2",
                params![job, frame],
                |r| r.get(0),
            )
            .optional()?)
    }

    /// Marks a finished frame done with its files, and the job done when it was its last
    /// frame. Returns whether the job is now done.
    pub fn frame_stitched(
        &self,
        job: i64,
        frame: u32,
        files: &[Artifact],
        estimated_rel_mse: Option<f64>,
        now: i64,
    ) -> Result<bool> {
        self.db.write(|tx| {
            for a in files {
                tx.execute(
                    "INSERT INTO artifacts (job_id, frame, kind, path, bytes, sha256, created_ms)
                     VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7)
                     ON CONFLICT (job_id, frame, kind) DO UPDATE SET path = excluded.path,
                        bytes = excluded.bytes, sha256 = excluded.sha256, created_ms = excluded.created_ms",
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
                params![job],
                |r| r.get(0),
            )?;
            let done = left == 0
                && tx.execute(
                    "UPDATE jobs SET state = 'done', finished_ms = ?2
                     WHERE id = ?1 AND state IN ('queued', 'running', 'paused')",
                    params![job, now],
                )? == 1;
            Ok(done)
        })
    }

    /// Deletes a job that has ended, with every row of it; returns its bundle's hash if no
    /// other job uses that bundle any more (and forgets the bundle), `None` if the job has not
    /// ended or does not exist.
    pub fn delete_job(&self, job: i64) -> Result<Option<Option<String>>> {
        self.db.write(|tx| {
            let row: Option<(String, String)> = tx
                .query_row(
                    "SELECT state, bundle FROM jobs WHERE id = ?1",
                    params![job],
                    |r| Ok((r.get(0)?, r.get(1)?)),
                )
                .optional()?;
            let Some((state, bundle)) = row else {
                return Ok(None);
            };
            if !JobState::parse(&state).is_final() {
                return Ok(None);
            }
            tx.execute(
                "DELETE FROM attempts WHERE task_id IN (SELECT id FROM tasks WHERE job_id = ?1)",
                params![job],
            )?;
            for table in ["tasks", "frames", "artifacts", "passes", "blocklist"] {
                tx.execute(
                    &format!("DELETE FROM {table} WHERE job_id = ?1"),
                    params![job],
                )?;
            }
            tx.execute("DELETE FROM jobs WHERE id = ?1", params![job])?;
            let used: i64 = tx.query_row(
                "SELECT COUNT(*) FROM jobs WHERE bundle = ?1",
                params![&bundle],
                |r| r.get(0),
            )?;
            let orphan = used == 0;
            if orphan {
                tx.execute("DELETE FROM bundles WHERE hash = ?1", params![&bundle])?;
            }
            Ok(Some(orphan.then_some(bundle)))
        })
    }

    /// Jobs that ended before `before` (ms since the epoch), oldest first.
    pub fn ended_before(&self, before: i64) -> Result<Vec<i64>> {
        let conn = self.conn()?;
        conn.query_map(
            "SELECT id FROM jobs WHERE state IN ('done', 'failed', 'cancelled')
               AND finished_ms IS NOT NULL AND finished_ms < ?1 ORDER BY id",
            params![before],
            |r| r.get(0),
        )
    }

    /// Workers, most recently seen first; alive if seen within `alive_ms`.
    pub fn workers(&self, now: i64, alive_ms: i64) -> Result<Vec<WorkerStatus>> {
        let conn = self.conn()?;
        let by_worker = |sql: &str| -> Result<HashMap<String, Vec<i64>>> {
            let mut m: HashMap<String, Vec<i64>> = HashMap::new();
            for (w, id) in conn.query_map(sql, params![], |r| Ok((r.get(0)?, r.get(1)?)))? {
                m.entry(w).or_default().push(id);
            }
            Ok(m)
        };
        let mut leased = by_worker(
            "SELECT worker, id FROM tasks WHERE state = 'leased' AND worker IS NOT NULL ORDER BY id",
        )?;
        let mut blocked = by_worker(
            "SELECT worker, job_id FROM blocklist WHERE blocked_ms IS NOT NULL ORDER BY job_id",
        )?;
        let rows: Vec<(WorkerStatus, String)> = conn.query_map(
            "SELECT w.id, w.name, w.host, w.slots, w.version, w.first_seen_ms, w.last_seen_ms,
                w.scene_builds, w.tasks_done, w.pid, NULL,
                w.tags, w.draining, w.cpu, w.samples_done, w.busy_seconds, w.failures
             FROM workers w ORDER BY w.last_seen_ms DESC",
            params![],
            |r| {
                let id: String = r.get(0)?;
                let last: i64 = r.get(6)?;
                let samples: i64 = r.get(14)?;
                let busy: f64 = r.get(15)?;
                Ok((
                    WorkerStatus {
                        leased_tasks: leased.remove(&id).unwrap_or_default(),
                        blocklisted_for: blocked.remove(&id).unwrap_or_default(),
                        id,
                        name: r.get(1)?,
                        host: r.get(2)?,
                        pid: r.get(9)?,
                        slots: r.get(3)?,
                        version: r.get(4)?,
                        first_seen_ms: r.get(5)?,
                        last_seen_ms: last,
                        alive: now - last <= alive_ms,
                        scene_builds: r.get::<i64>(7)? as u64,
                        tasks_done: r.get::<i64>(8)? as u64,
                        tags: Vec::new(),
                        draining: r.get(12)?,
                        cpu: r.get(13)?,
                        samples_per_second: (busy > 0.0 && samples > 0)
                            .then(|| samples as f64 / busy),
                        failures: r.get::<i64>(16)? as u64,
                    },
                    r.get(11)?,
                ))
            },
        )?;
        let mut out = Vec::with_capacity(rows.len());
        for (mut w, tags) in rows {
            w.tags = from_json(&tags, &format!("tags of worker {}", w.id))?;
            out.push(w);
        }
        Ok(out)
    }
}

impl From<StoreError> for String {
    fn from(e: StoreError) -> String {
        e.to_string()
    }
}

/// Parameters held as values, for a statement.
fn refs(values: &[Value]) -> Vec<&dyn ToValue> {
    values.iter().map(|v| v as &dyn ToValue).collect()
}
