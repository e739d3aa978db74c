//! A job's passes and frames in this process, through the same plan, tasks and fold as the
//! farm: the farm in one process (`tessera render`, the bench, the tests).
//!
//! Tasks run on `threads` threads of their own, as a farm's worker slots do; a task that
//! parallelises itself (one covering the whole film) takes the rayon pool, one such task at a
//! time. Results fold on the calling thread in the step's task order as they arrive, so the
//! frame is the farm's, bit for bit.

use std::collections::{BTreeMap, HashMap};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Instant;

use tessera_scene::SceneDesc;

use super::{
    Finished, LoadFn, Loaded, Next, Payload, Plan, Resources, Step, TaskCtx, TaskSpec, short,
};
use crate::scene::Scene;

/// What a run has done, for progress bars.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Progress {
    /// A pass (`pass`: Some(its name)) or a frame's step starts, with this much work (the
    /// sum of its tasks' [`TaskSpec::work`]).
    Start {
        pass: Option<&'static str>,
        work: u64,
    },
    /// This much more of it is done.
    Done(u64),
}

/// What [`Local::passes_within`] came to.
#[derive(Debug, Clone, PartialEq)]
pub enum Built {
    /// A line per pass saying what it built.
    Passes(Vec<String>),
    /// Not built: at least this many wall seconds, more than allowed.
    TooDear(f64),
}

/// Runs a planned job in this process.
pub struct Local<'a> {
    pub plan: &'a dyn Plan,
    pub scene: &'a Scene,
    pub desc: &'a SceneDesc,
    threads: usize,
    /// Artifacts built here, loaded, by key.
    artifacts: Mutex<HashMap<String, Loaded>>,
    progress: &'a (dyn Fn(Progress) + Sync),
}

type Memo = Arc<OnceLock<Result<Loaded, String>>>;

/// What one step's tasks read.
struct StepResources<'a> {
    local: &'a Local<'a>,
    input: Option<Loaded>,
    memos: Mutex<HashMap<String, Memo>>,
}

/// A task's view of its step's resources, counting the work it reports (up to its estimate).
struct TaskResources<'a> {
    step: &'a StepResources<'a>,
    work: u64,
    reported: std::sync::atomic::AtomicU64,
}

impl Resources for TaskResources<'_> {
    fn artifact(&self, key: &str, load: LoadFn) -> Result<Loaded, String> {
        self.step.artifact(key, load)
    }
    fn input(&self, load: LoadFn) -> Result<Loaded, String> {
        self.step.input(load)
    }
    fn memo(
        &self,
        name: &str,
        make: &dyn Fn() -> Result<Loaded, String>,
    ) -> Result<Loaded, String> {
        self.step.memo(name, make)
    }
    fn reuse(&self, key: &str) -> Option<Loaded> {
        self.step.reuse(key)
    }
    fn progress(&self, work: u64) {
        let before = self.reported.fetch_add(work, Ordering::Relaxed);
        let counted = (before + work)
            .min(self.work)
            .saturating_sub(before.min(self.work));
        if counted > 0 {
            (self.step.local.progress)(Progress::Done(counted));
        }
    }
}

impl TaskResources<'_> {
    /// Counts what the task did not report, once it is done.
    fn finish(&self) {
        let reported = self.reported.load(Ordering::Relaxed).min(self.work);
        if reported < self.work {
            (self.step.local.progress)(Progress::Done(self.work - reported));
        }
    }
}

impl Resources for StepResources<'_> {
    fn artifact(&self, key: &str, _load: LoadFn) -> Result<Loaded, String> {
        self.reuse(key)
            .ok_or_else(|| format!("artifact {} was not built", short(key)))
    }

    fn input(&self, _load: LoadFn) -> Result<Loaded, String> {
        self.input
            .clone()
            .ok_or_else(|| "the step has no input".to_string())
    }

    fn memo(
        &self,
        name: &str,
        make: &dyn Fn() -> Result<Loaded, String>,
    ) -> Result<Loaded, String> {
        let cell = self
            .memos
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .entry(name.to_string())
            .or_default()
            .clone();
        cell.get_or_init(make).clone()
    }

    fn reuse(&self, key: &str) -> Option<Loaded> {
        self.local
            .artifacts
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get(key)
            .cloned()
    }
}

impl<'a> Local<'a> {
    /// `threads` tasks at a time; `progress` hears of work started and done.
    pub fn new(
        plan: &'a dyn Plan,
        scene: &'a Scene,
        desc: &'a SceneDesc,
        threads: usize,
        progress: &'a (dyn Fn(Progress) + Sync),
    ) -> Self {
        Local {
            plan,
            scene,
            desc,
            threads: threads.max(1),
            artifacts: Mutex::new(HashMap::new()),
            progress,
        }
    }

    /// Takes artifacts built before (by `auto`'s pilot, for one): a pass whose key is among
    /// them is not built again, and a task's [`super::TaskCtx::reuse`] finds the others.
    pub fn with_artifacts(self, artifacts: impl IntoIterator<Item = (String, Loaded)>) -> Self {
        self.artifacts
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .extend(artifacts);
        self
    }

    /// The artifacts built or taken so far, by key.
    pub fn artifacts(&self) -> Vec<(String, Loaded)> {
        let map = self.artifacts.lock().unwrap_or_else(|e| e.into_inner());
        map.iter().map(|(k, v)| (k.clone(), v.clone())).collect()
    }

    /// Builds the job's passes in order; returns a line per pass saying what it built.
    pub fn passes(&self) -> Result<Vec<String>, String> {
        match self.passes_within(f64::INFINITY)? {
            Built::Passes(lines) => Ok(lines),
            Built::TooDear(s) => Err(format!("the passes would take {s:.2} s, more than any")),
        }
    }

    /// [`Self::passes`], unless they would take more than `left` wall seconds: the first pass
    /// not built yet runs its first wave of tasks (one per thread) and stops there when its
    /// remaining tasks at that wave's pace and its finish as it estimates it from that wave
    /// (balancing its trees, say: [`super::Pass::finish_estimate`]) would take the seconds
    /// spent past `left`. The passes after it are not counted: the prediction is a lower
    /// bound, and once a pass is under way the rest are built, so that no work is thrown
    /// away half done.
    pub fn passes_within(&self, left: f64) -> Result<Built, String> {
        let start = Instant::now();
        let mut probe = left.is_finite();
        let mut lines = Vec::new();
        for (i, pass) in self.plan.passes().into_iter().enumerate() {
            let have = self
                .artifacts
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .contains_key(pass.key());
            if have {
                lines.push(format!(
                    "{}: reused, built before with the same key ({})",
                    pass.name(),
                    short(pass.key())
                ));
                continue;
            }
            let tasks = pass.tasks(i as u32);
            let mut state = pass.start();
            let work: u64 = tasks.iter().map(TaskSpec::work).sum();
            (self.progress)(Progress::Start {
                pass: Some(pass.name()),
                work,
            });
            // Tasks that parallelise themselves run one at a time: their wave is one task.
            let wave = match tasks.first() {
                Some(t) if self.whole_film(t) => 1,
                _ => self.threads.min(tasks.len()),
            };
            let (first, rest) = tasks.split_at(if probe { wave } else { 0 });
            probe = false;
            if !first.is_empty() {
                let waving = Instant::now();
                self.run(first, None, |task, p| pass.fold(state.as_mut(), task, p))?;
                let pace = waving.elapsed().as_secs_f64();
                let tasks_s =
                    start.elapsed().as_secs_f64() + pace * rest.len().div_ceil(wave.max(1)) as f64;
                if tasks_s > left {
                    return Ok(Built::TooDear(tasks_s));
                }
                // Only where the tasks alone fit is the finish worth estimating.
                let done: u64 = first.iter().map(TaskSpec::work).sum();
                let share = done as f64 / (work as f64).max(1.0);
                let finish = pass.finish_estimate(state.as_ref(), share).unwrap_or(0.0);
                if tasks_s + finish > left {
                    return Ok(Built::TooDear(tasks_s + finish));
                }
            }
            self.run(rest, None, |task, p| pass.fold(state.as_mut(), task, p))?;
            let (artifact, line) = pass.finish(state)?;
            let loaded = pass.load(artifact)?;
            self.artifacts
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .insert(pass.key().to_string(), loaded);
            lines.push(line);
        }
        Ok(Built::Passes(lines))
    }

    /// Renders frame `frame` (after [`Self::passes`]) to the end of its steps.
    pub fn frame(&self, frame: u32) -> Result<Finished, String> {
        let mut state = self.plan.new_frame(frame);
        let step = self.plan.start(frame)?;
        self.steps(frame, state.as_mut(), step, Instant::now())
    }

    /// Takes a frame rendered by [`Self::frame`] or by this on to `spp` samples per pixel
    /// (iterations), where its method can continue a frame; `None` where it cannot.
    pub fn more(
        &self,
        frame: u32,
        state: &mut dyn Payload,
        spp: u32,
    ) -> Option<Result<Finished, String>> {
        let step = self.plan.more(frame, state, spp)?;
        Some(self.steps(frame, state, step, Instant::now()))
    }

    /// A frame's state as [`Self::frame`] leaves it, with the finished frame (for the bench,
    /// which continues it).
    pub fn frame_with_state(&self, frame: u32) -> Result<(Box<dyn Payload>, Finished), String> {
        let mut state = self.plan.new_frame(frame);
        let step = self.plan.start(frame)?;
        let done = self.steps(frame, state.as_mut(), step, Instant::now())?;
        Ok((state, done))
    }

    fn steps(
        &self,
        frame: u32,
        state: &mut dyn Payload,
        mut step: Step,
        start: Instant,
    ) -> Result<Finished, String> {
        loop {
            let input: Option<Loaded> = step.input.map(|p| Arc::from(p.into_any()) as Loaded);
            (self.progress)(Progress::Start {
                pass: None,
                work: step.tasks.iter().map(TaskSpec::work).sum(),
            });
            self.run(&step.tasks, input, |task, p| self.plan.fold(state, task, p))?;
            match self.plan.advance(frame, state, start.elapsed())? {
                Next::Step(next) => step = next,
                Next::Done(done) => return Ok(done),
            }
        }
    }

    /// Whether a task parallelises itself: it covers the whole film.
    fn whole_film(&self, task: &TaskSpec) -> bool {
        let film = self.desc.film.width as u64 * self.desc.film.height as u64;
        task.pixels() >= film && film > 1
    }

    /// Runs `tasks` on this process's threads and calls `fold` with each result in their
    /// order, as results arrive.
    fn run(
        &self,
        tasks: &[TaskSpec],
        input: Option<Loaded>,
        mut fold: impl FnMut(&TaskSpec, Box<dyn Payload>) -> Result<(), String>,
    ) -> Result<(), String> {
        let resources = StepResources {
            local: self,
            input,
            memos: Mutex::new(HashMap::new()),
        };
        let next = AtomicUsize::new(0);
        let stop = AtomicBool::new(false);
        let alone = Mutex::new(());
        let (tx, rx) = std::sync::mpsc::sync_channel(self.threads * 2);
        std::thread::scope(|s| {
            for _ in 0..self.threads.min(tasks.len()) {
                let tx = tx.clone();
                let (resources, next, stop, alone) = (&resources, &next, &stop, &alone);
                s.spawn(move || {
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        if i >= tasks.len() || stop.load(Ordering::Relaxed) {
                            return;
                        }
                        let guard = self
                            .whole_film(&tasks[i])
                            .then(|| alone.lock().unwrap_or_else(|e| e.into_inner()));
                        let counted = TaskResources {
                            step: resources,
                            work: tasks[i].work(),
                            reported: Default::default(),
                        };
                        let ctx = TaskCtx {
                            scene: self.scene,
                            desc: self.desc,
                            resources: &counted,
                        };
                        let result = self.plan.execute(&ctx, &tasks[i]);
                        drop(guard);
                        counted.finish();
                        if tx.send((i, result)).is_err() {
                            return;
                        }
                    }
                });
            }
            drop(tx);
            let mut pending = BTreeMap::new();
            let mut want = 0;
            for (i, result) in rx {
                pending.insert(i, result);
                while let Some(result) = pending.remove(&want) {
                    let task = &tasks[want];
                    let outcome = result.and_then(|p| fold(task, p));
                    if let Err(e) = outcome {
                        stop.store(true, Ordering::Relaxed);
                        return Err(format!(
                            "task {} {} of frame {}: {e}",
                            task.kind, task.index, task.frame
                        ));
                    }
                    want += 1;
                }
            }
            if want < tasks.len() {
                return Err(format!("{} of {} tasks ran", want, tasks.len()));
            }
            Ok(())
        })
    }
}
