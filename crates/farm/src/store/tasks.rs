//! Tasks in the store: the queue, fenced leases, results, retries, and a frame's steps.

use super::db::{Conn, Optional, params};

use super::{Result, SPEC_COLUMNS, Store, StoreError, from_json, task_spec};
use crate::job::{self, FrameRange, TaskSpec};
use crate::protocol::{LeaseGrant, WorkerInfo};

/// A step of a job: a frame's (frame ≥ 1), a pass's (frame 0, step = the pass's position), or
/// its pilot's (frame 0, [`job::PILOT_STEP`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct StepKey {
    pub job: i64,
    pub frame: u32,
    pub step: u32,
}

/// What became of a result.
#[derive(Debug, PartialEq, Eq)]
pub enum Completion {
    /// The lease was not current (expired and reassigned, or the job ended): dropped.
    Stale,
    /// Accepted; `complete` when it was the last of its step to be done.
    Accepted { step: StepKey, complete: bool },
}

/// What became of a failure report or an expired lease.
#[derive(Debug, PartialEq, Eq)]
pub enum Retry {
    Stale,
    Requeued,
    /// Out of attempts: the job failed with this error.
    JobFailed(String),
}

/// When a failed task is retried, and when its job fails.
#[derive(Debug, Clone, Copy)]
pub struct RetryPolicy {
    /// Failures of a task (on workers not blocklisted for its job) that fail the job.
    pub max_attempts: u32,
    /// Failures of a job's tasks on one worker that blocklist the worker for the job.
    pub blocklist_after: u32,
    /// A worker seen within this long counts as able to take work (for whether any is left).
    pub alive_ms: i64,
}

/// Queue gauges for `/metrics` and `/healthz`.
pub struct Gauges {
    pub queued: u64,
    pub leased: u64,
    /// Jobs by state.
    pub jobs: Vec<(String, u64)>,
}

/// One task of a step as the fold reads it: (task id, state, lease, spec).
pub type StepTask = (i64, String, Option<i64>, TaskSpec);

impl Store {
    fn upsert_worker(tx: &Conn, w: &WorkerInfo, now: i64) -> Result<()> {
        tx.execute(
            "INSERT INTO workers (id, name, host, pid, slots, version, first_seen_ms, last_seen_ms,
                scene_builds, tags, cpu)
             VALUES (?1, ?2, ?3, ?8, ?4, ?5, ?6, ?6, ?7, ?9, ?10)
             ON CONFLICT (id) DO UPDATE SET last_seen_ms = ?6, scene_builds = ?7, slots = ?4,
                tags = ?9, cpu = COALESCE(?10, workers.cpu)",
            params![
                w.id,
                w.name,
                w.host,
                w.slots,
                w.version,
                now,
                w.scene_builds as i64,
                w.pid,
                Self::tags_json(&w.tags),
                w.cpu
            ],
        )?;
        Ok(())
    }

    /// The next queued task `worker` may take: of the jobs not paused, not blocklisting it
    /// and requiring no tag it lacks, by priority, then job age, then task order.
    fn next_task(tx: &Conn, worker: &WorkerInfo) -> Result<Option<(i64, i64)>> {
        let excluded = Self::excluded_jobs(tx, &worker.id, &worker.tags)?;
        if excluded.is_empty() {
            return Ok(tx
                .query_row(
                    &format!(
                        "SELECT id, job_id FROM tasks WHERE state = 'queued'
                         ORDER BY priority DESC, job_id, id LIMIT 1{}",
                        tx.dialect().skip_locked()
                    ),
                    params![],
                    |r| Ok((r.get(0)?, r.get(1)?)),
                )
                .optional()?);
        }
        // Job by job, so that a large job it may not take costs one look, not a scan.
        let ids: Vec<i64> = tx.query_map(
            "SELECT id FROM jobs WHERE state IN ('queued', 'running') ORDER BY priority DESC, id",
            params![],
            |r| r.get(0),
        )?;
        for job in ids.into_iter().filter(|j| !excluded.contains(j)) {
            if let Some(task) = tx
                .query_row(
                    &format!(
                        "SELECT id FROM tasks WHERE job_id = ?1 AND state = 'queued' ORDER BY id LIMIT 1{}",
                        tx.dialect().skip_locked()
                    ),
                    params![job],
                    |r| r.get(0),
                )
                .optional()?
            {
                return Ok(Some((task, job)));
            }
        }
        Ok(None)
    }

    /// Grants the next task (priority, then job age, then task order) to `worker`, unless it
    /// is draining. A job whose stored settings cannot be read fails with that reason, and the
    /// next task is looked at.
    pub fn lease(
        &self,
        worker: &WorkerInfo,
        now: i64,
        lease_ms: u64,
    ) -> Result<Option<LeaseGrant>> {
        // The task is locked as it is taken: coordinators leasing at once take different ones.
        self.db.write_row_locked(|tx| {
            Self::upsert_worker(tx, worker, now)?;
            let draining: bool = tx.query_row(
                "SELECT draining FROM workers WHERE id = ?1",
                params![&worker.id],
                |r| r.get(0),
            )?;
            if draining {
                return Ok(None);
            }
            loop {
                let Some((task_id, job_id)) = Self::next_task(tx, worker)? else {
                    return Ok(None);
                };
                let (bundle, scene, settings, frames, spec): (String, String, String, _, TaskSpec) =
                    tx.query_row(
                        &format!(
                            "SELECT j.bundle, j.scene, j.settings, j.first_frame, j.last_frame,
                                {SPEC_COLUMNS}
                             FROM tasks t JOIN jobs j ON j.id = t.job_id WHERE t.id = ?1"
                        ),
                        params![task_id],
                        |r| {
                            let frames = FrameRange {
                                first: r.get(3)?,
                                last: r.get(4)?,
                            };
                            Ok((r.get(0)?, r.get(1)?, r.get(2)?, frames, task_spec(r, 5)?))
                        },
                    )?;
                let settings = match from_json(&settings, &format!("settings of job {job_id}")) {
                    Ok(s) => s,
                    Err(e) => {
                        Self::end_job(tx, job_id, "failed", Some(&e.to_string()), now)?;
                        continue;
                    }
                };
                let lease: i64 = tx.query_row(
                    "INSERT INTO attempts (task_id, worker, started_ms) VALUES (?1, ?2, ?3) RETURNING id",
                    params![task_id, worker.id, now],
                    |r| r.get(0),
                )?;
                tx.execute(
                    "UPDATE tasks SET state = 'leased', attempts = attempts + 1, lease = ?2, worker = ?3,
                        lease_expires_ms = ?4 WHERE id = ?1",
                    params![task_id, lease, worker.id, now + lease_ms as i64],
                )?;
                tx.execute(
                    "UPDATE jobs SET state = 'running', started_ms = COALESCE(started_ms, ?2)
                     WHERE id = ?1 AND state = 'queued'",
                    params![job_id, now],
                )?;
                let artifacts = Self::artifacts_for(tx, job_id, &spec)?;
                return Ok(Some(LeaseGrant {
                    task_id,
                    lease,
                    lease_ms,
                    job_id,
                    bundle,
                    scene,
                    settings,
                    frames,
                    task: spec,
                    artifacts,
                    input: None,
                    max_result_bytes: None,
                }));
            }
        })
    }

    /// Renews a lease (and notes the worker's CPU use); false if it is no longer the task's
    /// current lease.
    pub fn heartbeat(
        &self,
        task: i64,
        lease: i64,
        worker: &str,
        cpu: Option<f32>,
        now: i64,
        lease_ms: u64,
    ) -> Result<bool> {
        let conn = self.conn()?;
        // Only the worker holding the lease renews it (and is seen by renewing it).
        let n = conn.execute(
            "UPDATE tasks SET lease_expires_ms = ?3
             WHERE id = ?1 AND lease = ?2 AND state = 'leased' AND worker = ?4",
            params![task, lease, now + lease_ms as i64, worker],
        )?;
        if n == 1 {
            conn.execute(
                "UPDATE workers SET last_seen_ms = ?2, cpu = COALESCE(?3, cpu) WHERE id = ?1",
                params![worker, now, cpu],
            )?;
        }
        Ok(n == 1)
    }

    /// The job and the worker of a current lease.
    pub fn lease_holder(&self, task: i64, lease: i64) -> Result<Option<(i64, String)>> {
        self.conn()?
            .query_row(
                "SELECT job_id, COALESCE(worker, '') FROM tasks
                 WHERE id = ?1 AND lease = ?2 AND state = 'leased'",
                params![task, lease],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .optional()
    }

    /// The task a lease is for, if the lease is current: (job, spec).
    pub fn current_lease(&self, task: i64, lease: i64) -> Result<Option<(i64, TaskSpec)>> {
        Ok(self
            .conn()?
            .query_row(
                &format!(
                    "SELECT job_id, {SPEC_COLUMNS} FROM tasks
                     WHERE id = ?1 AND lease = ?2 AND state = 'leased'"
                ),
                params![task, lease],
                |r| Ok((r.get(0)?, task_spec(r, 1)?)),
            )
            .optional()?)
    }

    /// Marks a task done with its result (already on disk), if the lease is still current.
    pub fn complete(
        &self,
        task: i64,
        lease: i64,
        seconds: f64,
        sizes: (u64, u64),
        now: i64,
    ) -> Result<Completion> {
        // Completions of one step wait for each other on its frame's (or pass's) row, which
        // they update before counting the step's open tasks: the last to commit sees none.
        self.db.write_row_locked(|tx| {
            let done: Option<(i64, u32, u32)> = tx
                .query_row(
                    "UPDATE tasks SET state = 'done', seconds = ?3, lease_expires_ms = NULL,
                        result_bytes = ?4, payload_bytes = ?5
                     WHERE id = ?1 AND lease = ?2 AND state = 'leased'
                     RETURNING job_id, frame, step",
                    params![task, lease, seconds, sizes.0 as i64, sizes.1 as i64],
                    |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)),
                )
                .optional()?;
            let Some((job, frame, step)) = done else {
                tx.execute(
                    "UPDATE attempts SET ended_ms = ?2, outcome = 'stale' WHERE id = ?1 AND outcome IS NULL",
                    params![lease, now],
                )?;
                return Ok(Completion::Stale);
            };
            tx.execute(
                "UPDATE attempts SET ended_ms = ?2, outcome = 'done' WHERE id = ?1",
                params![lease, now],
            )?;
            // Throughput: pixel samples of the task (pixels × samples; none for a pass's task).
            tx.execute(
                "UPDATE workers SET tasks_done = tasks_done + 1, last_seen_ms = ?2,
                    busy_seconds = busy_seconds + ?3,
                    samples_done = samples_done + COALESCE((SELECT (x1 - x0) * (y1 - y0) * (range_end - range_start)
                                                            FROM tasks WHERE id = ?4 AND frame > 0), 0)
                 WHERE id = (SELECT worker FROM attempts WHERE id = ?1)",
                params![lease, now, seconds, task],
            )?;
            if frame == 0 {
                tx.execute(
                    "UPDATE passes SET tasks_done = tasks_done + 1 WHERE job_id = ?1 AND step = ?2",
                    params![job, step],
                )?;
            } else {
                tx.execute(
                    "UPDATE frames SET tasks_done = tasks_done + 1, state = 'running'
                     WHERE job_id = ?1 AND frame = ?2",
                    params![job, frame],
                )?;
            }
            let open: i64 = tx.query_row(
                "SELECT COUNT(*) FROM tasks WHERE job_id = ?1 AND frame = ?2 AND step = ?3 AND state != 'done'",
                params![job, frame, step],
                |r| r.get(0),
            )?;
            Ok(Completion::Accepted {
                step: StepKey { job, frame, step },
                complete: open == 0,
        })
        })
    }

    /// Ends an attempt that failed (`outcome` "failed"), whose lease expired ("expired") or
    /// whose result could not be read ("unreadable"): a failure counts toward blocklisting
    /// its worker for the job; the task is requeued, or the job fails once the task has
    /// failed `max_attempts` times on workers not blocklisted for it, or when no worker that
    /// could run it is left.
    fn retry(
        tx: &Conn,
        task: i64,
        lease: i64,
        outcome: &str,
        error: &str,
        now: i64,
        policy: &RetryPolicy,
    ) -> Result<Retry> {
        let row: Option<(i64, TaskSpec, String)> = tx
            .query_row(
                &format!(
                    "SELECT t.job_id, {SPEC_COLUMNS}, COALESCE(a.worker, '')
                     FROM tasks t LEFT JOIN attempts a ON a.id = t.lease
                     WHERE t.id = ?1 AND t.lease = ?2 AND t.state = 'leased'"
                ),
                params![task, lease],
                |r| Ok((r.get(0)?, task_spec(r, 1)?, r.get(11)?)),
            )
            .optional()?;
        let Some((job, spec, worker)) = row else {
            return Ok(Retry::Stale);
        };
        tx.execute(
            "UPDATE attempts SET ended_ms = ?2, outcome = ?3, error = ?4 WHERE id = ?1",
            params![lease, now, outcome, error],
        )?;
        // A worker that reports failures (not one whose lease lapsed: it may have lost the
        // network) is blocklisted for the job after `blocklist_after` of them.
        let blocked = outcome == "failed"
            && Self::count_failure(tx, job, &worker, error, now, policy.blocklist_after)?
                == super::Blocklisting::Blocked;
        let failures = Self::counted_failures(tx, task)?;
        let place = if job::is_pilot(&spec) {
            "auto's pilot".to_string()
        } else if spec.is_pass() {
            format!("pass {}", spec.step)
        } else {
            format!("frame {}, step {}", spec.frame, spec.step)
        };
        // Once a worker is blocklisted, its later failures no longer count toward attempts:
        // whether anyone is left to run the job is asked at every failure, not only the one
        // that blocklisted (a task failing the same way on every worker fails its job).
        let stranded = outcome == "failed" && (blocked || Self::is_blocked(tx, job, &worker)?);
        let message = if stranded && !Self::has_eligible_worker(tx, job, now, policy.alive_ms)? {
            Some(Self::stranded_message(tx, job, policy)?)
        } else if failures >= policy.max_attempts {
            Some(format!(
                "task {task} ({} {} of {place}) failed {failures} times; last attempt on worker {worker}: {error}",
                spec.kind, spec.index
            ))
        } else {
            None
        };
        let Some(message) = message else {
            tx.execute(
                "UPDATE tasks SET state = 'queued', lease = NULL, worker = NULL,
                    lease_expires_ms = NULL, error = ?2 WHERE id = ?1",
                params![task, error],
            )?;
            return Ok(Retry::Requeued);
        };
        tx.execute(
            "UPDATE tasks SET state = 'failed', lease_expires_ms = NULL, error = ?2 WHERE id = ?1",
            params![task, error],
        )?;
        Self::end_job(tx, job, "failed", Some(&message), now)?;
        Ok(Retry::JobFailed(message))
    }

    /// Why `job` fails when every worker that could run it is blocklisted for it.
    fn stranded_message(tx: &Conn, job: i64, policy: &RetryPolicy) -> Result<String> {
        let list = Self::blocklist_of(tx, job)?
            .iter()
            .map(|b| {
                format!(
                    "{} ({} failures; last: {})",
                    b.worker,
                    b.failures,
                    b.last_error.as_deref().unwrap_or("")
                )
            })
            .collect::<Vec<_>>()
            .join(", ");
        Ok(format!(
            "every worker that could run the job is blocklisted for it after failing its tasks {} times: {list}",
            policy.blocklist_after
        ))
    }

    /// Whether `worker` is blocklisted for `job`.
    fn is_blocked(tx: &Conn, job: i64, worker: &str) -> Result<bool> {
        Ok(tx
            .query_row(
                "SELECT 1 FROM blocklist WHERE job_id = ?1 AND worker = ?2 AND blocked_ms IS NOT NULL",
                params![job, worker],
                |_| Ok(()),
            )
            .optional()?
            .is_some())
    }

    /// Fails the open jobs that have queued tasks, a blocklist, and no worker left that could
    /// run them while workers are there (the last eligible one went quiet after the
    /// blocklisting). A farm with no live worker at all fails nothing: it is the farm that
    /// is down, not the job. Returns the jobs failed, with the reason.
    pub fn fail_stranded(&self, now: i64, policy: &RetryPolicy) -> Result<Vec<(i64, String)>> {
        self.db.write(|tx| Self::stranded(tx, now, policy))
    }

    fn stranded(tx: &Conn, now: i64, policy: &RetryPolicy) -> Result<Vec<(i64, String)>> {
        let live: Option<i64> = tx
            .query_row(
                "SELECT 1 FROM workers WHERE last_seen_ms >= ?1 LIMIT 1",
                params![now - policy.alive_ms],
                |r| r.get(0),
            )
            .optional()?;
        if live.is_none() {
            return Ok(Vec::new());
        }
        // The blocklist is short; queued tasks are many (and indexed).
        let jobs: Vec<i64> = tx.query_map(
            "SELECT DISTINCT b.job_id FROM blocklist b
             WHERE b.blocked_ms IS NOT NULL
               AND EXISTS (SELECT 1 FROM tasks t WHERE t.job_id = b.job_id AND t.state = 'queued')",
            params![],
            |r| r.get(0),
        )?;
        let mut out = Vec::new();
        for job in jobs {
            if Self::job_open(tx, job)?
                && !Self::has_eligible_worker(tx, job, now, policy.alive_ms)?
            {
                let message = Self::stranded_message(tx, job, policy)?;
                Self::end_job(tx, job, "failed", Some(&message), now)?;
                out.push((job, message));
            }
        }
        Ok(out)
    }

    /// A worker reports that a task cannot be rendered by anyone (see
    /// [`crate::protocol::Failure::permanent`]): the job fails at once with the error.
    pub fn fail_permanently(&self, task: i64, lease: i64, error: &str, now: i64) -> Result<Retry> {
        self.db.write(|tx| {
            let job: Option<i64> = tx
                .query_row(
                    "SELECT job_id FROM tasks WHERE id = ?1 AND lease = ?2 AND state = 'leased'",
                    params![task, lease],
                    |r| r.get(0),
                )
                .optional()?;
            let Some(job) = job else {
                return Ok(Retry::Stale);
            };
            tx.execute(
                "UPDATE attempts SET ended_ms = ?2, outcome = 'failed', error = ?3 WHERE id = ?1",
                params![lease, now, error],
            )?;
            tx.execute(
                "UPDATE tasks SET state = 'failed', lease_expires_ms = NULL, error = ?2 WHERE id = ?1",
                params![task, error],
            )?;
            let message = format!("task {task} cannot be run by any worker (no retry can mend it): {error}");
            Self::end_job(tx, job, "failed", Some(&message), now)?;
            Ok(Retry::JobFailed(message))
        })
    }

    /// A worker reports that it could not render a task.
    pub fn fail(
        &self,
        task: i64,
        lease: i64,
        error: &str,
        now: i64,
        policy: &RetryPolicy,
    ) -> Result<Retry> {
        self.db.write(|tx| {
            let r = Self::retry(tx, task, lease, "failed", error, now, policy)?;
            Ok(r)
        })
    }

    /// A done task whose result could not be read back: it is queued again (its attempt
    /// counting), or the job fails once it has had `max_attempts`.
    pub fn redo(&self, task: i64, error: &str, now: i64, policy: &RetryPolicy) -> Result<Retry> {
        self.db.write(|tx| {
            let lease: Option<i64> = tx
                .query_row(
                    "SELECT lease FROM tasks WHERE id = ?1 AND state = 'done'",
                    params![task],
                    |r| r.get(0),
                )
                .optional()?
                .flatten();
            let Some(lease) = lease else {
                return Ok(Retry::Stale);
            };
            let (job, frame): (i64, u32) = tx.query_row(
                "SELECT job_id, frame FROM tasks WHERE id = ?1",
                params![task],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )?;
            tx.execute(
                "UPDATE tasks SET state = 'leased' WHERE id = ?1",
                params![task],
            )?;
            let table = if frame == 0 { "passes" } else { "frames" };
            let by = if frame == 0 { "step" } else { "frame" };
            tx.execute(
                &format!(
                    "UPDATE {table} SET tasks_done = tasks_done - 1 WHERE job_id = ?1
                 AND {by} = (SELECT {by} FROM tasks WHERE id = ?2)"
                ),
                params![job, task],
            )?;
            let r = Self::retry(tx, task, lease, "unreadable", error, now, policy)?;
            Ok(r)
        })
    }

    /// Takes back every lease that expired before `now`. Returns what became of each.
    pub fn expire(&self, now: i64, policy: &RetryPolicy) -> Result<Vec<(i64, Retry)>> {
        self.db.write(|tx| {
            let expired: Vec<(i64, i64)> = tx.query_map(
                "SELECT id, lease FROM tasks WHERE state = 'leased' AND lease_expires_ms < ?1",
                params![now],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )?;
            let mut out = Vec::with_capacity(expired.len());
            for (task, lease) in expired {
                let r = Self::retry(
                    &tx,
                    task,
                    lease,
                    "expired",
                    "the lease expired: the worker stopped renewing it (died, hung or lost the network)",
                    now,
                    policy,
                )?;
                out.push((task, r));
            }
            Ok(out)
        })
    }

    /// Ends a job that has not ended (`cancelled` or `failed`, with an error), cancelling its
    /// open tasks; false if it had ended.
    pub(super) fn end_job(
        tx: &Conn,
        job: i64,
        state: &str,
        error: Option<&str>,
        now: i64,
    ) -> Result<bool> {
        let n = tx.execute(
            "UPDATE jobs SET state = ?2, error = COALESCE(?3, error), finished_ms = ?4
             WHERE id = ?1 AND state IN ('queued', 'running', 'paused')",
            params![job, state, error, now],
        )?;
        if n == 1 {
            tx.execute(
                "UPDATE tasks SET state = 'cancelled', lease_expires_ms = NULL
                 WHERE job_id = ?1 AND state IN ('queued', 'leased')",
                params![job],
            )?;
        }
        Ok(n == 1)
    }

    /// Whether a job exists and has not ended (it may still get tasks).
    pub(super) fn job_open(tx: &Conn, job: i64) -> Result<bool> {
        Ok(tx
            .query_row(
                "SELECT 1 FROM jobs WHERE id = ?1 AND state IN ('queued', 'running', 'paused')",
                params![job],
                |_| Ok(()),
            )
            .optional()?
            .is_some())
    }

    /// Cancels a job that has not ended; false if it had.
    pub fn cancel(&self, job: i64, now: i64) -> Result<bool> {
        self.db.write(|tx| {
            let ended = Self::end_job(tx, job, "cancelled", None, now)?;
            Ok(ended)
        })
    }

    /// Fails a job that has not ended (a frame that could not be written, say).
    pub fn fail_job(&self, job: i64, error: &str, now: i64) -> Result<()> {
        self.db.write(|tx| {
            Self::end_job(tx, job, "failed", Some(error), now)?;
            Ok(())
        })
    }

    /// Queues a frame's next step (its tasks all carry the step's number) and moves the frame
    /// to it; nothing if that step's tasks exist already (a repeated advance after a restart),
    /// or if the job has ended.
    pub fn add_step(&self, job: i64, frame: u32, tasks: &[TaskSpec]) -> Result<()> {
        let Some(step) = tasks.first().map(|t| t.step) else {
            return Ok(());
        };
        if tasks.iter().any(|t| t.step != step || t.frame != frame) {
            return Err(StoreError::Corrupt(format!(
                "a step of frame {frame} whose tasks are not all of frame {frame}, step {step}"
            )));
        }
        self.db.write(|tx| {
            let running = Self::job_open(tx, job)?;
            let exists = tx
                .query_row(
                    "SELECT 1 FROM tasks WHERE job_id = ?1 AND frame = ?2 AND step = ?3 LIMIT 1",
                    params![job, frame, step],
                    |_| Ok(()),
                )
                .optional()?
                .is_some();
            if running && !exists {
                Self::insert_tasks(tx, job, tasks)?;
                tx.execute(
                    "UPDATE frames SET step = ?3 WHERE job_id = ?1 AND frame = ?2",
                    params![job, frame, step],
                )?;
            }
            Ok(())
        })
    }

    /// A frame's current step.
    pub fn frame_step(&self, job: i64, frame: u32) -> Result<Option<u32>> {
        Ok(self
            .conn()?
            .query_row(
                "SELECT step FROM frames WHERE job_id = ?1 AND frame = ?2",
                params![job, frame],
                |r| r.get(0),
            )
            .optional()?)
    }

    /// A step's tasks in fold order from position `from` on, at most `limit` of them; and how
    /// many tasks the step has in all.
    pub fn step_tasks(
        &self,
        key: StepKey,
        from: usize,
        limit: usize,
    ) -> Result<(Vec<StepTask>, usize)> {
        let conn = self.conn()?;
        let out = conn.query_map(
            &format!(
                "SELECT id, state, lease, {SPEC_COLUMNS} FROM tasks
                 WHERE job_id = ?1 AND frame = ?2 AND step = ?3 ORDER BY idx LIMIT ?4 OFFSET ?5"
            ),
            params![key.job, key.frame, key.step, limit as i64, from as i64],
            |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, task_spec(r, 3)?)),
        )?;
        let total: i64 = conn.query_row(
            "SELECT COUNT(*) FROM tasks WHERE job_id = ?1 AND frame = ?2 AND step = ?3",
            params![key.job, key.frame, key.step],
            |r| r.get(0),
        )?;
        Ok((out, total as usize))
    }

    /// The results of a step's done tasks: (task id, lease).
    pub fn step_results(&self, key: StepKey) -> Result<Vec<(i64, i64)>> {
        let conn = self.conn()?;
        conn.query_map(
            "SELECT id, lease FROM tasks WHERE job_id = ?1 AND frame = ?2 AND step = ?3 AND state = 'done'",
            params![key.job, key.frame, key.step],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )
    }

    /// The done results of a job's tasks as (task, lease), for deleting their files.
    pub fn results_of(&self, job: i64, frame: u32) -> Result<Vec<(i64, i64)>> {
        let conn = self.conn()?;
        conn.query_map(
            "SELECT id, lease FROM tasks WHERE job_id = ?1 AND frame = ?2 AND state = 'done'",
            params![job, frame],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )
    }

    /// Steps of running jobs whose tasks are all done but which were not folded on (a restart
    /// in between): frames at their current step, passes still running, and pilots of jobs
    /// not yet planned.
    pub fn finished_steps(&self) -> Result<Vec<StepKey>> {
        let conn = self.conn()?;
        conn.query_map(
            "SELECT f.job_id, f.frame, f.step FROM frames f JOIN jobs j ON j.id = f.job_id
             WHERE f.state != 'done' AND j.state IN ('queued', 'running', 'paused')
               AND EXISTS (SELECT 1 FROM tasks t WHERE t.job_id = f.job_id AND t.frame = f.frame AND t.step = f.step)
               AND NOT EXISTS (SELECT 1 FROM tasks t WHERE t.job_id = f.job_id AND t.frame = f.frame
                               AND t.step = f.step AND t.state != 'done')
             UNION ALL
             SELECT p.job_id, 0, p.step FROM passes p JOIN jobs j ON j.id = p.job_id
             WHERE p.state = 'running' AND p.tasks_done = p.tasks_total
               AND j.state IN ('queued', 'running', 'paused')
             UNION ALL
             SELECT t.job_id, 0, t.step FROM tasks t JOIN jobs j ON j.id = t.job_id
             WHERE j.measuring = 1 AND t.frame = 0 AND t.step = ?1 AND t.state = 'done'
               AND j.state IN ('queued', 'running', 'paused')",
            params![job::PILOT_STEP],
            |r| {
                Ok(StepKey {
                    job: r.get(0)?,
                    frame: r.get(1)?,
                    step: r.get(2)?,
                })
            },
        )
    }

    /// Tasks queued and leased over all jobs, and jobs by state.
    pub fn gauges(&self) -> Result<Gauges> {
        let conn = self.conn()?;
        let (queued, leased): (i64, i64) = conn.query_row(
            "SELECT (SELECT COUNT(*) FROM tasks WHERE state = 'queued'),
                    (SELECT COUNT(*) FROM tasks WHERE state = 'leased')",
            params![],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )?;
        let jobs = conn.query_map(
            "SELECT state, COUNT(*) FROM jobs GROUP BY state",
            params![],
            |r| Ok((r.get(0)?, r.get::<i64>(1)? as u64)),
        )?;
        Ok(Gauges {
            queued: queued as u64,
            leased: leased as u64,
            jobs,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{store, task, worker};
    use super::*;
    use crate::protocol::JobState;

    /// A worker is blocklisted for a job only after more failures than these tests make.
    const POLICY: RetryPolicy = RetryPolicy {
        max_attempts: 3,
        blocklist_after: 100,
        alive_ms: 60_000,
    };

    #[test]
    fn leases_go_by_priority_then_age_then_task_order() {
        let (_d, s, jobs) = store(&[0, 5, 5], 2);
        let order: Vec<(i64, u32)> = (0..6)
            .map(|_| {
                let g = s
                    .lease(&worker("w"), 0, 1000)
                    .expect("lease")
                    .expect("a task");
                (g.job_id, g.task.index)
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

    /// A job awaiting `auto`'s choice runs its pilot alone; once the pilot is done its step is
    /// found again after a restart until the job is planned, and it is planned once.
    #[test]
    fn a_measuring_job_runs_its_pilot_and_is_planned_once() {
        use crate::job::{PILOT_STEP, pilot_task};
        use crate::store::tests::new_job;
        let (_d, s, _) = store(&[], 0);
        let frames = FrameRange { first: 1, last: 2 };
        let job = s
            .insert_job(
                &new_job(frames, true, "auto", vec![vec![pilot_task()]], vec![]),
                0,
            )
            .expect("job");
        let status = s.job(job).expect("q").expect("job");
        assert!(status.measuring && status.method == "auto", "{status:?}");
        let g = s
            .lease(&worker("w"), 0, 1000)
            .expect("lease")
            .expect("the pilot");
        assert_eq!(g.task, pilot_task());
        assert!(s.lease(&worker("w"), 0, 1000).expect("lease").is_none());
        let key = StepKey {
            job,
            frame: 0,
            step: PILOT_STEP,
        };
        assert_eq!(
            s.complete(g.task_id, g.lease, 1.0, (1, 1), 1).expect("c"),
            Completion::Accepted {
                step: key,
                complete: true
            }
        );
        assert_eq!(s.finished_steps().expect("q"), vec![key]);
        let tasks = vec![vec![task(1, 0), task(1, 1)], vec![task(2, 0)]];
        let work = new_job(frames, false, "path", tasks, vec![]).work;
        assert!(s.measured(job, &work).expect("plan"));
        assert!(!s.measured(job, &work).expect("plan"));
        assert_eq!(s.finished_steps().expect("q"), vec![]);
        let status = s.job(job).expect("q").expect("job");
        assert!(!status.measuring && status.method == "path", "{status:?}");
        // The pilot and the three frame tasks, once.
        assert_eq!((status.tasks.total, status.tasks.planned), (4, 4));
        let leased: Vec<u32> = (0..3)
            .map(|_| {
                s.lease(&worker("w"), 2, 1000)
                    .expect("lease")
                    .expect("a task")
                    .task
                    .frame
            })
            .collect();
        assert_eq!(leased, [1, 1, 2]);
    }

    #[test]
    fn a_stale_lease_cannot_heartbeat_or_complete_after_reassignment() {
        let (_d, s, jobs) = store(&[0], 1);
        let first = s.lease(&worker("a"), 0, 100).expect("lease").expect("task");
        // The lease expires and the task goes to another worker.
        assert_eq!(s.expire(50, &POLICY).expect("expire"), vec![]);
        assert_eq!(
            s.expire(101, &POLICY).expect("expire"),
            vec![(first.task_id, Retry::Requeued)]
        );
        let second = s
            .lease(&worker("b"), 102, 100)
            .expect("lease")
            .expect("task");
        assert_eq!(second.task_id, first.task_id);
        assert_ne!(second.lease, first.lease);
        assert!(
            !s.heartbeat(first.task_id, first.lease, "a", None, 103, 100)
                .expect("hb")
        );
        assert!(
            s.current_lease(first.task_id, first.lease)
                .expect("q")
                .is_none()
        );
        assert_eq!(
            s.complete(first.task_id, first.lease, 1.0, (1, 1), 104)
                .expect("c"),
            Completion::Stale
        );
        // The current holder completes; its step is then complete.
        assert!(
            s.heartbeat(second.task_id, second.lease, "b", None, 105, 100)
                .expect("hb")
        );
        let key = StepKey {
            job: jobs[0],
            frame: 1,
            step: 0,
        };
        assert_eq!(
            s.complete(second.task_id, second.lease, 1.0, (1, 1), 106)
                .expect("c"),
            Completion::Accepted {
                step: key,
                complete: true
            }
        );
        assert_eq!(
            s.complete(second.task_id, second.lease, 1.0, (1, 1), 107)
                .expect("c"),
            Completion::Stale
        );
        let job = s.job(jobs[0]).expect("q").expect("job");
        assert_eq!((job.tasks.done, job.attempts), (1, 2));
        // A later step (an adaptive round) queues once, however often it is added.
        let round = [TaskSpec {
            step: 1,
            ..task(1, 0)
        }];
        s.add_step(jobs[0], 1, &round).expect("add");
        s.add_step(jobs[0], 1, &round).expect("add again");
        assert_eq!(s.frame_step(jobs[0], 1).expect("q"), Some(1));
        let g = s
            .lease(&worker("b"), 110, 100)
            .expect("lease")
            .expect("the new round");
        assert_eq!(g.task.step, 1);
        assert!(s.lease(&worker("b"), 110, 100).expect("lease").is_none());
        assert_eq!(
            s.complete(g.task_id, g.lease, 1.0, (1, 1), 111).expect("c"),
            Completion::Accepted {
                step: StepKey { step: 1, ..key },
                complete: true
            }
        );
        assert_eq!(
            s.step_tasks(StepKey { step: 1, ..key }, 0, 10)
                .expect("q")
                .1,
            1
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
            assert_eq!(g.task.index, 0, "the failed task is retried first");
            let r = s
                .fail(g.task_id, g.lease, &format!("boom {attempt}"), 1, &POLICY)
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
