//! Frame methods (docs/src/design/overview.md: "the unit of extension is a frame method"): how each rendering
//! method makes a frame, in pieces a farm can move.
//!
//! A method is one type implementing [`Method`]: it plans a frame as *steps* of *tasks*
//! ([`TaskSpec`]), runs one task into a compact partial result, folds partial results in a
//! fixed order into the frame's state, and after each step says what follows — another step
//! (an adaptive round, an SPPM iteration) or the finished image. View-independent
//! precomputation is a [`Pass`] with a content key (photon maps, the irradiance cache, the
//! subsurface point cloud): its tasks fold into an artifact that every frame and every later
//! job with the same key reads.
//!
//! One registry ([`methods`]) names every method; the CLI, the bench, the farm's API,
//! coordinator and worker find methods there and see them only through the object-safe
//! [`Plan`]. Partial results, artifacts, step inputs and frame checkpoints cross processes in
//! the one [`crate::wire`] format. A task is a pure function of (job, task, the artifacts and
//! step input it reads), and the fold order is the plan's, so a frame is the same bits
//! whoever ran its tasks and whenever their results arrived.

pub mod aov;
pub mod auto;
mod bdpt;
pub mod film;
mod info;
mod layouts;
pub mod local;
mod metropolis;
pub mod passes;
mod path;
mod photon;
mod ranges;
mod registry;
mod sppm;
mod tiles;
mod vcm;

use std::any::Any;
use std::io::{Read, Write};
use std::ops::RangeInclusive;
use std::sync::Arc;
use std::time::Duration;

use serde::Serialize;
use serde::de::DeserializeOwned;
use tessera_scene::{FilmDesc, SceneDesc};

use crate::film::Image;
use crate::scene::Scene;
pub use crate::wire::TaskSpec;
use crate::wire::{self, Header, Sizes, WireError};

pub use info::{MethodInfo, Model, PerRay, PilotInfo, Probe, Sight, Transport};
pub use layouts::Payloads;
pub use registry::{methods, register};
pub use tiles::{Adaptive, TilePartial};

/// Every method's name.
pub fn names() -> Vec<&'static str> {
    methods().iter().map(|m| m.name).collect()
}

/// The method called `name`.
pub fn lookup(name: &str) -> Result<&'static MethodInfo, String> {
    methods()
        .into_iter()
        .find(|m| m.name == name.trim())
        .ok_or_else(|| {
            format!(
                "integrator.type: expected one of {}, got \"{name}\"",
                names().join(", ")
            )
        })
}

/// The method scene analysis chooses where nothing measured the scene: the first of the
/// registry that computes the light transport the scene needs ([`crate::analysis`]).
pub fn for_transport(transport: Transport) -> Result<&'static MethodInfo, String> {
    methods()
        .into_iter()
        .find(|m| m.transport == transport && !std::ptr::eq(*m, &auto::AUTO))
        .ok_or_else(|| format!("integrator.type: no method computes {transport:?} light transport"))
}

/// The per-ray estimator of the method `desc` names (scene analysis's choice for `auto`),
/// its passes (photon maps, irradiance records, point clouds) run in-process, and what was
/// decided on the way: for tests and tools that render pixels with [`crate::render`]
/// directly. Frames are rendered by [`plan`].
pub fn per_ray(
    desc: &SceneDesc,
    scene: &Scene,
) -> Result<(Box<dyn crate::integrator::Integrator>, Vec<String>), String> {
    let mut method = lookup(&desc.integrator.method)?;
    if std::ptr::eq(method, &auto::AUTO) {
        method = for_transport(crate::analysis::analyze(desc).transport)?;
    }
    let per_ray = method.per_ray.ok_or_else(|| {
        format!(
            "integrator.type: {} renders frames, not one ray at a time",
            method.name
        )
    })?;
    Ok(per_ray(desc, scene))
}

/// The per-ray estimator of [`per_ray`], without what was decided.
pub fn for_scene(
    desc: &SceneDesc,
    scene: &Scene,
) -> Result<Box<dyn crate::integrator::Integrator>, String> {
    Ok(per_ray(desc, scene)?.0)
}

/// Plans `job` with the method its scene names.
pub fn plan(job: &Job) -> Result<Box<dyn Plan>, String> {
    plan_as(lookup(&job.desc.integrator.method)?, job)
}

/// Plans `job` with `method`, after refusing what the method cannot render.
pub fn plan_as(method: &MethodInfo, job: &Job) -> Result<Box<dyn Plan>, String> {
    refuses(method, &job.desc)?;
    (method.plan)(job)
}

/// Why `method` cannot render `desc` (translucent materials, a camera or light it does not
/// support), in words that begin with the setting; `Ok` where it can.
pub fn refuses(method: &MethodInfo, desc: &SceneDesc) -> Result<(), String> {
    if !method.translucent {
        refuse_translucent(desc, method.name)?;
    }
    method.refuses.map_or(Ok(()), |refuses| refuses(desc))
}

/// Refuses translucent materials for method `name`, naming the materials and the methods that
/// do render them.
fn refuse_translucent(desc: &SceneDesc, name: &str) -> Result<(), String> {
    let translucent = desc.translucent_materials();
    if translucent.is_empty() {
        return Ok(());
    }
    let able: Vec<&str> = methods()
        .into_iter()
        .filter(|m| m.translucent)
        .map(|m| m.name)
        .collect();
    let able = match able.split_last() {
        Some((last, [])) => last.to_string(),
        Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
        None => "a method that renders them; none does".to_string(),
    };
    Err(format!(
        "integrator.type: {name} does not render translucent (subsurface) materials yet ({}); expected {able}",
        translucent.join(", ")
    ))
}

/// A job as methods see it: the scene with the job's settings applied, the frames to render,
/// and how the job wants its work cut.
#[derive(Debug, Clone)]
pub struct Job {
    pub desc: SceneDesc,
    pub frames: RangeInclusive<u32>,
    /// Side of a tile, pixels (does not change the image).
    pub tile: u32,
    /// Samples (or iterations) per task where a method cuts its frames by samples.
    pub samples_per_task: Option<u32>,
    /// Adaptive sampling: stop when the estimated relMSE is at most this.
    pub target_error: Option<f64>,
    /// Adaptive sampling: start no new round after this long (in-process renders only: it
    /// depends on the machine).
    pub time_limit: Option<Duration>,
    /// What `auto` chose for this job by measurement (`None`: scene analysis chooses).
    pub choice: Option<auto::Choice>,
    /// An `auto` pilot's: the film of the render it measures for. View-dependent caches (the
    /// photon map's irradiance cache) are planned for that film and under its key, so the
    /// pilot reads the records the render would make and the render takes them over; a
    /// cache of the pilot's own film would place its records as far apart in the scene as the
    /// pilot's pixels are. `None`: the job's own film.
    pub cache_film: Option<FilmDesc>,
}

impl Job {
    /// One frame of `desc` with default cutting.
    pub fn new(desc: SceneDesc, frame: u32) -> Self {
        Job {
            desc,
            frames: frame..=frame,
            tile: DEFAULT_TILE,
            samples_per_task: None,
            target_error: None,
            time_limit: None,
            choice: None,
            cache_film: None,
        }
    }
}

/// Smallest tile side when a job does not say.
pub const DEFAULT_TILE: u32 = 32;
/// Most tiles a frame is cut into when a job does not say the tile size.
const MAX_DEFAULT_TILES: usize = 600;

/// The tile side for a `width`×`height` film when a job does not say: 32 pixels, doubled
/// until the frame has at most 600 tiles (a task's overhead stays small beside its work).
pub fn default_tile(width: u32, height: u32) -> u32 {
    let mut tile = DEFAULT_TILE;
    while tile < MAX_TILE
        && (width.div_ceil(tile) as usize) * (height.div_ceil(tile) as usize) > MAX_DEFAULT_TILES
    {
        tile *= 2;
    }
    tile
}
/// Largest tile side.
pub const MAX_TILE: u32 = 256;

/// A loaded artifact, step input or memo: typed by whoever asked for it.
pub type Loaded = Arc<dyn Any + Send + Sync>;
/// Loads a value from a wire stream.
pub type LoadFn<'a> = &'a dyn Fn(&mut dyn Read) -> Result<Loaded, String>;

/// What a task reads besides the scene, provided by whoever runs it: a worker downloads
/// artifacts and step inputs and keeps what it loaded; `tessera render` has them in memory.
pub trait Resources: Sync {
    /// The artifact with this key, loaded by `load` from its stream (once per process).
    fn artifact(&self, key: &str, load: LoadFn) -> Result<Loaded, String>;
    /// The input of the task's step, loaded by `load` (once per process and step).
    fn input(&self, load: LoadFn) -> Result<Loaded, String>;
    /// A value made by `make` once per process for the task's step and this name (work that
    /// every task of a step shares, such as SPPM's camera paths).
    fn memo(&self, name: &str, make: &dyn Fn() -> Result<Loaded, String>)
    -> Result<Loaded, String>;
    /// `work` more units of the task done (for progress bars; units are the task's pixels ×
    /// samples, or its photons or points).
    fn progress(&self, _work: u64) {}
    /// A value made before the job ran and handed to it under `key` (`auto`'s pilot gives
    /// the render SPPM's first photons); `None` where nothing was (always on the farm).
    fn reuse(&self, _key: &str) -> Option<Loaded> {
        None
    }
}

/// What a task runs with.
pub struct TaskCtx<'a> {
    pub scene: &'a Scene,
    pub desc: &'a SceneDesc,
    pub resources: &'a dyn Resources,
}

impl TaskCtx<'_> {
    /// The loaded artifact of `pass`.
    pub fn artifact<P: Pass>(&self, pass: &P) -> Result<Arc<P::Loaded>, String> {
        let load = |r: &mut dyn Read| -> Result<Loaded, String> {
            let (header, artifact): (Header, P::Artifact) = wire::read(r)
                .map_err(|e| format!("the {} artifact {}: {e}", pass.name(), short(pass.key())))?;
            check_schema(&header, &pass_schema(pass.name()))?;
            Ok(Arc::new(pass.load(artifact)?))
        };
        self.resources
            .artifact(pass.key(), &load)?
            .downcast::<P::Loaded>()
            .map_err(|_| format!("artifact {} is not a {}", short(pass.key()), pass.name()))
    }

    /// The input of the task's step.
    pub fn input<T: DeserializeOwned + Send + Sync + 'static>(&self) -> Result<Arc<T>, String> {
        let load = |r: &mut dyn Read| -> Result<Loaded, String> {
            let (_, v): (Header, T) =
                wire::read(r).map_err(|e| format!("the step's input: {e}"))?;
            Ok(Arc::new(v))
        };
        self.resources
            .input(&load)?
            .downcast::<T>()
            .map_err(|_| "the step's input is not of the type its tasks read".to_string())
    }

    /// A value made once per process for the task's step.
    pub fn memo<T: Send + Sync + 'static>(
        &self,
        name: &str,
        make: impl Fn() -> Result<T, String>,
    ) -> Result<Arc<T>, String> {
        let make = || -> Result<Loaded, String> { Ok(Arc::new(make()?)) };
        self.resources
            .memo(name, &make)?
            .downcast::<T>()
            .map_err(|_| format!("memo {name} has another type"))
    }

    /// The value handed to the job under `key`, if one was and it is a `T`.
    pub fn reuse<T: Send + Sync + 'static>(&self, key: &str) -> Option<Arc<T>> {
        self.resources.reuse(key)?.downcast::<T>().ok()
    }

    pub fn progress(&self, work: u64) {
        self.resources.progress(work);
    }
}

/// The first 12 characters of a key, for messages.
pub fn short(key: &str) -> &str {
    &key[..key.len().min(12)]
}

/// A value that crosses processes: a task's partial result, an artifact, a step input or a
/// frame's state.
pub trait Payload: Any + Send + Sync {
    /// Writes it as a wire stream with `header`.
    fn write_to(&self, header: &Header, out: &mut dyn Write) -> Result<Sizes, WireError>;
    /// Writes it into the payload of a stream being written (after other values, say).
    fn encode(&self, payload: &mut dyn Write) -> Result<(), WireError>;
    fn into_any(self: Box<Self>) -> Box<dyn Any + Send + Sync>;
    fn as_any(&self) -> &dyn Any;
    fn as_any_mut(&mut self) -> &mut dyn Any;
}

impl<T: Serialize + Send + Sync + 'static> Payload for T {
    fn write_to(&self, header: &Header, out: &mut dyn Write) -> Result<Sizes, WireError> {
        Ok(wire::write(out, header, self)?.1)
    }
    fn encode(&self, payload: &mut dyn Write) -> Result<(), WireError> {
        wire::encode_into(self, payload)
    }
    fn into_any(self: Box<Self>) -> Box<dyn Any + Send + Sync> {
        self
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
}

/// Takes a payload back as the type it was made as.
pub fn downcast<T: 'static>(p: Box<dyn Payload>) -> Result<T, String> {
    p.into_any()
        .downcast::<T>()
        .map(|b| *b)
        .map_err(|_| format!("expected a {}", std::any::type_name::<T>()))
}

/// A step of a frame: its tasks, in fold order, and what they read besides the scene and the
/// job's artifacts.
pub struct Step {
    pub tasks: Vec<TaskSpec>,
    pub input: Option<Box<dyn Payload>>,
}

impl Step {
    pub fn tasks(tasks: Vec<TaskSpec>) -> Self {
        Step { tasks, input: None }
    }
}

/// A finished frame.
pub struct Finished {
    pub image: Image,
    pub stats: crate::RayStats,
    /// EXR header entries the method adds (settings, the adaptive rule's outcome).
    pub metadata: Vec<(String, String)>,
    /// The relMSE the frame estimates for itself, where the method estimates one.
    pub estimated_rel_mse: Option<f64>,
    /// Wall seconds of the frame's work that grows with its pixels, where the method tells it
    /// from work that does not (SPPM: camera paths and the gathering at their visible points,
    /// not the photons each iteration shoots whatever the film); `None` where all of it grows
    /// with the pixels. `auto`'s pilot, rendered at a fraction of the pixels, scales this part.
    pub pixels_s: Option<f64>,
    /// Wall seconds of the frame's work that grows neither with its pixels nor with its
    /// samples (a Metropolis frame's bootstrap: [`crate::integrator::metropolis::GroupWork`]);
    /// 0 where there is none. A render pays it once, a pilot once per frame it renders.
    pub fixed_s: f64,
}

/// What follows a step.
pub enum Next {
    Step(Step),
    Done(Finished),
}

/// A method planned for one job, as its implementor writes it. [`Plan`] is its object-safe
/// face, implemented for every `Method`.
pub trait Method: Send + Sync + 'static {
    /// One task's result: only what the fold needs.
    type Partial: Serialize + DeserializeOwned + Send + Sync + 'static;
    /// A frame's state between folds, and a step's checkpoint.
    type Frame: Serialize + DeserializeOwned + Send + Sync + 'static;

    /// The name of the method that runs (the registry's).
    fn name(&self) -> &'static str;
    /// What was decided for this job, with reasons (job status, logs, EXR header).
    fn decisions(&self) -> Vec<String>;
    /// EXR header entries.
    fn metadata(&self) -> Vec<(String, String)> {
        Vec::new()
    }
    /// The job's passes, in the order they are built.
    fn passes(&self) -> Vec<&dyn DynPass> {
        Vec::new()
    }
    /// The first step of `frame`.
    fn start(&self, frame: u32) -> Result<Step, String>;
    /// Tasks of a frame's later steps where the method knows them in advance (for progress;
    /// adaptive rounds are not known).
    fn later_tasks(&self) -> u64 {
        0
    }
    /// Tasks that take a finished frame on to `spp` samples per pixel (iterations), folded into
    /// the same state; `None` where the method cannot continue a frame (Markov chains).
    fn more(&self, _frame: u32, _state: &mut Self::Frame, _spp: u32) -> Option<Step> {
        None
    }
    fn new_frame(&self, frame: u32) -> Self::Frame;
    /// Bytes one frame's state holds in memory: what a process folding the frame keeps of
    /// it (for admitting a job by its memory before anything is allocated).
    fn frame_bytes(&self) -> u64;
    fn execute(&self, ctx: &TaskCtx, task: &TaskSpec) -> Result<Self::Partial, String>;
    /// Whether a task's result has the shape its task gives it (pixels, samples, lengths),
    /// checked when it arrives, before it is accepted: a result that fits is one [`fold`]
    /// takes, whatever came before it.
    ///
    /// [`fold`]: Method::fold
    fn fits(&self, task: &TaskSpec, p: &Self::Partial) -> Result<(), String>;
    /// Folds a task's result into its frame; called in the step's task order.
    fn fold(
        &self,
        state: &mut Self::Frame,
        task: &TaskSpec,
        p: Self::Partial,
    ) -> Result<(), String>;
    /// After every task of a step was folded: the next step, or the finished frame.
    /// `elapsed` is the frame's wall time so far (zero on a farm).
    fn advance(
        &self,
        frame: u32,
        state: &mut Self::Frame,
        elapsed: Duration,
    ) -> Result<Next, String>;
    /// The frame as it stands (for previews while it renders).
    fn preview(&self, frame: u32, state: &Self::Frame) -> Image;
}

/// A precomputation pass, as its implementor writes it; [`DynPass`] is its object-safe face.
pub trait Pass: Send + Sync + 'static {
    type Partial: Serialize + DeserializeOwned + Send + Sync + 'static;
    /// What its tasks' results fold into (in memory; refolded from results after a restart).
    type State: Send + Sync + 'static;
    /// What is stored under the key and read by later tasks.
    type Artifact: Serialize + DeserializeOwned + Send + Sync + 'static;
    /// The artifact as tasks use it (trees built, tables filled), once per process.
    type Loaded: Send + Sync + 'static;

    fn name(&self) -> &'static str;
    /// A hash of everything that determines the artifact (never the camera, for
    /// view-independent data): equal keys, equal artifacts.
    fn key(&self) -> &str;
    /// Its tasks, for a pass at position `step` among the job's.
    fn tasks(&self, step: u32) -> Vec<TaskSpec>;
    fn execute(&self, ctx: &TaskCtx, task: &TaskSpec) -> Result<Self::Partial, String>;
    /// Whether a task's result has the shape its task gives it, before it is accepted (see
    /// [`Method::fits`]).
    fn fits(&self, task: &TaskSpec, p: &Self::Partial) -> Result<(), String>;
    fn start(&self) -> Self::State;
    /// Bytes `state` holds now (what it has allocated): a process folding a pass checks it
    /// against the job's memory budget as results come in, since how much a pass stores
    /// (photons that land, records the error bound asks for) is known only then.
    fn state_bytes(&self, state: &Self::State) -> u64;
    fn fold(
        &self,
        state: &mut Self::State,
        task: &TaskSpec,
        p: Self::Partial,
    ) -> Result<(), String>;
    fn finish(&self, state: Self::State) -> Result<Self::Artifact, String>;
    /// Wall seconds [`Pass::finish`] would take once every task is folded, estimated from
    /// `state` holding the results of `share` (0–1] of them; `None` where finishing costs
    /// little beside the tasks.
    fn finish_estimate(&self, _state: &Self::State, _share: f64) -> Option<f64> {
        None
    }
    fn load(&self, artifact: Self::Artifact) -> Result<Self::Loaded, String>;
    /// What the artifact holds, for the job status.
    fn describe(&self, artifact: &Self::Artifact) -> String;
}

/// The schema string of a pass's payloads.
fn pass_schema(name: &str) -> String {
    format!("{name}/{}", wire::VERSION)
}

fn check_schema(header: &Header, schema: &str) -> Result<(), String> {
    if header.schema != schema {
        return Err(format!(
            "expected a {schema} payload, got {}",
            header.schema
        ));
    }
    Ok(())
}

/// A pass as the farm and the runner see it.
pub trait DynPass: Send + Sync {
    fn name(&self) -> &'static str;
    fn key(&self) -> &str;
    /// The schema of its results and artifact.
    fn schema(&self) -> String {
        pass_schema(self.name())
    }
    fn tasks(&self, step: u32) -> Vec<TaskSpec>;
    fn execute(&self, ctx: &TaskCtx, task: &TaskSpec) -> Result<Box<dyn Payload>, String>;
    /// Reads a task's result from the payload of its stream.
    fn decode(&self, payload: &mut dyn Read) -> Result<Box<dyn Payload>, WireError>;
    /// See [`Pass::fits`].
    fn fits(&self, task: &TaskSpec, p: &dyn Payload) -> Result<(), String>;
    fn start(&self) -> Box<dyn Any + Send + Sync>;
    /// See [`Pass::state_bytes`].
    fn state_bytes(&self, state: &(dyn Any + Send + Sync)) -> u64;
    fn fold(
        &self,
        state: &mut (dyn Any + Send + Sync),
        task: &TaskSpec,
        p: Box<dyn Payload>,
    ) -> Result<(), String>;
    /// The artifact and a line saying what it holds.
    fn finish(
        &self,
        state: Box<dyn Any + Send + Sync>,
    ) -> Result<(Box<dyn Payload>, String), String>;
    /// See [`Pass::finish_estimate`].
    fn finish_estimate(&self, state: &(dyn Any + Send + Sync), share: f64) -> Option<f64>;
    /// The artifact, as made by [`Self::finish`], loaded for tasks to read.
    fn load(&self, artifact: Box<dyn Payload>) -> Result<Loaded, String>;
}

impl<P: Pass> DynPass for P {
    fn name(&self) -> &'static str {
        Pass::name(self)
    }
    fn key(&self) -> &str {
        Pass::key(self)
    }
    fn tasks(&self, step: u32) -> Vec<TaskSpec> {
        Pass::tasks(self, step)
    }
    fn execute(&self, ctx: &TaskCtx, task: &TaskSpec) -> Result<Box<dyn Payload>, String> {
        Ok(Box::new(Pass::execute(self, ctx, task)?))
    }
    fn decode(&self, payload: &mut dyn Read) -> Result<Box<dyn Payload>, WireError> {
        Ok(Box::new(wire::decode_from::<P::Partial>(payload)?))
    }
    fn fits(&self, task: &TaskSpec, p: &dyn Payload) -> Result<(), String> {
        let p = p
            .as_any()
            .downcast_ref::<P::Partial>()
            .ok_or("a result of another pass")?;
        Pass::fits(self, task, p)
    }
    fn start(&self) -> Box<dyn Any + Send + Sync> {
        Box::new(Pass::start(self))
    }
    fn state_bytes(&self, state: &(dyn Any + Send + Sync)) -> u64 {
        state
            .downcast_ref::<P::State>()
            .map_or(0, |s| Pass::state_bytes(self, s))
    }
    fn fold(
        &self,
        state: &mut (dyn Any + Send + Sync),
        task: &TaskSpec,
        p: Box<dyn Payload>,
    ) -> Result<(), String> {
        let state = state
            .downcast_mut::<P::State>()
            .ok_or("a pass state of another pass")?;
        Pass::fold(self, state, task, downcast(p)?)
    }
    fn finish(
        &self,
        state: Box<dyn Any + Send + Sync>,
    ) -> Result<(Box<dyn Payload>, String), String> {
        let state = state
            .downcast::<P::State>()
            .map_err(|_| "a pass state of another pass")?;
        let artifact = Pass::finish(self, *state)?;
        let line = self.describe(&artifact);
        Ok((Box::new(artifact), line))
    }
    fn finish_estimate(&self, state: &(dyn Any + Send + Sync), share: f64) -> Option<f64> {
        Pass::finish_estimate(self, state.downcast_ref::<P::State>()?, share)
    }
    fn load(&self, artifact: Box<dyn Payload>) -> Result<Loaded, String> {
        Ok(Arc::new(Pass::load(self, downcast(artifact)?)?))
    }
}

/// A method planned for one job, as the farm, the CLI and the bench hold it.
pub trait Plan: Send + Sync {
    /// The method that runs (for `auto`, the one it chose).
    fn method(&self) -> &'static str;
    /// The schema of its task results and frame checkpoints.
    fn schema(&self) -> String {
        format!("{}/{}", self.method(), wire::VERSION)
    }
    fn decisions(&self) -> Vec<String>;
    fn metadata(&self) -> Vec<(String, String)>;
    fn passes(&self) -> Vec<&dyn DynPass>;
    fn start(&self, frame: u32) -> Result<Step, String>;
    /// Tasks of a frame's later steps where known in advance (see [`Method::later_tasks`]).
    fn later_tasks(&self) -> u64;
    fn more(&self, frame: u32, state: &mut dyn Payload, spp: u32) -> Option<Step>;
    /// Runs a frame's or a pass's task.
    fn execute(&self, ctx: &TaskCtx, task: &TaskSpec) -> Result<Box<dyn Payload>, String>;
    /// Reads a frame task's result from the payload of its stream.
    fn decode(&self, payload: &mut dyn Read) -> Result<Box<dyn Payload>, WireError>;
    /// Whether a decoded result of a frame's or a pass's task fits the task (see
    /// [`Method::fits`]).
    fn fits(&self, task: &TaskSpec, p: &dyn Payload) -> Result<(), String>;
    fn new_frame(&self, frame: u32) -> Box<dyn Payload>;
    /// See [`Method::frame_bytes`].
    fn frame_bytes(&self) -> u64;
    /// Reads a frame's checkpoint from the payload of its stream.
    fn decode_frame(&self, payload: &mut dyn Read) -> Result<Box<dyn Payload>, WireError>;
    fn fold(
        &self,
        state: &mut dyn Payload,
        task: &TaskSpec,
        p: Box<dyn Payload>,
    ) -> Result<(), String>;
    fn advance(
        &self,
        frame: u32,
        state: &mut dyn Payload,
        elapsed: Duration,
    ) -> Result<Next, String>;
    fn preview(&self, frame: u32, state: &dyn Payload) -> Image;
}

/// The pass a pass's task is of.
fn pass_of<'a, M: Method>(m: &'a M, task: &TaskSpec) -> Result<&'a dyn DynPass, String> {
    Method::passes(m)
        .get(task.step as usize)
        .copied()
        .ok_or_else(|| format!("the job has no pass {}", task.step))
}

fn frame_state<M: Method>(state: &dyn Payload) -> Result<&M::Frame, String> {
    state.as_any().downcast_ref::<M::Frame>().ok_or_else(|| {
        format!(
            "a frame state of another method than {}",
            std::any::type_name::<M>()
        )
    })
}

impl<M: Method> Plan for M {
    fn method(&self) -> &'static str {
        Method::name(self)
    }
    fn decisions(&self) -> Vec<String> {
        Method::decisions(self)
    }
    fn metadata(&self) -> Vec<(String, String)> {
        Method::metadata(self)
    }
    fn passes(&self) -> Vec<&dyn DynPass> {
        Method::passes(self)
    }
    fn start(&self, frame: u32) -> Result<Step, String> {
        Method::start(self, frame)
    }
    fn later_tasks(&self) -> u64 {
        Method::later_tasks(self)
    }
    fn more(&self, frame: u32, state: &mut dyn Payload, spp: u32) -> Option<Step> {
        let state = state.as_any_mut().downcast_mut::<M::Frame>()?;
        Method::more(self, frame, state, spp)
    }
    fn execute(&self, ctx: &TaskCtx, task: &TaskSpec) -> Result<Box<dyn Payload>, String> {
        if task.is_pass() {
            return pass_of(self, task)?.execute(ctx, task);
        }
        Ok(Box::new(Method::execute(self, ctx, task)?))
    }
    fn decode(&self, payload: &mut dyn Read) -> Result<Box<dyn Payload>, WireError> {
        Ok(Box::new(wire::decode_from::<M::Partial>(payload)?))
    }
    fn fits(&self, task: &TaskSpec, p: &dyn Payload) -> Result<(), String> {
        if task.is_pass() {
            return pass_of(self, task)?.fits(task, p);
        }
        let p = p
            .as_any()
            .downcast_ref::<M::Partial>()
            .ok_or("a result of another method")?;
        Method::fits(self, task, p)
    }
    fn new_frame(&self, frame: u32) -> Box<dyn Payload> {
        Box::new(Method::new_frame(self, frame))
    }
    fn frame_bytes(&self) -> u64 {
        Method::frame_bytes(self)
    }
    fn decode_frame(&self, payload: &mut dyn Read) -> Result<Box<dyn Payload>, WireError> {
        Ok(Box::new(wire::decode_from::<M::Frame>(payload)?))
    }
    fn fold(
        &self,
        state: &mut dyn Payload,
        task: &TaskSpec,
        p: Box<dyn Payload>,
    ) -> Result<(), String> {
        let state = state
            .as_any_mut()
            .downcast_mut::<M::Frame>()
            .ok_or("a frame state of another method")?;
        Method::fold(self, state, task, downcast(p)?)
    }
    fn advance(
        &self,
        frame: u32,
        state: &mut dyn Payload,
        elapsed: Duration,
    ) -> Result<Next, String> {
        let state = state
            .as_any_mut()
            .downcast_mut::<M::Frame>()
            .ok_or("a frame state of another method")?;
        Method::advance(self, frame, state, elapsed)
    }
    fn preview(&self, frame: u32, state: &dyn Payload) -> Image {
        match frame_state::<M>(state) {
            Ok(s) => Method::preview(self, frame, s),
            Err(_) => Image::new(0, 0),
        }
    }
}
