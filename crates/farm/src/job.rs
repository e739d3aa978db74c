//! How an image is made, wherever it is made: a job's settings applied to a scene, frames cut
//! into tasks (tile × sample range), a task rendered, and a frame stitched from its tasks in a
//! fixed order. `tessera render` runs these in-process; the coordinator plans and stitches,
//! workers execute. One code path, so a frame is bit-identical however it was rendered.

use std::path::Path;
use std::time::Instant;

use serde::{Deserialize, Serialize};
use tessera_render::analysis::Analysis;
use tessera_render::camera::Camera;
use tessera_render::film::{MAX_SPP, TileSums, tiles};
use tessera_render::integrator::sppm::SppmSettings;
use tessera_render::output::{ExrMetadata, write_exr, write_png};
use tessera_render::photon::PhotonSettings;
use tessera_render::{Image, Integrator, RayStats, SampleRange, Scene, Tile, integrator, render};
use tessera_scene::{IntegratorKind, SceneDesc};

use crate::progressive::Adaptive;
use utoipa::ToSchema;

/// Render settings a job gives on top of its scene. Every field is optional.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RenderSettings {
    /// Samples per pixel (default: the scene's `integrator.spp`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spp: Option<u32>,
    /// Random seed (default: the scene's `integrator.seed`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Tile side in pixels (default 32). Does not change the image.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tile: Option<u32>,
    /// Samples per task (default: all of them in one task per tile). Does not change the image.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples_per_task: Option<u32>,
    /// Film size `[width, height]` in pixels (default: the scene's). The vertical field of
    /// view is kept, so a different aspect ratio widens or narrows the view.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub size: Option<[u32; 2]>,
    /// Adaptive sampling: render rounds until the estimated relMSE is at most this; `spp`
    /// becomes the per-pixel maximum (see `progressive`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_error: Option<f64>,
    /// The integrator (default: the scene's `integrator.type`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub integrator: Option<IntegratorName>,
    /// Reuse cached pass artifacts (photon maps, irradiance caches) whose key matches
    /// (default true). False builds them anew for this job — for measurements.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reuse: Option<bool>,
}

/// Integrators a job may ask for by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum IntegratorName {
    Path,
    Direct,
    Auto,
    Photon,
    Sppm,
    Bdpt,
    Pssmlt,
    Mlt,
    Vcm,
}

impl IntegratorName {
    pub const ALL: [IntegratorName; 9] = [
        IntegratorName::Path,
        IntegratorName::Direct,
        IntegratorName::Auto,
        IntegratorName::Photon,
        IntegratorName::Sppm,
        IntegratorName::Bdpt,
        IntegratorName::Pssmlt,
        IntegratorName::Mlt,
        IntegratorName::Vcm,
    ];

    pub fn kind(self) -> IntegratorKind {
        match self {
            IntegratorName::Path => IntegratorKind::Path,
            IntegratorName::Direct => IntegratorKind::Direct,
            IntegratorName::Auto => IntegratorKind::Auto,
            IntegratorName::Photon => IntegratorKind::Photon,
            IntegratorName::Sppm => IntegratorKind::Sppm,
            IntegratorName::Bdpt => IntegratorKind::Bdpt,
            IntegratorName::Pssmlt => IntegratorKind::Pssmlt,
            IntegratorName::Mlt => IntegratorKind::Mlt,
            IntegratorName::Vcm => IntegratorKind::Vcm,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            IntegratorName::Path => "path",
            IntegratorName::Direct => "direct",
            IntegratorName::Auto => "auto",
            IntegratorName::Photon => "photon",
            IntegratorName::Sppm => "sppm",
            IntegratorName::Bdpt => "bdpt",
            IntegratorName::Pssmlt => "pssmlt",
            IntegratorName::Mlt => "mlt",
            IntegratorName::Vcm => "vcm",
        }
    }
}

impl std::str::FromStr for IntegratorName {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|n| n.name() == s.trim())
            .ok_or_else(|| {
                let names: Vec<&str> = Self::ALL.iter().map(|n| n.name()).collect();
                format!(
                    "unknown integrator \"{s}\"; expected one of {}",
                    names.join(", ")
                )
            })
    }
}

/// Samples per pixel of an adaptive render's first round.
pub const ADAPTIVE_FIRST_SPP: u32 = 16;

/// The adaptive rule a job's settings ask for, if any (the scene's spp is the maximum).
pub fn adaptive_rule(desc: &SceneDesc, settings: &RenderSettings) -> Option<Adaptive> {
    settings.target_error.map(|t| Adaptive {
        target_rel_mse: Some(t),
        time_limit: None,
        first_spp: ADAPTIVE_FIRST_SPP.min(desc.integrator.spp),
        max_spp: desc.integrator.spp,
    })
}

pub const DEFAULT_TILE: u32 = 32;
/// Largest tile side: bounds the size of one task's result (≈ 15 MB of sums).
pub const MAX_TILE: u32 = 256;

/// Frames `first..=last` (1-based).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
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
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_resolution: 16384,
            max_spp: MAX_SPP,
            max_frames: 100_000,
        }
    }
}

/// Applies `settings` to `desc`, checks them and the frames against `limits` and the scene's
/// animation. Errors name the field and what was expected.
pub fn apply(
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
    if let Some(i) = settings.integrator {
        desc.integrator.kind = i.kind();
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
    let spp = desc.integrator.spp;
    let max_spp = limits.max_spp.min(MAX_SPP);
    if !(1..=max_spp).contains(&spp) {
        return Err(format!(
            "spp: expected 1 to {max_spp} samples per pixel, got {spp}"
        ));
    }
    if desc
        .integrator
        .photon
        .alpha
        .is_some_and(|a| !(a > 0.0 && a < 1.0))
    {
        return Err("integrator.photon_map.alpha: expected a fraction in (0, 1)".into());
    }
    let (w, h) = (desc.film.width, desc.film.height);
    if w > limits.max_resolution || h > limits.max_resolution {
        return Err(format!(
            "film: expected at most {0}×{0} pixels (this farm's limit), the scene asks for {w}×{h}",
            limits.max_resolution
        ));
    }
    if let Some(tile) = settings.tile
        && !(1..=MAX_TILE).contains(&tile)
    {
        return Err(format!("tile: expected 1 to {MAX_TILE} pixels, got {tile}"));
    }
    if let Some(t) = settings.target_error
        && !(t > 0.0 && t.is_finite())
    {
        return Err(format!("target_error: expected a positive relMSE, got {t}"));
    }
    if settings.samples_per_task == Some(0) {
        return Err("samples_per_task: expected at least 1".into());
    }
    if desc.integrator.kind == IntegratorKind::Sppm {
        crate::sppm::check(desc, settings)?;
    }
    if crate::bdpt::film_tasks(desc.integrator.kind) {
        crate::bdpt::check(desc, settings)?;
    }
    let translucent = desc.translucent_materials();
    if !translucent.is_empty()
        && !matches!(
            desc.integrator.kind,
            IntegratorKind::Path | IntegratorKind::Direct | IntegratorKind::Auto
        )
    {
        return Err(format!(
            "integrator.type: {} does not render translucent (subsurface) materials yet ({}); expected path, direct or auto",
            format!("{:?}", desc.integrator.kind).to_lowercase(),
            translucent.join(", ")
        ));
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
            "frames: expected at most {} frames per job, got {}",
            limits.max_frames,
            frames.len()
        ));
    }
    Ok(())
}

/// What a task computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum TaskKind {
    /// Samples `sample_start..sample_end` of the pixels of a tile of frame `frame`.
    #[default]
    Tile,
    /// Photons `sample_start..sample_end` of the global map (frame 0).
    GlobalPhotons,
    /// Photons `sample_start..sample_end` of the caustic map (frame 0).
    CausticPhotons,
    /// Irradiance records over the tile `x0..x1 × y0..y1` of the record-candidate grid of
    /// keyframe `frame`.
    Records,
    /// SPPM iteration `sample_start` of frame `frame`: photons `x0..x1` of the iteration
    /// (chunk `tile_index`) gathered at every pixel's visible point (see [`crate::sppm`]).
    Sppm,
    /// Samples `sample_start..sample_end` of every pixel of frame `frame` by BDPT (chunk
    /// `tile_index`; the tile spans the film: see [`crate::bdpt`]).
    Bdpt,
    /// The irradiance of points `sample_start..sample_end` of the subsurface point cloud (the
    /// hierarchical method's pass; frame 0).
    SubsurfacePoints,
}

impl TaskKind {
    pub fn as_str(self) -> &'static str {
        match self {
            TaskKind::Tile => "tile",
            TaskKind::GlobalPhotons => "global_photons",
            TaskKind::CausticPhotons => "caustic_photons",
            TaskKind::Records => "records",
            TaskKind::Sppm => "sppm",
            TaskKind::Bdpt => "bdpt",
            TaskKind::SubsurfacePoints => "subsurface_points",
        }
    }

    pub fn parse(s: &str) -> TaskKind {
        match s {
            "global_photons" => TaskKind::GlobalPhotons,
            "caustic_photons" => TaskKind::CausticPhotons,
            "records" => TaskKind::Records,
            "sppm" => TaskKind::Sppm,
            "bdpt" => TaskKind::Bdpt,
            "subsurface_points" => TaskKind::SubsurfacePoints,
            _ => TaskKind::Tile,
        }
    }

    /// The pass this task belongs to (`None` for a frame's tasks: tiles, SPPM iterations).
    pub fn pass(self) -> Option<PassKind> {
        match self {
            TaskKind::Tile | TaskKind::Sppm | TaskKind::Bdpt => None,
            TaskKind::GlobalPhotons | TaskKind::CausticPhotons => Some(PassKind::Photons),
            TaskKind::Records => Some(PassKind::Records),
            TaskKind::SubsurfacePoints => Some(PassKind::Subsurface),
        }
    }
}

/// A precomputation pass, merged into one artifact.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum PassKind {
    /// The global and caustic photon maps.
    Photons,
    /// The irradiance cache.
    Records,
    /// The hierarchical method's point cloud: the irradiance at every point.
    Subsurface,
}

impl PassKind {
    pub fn as_str(self) -> &'static str {
        match self {
            PassKind::Photons => "photons",
            PassKind::Records => "records",
            PassKind::Subsurface => "subsurface",
        }
    }

    pub fn parse(s: &str) -> Option<PassKind> {
        match s {
            "photons" => Some(PassKind::Photons),
            "records" => Some(PassKind::Records),
            "subsurface" => Some(PassKind::Subsurface),
            _ => None,
        }
    }
}

/// One unit of work: samples `samples` of the pixels of `tile` in frame `frame`, or a piece
/// of a pass (see [`TaskKind`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct TaskSpec {
    #[serde(default)]
    pub kind: TaskKind,
    pub frame: u32,
    /// Position of the tile in the frame's tile order (the stitch order).
    pub tile_index: u32,
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
    /// Sample indices [sample_start, sample_end).
    pub sample_start: u32,
    pub sample_end: u32,
}

impl TaskSpec {
    pub fn tile(&self) -> Tile {
        Tile {
            x0: self.x0,
            y0: self.y0,
            x1: self.x1,
            y1: self.y1,
        }
    }
    pub fn samples(&self) -> SampleRange {
        SampleRange {
            start: self.sample_start,
            end: self.sample_end,
        }
    }

    /// A pass's tasks of `kind` over [0, `count`) in ranges of `per_task` indices (photons,
    /// subsurface points; no tile), in order, numbered on from `first_index`.
    pub fn index_ranges(
        kind: TaskKind,
        count: u32,
        per_task: u32,
        first_index: u32,
    ) -> impl Iterator<Item = TaskSpec> {
        let per_task = per_task.max(1);
        (0..count.div_ceil(per_task)).map(move |i| {
            let start = i * per_task;
            TaskSpec {
                kind,
                frame: 0,
                tile_index: first_index + i,
                x0: 0,
                y0: 0,
                x1: 0,
                y1: 0,
                sample_start: start,
                sample_end: start.saturating_add(per_task).min(count),
            }
        })
    }
}

/// The tasks of one frame, in stitch order: tiles row-major, each tile's sample ranges in
/// increasing order.
pub fn plan_frame(desc: &SceneDesc, settings: &RenderSettings, frame: u32) -> Vec<TaskSpec> {
    // SPPM starts with its first iteration; each later one follows the one before.
    if desc.integrator.kind == IntegratorKind::Sppm {
        return crate::sppm::iteration_tasks(desc, frame, 0);
    }
    if crate::bdpt::film_tasks(desc.integrator.kind) {
        return crate::bdpt::tasks(desc, settings, frame);
    }
    // An adaptive frame starts with one round of every tile; later rounds follow its noise.
    let (spp, chunk) = match adaptive_rule(desc, settings) {
        Some(rule) => (rule.first_spp, rule.first_spp),
        None => {
            let spp = desc.integrator.spp;
            let chunk = settings
                .samples_per_task
                .unwrap_or(spp)
                .clamp(1, spp.max(1));
            (spp, chunk)
        }
    };
    let tile = settings.tile.unwrap_or(DEFAULT_TILE);
    let mut out = Vec::new();
    for (i, t) in tiles(desc.film.width, desc.film.height, tile)
        .into_iter()
        .enumerate()
    {
        let mut start = 0;
        while start < spp {
            let end = (start + chunk).min(spp);
            out.push(TaskSpec {
                kind: TaskKind::Tile,
                frame,
                tile_index: i as u32,
                x0: t.x0,
                y0: t.y0,
                x1: t.x1,
                y1: t.y1,
                sample_start: start,
                sample_end: end,
            });
            start = end;
        }
    }
    out
}

/// A scene built for rendering: the BVH and lights once, for every frame and tile of a job.
pub struct Prepared {
    pub desc: SceneDesc,
    pub scene: Scene,
    /// What scene analysis decided (the integrator among it).
    pub analysis: Analysis,
    /// Photon-mapping settings, when the integrator maps photons.
    pub photon: Option<PhotonSettings>,
    /// SPPM's settings (and the photon settings its shooter uses), for an SPPM scene.
    pub sppm: Option<(PhotonSettings, SppmSettings)>,
    /// The integrator; `None` for photon mapping on a worker, whose passes come as
    /// artifacts (`passes::integrator`).
    integrator: Option<Box<dyn Integrator>>,
    /// What the integrator's passes decided and built (photon counts, records).
    pub passes: Vec<String>,
    /// Seconds spent building (the scene and the passes).
    pub build_seconds: f64,
}

impl Prepared {
    /// The scene built and any passes run in this process, for rendering `frames`.
    pub fn new(desc: SceneDesc, frames: FrameRange) -> Self {
        let start = Instant::now();
        let mut p = Self::scene_only(desc);
        // SPPM and BDPT render whole frames, not tiles.
        if !p.analysis.integrator.whole_frame() {
            let (integrator, passes) =
                integrator::prepare(&p.desc, &p.scene, &p.analysis, frames.first..=frames.last);
            p.integrator = Some(integrator);
            p.passes = passes;
        }
        p.build_seconds = start.elapsed().as_secs_f64();
        p
    }

    /// The scene built, no passes run: a worker's, whose passes arrive as artifacts.
    pub fn scene_only(desc: SceneDesc) -> Self {
        let start = Instant::now();
        let scene = Scene::build(&desc);
        let analysis = tessera_render::analysis::analyze(&desc);
        let photon = (analysis.integrator == IntegratorKind::Photon)
            .then(|| PhotonSettings::resolve(&desc, &analysis).0);
        let sppm = (analysis.integrator == IntegratorKind::Sppm)
            .then(|| SppmSettings::resolve(&desc, &analysis));
        // Photon maps and point clouds come as artifacts.
        let integrator = (photon.is_none()
            && !analysis.integrator.whole_frame()
            && !integrator::needs_point_clouds(&desc))
        .then(|| integrator::prepare(&desc, &scene, &analysis, 1..=1).0);
        Prepared {
            desc,
            scene,
            analysis,
            photon,
            sppm,
            integrator,
            passes: Vec::new(),
            build_seconds: start.elapsed().as_secs_f64(),
        }
    }

    /// The integrator, if it needs no artifacts or had its passes run here.
    pub fn integrator(&self) -> Option<&dyn Integrator> {
        self.integrator.as_deref()
    }

    /// The camera of `frame`.
    pub fn camera(&self, frame: u32) -> Camera {
        camera(&self.desc, frame)
    }

    /// Renders one tile task (with this process's integrator: see [`Self::new`]).
    pub fn execute(&self, task: &TaskSpec) -> TaskOutput {
        let camera = self.camera(task.frame);
        self.execute_with(&camera, task)
    }

    /// Renders one tile task with a camera already made for its frame.
    pub fn execute_with(&self, camera: &Camera, task: &TaskSpec) -> TaskOutput {
        let integrator = self
            .integrator
            .as_deref()
            .expect("Prepared::new makes the integrator; workers use execute_using");
        self.execute_using(integrator, camera, task)
    }

    /// Renders one tile task with `integrator`.
    pub fn execute_using(
        &self,
        integrator: &dyn Integrator,
        camera: &Camera,
        task: &TaskSpec,
    ) -> TaskOutput {
        let (sums, stats) =
            render::render_tile(&self.scene, camera, integrator, task.tile(), task.samples());
        TaskOutput { sums, stats }
    }
}

/// The camera of `frame` of a (settings-applied) scene.
pub fn camera(desc: &SceneDesc, frame: u32) -> Camera {
    Camera::new(&desc.camera_at(frame), &desc.film)
}

/// What a task produces: the tile's fixed-point sums and its counters.
#[derive(Debug, Clone, PartialEq)]
pub struct TaskOutput {
    pub sums: TileSums,
    pub stats: RayStats,
}

/// Stitches a frame from its task outputs, given in the order of [`plan_frame`]: the sample
/// ranges of each tile are merged in order, tiles put in place, counters summed.
pub fn stitch<'a>(
    width: u32,
    height: u32,
    outputs: impl IntoIterator<Item = &'a TaskOutput>,
) -> (Image, RayStats) {
    let (tiles, stats) = merge_tiles(outputs);
    (Image::from_tiles(width, height, &tiles), stats)
}

/// Merges task outputs given in stitch order into one sum per tile (in tile order), and adds
/// their counters.
pub fn merge_tiles<'a>(
    outputs: impl IntoIterator<Item = &'a TaskOutput>,
) -> (Vec<TileSums>, RayStats) {
    let mut tiles: Vec<TileSums> = Vec::new();
    let mut stats = RayStats::default();
    for out in outputs {
        stats.add(&out.stats);
        match tiles.last_mut() {
            Some(sums) if sums.tile == out.sums.tile => sums.merge(&out.sums),
            _ => tiles.push(out.sums.clone()),
        }
    }
    (tiles, stats)
}

/// The EXR metadata of a frame: what determines it and what was dropped. No times or hosts,
/// so the file's bytes depend only on the job.
pub fn frame_metadata(
    desc: &SceneDesc,
    frame: u32,
    stats: &RayStats,
    extra: &[(String, String)],
) -> ExrMetadata {
    let i = &desc.integrator;
    let analysis = tessera_render::analysis::analyze(desc);
    let integrator = match i.kind {
        IntegratorKind::Auto => format!("auto: {:?}", analysis.integrator),
        kind => format!("{kind:?}"),
    };
    let decisions: Vec<String> = analysis.decisions.iter().map(|d| d.to_string()).collect();
    let mut entries = vec![
        ("scene".to_string(), desc.name.clone()),
        ("integrator".into(), integrator.to_lowercase()),
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
            stats.nonfinite.to_string(),
        ),
    ];
    if desc.camera_path.is_some() {
        entries.push(("frame".into(), frame.to_string()));
    }
    entries.extend_from_slice(extra);
    ExrMetadata { entries }
}

/// `frame_0001.exr`: the file name of a frame of a sequence.
pub fn frame_file_name(frame: u32) -> String {
    format!("frame_{frame:04}.exr")
}

/// Writes a stitched frame as EXR (with `extra` metadata entries), and its PNG preview beside it.
pub fn write_frame(
    path: &Path,
    desc: &SceneDesc,
    frame: u32,
    image: &Image,
    stats: &RayStats,
    extra: &[(String, String)],
) -> Result<(), tessera_render::RenderError> {
    write_exr(path, image, &frame_metadata(desc, frame, stats, extra))?;
    write_png(&path.with_extension("png"), image)
}

/// What the core will do with a scene, with reasons, for logs, the EXR header and the job
/// status (DESIGN invariant 4).
pub fn decisions(desc: &SceneDesc) -> Vec<String> {
    let i = &desc.integrator;
    let mut out: Vec<String> = tessera_render::analysis::analyze(desc)
        .decisions
        .iter()
        .map(|d| d.to_string())
        .collect();
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

    #[test]
    fn index_ranges_cover_the_count_in_order() {
        let t: Vec<TaskSpec> =
            TaskSpec::index_ranges(TaskKind::GlobalPhotons, 60_001, 25_000, 5).collect();
        let ranges: Vec<(u32, u32, u32)> = t
            .iter()
            .map(|t| (t.tile_index, t.sample_start, t.sample_end))
            .collect();
        assert_eq!(
            ranges,
            [(5, 0, 25_000), (6, 25_000, 50_000), (7, 50_000, 60_001)]
        );
        assert!(
            t.iter()
                .all(|t| t.kind == TaskKind::GlobalPhotons && t.tile().x1 == 0)
        );
        assert_eq!(
            TaskSpec::index_ranges(TaskKind::Records, 0, 10, 0).count(),
            0
        );
        // The last range ends at the count even where start + per_task would overflow.
        let last = TaskSpec::index_ranges(TaskKind::Records, u32::MAX, u32::MAX - 1, 0).last();
        assert_eq!(
            last.map(|t| (t.sample_start, t.sample_end)),
            Some((u32::MAX - 1, u32::MAX))
        );
    }

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

    /// The Cornell box, 24×20 at 5 spp.
    pub(crate) fn cornell() -> SceneDesc {
        scene("cornell-box", 5)
    }

    #[test]
    fn any_split_into_tasks_stitches_to_the_same_image() {
        let desc = cornell();
        let prepared = Prepared::new(desc.clone(), FrameRange::single(1));
        let frame = |settings: &RenderSettings| {
            let tasks = plan_frame(&desc, settings, 1);
            let outs: Vec<TaskOutput> = tasks.iter().map(|t| prepared.execute(t)).collect();
            stitch(desc.film.width, desc.film.height, &outs)
        };
        let whole = frame(&RenderSettings {
            tile: Some(64),
            ..Default::default()
        });
        let split = frame(&RenderSettings {
            tile: Some(7),
            samples_per_task: Some(2),
            ..Default::default()
        });
        assert_eq!(whole, split);
        assert_eq!(whole.1.samples, 24 * 20 * 5);
    }

    #[test]
    fn plans_cover_every_pixel_sample_once_in_stitch_order() {
        let desc = cornell();
        let tasks = plan_frame(
            &desc,
            &RenderSettings {
                tile: Some(10),
                samples_per_task: Some(2),
                ..Default::default()
            },
            3,
        );
        // 3×2 tiles, samples 0-2, 2-4, 4-5.
        assert_eq!(tasks.len(), 6 * 3);
        assert!(tasks.iter().all(|t| t.frame == 3));
        assert!(
            tasks.windows(2).all(
                |w| (w[0].tile_index, w[0].sample_start) < (w[1].tile_index, w[1].sample_start)
            )
        );
        let samples: u64 = tasks
            .iter()
            .map(|t| t.tile().pixel_count() as u64 * (t.sample_end - t.sample_start) as u64)
            .sum();
        assert_eq!(samples, 24 * 20 * 5);
    }

    #[test]
    fn settings_are_checked_against_limits_and_frames() {
        let limits = Limits {
            max_resolution: 16,
            ..Default::default()
        };
        let mut d = cornell();
        let err = apply(
            &mut d,
            &RenderSettings::default(),
            FrameRange::single(1),
            &limits,
        )
        .unwrap_err();
        assert!(err.contains("film") && err.contains("16×16"), "{err}");
        let mut d = cornell();
        let err = apply(
            &mut d,
            &RenderSettings {
                spp: Some(0),
                ..Default::default()
            },
            FrameRange::single(1),
            &Limits::default(),
        )
        .unwrap_err();
        assert!(err.starts_with("spp"), "{err}");
        let mut d = cornell();
        let err = apply(
            &mut d,
            &RenderSettings::default(),
            FrameRange { first: 1, last: 3 },
            &Limits::default(),
        )
        .unwrap_err();
        assert!(err.contains("no camera path"), "{err}");
        assert_eq!(
            FrameRange::parse("2-24"),
            Ok(FrameRange { first: 2, last: 24 })
        );
        assert!(FrameRange::parse("0").is_err() && FrameRange::parse("5-2").is_err());
    }
}
