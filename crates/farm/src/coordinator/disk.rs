//! Disk is reclaimed (docs/src/design/overview.md: "task results go once their frame is written; jobs can be
//! deleted and expire; the artifact cache has a size cap").

use super::{App, now_ms};

impl App {
    /// Removes what a written frame no longer needs: its tasks' results, its checkpoint and
    /// its steps' inputs.
    pub(super) fn remove_frame_files(&self, job: i64, frame: u32) -> anyhow::Result<()> {
        for (task, lease) in self.store.results_of(job, frame)? {
            self.discard(&self.result_key(job, task, lease));
        }
        self.discard(&self.checkpoint_key(job, frame));
        let inputs = format!("{}/steps/{frame}-", self.job_prefix(job));
        for key in self
            .objects
            .list(&format!("{}/steps", self.job_prefix(job)))?
        {
            if key.starts_with(&inputs) {
                self.discard(&key);
            }
        }
        Ok(())
    }

    /// Deletes an object no longer needed; one that cannot be deleted is left (and logged):
    /// the job it belongs to goes on, and its deletion deletes it.
    pub(super) fn discard(&self, key: &str) {
        if let Err(e) = self.objects.delete(key) {
            tracing::warn!(key, error = %format!("{e:#}"), "an object could not be deleted");
        }
    }

    /// Deletes a job that has ended, with its objects (and its bundle, if no other job uses
    /// it). `None` if the job has not ended or does not exist.
    pub(super) fn delete_job(&self, job: i64) -> anyhow::Result<Option<()>> {
        let Some(orphan) = self.store.delete_job(job)? else {
            return Ok(None);
        };
        self.forget_job(job);
        self.objects.delete_all(&self.job_prefix(job))?;
        if let Some(bundle) = orphan {
            self.objects.delete(&self.bundle_key(&bundle))?;
        }
        self.store.checkpoint()?;
        tracing::info!(job, "job deleted");
        Ok(Some(()))
    }

    /// Deletes the jobs that ended longer ago than `--retain-days`.
    pub(super) fn sweep_expired_jobs(&self) {
        let Some(retain) = self.config.retain else {
            return;
        };
        self.alone("retention", || self.delete_ended_before(retain));
    }

    /// Runs `f` unless another coordinator sharing the store is running work of this `name`
    /// (under a claim, released after).
    fn alone(&self, name: &str, f: impl FnOnce()) {
        match self.store.claim(name, &self.id, now_ms(), self.claim_ms()) {
            Ok(crate::store::Claim::Refused(owner)) => {
                tracing::debug!(claim = name, %owner, "left to another coordinator");
            }
            Ok(_) => {
                f();
                if let Err(e) = self.store.release(name, &self.id) {
                    tracing::warn!(claim = name, error = %e, "releasing a claim");
                }
            }
            Err(e) => tracing::warn!(claim = name, error = %e, "claiming"),
        }
    }

    fn delete_ended_before(&self, retain: std::time::Duration) {
        let before = now_ms() - retain.as_millis() as i64;
        match self.store.ended_before(before) {
            Ok(jobs) => {
                for job in jobs {
                    if let Err(e) = self.delete_job(job) {
                        tracing::warn!(job, error = %e, "deleting an expired job");
                    }
                }
            }
            Err(e) => tracing::warn!(error = %e, "listing expired jobs"),
        }
    }

    /// Evicts the least recently used artifacts until the cache is within `--cache-max-gib`,
    /// keeping those a job that has not ended reads.
    pub(super) fn enforce_cache_cap(&self) {
        self.alone("cache eviction", || self.evict_over_cap());
    }

    fn evict_over_cap(&self) {
        let entries = match self.store.cache_entries() {
            Ok(e) => e,
            Err(e) => {
                tracing::warn!(error = %e, "listing the artifact cache");
                return;
            }
        };
        let mut total: u64 = entries.iter().map(|(e, _)| e.bytes).sum();
        for (entry, in_use) in entries {
            if total <= self.config.cache_max {
                break;
            }
            if in_use {
                continue;
            }
            if let Err(e) = self.store.uncache(&entry.key) {
                tracing::warn!(key = %entry.key, error = %e, "evicting an artifact");
                continue;
            }
            self.discard(&entry.path);
            total = total.saturating_sub(entry.bytes);
            tracing::info!(key = %entry.key, pass = %entry.name, bytes = entry.bytes, "artifact evicted (the cache is over its cap)");
        }
    }
}
