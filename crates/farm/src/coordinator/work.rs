//! What a compiled job runs, as the coordinator queues it: its passes (each reused from the
//! cache where an artifact of its key is there) and every frame's first step; or, for a job
//! that awaits `auto`'s choice, its pilot alone ([`job::pilot_task`]), and when the pilot is
//! done the rest, planned with the choice it returned.

use std::io::BufReader;

use anyhow::Context;

use super::{App, now_ms};
use crate::job::{self, Compiled, RenderSettings};
use crate::store::{CacheEntry, NewPass, PassStart, StepKey, Work};

impl App {
    /// What `compiled` runs, for a job submitted with `settings`: its pilot where it awaits
    /// `auto`'s choice, else its passes and frames ([`Self::planned_work`]).
    pub(super) fn work(
        &self,
        compiled: &Compiled,
        settings: &RenderSettings,
    ) -> anyhow::Result<Work> {
        if !compiled.awaits_choice() {
            return self.planned_work(compiled, settings);
        }
        let desc = &compiled.job.desc;
        Ok(Work {
            settings: settings.clone(),
            spp: desc.integrator.spp,
            method: desc.integrator.method.clone(),
            decisions: vec![format!(
                "integrator: {} — its pilot renders run as a task on a worker; the job's passes and frames are planned with the method they choose",
                desc.integrator.method
            )],
            tasks: vec![vec![job::pilot_task()]],
            passes: Vec::new(),
            planned_tasks: 1,
        })
    }

    /// The passes and frames' first steps of `compiled`, a job that carries its method (or
    /// `auto`'s choice), with the decisions made about it: which passes are reused.
    fn planned_work(&self, compiled: &Compiled, settings: &RenderSettings) -> anyhow::Result<Work> {
        let (desc, plan) = (&compiled.job.desc, compiled.plan.as_ref());
        let mut decisions = job::decisions(desc, plan);
        decisions.extend(compiled.unread.iter().map(|u| format!("warning: {u}")));
        let reuse = settings.reuse.unwrap_or(true);
        let mut passes = Vec::new();
        let mut planned_tasks = 0u64;
        for (i, pass) in plan.passes().into_iter().enumerate() {
            let cached: Option<CacheEntry> = if reuse {
                self.cached(pass.key())?
            } else {
                None
            };
            let tasks = pass.tasks(i as u32);
            decisions.push(match &cached {
                Some(e) => format!(
                    "{} pass: reused — artifact {} ({} bytes) built by job {} has the same key (everything that determines it)",
                    pass.name(), &e.key[..12.min(e.key.len())], e.bytes, e.job
                ),
                None => format!(
                    "{} pass: built by this job in {} tasks{}",
                    pass.name(),
                    tasks.len(),
                    if reuse { " (no cached artifact with its key)" } else { " (reuse disabled)" }
                ),
            });
            if let Some(e) = &cached {
                self.store.touch(&e.key, now_ms())?;
            }
            planned_tasks += if cached.is_some() {
                0
            } else {
                tasks.len() as u64
            };
            passes.push(NewPass {
                name: pass.name().to_string(),
                key: pass.key().to_string(),
                start: match cached {
                    Some(_) => PassStart::Reused,
                    None if i == 0 => PassStart::Build(tasks),
                    None => PassStart::Waiting(tasks),
                },
            });
        }
        let frames = compiled.frames;
        let steps: Vec<_> = frames
            .iter()
            .map(|f| plan.start(f))
            .collect::<Result<_, _>>()
            .map_err(anyhow::Error::msg)?;
        anyhow::ensure!(
            steps.iter().all(|s| s.input.is_none()),
            "a method whose first step has an input: not supported by this coordinator"
        );
        let tasks: Vec<Vec<job::TaskSpec>> = steps.into_iter().map(|s| s.tasks).collect();
        planned_tasks += tasks.iter().map(|t| t.len() as u64).sum::<u64>()
            + frames.len() as u64 * plan.later_tasks();
        let settings = compiled.settings(settings);
        Ok(Work {
            spp: settings
                .choice
                .as_ref()
                .map_or(desc.integrator.spp, |c| c.spp),
            settings,
            method: plan.method().to_string(),
            decisions,
            tasks,
            passes,
            planned_tasks,
        })
    }

    /// Folds a job's pilot (`key`): reads the choice its result holds, compiles the job with
    /// it and queues what the job then runs. A request for a job already planned does
    /// nothing.
    pub(super) fn fold_pilot(&self, key: StepKey) -> anyhow::Result<()> {
        let results = self.store.step_results(key)?;
        let Some(&(id, lease)) = results.first() else {
            return Ok(());
        };
        let (hash, scene, settings, frames) = self
            .store
            .job_source(key.job)?
            .with_context(|| format!("job {} is not in the store", key.job))?;
        let name = self.result_key(key.job, id, lease);
        let local = self
            .objects
            .read(&name)?
            .with_context(|| format!("{name} is not in the object store"))?;
        let read = std::fs::File::open(local.path())
            .map_err(anyhow::Error::from)
            .and_then(|file| job::read_choice(&job::pilot_task(), BufReader::new(file)));
        let choice = match read {
            Ok((choice, _)) => choice,
            Err(e) => return self.unreadable(id, e.context(name)).map(|_| ()),
        };
        let bytes = self
            .objects
            .get(&self.bundle_key(&hash))?
            .with_context(|| {
                format!(
                    "bundle {hash} of job {} is not in the object store",
                    key.job
                )
            })?;
        let (method, spp) = (choice.method.clone(), choice.spp);
        let settings = RenderSettings {
            choice: Some(choice),
            ..settings
        };
        let compiled = job::compile_bundled(
            &bytes,
            &scene,
            &settings,
            Some(frames),
            job::Options::new(&self.config.limits),
        )
        .map_err(anyhow::Error::msg)?;
        let work = self.planned_work(&compiled, &settings)?;
        let planned = self.store.measured(key.job, &work)?;
        self.discard(&name);
        if planned {
            tracing::info!(job = key.job, %method, spp, tasks = work.planned_tasks, "auto chose; job planned");
            self.wake_workers();
        }
        Ok(())
    }
}
