//! `tessera render`: one machine, all its cores.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use tessera_farm::job::{self, FrameRange, Limits, Prepared, RenderSettings, TaskOutput};
use tessera_farm::progressive::{Adaptive, render_adaptive};

#[derive(clap::Args)]
pub struct RenderArgs {
    /// The scene file (scene.json); meshes and images it names are read from its folder.
    pub scene: PathBuf,
    /// Output OpenEXR file; a PNG preview is written beside it. Default: <scene folder>.exr.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Samples per pixel (overrides the scene's integrator.spp).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Tile size in pixels; it does not change the image, only the work units.
    #[arg(long, default_value_t = job::DEFAULT_TILE)]
    pub tile: u32,
    /// Random seed (overrides the scene's integrator.seed).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Film size WxH (overrides the scene's film; the vertical field of view is kept).
    #[arg(long)]
    pub size: Option<Size>,
    /// The integrator: path, direct, auto, photon, sppm, bdpt, pssmlt, mlt or vcm (overrides
    /// the scene's integrator.type).
    #[arg(long)]
    pub integrator: Option<tessera_farm::job::IntegratorName>,
    /// Translucent materials: dipole (the sampled BSSRDF), hierarchical (Jensen & Buhler's point
    /// cloud) or random-walk (the brute-force reference); overrides the scene's
    /// integrator.subsurface.
    #[arg(long, value_parser = parse_subsurface)]
    pub subsurface: Option<tessera_scene::SubsurfaceMethod>,
    /// The frame of the scene's camera path to render (1-based).
    #[arg(long, default_value_t = 1)]
    pub frame: u32,
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
    /// BDPT only: also write each strategy (s, t) of depth ≤ 5 into this folder, MIS-weighted
    /// (`d1_s2_t1.exr`) and unweighted (`d1_s2_t1_unweighted.exr`), for debugging.
    #[arg(long)]
    pub strategies: Option<PathBuf>,
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

/// Renders one frame in this process, through the same plan → tasks → stitch path as the
/// farm (`tessera_farm::job`), with the tasks spread over a thread pool.
pub fn run(args: RenderArgs) -> anyhow::Result<()> {
    let start = Instant::now();
    let mut desc = tessera_scene::load(&args.scene)?;
    let settings = RenderSettings {
        spp: args.spp,
        seed: args.seed,
        tile: Some(args.tile),
        samples_per_task: None,
        size: args.size.map(|s| s.0),
        target_error: args.target_error,
        integrator: args.integrator,
        reuse: None,
    };
    let frame = args.frame;
    job::apply(
        &mut desc,
        &settings,
        FrameRange::single(frame),
        &Limits::default(),
    )
    .map_err(|e| anyhow::anyhow!("{}: {e}", args.scene.display()))?;
    if let Some(m) = args.subsurface {
        desc.integrator.subsurface = m;
    }
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| default_output(&args.scene));

    let threads = args
        .threads
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    anyhow::ensure!(threads >= 1, "--threads: expected at least 1");
    if let Some(t) = args.time_limit {
        anyhow::ensure!(
            t > 0.0 && t.is_finite(),
            "--time-limit: expected positive seconds, got {t}"
        );
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("cannot start worker threads")?;

    let load_time = start.elapsed();
    let tasks = job::plan_frame(&desc, &settings, frame);
    let prepared = pool.install(|| Prepared::new(desc, FrameRange::single(frame)));
    let build_time = prepared.build_seconds;
    let desc = &prepared.desc;
    let stats = &prepared.scene.stats;
    tracing::info!(
        scene = %desc.name,
        triangles = stats.triangles,
        spheres = stats.spheres,
        lights = stats.lights,
        emissive_triangles = stats.emissive_triangles,
        load_s = load_time.as_secs_f64(),
        build_s = build_time,
        "scene ready"
    );
    let (w, h, spp) = (desc.film.width, desc.film.height, desc.integrator.spp);
    let analysis = &prepared.analysis;
    for d in &analysis.decisions {
        tracing::info!(topic = d.topic, choice = %d.choice, reason = %d.reason, "decision");
    }
    for p in &prepared.passes {
        tracing::info!(pass = %p, "pass");
    }

    let progress = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(w as u64 * h as u64)
    };
    progress.set_style(
        ProgressStyle::with_template(
            "{spinner} {wide_bar} {percent:>3}% {elapsed_precise} eta {eta}",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let rendering = Instant::now();
    let cpu_start = cpu_seconds();
    let camera = prepared.camera(frame);
    let adaptive = (args.target_error.is_some() || args.time_limit.is_some()).then(|| Adaptive {
        target_rel_mse: args.target_error,
        time_limit: args.time_limit.map(std::time::Duration::from_secs_f64),
        first_spp: job::ADAPTIVE_FIRST_SPP.min(spp),
        max_spp: spp,
    });
    let kind = analysis.integrator;
    let (sppm, bdpt) = (
        kind == tessera_scene::IntegratorKind::Sppm,
        tessera_farm::bdpt::sample_ranges(kind),
    );
    let metropolis = tessera_render::integrator::metropolis::Metropolis::new(kind, desc);
    // Adaptive sampling refines tiles; these refine every pixel at once.
    anyhow::ensure!(
        !(kind.whole_frame() && adaptive.is_some()),
        "--target-error/--time-limit: {} renders whole frames, not tiles; give --spp (samples, or sppm's iterations) instead",
        format!("{kind:?}").to_lowercase()
    );
    anyhow::ensure!(
        args.strategies.is_none() || kind == tessera_scene::IntegratorKind::Bdpt,
        "--strategies: per-strategy images are BDPT's; give --integrator bdpt"
    );
    let (image, stats, extra, spp_text) = match &adaptive {
        None if sppm => {
            use tessera_render::integrator::sppm::{self, SppmSettings};
            let (settings, s) = SppmSettings::resolve(desc, analysis);
            progress.set_length(spp as u64);
            let (image, stats) = pool.install(|| {
                sppm::render(&prepared.scene, &camera, &settings, &s, &|_| {
                    progress.inc(1)
                })
            });
            let text = s.describe();
            (image, stats, tessera_farm::sppm::metadata(&s), text)
        }
        None if bdpt => {
            let range = tessera_render::SampleRange { start: 0, end: spp };
            let (sums, stats) = pool
                .install(|| {
                    tessera_farm::bdpt::render_range(&prepared, &camera, range, &|n| {
                        progress.inc(n)
                    })
                })
                .map_err(anyhow::Error::msg)?;
            let name = format!("{kind:?}").to_lowercase();
            let image = sums.image(camera.exposure);
            if let Some(dir) = &args.strategies {
                pool.install(|| write_strategies(dir, &prepared, &camera, range))?;
            }
            (image, stats, Vec::new(), format!("{spp} spp, {name}"))
        }
        None if metropolis.is_some() => {
            let m = metropolis.expect("checked");
            progress.set_length(spp as u64 * w as u64 * h as u64);
            let (image, stats) = pool
                .install(|| m.render(&prepared.scene, &camera, spp, &|n| progress.inc(n)))
                .map_err(anyhow::Error::msg)?;
            // No settings in the EXR: the farm's frame of the same job is the same file.
            (image, stats, Vec::new(), m.describe(spp))
        }
        None => {
            let outputs: Vec<TaskOutput> = pool.install(|| {
                tasks
                    .par_iter()
                    .map(|task| {
                        let out = prepared.execute_with(&camera, task);
                        progress.inc(out.sums.tile.pixel_count() as u64);
                        out
                    })
                    .collect()
            });
            let (image, stats) = job::stitch(w, h, &outputs);
            (image, stats, Vec::new(), format!("{spp} spp"))
        }
        Some(rule) => {
            progress.set_length(0);
            let r = pool.install(|| render_adaptive(&prepared, &camera, args.tile, rule));
            let text = format!(
                "adaptive {}–{} spp in {} rounds ({}; estimated relMSE {:.3e})",
                r.spp_min, r.spp_max, r.rounds, r.stopped, r.estimated_rel_mse
            );
            (r.image, r.stats, r.metadata, text)
        }
    };
    let render_s = rendering.elapsed().as_secs_f64();
    let cpu_s = cpu_seconds().zip(cpu_start).map(|(b, a)| b - a);
    progress.finish_and_clear();

    job::write_frame(&output, desc, frame, &image, &stats, &extra)?;
    let preview = output.with_extension("png");

    let mut report = format!("{}: {w}×{h}, {spp_text}, {threads} threads\n", desc.name);
    if let Some(d) = analysis.decisions.first() {
        report += &format!("{d}\n");
    }
    for p in &prepared.passes {
        report += &format!("{p}\n");
    }
    report += &format!(
        "render {render_s:.2} s wall{}; {:.3} M samples/s, {:.2} M rays/s\n",
        cpu_s.map(|c| format!(", {c:.2} s CPU")).unwrap_or_default(),
        stats.samples as f64 / render_s / 1e6,
        stats.rays as f64 / render_s / 1e6,
    );
    report += &format!(
        "setup {:.2} s (load {:.2} s, BVH, lights and passes {:.2} s)\n",
        load_time.as_secs_f64() + build_time,
        load_time.as_secs_f64(),
        build_time
    );
    if stats.nonfinite > 0 {
        report += &format!(
            "dropped {} non-finite samples (NaN/Inf) before the film\n",
            stats.nonfinite
        );
    }
    report += &format!("wrote {} and {}\n", output.display(), preview.display());
    crate::print(&report)
}

/// `--strategies DIR`: BDPT's per-strategy images of depth ≤ 5.
fn write_strategies(
    dir: &Path,
    prepared: &Prepared,
    camera: &tessera_render::camera::Camera,
    range: tessera_render::SampleRange,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| dir.display().to_string())?;
    let bdpt = tessera_render::integrator::bdpt::Bdpt::new(&prepared.desc);
    let images = bdpt
        .render_strategies(&prepared.scene, camera, range, 5)
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

/// CPU time of this process (user + system), where the platform tells it.
pub(crate) fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
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
