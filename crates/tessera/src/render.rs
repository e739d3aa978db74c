//! `tessera render`: one machine, all its cores — the farm in one process.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use tessera_render::job::{self, FrameRange, Limits, RenderSettings};
use tessera_render::method::auto::Choice;
use tessera_render::method::local::{Local, Progress};
use tessera_scene::{Problem, SceneDesc, SceneError};

#[derive(clap::Args)]
pub struct RenderArgs {
    /// The scene file (scene.json); meshes and images it names are read from its folder.
    pub scene: PathBuf,
    /// Output OpenEXR file; a PNG preview is written beside it. Default: <scene folder>.exr.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Samples per pixel (overrides the scene's integrator.spp; what a sample is depends on
    /// the method).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Tile size in pixels (default: 32, doubled until a frame has at most 600 tiles); it does
    /// not change the image, only the work units (but for adaptive sampling, which refines
    /// tiles).
    #[arg(long)]
    pub tile: Option<u32>,
    /// Samples (iterations) per task where the method cuts frames by samples, as a farm job
    /// may ask (each task's sums are rounded to f32 once, so the same job cut alike is the
    /// same image on a farm and here).
    #[arg(long)]
    pub samples_per_task: Option<u32>,
    /// Random seed (overrides the scene's integrator.seed).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Film size WxH (overrides the scene's film; the vertical field of view is kept).
    #[arg(long)]
    pub size: Option<Size>,
    /// The rendering method (overrides the scene's integrator.type): one of the registry's,
    /// listed by `tessera methods`.
    #[arg(long, value_parser = parse_method)]
    pub integrator: Option<String>,
    /// Translucent materials: dipole (the sampled BSSRDF), hierarchical (Jensen & Buhler's point
    /// cloud) or random-walk (the brute-force reference); overrides the scene's
    /// integrator.subsurface.
    #[arg(long, value_parser = parse_subsurface)]
    pub subsurface: Option<tessera_scene::SubsurfaceMethod>,
    /// The frame of the scene's camera path to render (1-based).
    #[arg(long, default_value_t = 1)]
    pub frame: u32,
    /// Replays a choice `auto` made before (JSON, as in a farm job's `settings.choice`)
    /// instead of measuring anew: the same method, settings and header, so the same image.
    #[arg(long, value_parser = parse_choice)]
    pub auto_choice: Option<Choice>,
    /// Adaptive sampling: stop when the relMSE estimated from the film's own variance is at
    /// most this; samples go to the noisiest tiles. --spp becomes the per-pixel maximum.
    #[arg(long)]
    pub target_error: Option<f64>,
    /// Adaptive sampling: start no new round after this many seconds.
    #[arg(long)]
    pub time_limit: Option<f64>,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
    /// Also write each of BDPT's strategies (s, t) of depth ≤ 5 into this folder, at the job's
    /// spp and whatever method renders the image, MIS-weighted (`d1_s2_t1.exr`) and
    /// unweighted (`d1_s2_t1_unweighted.exr`), for debugging.
    #[arg(long)]
    pub strategies: Option<PathBuf>,
}

/// A method name of the registry.
pub fn parse_method(s: &str) -> Result<String, String> {
    tessera_render::method::lookup(s)
        .map(|m| m.name.to_string())
        .map_err(|e| e.trim_start_matches("integrator.type: ").to_string())
}

/// A recorded `auto` choice (JSON).
fn parse_choice(s: &str) -> Result<Choice, String> {
    serde_json::from_str(s).map_err(|e| format!("expected the JSON of an auto choice: {e}"))
}

/// A subsurface method by name (`dipole`, `hierarchical`, `random-walk` or `random_walk`).
pub fn parse_subsurface(s: &str) -> Result<tessera_scene::SubsurfaceMethod, String> {
    use tessera_scene::SubsurfaceMethod;
    match s.trim().to_ascii_lowercase().replace('-', "_").as_str() {
        "dipole" => Ok(SubsurfaceMethod::Dipole),
        "hierarchical" => Ok(SubsurfaceMethod::Hierarchical),
        "random_walk" => Ok(SubsurfaceMethod::RandomWalk),
        other => Err(format!(
            "unknown subsurface method \"{other}\"; expected dipole, hierarchical or random-walk"
        )),
    }
}

/// A bad job setting as a scene error (exit code 2), naming the scene file.
pub fn setting_error(scene: &Path, message: String) -> anyhow::Error {
    let (path, message) = match message.split_once(": ") {
        Some((field, rest)) if !field.contains(' ') => (field.to_string(), rest.to_string()),
        _ => (String::new(), message),
    };
    SceneError::Invalid(vec![Problem {
        file: scene.to_path_buf(),
        path,
        message,
    }])
    .into()
}

/// The scene of `args` (loaded in `load_s` seconds) and its job compiled in this process:
/// the settings applied and checked, `auto` measured here with `threads` threads where the
/// job asks for it, the method planned.
pub fn compile(args: &RenderArgs, threads: usize) -> anyhow::Result<(job::Compiled, f64)> {
    let loading = Instant::now();
    let mut desc = tessera_scene::load(&args.scene)?;
    let load_s = loading.elapsed().as_secs_f64();
    if let Some(m) = args.subsurface {
        desc.integrator.subsurface = m;
    }
    let settings = RenderSettings {
        spp: args.spp,
        seed: args.seed,
        tile: args.tile,
        samples_per_task: args.samples_per_task,
        size: args.size.map(|s| s.0),
        target_error: args.target_error,
        integrator: args.integrator.clone(),
        choice: args.auto_choice.clone(),
        reuse: None,
    };
    let time_limit = match args.time_limit {
        Some(t) => {
            anyhow::ensure!(
                t > 0.0 && t.is_finite(),
                "--time-limit: expected positive seconds, got {t}"
            );
            Some(Duration::from_secs_f64(t))
        }
        None => None,
    };
    let limits = Limits::default();
    let options = job::Options {
        limits: &limits,
        choose: job::Choose::Measure { threads },
        time_limit,
    };
    let compiled = job::compile(desc, &settings, FrameRange::single(args.frame), options)
        .map_err(|e| setting_error(&args.scene, e))?;
    if let Some((selection, _)) = &compiled.measured {
        for line in &selection.choice.report {
            tracing::info!(choice = %line, "auto");
        }
    }
    Ok((compiled, load_s))
}

/// Sizes the rayon pool that tasks which parallelise themselves use (once per process).
pub fn threads(threads: Option<usize>) -> anyhow::Result<usize> {
    let threads =
        threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    anyhow::ensure!(threads >= 1, "--threads: expected at least 1");
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global()
        .context("cannot start worker threads")?;
    Ok(threads)
}

/// A progress bar fed by [`Local`]'s progress.
pub fn progress_bar(quiet: bool) -> ProgressBar {
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(0)
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} {msg:>10} {wide_bar} {percent:>3}% {elapsed_precise} eta {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
}

/// Moves `bar` on with `p`.
pub fn show(bar: &ProgressBar, p: Progress) {
    match p {
        Progress::Start { pass, work } => {
            bar.set_message(pass.unwrap_or("frame"));
            bar.set_position(0);
            bar.set_length(work);
        }
        Progress::Done(n) => bar.inc(n),
    }
}

/// Renders one frame in this process, through the same plan → tasks → fold as the farm
/// (`tessera_render::method::local`).
pub fn run(args: RenderArgs) -> anyhow::Result<()> {
    let threads = threads(args.threads)?;
    let building = Instant::now();
    let (compiled, load_s) = compile(&args, threads)?;
    let job::Compiled {
        job,
        plan,
        measured,
        unread,
        ..
    } = compiled;
    let desc = &job.desc;
    for u in &unread {
        tracing::warn!("{u}");
    }
    let (scene, built, pilot_s) = match measured {
        Some((s, scene)) => (scene, s.artifacts, Some((s.pilot_s, s.handed_s))),
        None => (tessera_render::Scene::build(&desc), Vec::new(), None),
    };
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| default_output(&args.scene));
    let stats = &scene.stats;
    tracing::info!(
        scene = %desc.name,
        triangles = stats.triangles,
        spheres = stats.spheres,
        lights = stats.lights,
        emissive_triangles = stats.emissive_triangles,
        load_s,
        build_s = building.elapsed().as_secs_f64() - load_s,
        "scene ready"
    );
    let spp = job.choice.as_ref().map_or(desc.integrator.spp, |c| c.spp);
    let (w, h) = (desc.film.width, desc.film.height);
    let analysis = tessera_render::analysis::analyze(&desc);
    for d in &analysis.decisions {
        tracing::info!(topic = d.topic, choice = %d.choice, reason = %d.reason, "decision");
    }
    for d in plan.decisions() {
        tracing::info!(decision = %d, "method");
    }
    let bar = progress_bar(args.quiet);
    let progress = |p: Progress| show(&bar, p);
    let local = Local::new(plan.as_ref(), &scene, &desc, threads, &progress).with_artifacts(built);
    let passes = local.passes().map_err(anyhow::Error::msg)?;
    let build_time = building.elapsed().as_secs_f64() - load_s;
    let rendering = Instant::now();
    let cpu_start = cpu_seconds();
    let done = local.frame(args.frame).map_err(anyhow::Error::msg)?;
    let render_s = rendering.elapsed().as_secs_f64();
    let cpu_s = cpu_seconds().zip(cpu_start).map(|(b, a)| b - a);
    bar.finish_and_clear();
    if let Some(dir) = &args.strategies {
        let camera = tessera_render::camera::Camera::new(&desc.camera_at(args.frame), &desc.film);
        write_strategies(dir, &desc, &scene, &camera, spp)?;
    }
    job::write_frame(&output, &desc, plan.as_ref(), args.frame, &done)?;
    let preview = output.with_extension("png");

    let meta = |k: &str| {
        done.metadata
            .iter()
            .find(|(key, _)| key == k)
            .map(|(_, v)| v.as_str())
    };
    let spp_text = match (meta("adaptive_spp_min"), meta("adaptive_spp_max")) {
        (Some(lo), Some(hi)) => format!(
            "adaptive {lo}–{hi} spp in {} rounds ({}; estimated relMSE {})",
            meta("adaptive_rounds").unwrap_or("?"),
            meta("adaptive_stopped").unwrap_or("?"),
            meta("estimated_rel_mse").unwrap_or("?")
        ),
        _ => format!("{spp} spp"),
    };
    let mut report = format!(
        "{}: {w}×{h}, {}, {spp_text}, {threads} threads\n",
        desc.name,
        plan.method()
    );
    match &job.choice {
        Some(c) => {
            for line in &c.report {
                report += &format!("auto: {line}\n");
            }
        }
        None => {
            if let Some(d) = analysis.decisions.first() {
                report += &format!("{d}\n");
            }
        }
    }
    for w in desc.warnings.iter().chain(&unread) {
        report += &format!("warning: {w}\n");
    }
    if let Some(r) = meta("reproducible") {
        report += &format!("reproducible: {r}\n");
    }
    for p in &passes {
        report += &format!("{p}\n");
    }
    let stats = done.stats;
    report += &format!(
        "render {render_s:.2} s wall{}; {:.3} M samples/s, {:.2} M rays/s\n",
        cpu_s.map(|c| format!(", {c:.2} s CPU")).unwrap_or_default(),
        stats.samples as f64 / render_s / 1e6,
        stats.rays as f64 / render_s / 1e6,
    );
    let pilot = pilot_s.map_or(0.0, |(p, _)| p);
    report += &format!(
        "setup {:.2} s (load {:.2} s, BVH, lights and passes {:.2} s{})\n",
        load_s + build_time,
        load_s,
        build_time - pilot,
        pilot_s
            .map(|(p, handed)| format!(
                ", auto's pilot {p:.2} s{}",
                tessera_render::method::auto::pilot::handed_on(handed)
            ))
            .unwrap_or_default()
    );
    if stats.nonfinite > 0 {
        report += &format!(
            "dropped {} non-finite samples (NaN/Inf) before the film\n",
            stats.nonfinite
        );
    }
    if let Some(mib) = peak_rss_mib() {
        report += &format!("peak resident memory {mib:.0} MiB\n");
    }
    if scene.stats.texture_bytes > 0 {
        report += &format!(
            "textures {:.1} MiB (mip-map pyramids, each image once)\n",
            scene.stats.texture_bytes as f64 / (1 << 20) as f64
        );
    }
    report += &format!("wrote {} and {}\n", output.display(), preview.display());
    crate::print(&report)
}

/// `--strategies DIR`: BDPT's per-strategy images of depth ≤ 5.
fn write_strategies(
    dir: &Path,
    desc: &SceneDesc,
    scene: &tessera_render::Scene,
    camera: &tessera_render::camera::Camera,
    spp: u32,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| dir.display().to_string())?;
    let bdpt = tessera_render::integrator::bdpt::Bdpt::new(desc);
    let range = tessera_render::SampleRange { start: 0, end: spp };
    let images = bdpt
        .render_strategies(scene, camera, range, 5)
        .map_err(anyhow::Error::msg)?;
    let meta = tessera_render::output::ExrMetadata::default();
    for i in &images {
        let name = format!("d{}_s{}_t{}", i.s + i.t - 2, i.s, i.t);
        tessera_render::output::write_exr(&dir.join(format!("{name}.exr")), &i.weighted, &meta)?;
        let unweighted = dir.join(format!("{name}_unweighted.exr"));
        tessera_render::output::write_exr(&unweighted, &i.unweighted, &meta)?;
    }
    crate::print(&format!(
        "wrote {} strategy images into {}\n",
        2 * images.len(),
        dir.display()
    ))
}

fn default_output(scene: &Path) -> PathBuf {
    let name = scene
        .canonicalize()
        .ok()
        .and_then(|p| {
            p.parent()
                .and_then(|d| d.file_name())
                .map(|n| n.to_os_string())
        })
        .unwrap_or_else(|| "render".into());
    PathBuf::from(name).with_extension("exr")
}

/// Peak resident memory of this process (`VmHWM`), MiB, where the platform tells it.
pub(crate) fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

/// CPU time of this process (user + system), where the platform tells it.
pub(crate) fn cpu_seconds() -> Option<f64> {
    process_cpu_seconds("self")
}

/// CPU time (user + system) of the process `pid` (a number, or `self`), seconds, where the
/// platform tells it.
pub(crate) fn process_cpu_seconds(pid: &str) -> Option<f64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // Fields after the command name (which is in parentheses and may contain spaces).
    let rest = &stat[stat.rfind(')')? + 2..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = fields.get(11)?.parse::<f64>().ok()? + fields.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

/// A film size given as `WxH`.
#[derive(Debug, Clone, Copy)]
pub struct Size(pub [u32; 2]);

impl std::str::FromStr for Size {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("expected a size like 640x480, got \"{s}\"");
        let (w, h) = s.split_once(['x', 'X', '×']).ok_or_else(bad)?;
        let w: u32 = w.trim().parse().map_err(|_| bad())?;
        let h: u32 = h.trim().parse().map_err(|_| bad())?;
        if w == 0 || h == 0 {
            return Err(bad());
        }
        Ok(Size([w, h]))
    }
}
