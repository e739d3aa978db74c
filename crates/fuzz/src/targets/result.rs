//! `result`: a task's result stream as `PUT /v1/tasks/{id}/result` receives it, checked
//! against the task it names by [`check_result`] (the coordinator's check), one job per
//! method of the registry (a 16×16 Cornell box in 8×8 tiles). A result the check accepts
//! must then fold into a fresh frame or pass: what fits is what the fold takes. A pilot's
//! result (`auto`'s choice, [`job::read_choice`]) that is accepted must then compile its job,
//! or be refused by it with an error, as the coordinator's fold of the pilot does.

use std::sync::OnceLock;

use tessera_farm::job::{self, FrameRange, RenderSettings, check_result};
use tessera_render::method::auto::Choice;
use tessera_render::method::{LoadFn, Loaded, Plan, Resources, TaskCtx, TaskSpec};
use tessera_render::wire::{Header, Reader};
use tessera_scene::SceneDesc;

use crate::{Target, repo};

pub const TARGET: Target = Target {
    name: "result",
    about: "a task's result wire stream: checked against its task (every method), then folded",
    run,
    seeds,
};

/// One job per method, with the tasks of its passes and of its frame's first step.
struct Job {
    plan: Box<dyn Plan>,
    tasks: Vec<TaskSpec>,
}

struct Jobs {
    /// The scene as loaded, before any method's settings.
    base: SceneDesc,
    desc: SceneDesc,
    jobs: Vec<Job>,
}

/// The settings of the jobs, with `method`.
fn settings(method: &str) -> RenderSettings {
    RenderSettings {
        size: Some([16, 16]),
        tile: Some(8),
        spp: Some(1),
        integrator: Some(method.into()),
        ..Default::default()
    }
}

fn jobs() -> &'static Jobs {
    static JOBS: OnceLock<Jobs> = OnceLock::new();
    JOBS.get_or_init(|| {
        let path = repo().join("scenes/cornell-box/scene.json");
        let mut base = tessera_scene::load(&path).expect("the Cornell box loads");
        // Photon passes of few photons: small results, fast mutations.
        base.integrator.photon.photons = Some(4096);
        let mut desc = base.clone();
        let jobs = tessera_render::method::names()
            .into_iter()
            .filter(|m| *m != "auto")
            .filter_map(|method| {
                let compiled = job::compile(
                    base.clone(),
                    &settings(method),
                    FrameRange::single(1),
                    job::Options::admitted(),
                )
                .ok()?;
                desc = compiled.job.desc;
                let plan = compiled.plan;
                let mut tasks = Vec::new();
                for (i, pass) in plan.passes().iter().enumerate() {
                    tasks.extend(pass.tasks(i as u32));
                }
                tasks.extend(plan.start(1).ok()?.tasks);
                Some(Job { plan, tasks })
            })
            .collect();
        Jobs { base, desc, jobs }
    })
}

fn run(data: &[u8]) -> bool {
    let Ok((_, header)) = Reader::new(data) else {
        return false;
    };
    let Some(task) = header.task else {
        return false;
    };
    if job::is_pilot(&task) {
        let Ok((choice, _)) = job::read_choice(&task, data) else {
            return false;
        };
        let settings = RenderSettings {
            choice: Some(choice),
            ..settings("auto")
        };
        let limits = job::Limits::default();
        let options = job::Options::new(&limits);
        // Planned, or refused with an error: never a panic.
        let _ = job::compile(
            jobs().base.clone(),
            &settings,
            FrameRange::single(1),
            options,
        );
        return true;
    }
    let Some(job) = jobs().jobs.iter().find(|j| {
        j.tasks.contains(&task)
            && (j.plan.schema() == header.schema
                || j.plan.passes().iter().any(|p| p.schema() == header.schema))
    }) else {
        return false;
    };
    if check_result(job.plan.as_ref(), &task, data).is_err() {
        return false;
    }
    let (mut reader, _) = Reader::new(data).expect("a checked stream opens again");
    let folded = match task.is_pass() {
        true => {
            let pass = job.plan.passes()[task.step as usize];
            let value = pass
                .decode(&mut reader)
                .expect("a checked result decodes again");
            let mut state = pass.start();
            pass.fold(&mut *state, &task, value)
        }
        false => {
            let value = job
                .plan
                .decode(&mut reader)
                .expect("a checked result decodes again");
            let mut frame = job.plan.new_frame(task.frame);
            job.plan.fold(&mut *frame, &task, value)
        }
    };
    if let Err(e) = folded {
        panic!("a result that fits its task {task:?} does not fold: {e}");
    }
    true
}

/// Nothing of another task: a pass's artifacts and a step's inputs are missing.
struct Bare;

impl Resources for Bare {
    fn artifact(&self, key: &str, _: LoadFn) -> Result<Loaded, String> {
        Err(format!("no artifact {key}"))
    }
    fn input(&self, _: LoadFn) -> Result<Loaded, String> {
        Err("no input".into())
    }
    fn memo(&self, _: &str, make: &dyn Fn() -> Result<Loaded, String>) -> Result<Loaded, String> {
        make()
    }
}

/// The first task of each method's passes and frame, run here and written as a worker writes
/// it (tasks that need another task's output are skipped).
fn seeds() -> Vec<(String, Vec<u8>)> {
    let jobs = jobs();
    let scene = tessera_render::Scene::build(&jobs.desc);
    let ctx = TaskCtx {
        scene: &scene,
        desc: &jobs.desc,
        resources: &Bare,
    };
    let mut out = pilot_seeds();
    for job in &jobs.jobs {
        let mut seen = Vec::new();
        for task in &job.tasks {
            let kind = (task.is_pass(), task.step, task.kind.clone());
            if seen.contains(&kind) {
                continue;
            }
            seen.push(kind);
            let Ok(value) = job.plan.execute(&ctx, task) else {
                continue;
            };
            let schema = match task.is_pass() {
                true => job.plan.passes()[task.step as usize].schema(),
                false => job.plan.schema(),
            };
            let mut header = Header::new("result", &schema);
            header.task = Some(task.clone());
            let mut bytes = Vec::new();
            value
                .write_to(&header, &mut bytes)
                .expect("a result writes");
            out.push((
                format!("{}-{}-{}.tswf", job.plan.method(), task.kind, task.step),
                bytes,
            ));
        }
    }
    out
}

/// A pilot's result holding `choice`, as a worker writes it.
fn pilot_result(choice: &Choice) -> Vec<u8> {
    let mut bytes = Vec::new();
    job::write_choice(&mut bytes, &job::pilot_task(), choice).expect("a choice writes");
    bytes
}

/// Pilots' choices of a method without passes and of one with.
fn pilot_seeds() -> Vec<(String, Vec<u8>)> {
    [("path", None), ("photon", Some(20_000))]
        .into_iter()
        .map(|(method, photons)| {
            let choice = Choice {
                method: method.into(),
                subsurface: None,
                photons,
                spp: 4,
                target_error: None,
                report: vec![format!("auto: chose {method} at 4 spp")],
            };
            (format!("pilot-{method}.tswf"), pilot_result(&choice))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pilot's choice is read and its job compiled; one naming no method `auto` may choose
    /// is refused before.
    #[test]
    fn a_pilots_choice_is_checked_then_compiled() {
        for (name, bytes) in pilot_seeds() {
            assert!(run(&bytes), "{name} refused");
        }
        let auto = Choice {
            method: "auto".into(),
            subsurface: None,
            photons: None,
            spp: 4,
            target_error: None,
            report: vec![],
        };
        assert!(!run(&pilot_result(&auto)));
    }
}
