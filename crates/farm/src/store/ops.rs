//! Farm operations people steer with: pausing and resuming a job, requeueing what failed,
//! changing a priority, draining a worker, and the per-job worker blocklist (a worker that
//! fails a job's tasks too often takes no more of them, as Flamenco does).

use super::db::{Conn, Optional, params};

use super::{Result, Store, from_json, json};
use crate::protocol::{Blocklisted, JobState};

/// What a failure did to the blocklist.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Blocklisting {
    /// The worker may go on with the job.
    Counted,
    /// The worker is now blocklisted for the job.
    Blocked,
}

impl Store {
    /// Pauses a queued or running job: nothing more of it is leased; leased tasks finish.
    /// False if it was not queued or running.
    pub fn pause(&self, job: i64) -> Result<bool> {
        let n = self.conn()?.execute(
            "UPDATE jobs SET state = 'paused' WHERE id = ?1 AND state IN ('queued', 'running')",
            params![job],
        )?;
        Ok(n == 1)
    }

    /// Resumes a paused job; false if it was not paused.
    pub fn resume(&self, job: i64) -> Result<bool> {
        let n = self.conn()?.execute(
            "UPDATE jobs SET state = CASE WHEN started_ms IS NULL THEN 'queued' ELSE 'running' END
             WHERE id = ?1 AND state = 'paused'",
            params![job],
        )?;
        Ok(n == 1)
    }

    /// Puts a failed or cancelled job back in the queue: its failed and cancelled tasks are
    /// queued again (a pass's tasks that were waiting wait again), earlier failures and its
    /// blocklist are forgotten. Returns how many tasks were requeued, `None` if the job was
    /// not failed or cancelled.
    pub fn requeue(&self, job: i64, now: i64) -> Result<Option<u64>> {
        self.db.write(|tx| {
            let state: Option<String> = tx
                .query_row("SELECT state FROM jobs WHERE id = ?1", params![job], |r| {
                    r.get(0)
                })
                .optional()?;
            if !matches!(
                state.as_deref().map(JobState::parse),
                Some(JobState::Failed | JobState::Cancelled)
            ) {
                return Ok(None);
            }
            let n = tx.execute(
                "UPDATE tasks SET
                state = CASE WHEN frame = 0 AND (SELECT p.state FROM passes p
                    WHERE p.job_id = tasks.job_id AND p.step = tasks.step) = 'waiting'
                    THEN 'waiting' ELSE 'queued' END,
                lease = NULL, worker = NULL, lease_expires_ms = NULL, error = NULL
             WHERE job_id = ?1 AND state IN ('failed', 'cancelled')",
                params![job],
            )?;
            tx.execute(
            "UPDATE jobs SET state = CASE WHEN started_ms IS NULL THEN 'queued' ELSE 'running' END,
                error = NULL, finished_ms = NULL, requeued_ms = ?2
             WHERE id = ?1",
            params![job, now],
        )?;
            tx.execute("DELETE FROM blocklist WHERE job_id = ?1", params![job])?;
            Ok(Some(n as u64))
        })
    }

    /// Sets a job's priority (and its tasks', which the queue orders by); false if there is no
    /// such job.
    pub fn set_priority(&self, job: i64, priority: i32) -> Result<bool> {
        self.db.write(|tx| {
            let n = tx.execute(
                "UPDATE jobs SET priority = ?2 WHERE id = ?1",
                params![job, priority],
            )?;
            tx.execute(
                "UPDATE tasks SET priority = ?2 WHERE job_id = ?1",
                params![job, priority],
            )?;
            Ok(n == 1)
        })
    }

    /// Drains a worker (it finishes what it holds and leases nothing more), or lets it take
    /// work again; false if no such worker has been seen.
    pub fn set_draining(&self, worker: &str, draining: bool) -> Result<bool> {
        let n = self.conn()?.execute(
            "UPDATE workers SET draining = ?2 WHERE id = ?1",
            params![worker, draining],
        )?;
        Ok(n == 1)
    }

    /// Lets a worker run a job's tasks again (`job`), or every job's (`None`); the number of
    /// blocklist entries removed.
    pub fn unblock(&self, worker: &str, job: Option<i64>) -> Result<u64> {
        let n = match job {
            Some(j) => self.conn()?.execute(
                "DELETE FROM blocklist WHERE worker = ?1 AND job_id = ?2",
                params![worker, j],
            )?,
            None => self
                .conn()?
                .execute("DELETE FROM blocklist WHERE worker = ?1", params![worker])?,
        };
        Ok(n as u64)
    }

    /// Counts a failure of `job`'s task on `worker`; at `after` failures the worker is
    /// blocklisted for the job.
    pub(super) fn count_failure(
        tx: &Conn,
        job: i64,
        worker: &str,
        error: &str,
        now: i64,
        after: u32,
    ) -> Result<Blocklisting> {
        tx.execute(
            "UPDATE workers SET failures = failures + 1 WHERE id = ?1",
            params![worker],
        )?;
        tx.execute(
            "INSERT INTO blocklist (job_id, worker, failures, last_error) VALUES (?1, ?2, 1, ?3)
             ON CONFLICT (job_id, worker) DO UPDATE SET failures = blocklist.failures + 1, last_error = ?3",
            params![job, worker, error],
        )?;
        let n = tx.execute(
            "UPDATE blocklist SET blocked_ms = ?3
             WHERE job_id = ?1 AND worker = ?2 AND blocked_ms IS NULL AND failures >= ?4",
            params![job, worker, now, after],
        )?;
        Ok(if n == 1 {
            Blocklisting::Blocked
        } else {
            Blocklisting::Counted
        })
    }

    /// Failures of a task that count toward its attempts: since its job was last requeued,
    /// on workers not blocklisted for the job (a broken worker's failures are its own).
    pub(super) fn counted_failures(tx: &Conn, task: i64) -> Result<u32> {
        Ok(tx.query_row(
            "SELECT COUNT(*) FROM attempts a JOIN tasks t ON t.id = a.task_id
             JOIN jobs j ON j.id = t.job_id
             WHERE a.task_id = ?1 AND a.outcome IN ('failed', 'expired', 'unreadable')
               AND a.started_ms >= j.requeued_ms
               AND NOT EXISTS (SELECT 1 FROM blocklist b WHERE b.job_id = t.job_id
                               AND b.worker = a.worker AND b.blocked_ms IS NOT NULL)",
            params![task],
            |r| r.get(0),
        )?)
    }

    /// Whether some worker seen within `alive_ms` of `now`, not draining, could still run
    /// `job`'s tasks: not blocklisted for it and with the tags it requires.
    pub(super) fn has_eligible_worker(
        tx: &Conn,
        job: i64,
        now: i64,
        alive_ms: i64,
    ) -> Result<bool> {
        let required: String = tx.query_row(
            "SELECT require_tags FROM jobs WHERE id = ?1",
            params![job],
            |r| r.get(0),
        )?;
        let required: Vec<String> = from_json(&required, &format!("require_tags of job {job}"))?;
        let tags: Vec<String> = tx.query_map(
            "SELECT w.tags FROM workers w
             WHERE w.last_seen_ms >= ?2 AND w.draining = 0
               AND NOT EXISTS (SELECT 1 FROM blocklist b WHERE b.job_id = ?1 AND b.worker = w.id
                               AND b.blocked_ms IS NOT NULL)",
            params![job, now - alive_ms],
            |r| r.get(0),
        )?;
        for t in tags {
            let offered: Vec<String> = from_json(&t, "tags of a worker")?;
            if required.iter().all(|r| offered.contains(r)) {
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// The workers blocklisted for a job.
    pub(super) fn blocklist_of(tx: &Conn, job: i64) -> Result<Vec<Blocklisted>> {
        tx.query_map(
            "SELECT worker, failures, blocked_ms, last_error FROM blocklist
             WHERE job_id = ?1 AND blocked_ms IS NOT NULL ORDER BY blocked_ms",
            params![job],
            |r| {
                Ok(Blocklisted {
                    worker: r.get(0)?,
                    failures: r.get(1)?,
                    since_ms: r.get(2)?,
                    last_error: r.get(3)?,
                })
            },
        )
    }

    /// Jobs a worker may not lease from now: paused, blocklisting it, or requiring a tag it
    /// lacks (of the jobs that have not ended).
    pub(super) fn excluded_jobs(tx: &Conn, worker: &str, tags: &[String]) -> Result<Vec<i64>> {
        let rows: Vec<(i64, String, String, bool)> = tx.query_map(
            "SELECT j.id, j.state, j.require_tags,
                EXISTS (SELECT 1 FROM blocklist b WHERE b.job_id = j.id AND b.worker = ?1
                        AND b.blocked_ms IS NOT NULL)
             FROM jobs j WHERE j.state IN ('queued', 'running', 'paused')
               AND (j.state = 'paused' OR j.require_tags != '[]'
                    OR EXISTS (SELECT 1 FROM blocklist b WHERE b.job_id = j.id AND b.worker = ?1))",
            params![worker],
            |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?)),
        )?;
        let mut out = Vec::new();
        for (id, state, required, blocked) in rows {
            let required: Vec<String> = from_json(&required, &format!("require_tags of job {id}"))?;
            if state == "paused" || blocked || !required.iter().all(|r| tags.contains(r)) {
                out.push(id);
            }
        }
        Ok(out)
    }

    /// Tags as stored.
    pub(super) fn tags_json(tags: &[String]) -> String {
        json(&tags)
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{store, worker};
    use crate::store::db::params;
    use crate::store::{Retry, RetryPolicy};

    fn policy() -> RetryPolicy {
        RetryPolicy {
            max_attempts: 3,
            blocklist_after: 3,
            alive_ms: 60_000,
        }
    }

    #[test]
    fn a_paused_job_leases_nothing_until_resumed() {
        let (_d, s, jobs) = store(&[5, 0], 1);
        assert!(s.pause(jobs[0]).expect("pause"));
        let g = s
            .lease(&worker("w"), 0, 1000)
            .expect("lease")
            .expect("task");
        assert_eq!(g.job_id, jobs[1], "the paused job is passed over");
        assert!(s.lease(&worker("w"), 0, 1000).expect("lease").is_none());
        assert!(s.resume(jobs[0]).expect("resume"));
        assert!(!s.resume(jobs[0]).expect("resume"), "not paused any more");
        assert_eq!(
            s.lease(&worker("w"), 0, 1000)
                .expect("lease")
                .map(|g| g.job_id),
            Some(jobs[0])
        );
    }

    #[test]
    fn a_priority_change_reorders_the_queue() {
        let (_d, s, jobs) = store(&[0, 0], 1);
        assert!(s.set_priority(jobs[1], 10).expect("priority"));
        let g = s
            .lease(&worker("w"), 0, 1000)
            .expect("lease")
            .expect("task");
        assert_eq!(g.job_id, jobs[1]);
        assert!(!s.set_priority(999, 1).expect("priority"), "no such job");
    }

    #[test]
    fn tags_and_draining_decide_who_leases() {
        let (_d, s, jobs) = store(&[0], 1);
        s.conn()
            .expect("conn")
            .execute(
                "UPDATE jobs SET require_tags = '[\"gpu\",\"big\"]' WHERE id = ?1",
                params![jobs[0]],
            )
            .expect("tags");
        let mut gpu = worker("g");
        gpu.tags = vec!["gpu".into()];
        assert!(
            s.lease(&gpu, 0, 1000).expect("lease").is_none(),
            "lacks big"
        );
        gpu.tags.push("big".into());
        s.set_draining("g", true).expect("drain");
        assert!(s.lease(&gpu, 0, 1000).expect("lease").is_none(), "draining");
        s.set_draining("g", false).expect("undrain");
        assert!(s.lease(&gpu, 0, 1000).expect("lease").is_some());
    }

    #[test]
    fn a_worker_failing_a_jobs_tasks_is_blocklisted_and_its_failures_forgiven() {
        // Two tasks; worker "bad" fails three times and is blocklisted; the failures do not
        // count against the tasks, which "good" then renders.
        let (_d, s, jobs) = store(&[0], 2);
        let held = s
            .lease(&worker("good"), 0, 100_000)
            .expect("lease")
            .expect("task");
        for i in 0..3 {
            let g = s
                .lease(&worker("bad"), 1, 100_000)
                .expect("lease")
                .expect("task");
            assert_ne!(g.task_id, held.task_id);
            let r = s
                .fail(g.task_id, g.lease, &format!("broken {i}"), 2, &policy())
                .expect("fail");
            assert_eq!(r, Retry::Requeued, "failure {i}");
        }
        assert!(
            s.lease(&worker("bad"), 3, 100_000)
                .expect("lease")
                .is_none(),
            "blocklisted"
        );
        let job = s.job(jobs[0]).expect("q").expect("job");
        assert_eq!(job.blocklist.len(), 1);
        assert_eq!(job.blocklist[0].worker, "bad");
        assert_eq!(job.blocklist[0].last_error.as_deref(), Some("broken 2"));
        let g = s
            .lease(&worker("good"), 4, 100_000)
            .expect("lease")
            .expect("the other task");
        assert_ne!(g.task_id, held.task_id);
        // Un-blocklisted, it may lease again (nothing is left to lease here).
        assert_eq!(s.unblock("bad", Some(jobs[0])).expect("unblock"), 1);
        assert!(
            s.job(jobs[0])
                .expect("q")
                .expect("job")
                .blocklist
                .is_empty()
        );
    }

    #[test]
    fn a_job_fails_when_every_worker_that_could_run_it_is_blocklisted() {
        let (_d, s, jobs) = store(&[0], 1);
        for i in 0..3 {
            let g = s
                .lease(&worker("only"), i, 100_000)
                .expect("lease")
                .expect("task");
            let r = s
                .fail(g.task_id, g.lease, "out of memory", i, &policy())
                .expect("fail");
            if i < 2 {
                assert_eq!(r, Retry::Requeued);
            } else {
                assert!(
                    matches!(&r, Retry::JobFailed(m) if m.contains("blocklisted") && m.contains("only") && m.contains("out of memory")),
                    "{r:?}"
                );
            }
        }
        assert_eq!(
            s.job_state(jobs[0]).expect("q"),
            Some(crate::protocol::JobState::Failed)
        );
        // Requeued, it runs again from a clean slate.
        assert_eq!(s.requeue(jobs[0], 10).expect("requeue"), Some(1));
        assert!(
            s.lease(&worker("only"), 11, 100_000)
                .expect("lease")
                .is_some()
        );
        assert_eq!(s.requeue(jobs[0], 12).expect("requeue"), None, "running");
    }
}
