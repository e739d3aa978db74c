//! Folding results as they arrive, in each step's task order: a frame's into its state (then
//! the next step, or the frame's EXR), a pass's into its artifact (then the next pass, or
//! every frame's first step), a pilot's into its job's plan ([`App::fold_pilot`]).
//!
//! One fold runs at a time, so the coordinator holds one task's decoded result at a time. A
//! fold's state is kept in memory for the few frames in flight; any state can be rebuilt from
//! the frame's checkpoint (written between steps) and the step's results on disk, which stay
//! until the frame is written — so a restart, or an eviction, loses nothing. Results that
//! arrive out of order wait on disk until those before them are folded: the frame is the same
//! bits whatever the order of arrival.

use std::any::Any;
use std::collections::HashMap;
use std::io::{BufReader, BufWriter, Seek, Write};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use anyhow::Context;
use tessera_render::method::{DynPass, Next, Payload};
use tessera_render::wire::{self, Header};

use super::{App, JobPlan, now_ms};
use crate::job;
use crate::protocol::Event;
use crate::store::{Artifact, CacheEntry, Claim, StepKey};

use crate::job::FRAMES_IN_MEMORY;
/// Tasks looked at per query while folding.
const BATCH: usize = 64;

struct FrameFold {
    step: u32,
    /// Tasks of the step folded so far.
    next: usize,
    state: Box<dyn Payload>,
}

struct PassFold {
    next: usize,
    state: Box<dyn Any + Send + Sync>,
}

#[derive(Default)]
struct Inner {
    /// Least recently used first.
    frames: Vec<((i64, u32), FrameFold)>,
    passes: HashMap<(i64, u32), PassFold>,
}

#[derive(Default)]
pub(super) struct Folds {
    inner: Mutex<Inner>,
    /// Steps asked to be folded and not yet taken up by the fold thread: asking again adds
    /// nothing (the reaper asks for every claimed step each tick).
    queued: Mutex<std::collections::HashSet<StepKey>>,
}

impl Folds {
    fn lock(&self) -> MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Drops what is held of a frame (`key.frame` ≥ 1) or a pass.
    fn forget(&self, key: StepKey) {
        let mut inner = self.lock();
        if key.frame == 0 {
            inner.passes.remove(&(key.job, key.step));
        } else {
            inner.frames.retain(|(k, _)| *k != (key.job, key.frame));
        }
    }

    /// Whether `key` was not already waiting to be folded (it is now).
    fn enqueue(&self, key: StepKey) -> bool {
        self.queued
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(key)
    }

    fn dequeued(&self, key: StepKey) {
        self.queued
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(&key);
    }

    pub fn forget_job(&self, job: i64) {
        let mut inner = self.lock();
        inner.frames.retain(|((j, _), _)| *j != job);
        inner.passes.retain(|(j, _), _| *j != job);
    }
}

/// What a result file holds, read and checked against its task.
fn read_result(
    app: &App,
    job: &JobPlan,
    key: StepKey,
    id: i64,
    lease: i64,
    pass: Option<&dyn DynPass>,
) -> anyhow::Result<Box<dyn Payload>> {
    let name = app.result_key(key.job, id, lease);
    let local = app
        .objects
        .read(&name)?
        .with_context(|| format!("{name} is not in the object store"))?;
    let file = std::fs::File::open(local.path()).with_context(|| name.clone())?;
    let (mut reader, _header) =
        wire::Reader::new(BufReader::new(file)).with_context(|| name.clone())?;
    let partial = match pass {
        Some(p) => p.decode(&mut reader),
        None => job.plan.decode(&mut reader),
    }
    .with_context(|| format!("{name}: the result of task {id}"))?;
    reader
        .finish()
        .with_context(|| format!("{name}: the result of task {id}"))?;
    Ok(partial)
}

/// The claim under which one coordinator folds a frame (`key.frame` ≥ 1, whatever its step)
/// or a pass.
pub(super) fn claim_name(key: StepKey) -> String {
    if key.frame == 0 {
        format!("pass {} {}", key.job, key.step)
    } else {
        format!("frame {} {}", key.job, key.frame)
    }
}

/// The step a claim of [`claim_name`] is for (a frame's at step 0: the fold reads its step).
pub(super) fn claimed_step(name: &str) -> Option<StepKey> {
    let mut words = name.split(' ');
    let (kind, job, n) = (words.next()?, words.next()?, words.next()?);
    let (job, n) = (job.parse().ok()?, n.parse().ok()?);
    match kind {
        "pass" => Some(StepKey {
            job,
            frame: 0,
            step: n,
        }),
        "frame" => Some(StepKey {
            job,
            frame: n,
            step: 0,
        }),
        _ => None,
    }
}

/// A frame another coordinator folds (and so holds the preview of).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub(super) struct FoldedElsewhere(String);

/// What the fold thread is asked.
pub(super) enum FoldRequest {
    /// Fold what can be folded of a step.
    Step(StepKey),
    /// The frame as it stands.
    Preview(
        i64,
        u32,
        tokio::sync::oneshot::Sender<anyhow::Result<tessera_render::Image>>,
    ),
}

/// Starts the fold thread: every fold and preview runs on it, one at a time, so the large
/// allocations of frames (states, images, EXR writing) come from one thread's heap.
pub(super) fn start_thread(
    app: &Arc<App>,
    requests: std::sync::mpsc::Receiver<FoldRequest>,
) -> anyhow::Result<()> {
    let app = app.clone();
    std::thread::Builder::new()
        .name("tessera-fold".into())
        .spawn(move || {
            for request in requests {
                match request {
                    FoldRequest::Step(key) => {
                        // Taken up: results arriving from now on ask again.
                        app.folds.dequeued(key);
                        app.fold_or_fail(key)
                    }
                    FoldRequest::Preview(job, frame, reply) => {
                        let _ = reply.send(app.preview(job, frame));
                    }
                }
            }
        })?;
    Ok(())
}

impl App {
    /// Asks the fold thread to fold in the results of `key`'s step that are done and next in
    /// order; a failure fails the job with its reason.
    pub(super) fn spawn_fold(&self, key: StepKey) {
        if !self.folds.enqueue(key) {
            return;
        }
        let sent = self
            .fold_requests
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .send(FoldRequest::Step(key));
        if sent.is_err() {
            tracing::error!(job = key.job, "the fold thread is gone");
        }
    }

    /// A frame as it stands, from the fold thread.
    pub(super) async fn preview_of(
        &self,
        job: i64,
        frame: u32,
    ) -> anyhow::Result<tessera_render::Image> {
        let (tx, rx) = tokio::sync::oneshot::channel();
        self.fold_requests
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .send(FoldRequest::Preview(job, frame, tx))
            .map_err(|_| anyhow::anyhow!("the fold thread is gone"))?;
        rx.await?
    }

    fn fold_or_fail(&self, key: StepKey) {
        if let Err(e) = self.fold(key) {
            // A coordinator that lost its claim (it lapsed while this one stalled) leaves the
            // frame to the one that took it over: its own view may be stale.
            let name = claim_name(key);
            if !self.store.holds(&name, &self.id, now_ms()).unwrap_or(false) {
                tracing::warn!(job = key.job, claim = %name, error = %format!("{e:#}"), "fold given up: its claim lapsed");
                self.folds.forget(key);
                return;
            }
            let place = if job::is_pilot_step(key.frame, key.step) {
                "auto's pilot".to_string()
            } else if key.frame == 0 {
                format!("pass {}", key.step)
            } else {
                format!("frame {}", key.frame)
            };
            let message = format!("folding {place}: {e:#}");
            tracing::error!(job = key.job, error = %message, "fold failed");
            let _ = self.store.fail_job(key.job, &message, now_ms());
            self.forget_job(key.job);
        }
    }

    /// Claims the fold of `key` for this coordinator: `Some(owner)` when another holds it. A
    /// claim newly taken (over a lapsed one, maybe this coordinator's own) drops what this
    /// coordinator held of the fold, since another may have folded more since.
    fn claim_fold(&self, key: StepKey) -> anyhow::Result<Option<String>> {
        match self
            .store
            .claim(&claim_name(key), &self.id, now_ms(), self.claim_ms())?
        {
            Claim::Refused(owner) => return Ok(Some(owner)),
            Claim::Taken => self.folds.forget(key),
            Claim::Held => {}
        }
        Ok(None)
    }

    /// Folds what can be folded of `key`'s frame or pass (blocking).
    pub(super) fn fold(&self, key: StepKey) -> anyhow::Result<()> {
        let name = claim_name(key);
        if self.store.job_state(key.job)?.is_none_or(|s| s.is_final()) {
            self.store.release(&name, &self.id)?;
            return Ok(());
        }
        // One coordinator folds a frame or a pass; another's results wait for it.
        if self.claim_fold(key)?.is_some() {
            return Ok(());
        }
        if job::is_pilot_step(key.frame, key.step) {
            self.fold_pilot(key)?;
            return Ok(self.store.release(&name, &self.id)?);
        }
        let job = self.job_plan(key.job)?;
        let mut inner = self.folds.lock();
        if key.frame == 0 {
            self.fold_pass(&mut inner, &job, key)
        } else {
            self.fold_frame(&mut inner, &job, key.job, key.frame)
                .map(|_| ())
        }
    }

    /// The frame as it stands, folded as far as its results allow (blocking).
    fn preview(&self, job_id: i64, frame: u32) -> anyhow::Result<tessera_render::Image> {
        let job = self.job_plan(job_id)?;
        let key = StepKey {
            job: job_id,
            frame,
            step: 0,
        };
        // Another coordinator folds this frame: it has the preview.
        if let Some(owner) = self.claim_fold(key)? {
            return Err(FoldedElsewhere(format!(
                "frame {frame} of job {job_id} is being folded by coordinator {owner}: its preview is there"
            ))
            .into());
        }
        let mut inner = self.folds.lock();
        self.fold_frame(&mut inner, &job, job_id, frame)?;
        Ok(
            match inner.frames.iter().find(|(k, _)| *k == (job_id, frame)) {
                Some((_, f)) => job.plan.preview(frame, f.state.as_ref()),
                None => tessera_render::Image::new(job.desc.film.width, job.desc.film.height),
            },
        )
    }

    /// The fold of a frame, moved to the back of the LRU list: kept, or rebuilt from its
    /// checkpoint (or from nothing at step 0).
    fn frame_fold<'a>(
        &self,
        inner: &'a mut Inner,
        job: &JobPlan,
        job_id: i64,
        frame: u32,
    ) -> anyhow::Result<&'a mut FrameFold> {
        let at = inner.frames.iter().position(|(k, _)| *k == (job_id, frame));
        let entry = match at {
            Some(i) => inner.frames.remove(i),
            None => {
                let name = self.checkpoint_key(job_id, frame);
                let fold = match self.objects.read(&name)? {
                    Some(local) => {
                        let file =
                            std::fs::File::open(local.path()).with_context(|| name.clone())?;
                        let (mut r, _) = wire::Reader::new(BufReader::new(file))
                            .with_context(|| name.clone())?;
                        let step: u32 = wire::decode_from(&mut r).with_context(|| name.clone())?;
                        let state = job
                            .plan
                            .decode_frame(&mut r)
                            .with_context(|| name.clone())?;
                        r.finish().with_context(|| name.clone())?;
                        FrameFold {
                            step,
                            next: 0,
                            state,
                        }
                    }
                    None => FrameFold {
                        step: 0,
                        next: 0,
                        state: job.plan.new_frame(frame),
                    },
                };
                if inner.frames.len() >= FRAMES_IN_MEMORY as usize {
                    // Rebuilt from its checkpoint when next folded, here or elsewhere.
                    let ((j, f), _) = inner.frames.remove(0);
                    let evicted = StepKey {
                        job: j,
                        frame: f,
                        step: 0,
                    };
                    self.store.release(&claim_name(evicted), &self.id)?;
                }
                ((job_id, frame), fold)
            }
        };
        inner.frames.push(entry);
        Ok(&mut inner.frames.last_mut().expect("just pushed").1)
    }

    /// Folds a frame's done results in order, and moves it on when a step is complete.
    /// Returns whether the frame was written.
    fn fold_frame(
        &self,
        inner: &mut Inner,
        job: &JobPlan,
        job_id: i64,
        frame: u32,
    ) -> anyhow::Result<bool> {
        if self.store.frame_state(job_id, frame)?.as_deref() != Some("running") {
            return Ok(false);
        }
        loop {
            let f = self.frame_fold(inner, job, job_id, frame)?;
            let key = StepKey {
                job: job_id,
                frame,
                step: f.step,
            };
            let total = loop {
                let (batch, total) = self.store.step_tasks(key, f.next, BATCH)?;
                let mut folded = 0;
                for (id, state, lease, spec) in &batch {
                    let Some(lease) = lease.filter(|_| state == "done") else {
                        break;
                    };
                    let partial = match read_result(self, job, key, *id, lease, None) {
                        Ok(p) => p,
                        Err(e) => return self.unreadable(*id, e),
                    };
                    job.plan
                        .fold(f.state.as_mut(), spec, partial)
                        .map_err(|e| {
                            anyhow::anyhow!("task {id} ({} {}): {e}", spec.kind, spec.index)
                        })?;
                    f.next += 1;
                    folded += 1;
                }
                if folded < BATCH {
                    break total;
                }
            };
            if total == 0 || f.next < total {
                return Ok(false);
            }
            match job
                .plan
                .advance(frame, f.state.as_mut(), Duration::ZERO)
                .map_err(anyhow::Error::msg)?
            {
                Next::Step(step) => {
                    let Some(number) = step.tasks.first().map(|t| t.step) else {
                        anyhow::bail!(
                            "step {} of frame {frame} led to a step without tasks",
                            f.step
                        );
                    };
                    if let Some(input) = &step.input {
                        let header = Header::new("input", &job.plan.schema());
                        self.objects
                            .write(&self.input_key(job_id, frame, number), |file| {
                                input.write_to(&header, &mut BufWriter::new(file))?;
                                Ok(())
                            })?;
                    }
                    self.store.add_step(job_id, frame, &step.tasks)?;
                    let header = Header::new("checkpoint", &job.plan.schema());
                    self.objects
                        .write(&self.checkpoint_key(job_id, frame), |file| {
                            let mut w = wire::Writer::new(BufWriter::new(file), &header)?;
                            wire::encode_into(&number, &mut w)?;
                            f.state.encode(&mut w)?;
                            w.finish()?;
                            Ok(())
                        })?;
                    for (id, lease) in self.store.step_results(key)? {
                        self.discard(&self.result_key(job_id, id, lease));
                    }
                    self.discard(&self.input_key(job_id, frame, f.step));
                    tracing::debug!(
                        job = job_id,
                        frame,
                        step = number,
                        tasks = step.tasks.len(),
                        "step queued"
                    );
                    f.step = number;
                    f.next = 0;
                    self.wake_workers();
                }
                Next::Done(done) => {
                    let name = self.frame_key(job_id, frame);
                    let tmp = self.objects.spool_file(&name);
                    job::write_frame(&tmp, &job.desc, job.plan.as_ref(), frame, &done)?;
                    let mut files = Vec::new();
                    // The preview first: a frame whose EXR is there has its PNG.
                    let png = (tmp.with_extension("png"), self.preview_key(job_id, frame));
                    for (kind, (file, path)) in [("png", png), ("exr", (tmp, name.clone()))] {
                        let (sha256, bytes) = crate::bundle::hash_file(&file)?;
                        self.objects.put_file(&path, &file)?;
                        files.insert(
                            0,
                            Artifact {
                                kind: kind.into(),
                                path,
                                bytes,
                                sha256,
                            },
                        );
                    }
                    self.metrics.count_frame();
                    let job_done = self.store.frame_stitched(
                        job_id,
                        frame,
                        &files,
                        done.estimated_rel_mse,
                        now_ms(),
                    )?;
                    inner.frames.retain(|(k, _)| *k != (job_id, frame));
                    self.remove_frame_files(job_id, frame)?;
                    self.store.release(
                        &claim_name(StepKey {
                            job: job_id,
                            frame,
                            step: 0,
                        }),
                        &self.id,
                    )?;
                    tracing::info!(job = job_id, frame, key = %name, job_done, "frame written");
                    self.emit(Event::Job { id: job_id });
                    if job_done {
                        inner.frames.retain(|((j, _), _)| *j != job_id);
                        inner.passes.retain(|(j, _), _| *j != job_id);
                        self.jobs
                            .lock()
                            .unwrap_or_else(|e| e.into_inner())
                            .remove(&job_id);
                        self.enforce_cache_cap();
                        self.store.checkpoint()?;
                    }
                    return Ok(true);
                }
            }
        }
    }

    /// A result that passed its checks on arrival but cannot be folded: the task runs again
    /// (its attempt counts).
    pub(super) fn unreadable(&self, task: i64, e: anyhow::Error) -> anyhow::Result<bool> {
        let message = format!("the result could not be read back: {e:#}");
        tracing::warn!(task, error = %message, "task queued again");
        self.store
            .redo(task, &message, now_ms(), &self.config.retry_policy())?;
        self.wake_workers();
        Ok(false)
    }

    /// Folds a pass's done results in order; when all are in, writes its artifact and queues
    /// what follows.
    fn fold_pass(&self, inner: &mut Inner, job: &JobPlan, key: StepKey) -> anyhow::Result<()> {
        // A request that arrives after the pass was built (its results deleted) has nothing
        // to fold.
        if self.store.pass_state(key.job, key.step)?.as_deref() != Some("running") {
            return Ok(());
        }
        let passes = job.plan.passes();
        let pass = *passes
            .get(key.step as usize)
            .with_context(|| format!("job {} has no pass {}", key.job, key.step))?;
        let fold = inner
            .passes
            .entry((key.job, key.step))
            .or_insert_with(|| PassFold {
                next: 0,
                state: pass.start(),
            });
        let total = loop {
            let (batch, total) = self.store.step_tasks(key, fold.next, BATCH)?;
            let mut folded = 0;
            for (id, state, lease, spec) in &batch {
                let Some(lease) = lease.filter(|_| state == "done") else {
                    break;
                };
                let partial = match read_result(self, job, key, *id, lease, Some(pass)) {
                    Ok(p) => p,
                    Err(e) => return self.unreadable(*id, e).map(|_| ()),
                };
                pass.fold(fold.state.as_mut(), spec, partial).map_err(|e| {
                    anyhow::anyhow!("task {id} ({} {}): {e}", spec.kind, spec.index)
                })?;
                fold.next += 1;
                check_pass_memory(pass, fold, *id, self.config.limits.max_memory)?;
                folded += 1;
            }
            if folded < BATCH {
                break total;
            }
        };
        if fold.next < total {
            return Ok(());
        }
        let fold = inner
            .passes
            .remove(&(key.job, key.step))
            .context("the pass's fold vanished")?;
        let (artifact, summary) = pass.finish(fold.state).map_err(anyhow::Error::msg)?;
        let name = self.artifact_key(pass.key());
        // Jobs that build the same key at once (reuse disabled) each write their own spool
        // file; the second store replaces one identical artifact with another.
        let header = Header::new("artifact", &pass.schema());
        let (sha256, bytes) = self.objects.write(&name, |file| {
            let mut w = BufWriter::new(&mut *file);
            artifact.write_to(&header, &mut w)?;
            w.flush()?;
            drop(w);
            file.rewind()?;
            Ok(crate::bundle::hash_reader(&mut *file)?)
        })?;
        let entry = CacheEntry {
            key: pass.key().to_string(),
            name: pass.name().to_string(),
            path: name,
            bytes,
            sha256,
            job: key.job,
        };
        let frames = self.first_steps(key.job, job)?;
        let frames_queued =
            self.store
                .pass_built(key.job, key.step, &entry, &summary, &frames, now_ms())?;
        for (id, lease) in self.store.step_results(key)? {
            self.discard(&self.result_key(key.job, id, lease));
        }
        self.store.release(&claim_name(key), &self.id)?;
        tracing::info!(job = key.job, pass = pass.name(), key = %pass.key(), bytes = entry.bytes, frames_queued, "{summary}");
        self.enforce_cache_cap();
        self.wake_workers();
        Ok(())
    }

    /// Every frame's first step, its input written: what a job queues when its passes are
    /// done.
    pub(super) fn first_steps(
        &self,
        job_id: i64,
        job: &JobPlan,
    ) -> anyhow::Result<Vec<Vec<job::TaskSpec>>> {
        let mut out = Vec::new();
        for frame in job.frames.iter() {
            let step = job.plan.start(frame).map_err(anyhow::Error::msg)?;
            if let Some(input) = &step.input {
                let header = Header::new("input", &job.plan.schema());
                self.objects
                    .write(&self.input_key(job_id, frame, 0), |file| {
                        input.write_to(&header, &mut BufWriter::new(file))?;
                        Ok(())
                    })?;
            }
            out.push(step.tasks);
        }
        Ok(out)
    }
}

/// A pass's state against the job's memory budget, after task `id` folded into it: how much a
/// pass stores is known only as its results come in, so a job whose pass outgrows the budget
/// fails then, with the figures, before the process folding it runs out of memory.
fn check_pass_memory(
    pass: &dyn DynPass,
    fold: &PassFold,
    id: i64,
    budget: u64,
) -> anyhow::Result<()> {
    let held = pass.state_bytes(fold.state.as_ref());
    if held > budget {
        let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
        anyhow::bail!(
            "the {} pass holds {:.2} GiB after task {id} ({} of its tasks folded), past this farm's {:.2} GiB a job (--max-job-memory-gib)",
            pass.name(),
            gib(held),
            fold.next,
            gib(budget)
        );
    }
    Ok(())
}
