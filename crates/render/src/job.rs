//! A job compiled: its settings applied to its scene and checked against the limits of the
//! process that admits it, `auto`'s choice measured or replayed, and its method's plan
//! ([`compile`]); and the file a finished frame is written as. `tessera render`, the
//! coordinator (when a job is submitted and when it plans its stored jobs again) and the
//! worker all compile a job here, so they plan the same passes, tasks and artifact keys, and
//! a frame is the same file wherever it was made. Nothing here knows one method from
//! another: they are the registry's ([`crate::method`]).

use std::path::Path;
use std::time::Duration;

use serde::{Deserialize, Serialize};
use tessera_scene::SceneDesc;

use crate::film::MAX_SPP;
use crate::method::MethodInfo;
use crate::method::auto::pilot::{self, Selection};
use crate::method::auto::{AUTO, Choice};
use crate::method::{self, Finished, Job, MAX_TILE, Plan};
use crate::output::{ExrMetadata, write_exr, write_png};
use crate::scene::Scene;

/// Render settings a job gives on top of its scene. Every field is optional.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct RenderSettings {
    /// Samples per pixel (default: the scene's `integrator.spp`; what a sample is depends on
    /// the method: `GET /v1/methods`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spp: Option<u32>,
    /// Random seed (default: the scene's `integrator.seed`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Tile side in pixels (default: 32, doubled until a frame has at most 600 tiles). Does
    /// not change the image, but for adaptive sampling, which refines tiles.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tile: Option<u32>,
    /// Samples per task where a method cuts frames by samples (default: the method's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples_per_task: Option<u32>,
    /// Film size `[width, height]` in pixels (default: the scene's). The vertical field of
    /// view is kept, so a different aspect ratio widens or narrows the view.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size: Option<[u32; 2]>,
    /// Adaptive sampling: render rounds until the estimated relMSE is at most this; `spp`
    /// becomes the per-pixel maximum.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_error: Option<f64>,
    /// The rendering method, by its name in `GET /v1/methods` (default: the scene's
    /// `integrator.type`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub integrator: Option<String>,
    /// What `auto` chose for this job by measuring it, set by the coordinator when the job
    /// asks for `auto` (a job that gives one is planned with it, unmeasured: how a recorded
    /// choice is replayed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub choice: Option<Choice>,
    /// Reuse cached pass artifacts (photon maps, irradiance caches) whose key matches
    /// (default true). False builds them anew for this job — for measurements.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reuse: Option<bool>,
}

/// Frames `first..=last` (1-based).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct FrameRange {
    pub first: u32,
    pub last: u32,
}

impl FrameRange {
    pub fn single(frame: u32) -> Self {
        FrameRange {
            first: frame,
            last: frame,
        }
    }
    pub fn len(&self) -> u32 {
        self.last + 1 - self.first
    }
    pub fn is_empty(&self) -> bool {
        false
    }
    pub fn iter(&self) -> impl Iterator<Item = u32> {
        self.first..=self.last
    }

    /// Parses `N` or `A-B`.
    pub fn parse(s: &str) -> Result<Self, String> {
        let num = |t: &str| {
            t.trim()
                .parse::<u32>()
                .map_err(|_| format!("expected a frame number or a range like 1-24, got \"{s}\""))
        };
        let range = match s.split_once('-') {
            Some((a, b)) => FrameRange {
                first: num(a)?,
                last: num(b)?,
            },
            None => FrameRange::single(num(s)?),
        };
        if range.first == 0 || range.last < range.first {
            return Err(format!(
                "expected frames counted from 1, first ≤ last, got \"{s}\""
            ));
        }
        Ok(range)
    }
}

impl std::fmt::Display for FrameRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.first == self.last {
            write!(f, "{}", self.first)
        } else {
            write!(f, "{}-{}", self.first, self.last)
        }
    }
}

/// Limits a coordinator (or `tessera render`) puts on what a job may ask for.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// Largest film side, pixels.
    pub max_resolution: u32,
    pub max_spp: u32,
    pub max_frames: u32,
    /// Most bytes a job's frames may hold in the process folding them ([`job_memory`]).
    pub max_memory: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_resolution: 16384,
            max_spp: MAX_SPP,
            max_frames: 100_000,
            max_memory: default_max_memory(),
        }
    }
}

impl Limits {
    /// No farm's limits (the core's own still hold): for a job another process admitted (a
    /// worker, a coordinator planning its stored jobs again) or will admit (a client).
    pub fn none() -> Self {
        Limits {
            max_resolution: u32::MAX,
            max_spp: MAX_SPP,
            max_frames: u32::MAX,
            max_memory: u64::MAX,
        }
    }
}

/// Frames a process folds in memory at once (the coordinator keeps the rest as checkpoints).
pub const FRAMES_IN_MEMORY: u32 = 2;

/// Half of this machine's memory (`MemTotal` of /proc/meminfo), or 8 GiB where it cannot
/// be read: what one job may hold by default.
pub fn default_max_memory() -> u64 {
    machine_memory().map_or(8 << 30, |m| m / 2)
}

/// This machine's memory in bytes, where the system says.
pub fn machine_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Bytes a job's frames hold in the process that folds them: the states of the frames in
/// memory at once ([`Plan::frame_bytes`]), and a finished frame's image and its OpenEXR
/// encoding.
pub fn job_memory(plan: &dyn Plan, width: u32, height: u32, frames: FrameRange) -> u64 {
    let pixels = width as u64 * height as u64;
    let image = pixels * std::mem::size_of::<crate::film::Pixel>() as u64;
    plan.frame_bytes() * u64::from(frames.len().min(FRAMES_IN_MEMORY)) + 2 * image
}

/// Checks [`job_memory`] against the limit, with the figures.
fn check_memory(
    plan: &dyn Plan,
    desc: &SceneDesc,
    frames: FrameRange,
    limits: &Limits,
) -> Result<(), String> {
    let (w, h) = (desc.film.width, desc.film.height);
    let need = job_memory(plan, w, h, frames);
    if need > limits.max_memory {
        let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
        return Err(format!(
            "film: a {w}×{h} frame of {} needs {:.1} GiB to fold ({:.1} GiB of state per frame, {} in memory at once, and the finished image); this farm admits jobs of up to {:.1} GiB (--max-job-memory-gib)",
            plan.method(),
            gib(need),
            gib(plan.frame_bytes()),
            frames.len().min(FRAMES_IN_MEMORY),
            gib(limits.max_memory)
        ));
    }
    Ok(())
}

/// Whether `m` is `auto`, the method that measures the others.
fn is_auto(m: &MethodInfo) -> bool {
    std::ptr::eq(m, &AUTO)
}

/// How [`compile`] gets `auto`'s choice for a job that asks for `auto` and carries none.
#[derive(Debug, Clone, Copy)]
pub enum Choose {
    /// Plans what the job carries: its recorded choice, or without one what scene analysis
    /// chooses from features alone ([`Compiled::awaits_choice`]). For a job another process
    /// measured, or one whose measurement comes later (the farm's pilot task).
    AsRecorded,
    /// Measures it: pilots of every candidate on the job's first frame ([`pilot::select`]),
    /// on a scene built here with this many threads.
    Measure { threads: usize },
}

/// What a job asks for besides its scene, settings and frames.
#[derive(Debug, Clone, Copy)]
pub struct Options<'a> {
    /// What the process that admits the job allows ([`Limits::none`] for one another
    /// process admitted).
    pub limits: &'a Limits,
    pub choose: Choose,
    /// Adaptive sampling by wall time per frame (`tessera render --time-limit`; a farm's
    /// frames must not depend on its machines' speed, so its jobs give none).
    pub time_limit: Option<Duration>,
}

impl<'a> Options<'a> {
    /// A job held to `limits`, planned with the choice it carries (nothing measured).
    pub fn new(limits: &'a Limits) -> Self {
        Options {
            limits,
            choose: Choose::AsRecorded,
            time_limit: None,
        }
    }

    /// A job another process admitted (and measured): planned as it was.
    pub fn admitted() -> Self {
        static NONE: std::sync::LazyLock<Limits> = std::sync::LazyLock::new(Limits::none);
        Options::new(&NONE)
    }
}

/// A compiled job: the core's job (its scene with the settings applied, and `auto`'s choice
/// where it was measured) and its method's plan.
pub struct Compiled {
    pub frames: FrameRange,
    pub job: Job,
    pub plan: Box<dyn Plan>,
    /// `auto`'s measurement, where [`Choose::Measure`] made one: the selection (its report,
    /// timings and the passes its pilot built, which a render in this process takes over)
    /// and the scene it was measured on.
    pub measured: Option<(Selection, Scene)>,
    /// Settings the scene gave that the planned method does not read, one line each (as
    /// pbrt's `ReportUnused`, but a warning: a job may override the scene's method).
    pub unread: Vec<String>,
}

impl Compiled {
    /// The settings to keep with the job: `settings` with the choice measured here, so that
    /// every process that compiles the job again plans the same method.
    pub fn settings(&self, settings: &RenderSettings) -> RenderSettings {
        RenderSettings {
            choice: self.job.choice.clone(),
            ..settings.clone()
        }
    }

    /// Whether the job asks for `auto` and carries no choice: compiled as recorded, its plan
    /// is what scene analysis chooses from features alone, until a measurement
    /// ([`Choose::Measure`]) records one.
    pub fn awaits_choice(&self) -> bool {
        self.job.choice.is_none()
            && method::lookup(&self.job.desc.integrator.method).is_ok_and(is_auto)
    }
}

/// Compiles a job of `desc`: applies `settings` and checks them and `frames` against
/// `options.limits` and the scene; measures `auto`'s choice where the job asks for one
/// ([`Choose`]); plans it with its method, which checks its own settings; and checks the
/// memory its frames need. Errors name the setting and what was expected.
pub fn compile(
    mut desc: SceneDesc,
    settings: &RenderSettings,
    frames: FrameRange,
    options: Options,
) -> Result<Compiled, String> {
    apply(&mut desc, settings, frames, options.limits)?;
    let mut job = job(desc, settings, frames);
    let desc = &job.desc;
    job.time_limit = options.time_limit;
    let mut measured = None;
    if let Choose::Measure { threads } = options.choose
        && job.choice.is_none()
        && is_auto(method::lookup(&desc.integrator.method)?)
    {
        let mut scene = Scene::build(desc);
        let goal = pilot::Goal::of(&job);
        let selection = pilot::select(desc, &mut scene, frames.first, goal, threads)?;
        job.choice = Some(selection.choice.clone());
        measured = Some((selection, scene));
    }
    let plan = method::plan(&job)?;
    check_memory(plan.as_ref(), &job.desc, frames, options.limits)?;
    let planned = method::lookup(plan.method())?;
    let unread = job
        .desc
        .integrator
        .given
        .iter()
        .filter(|s| !planned.reads(s))
        .map(|s| {
            format!(
                "integrator.{}: given, but {} does not read it (it reads {})",
                s.name,
                planned.name,
                reads(planned)
            )
        })
        .collect();
    Ok(Compiled {
        frames,
        job,
        plan,
        measured,
        unread,
    })
}

/// The settings a method reads, as a list for a sentence.
fn reads(m: &MethodInfo) -> String {
    match m.settings {
        [] => "none of them".into(),
        s => s
            .iter()
            .map(|s| format!("integrator.{}", s.name))
            .collect::<Vec<_>>()
            .join(", "),
    }
}

/// Applies `settings` to `desc` and checks them and the frames against `limits` and the
/// scene's animation; the method's own checks come when it plans. Errors name the field and
/// what was expected.
fn apply(
    desc: &mut SceneDesc,
    settings: &RenderSettings,
    frames: FrameRange,
    limits: &Limits,
) -> Result<(), String> {
    if let Some(spp) = settings.spp {
        desc.integrator.spp = spp;
    }
    if let Some(seed) = settings.seed {
        desc.integrator.seed = seed;
    }
    if let Some(m) = &settings.integrator {
        desc.integrator.method = m.trim().to_string();
    }
    method::lookup(&desc.integrator.method)?;
    if let Some(choice) = &settings.choice {
        check_choice(choice, &desc.integrator.method)?;
    }
    if let Some([w, h]) = settings.size {
        if w == 0 || h == 0 {
            return Err(format!(
                "size: expected a film of at least 1×1 pixels, got {w}×{h}"
            ));
        }
        desc.film.width = w;
        desc.film.height = h;
    }
    // The samples the plan will take: the scene's or the settings', or a recorded choice's.
    let max_spp = limits.max_spp.min(MAX_SPP);
    let spp = [("spp", Some(desc.integrator.spp))]
        .into_iter()
        .chain([("choice.spp", settings.choice.as_ref().map(|c| c.spp))]);
    for (field, spp) in spp {
        if let Some(spp) = spp
            && !(1..=max_spp).contains(&spp)
        {
            return Err(format!(
                "{field}: expected 1 to {max_spp} samples per pixel (this farm's limit: --max-spp), got {spp}"
            ));
        }
    }
    let (w, h) = (desc.film.width, desc.film.height);
    if w > limits.max_resolution || h > limits.max_resolution {
        return Err(format!(
            "film: expected at most {0}×{0} pixels (this farm's limit: --max-resolution), the job asks for {w}×{h}",
            limits.max_resolution
        ));
    }
    if let Some(tile) = settings.tile
        && !(1..=MAX_TILE).contains(&tile)
    {
        return Err(format!("tile: expected 1 to {MAX_TILE} pixels, got {tile}"));
    }
    let targets = [("target_error", settings.target_error)]
        .into_iter()
        .chain([(
            "choice.target_error",
            settings.choice.as_ref().and_then(|c| c.target_error),
        )]);
    for (field, t) in targets {
        if let Some(t) = t
            && !(t > 0.0 && t.is_finite())
        {
            return Err(format!("{field}: expected a positive relMSE, got {t}"));
        }
    }
    if settings.samples_per_task == Some(0) {
        return Err("samples_per_task: expected at least 1".into());
    }
    let available = desc.frame_count();
    if frames.first == 0 || frames.last < frames.first || frames.last > available {
        return Err(format!(
            "frames: expected a range within 1-{available} (the scene's {}), got {}-{}",
            if desc.camera_path.is_some() {
                "camera path"
            } else {
                "single frame: it has no camera path"
            },
            frames.first,
            frames.last
        ));
    }
    if frames.len() > limits.max_frames {
        return Err(format!(
            "frames: expected at most {} frames per job (this farm's limit: --max-frames), got {}",
            limits.max_frames,
            frames.len()
        ));
    }
    Ok(())
}

/// Checks that a recorded `auto` choice replays `auto` and that what it sets besides its
/// samples and target (checked with the settings' own) is the core's to take.
fn check_choice(choice: &Choice, method: &str) -> Result<(), String> {
    if !is_auto(method::lookup(method)?) {
        return Err(format!(
            "choice: a recorded choice replays `{}`; this job's method is {method}",
            AUTO.name
        ));
    }
    choice.check().map_err(|e| format!("choice.{e}"))
}

/// The core's view of a job whose settings were applied to `desc`.
fn job(desc: SceneDesc, settings: &RenderSettings, frames: FrameRange) -> Job {
    let tile = settings
        .tile
        .unwrap_or_else(|| method::default_tile(desc.film.width, desc.film.height));
    Job {
        desc,
        frames: frames.first..=frames.last,
        tile,
        samples_per_task: settings.samples_per_task,
        target_error: settings.target_error,
        time_limit: None,
        choice: settings.choice.clone(),
        cache_film: None,
    }
}

/// The EXR metadata of a finished frame: what determines it and what was dropped. No times or
/// hosts, so the file's bytes depend only on the job.
pub fn frame_metadata(
    desc: &SceneDesc,
    plan: &dyn Plan,
    frame: u32,
    done: &Finished,
) -> ExrMetadata {
    let i = &desc.integrator;
    let analysis = crate::analysis::analyze(desc);
    // A method that plans another (`auto`) is named with the one it planned.
    let integrator = if i.method == plan.method() {
        plan.method().to_string()
    } else {
        format!("{}: {}", i.method, plan.method())
    };
    let decisions: Vec<String> = analysis.decisions.iter().map(|d| d.to_string()).collect();
    let mut entries = vec![
        ("scene".to_string(), desc.name.clone()),
        ("integrator".into(), integrator),
        (
            "decisions".into(),
            serde_json::to_string(&decisions).unwrap_or_default(),
        ),
        ("spp".into(), i.spp.to_string()),
        ("seed".into(), i.seed.to_string()),
        ("sampler".into(), format!("{:?}", i.sampler).to_lowercase()),
        ("max_depth".into(), i.max_depth.to_string()),
        (
            "nonfinite_samples_dropped".into(),
            done.stats.nonfinite.to_string(),
        ),
    ];
    if desc.camera_path.is_some() {
        entries.push(("frame".into(), frame.to_string()));
    }
    entries.extend(plan.metadata());
    entries.extend(done.metadata.iter().cloned());
    ExrMetadata { entries }
}

/// `frame_0001.exr`: the file name of a frame of a sequence.
pub fn frame_file_name(frame: u32) -> String {
    format!("frame_{frame:04}.exr")
}

/// Writes a finished frame as EXR, and its PNG preview beside it.
pub fn write_frame(
    path: &Path,
    desc: &SceneDesc,
    plan: &dyn Plan,
    frame: u32,
    done: &Finished,
) -> Result<(), crate::RenderError> {
    write_exr(path, &done.image, &frame_metadata(desc, plan, frame, done))?;
    write_png(&path.with_extension("png"), &done.image)
}

/// What the core will do with a job, with reasons, for logs and the job status (docs/src/design/overview.md
/// invariant 4): scene analysis, then the method's own decisions.
pub fn decisions(desc: &SceneDesc, plan: &dyn Plan) -> Vec<String> {
    let i = &desc.integrator;
    let mut out: Vec<String> = crate::analysis::analyze(desc)
        .decisions
        .iter()
        .map(|d| d.to_string())
        .collect();
    out.extend(plan.decisions());
    out.push(format!(
        "sampling: {:?} sampler, max depth {}, Russian roulette from depth {}",
        i.sampler, i.max_depth, i.rr_depth
    ));
    out.push(match &desc.camera_path {
        Some(p) => format!(
            "camera path: {} keyframes at {} fps, {} frames — the scene is built once per worker, the camera per frame",
            p.keyframes.len(),
            p.fps,
            p.frame_count()
        ),
        None => "camera: still, one frame".into(),
    });
    out
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// `scenes/NAME/scene.json` at 24×20 with `spp` samples (or iterations).
    pub(crate) fn scene(name: &str, spp: u32) -> SceneDesc {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../scenes")
            .join(name)
            .join("scene.json");
        let mut d = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        d.film.width = 24;
        d.film.height = 20;
        d.integrator.spp = spp;
        d
    }

    #[test]
    fn settings_are_checked_against_limits_frames_and_the_registry() {
        let limits = Limits {
            max_resolution: 16,
            ..Default::default()
        };
        let cornell = || scene("cornell-box", 5);
        let run = |settings: RenderSettings, frames: FrameRange, limits: &Limits| {
            apply(&mut cornell(), &settings, frames, limits).unwrap_err()
        };
        let err = run(RenderSettings::default(), FrameRange::single(1), &limits);
        assert!(
            err.contains("film") && err.contains("16×16") && err.contains("--max-resolution"),
            "{err}"
        );
        let zero = RenderSettings {
            spp: Some(0),
            ..Default::default()
        };
        let err = run(zero, FrameRange::single(1), &Limits::default());
        assert!(err.starts_with("spp"), "{err}");
        let err = run(
            RenderSettings::default(),
            FrameRange { first: 1, last: 3 },
            &Limits::default(),
        );
        assert!(err.contains("no camera path"), "{err}");
        let unknown = RenderSettings {
            integrator: Some("raytrace".into()),
            ..Default::default()
        };
        let err = run(unknown, FrameRange::single(1), &Limits::default());
        assert!(
            err.contains("integrator.type") && err.contains("bdpt") && err.contains("raytrace"),
            "{err}"
        );
        assert_eq!(
            FrameRange::parse("2-24"),
            Ok(FrameRange { first: 2, last: 24 })
        );
        assert!(FrameRange::parse("0").is_err() && FrameRange::parse("5-2").is_err());
    }

    /// A recorded `auto` choice is checked like the settings: its samples against the same
    /// limit, its photons against the scene format's, its method against the registry.
    #[test]
    fn a_recorded_choice_is_held_to_the_same_limits() {
        let choice = |spp: u32, photons: Option<u32>, method: &str| RenderSettings {
            integrator: Some("auto".into()),
            choice: Some(Choice {
                method: method.into(),
                subsurface: None,
                photons,
                spp,
                target_error: None,
                report: Vec::new(),
            }),
            ..Default::default()
        };
        let limits = Limits {
            max_spp: 1024,
            ..Default::default()
        };
        let run = |settings: RenderSettings| {
            apply(
                &mut scene("cornell-box", 5),
                &settings,
                FrameRange::single(1),
                &limits,
            )
        };
        assert_eq!(run(choice(64, None, "path")), Ok(()));
        for (settings, needle) in [
            (
                choice(3_000_000, None, "path"),
                "choice.spp: expected 1 to 1024",
            ),
            (choice(u32::MAX, None, "path"), "choice.spp"),
            (choice(64, Some(u32::MAX), "photon"), "choice.photons"),
            (choice(64, None, "auto"), "choice.method"),
            (choice(64, None, "raytrace"), "choice.method"),
        ] {
            let err = run(settings).unwrap_err();
            assert!(err.contains(needle), "{needle:?} not in {err}");
        }
        let mut on_path = choice(64, None, "path");
        on_path.integrator = Some("path".into());
        assert!(run(on_path).unwrap_err().contains("replays `auto`"));
    }

    /// `auto` is measured only where the options ask for it and the job carries no choice;
    /// the measured choice is what the job's settings then carry, and compiling those again
    /// elsewhere (as recorded) plans the same method with the same samples.
    #[test]
    fn auto_is_measured_once_and_replayed_as_recorded() {
        let settings = RenderSettings {
            integrator: Some(AUTO.name.into()),
            ..Default::default()
        };
        let limits = Limits::default();
        let frames = FrameRange::single(1);
        let desc = || scene("cornell-box", 4);
        let unmeasured = compile(desc(), &settings, frames, Options::new(&limits)).unwrap();
        assert!(unmeasured.measured.is_none() && unmeasured.awaits_choice());
        let measure = Options {
            choose: Choose::Measure { threads: 2 },
            ..Options::new(&limits)
        };
        let measured = compile(desc(), &settings, frames, measure).unwrap();
        let (selection, _) = measured.measured.as_ref().expect("measured");
        let kept = measured.settings(&settings);
        assert!(!measured.awaits_choice());
        assert_eq!(kept.choice.as_ref(), Some(&selection.choice));
        assert_eq!(kept.integrator, settings.integrator);
        let again = compile(desc(), &kept, frames, Options::admitted()).unwrap();
        assert!(again.measured.is_none() && !again.awaits_choice());
        assert_eq!(again.plan.method(), measured.plan.method());
        assert_eq!(again.plan.method(), selection.choice.method);
        assert_eq!(again.plan.passes().len(), measured.plan.passes().len());
        for (a, b) in again.plan.passes().iter().zip(measured.plan.passes()) {
            assert_eq!(a.key(), b.key());
        }
        assert_eq!(
            again.plan.start(1).unwrap().tasks,
            measured.plan.start(1).unwrap().tasks
        );
        // A recorded choice is not measured again even where measuring is asked for.
        let replayed = compile(desc(), &kept, frames, measure).unwrap();
        assert!(replayed.measured.is_none());
    }

    /// A setting the scene gives that the planned method does not read is named, with the
    /// method and what it reads; one it reads is not, nor one the scene leaves out.
    #[test]
    fn settings_the_method_does_not_read_are_named() {
        use tessera_scene::setting::{ALPHA, CAUSTIC_FILTER, SAMPLER, SUBSURFACE};
        let limits = Limits::default();
        let mut desc = scene("cornell-box", 2);
        desc.integrator.photon.alpha = Some(0.5);
        desc.integrator.given = vec![&SAMPLER, &SUBSURFACE, &CAUSTIC_FILTER, &ALPHA];
        let unread = |desc: &SceneDesc, method: &str| {
            let settings = RenderSettings {
                integrator: Some(method.into()),
                ..Default::default()
            };
            let options = Options::new(&limits);
            compile(desc.clone(), &settings, FrameRange::single(1), options)
                .unwrap()
                .unread
        };
        // The settings named, by their paths.
        let on = |method: &str| -> Vec<String> {
            let lines = unread(&desc, method);
            lines
                .iter()
                .map(|u| u.split(':').next().unwrap_or("").to_string())
                .collect()
        };
        let named = |names: &[&str]| -> Vec<String> {
            names.iter().map(|n| format!("integrator.{n}")).collect()
        };
        assert_eq!(
            on("path"),
            named(&["photon_map.caustic_filter", "photon_map.alpha"])
        );
        assert_eq!(
            on("sppm"),
            named(&["subsurface", "photon_map.caustic_filter"])
        );
        let all = [
            "sampler",
            "subsurface",
            "photon_map.caustic_filter",
            "photon_map.alpha",
        ];
        assert_eq!(on("mlt"), named(&all));
        let lines = unread(&desc, "path");
        assert!(
            lines[1].starts_with("integrator.photon_map.alpha: given, but path does not read it")
                && lines[1].contains("it reads integrator.subsurface, integrator.sampler"),
            "{lines:?}"
        );
        // Left out, they are not named.
        desc.integrator.given.clear();
        assert_eq!(unread(&desc, "mlt"), Vec::<String>::new());
    }
}
