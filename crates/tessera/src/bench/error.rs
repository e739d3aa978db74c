//! Speed against error: a scene rendered with each method at increasing budgets, each
//! checkpoint compared with a reference. One progressive render per method and seed where the
//! method can continue a frame (the frame's state takes each further range of samples, so the
//! time to reach a checkpoint is the render time so far); a fresh render per budget where it
//! cannot (Markov chains).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, ensure};
use serde::Serialize;
use tessera_farm::job::{self, FrameRange, Limits, RenderSettings};
use tessera_render::method::Plan;
use tessera_render::method::auto::pilot;
use tessera_render::method::local::{Local, Progress};
use tessera_render::metrics;
use tessera_scene::SubsurfaceMethod;

#[derive(clap::Args)]
pub struct ErrorArgs {
    /// The scene file (scene.json).
    pub scene: Option<PathBuf>,
    /// The converged reference image (OpenEXR). Its size is the size rendered (the scene's
    /// vertical field of view is kept, as `tessera reference --size` does).
    #[arg(long)]
    pub reference: Option<PathBuf>,
    /// Integrators to compare, comma-separated: path, direct, auto, photon, sppm (whose
    /// sample budgets are iterations), bdpt, pssmlt, mlt, vcm; a suffix picks how translucent
    /// materials are rendered: `path:dipole`, `path:random-walk`.
    #[arg(long, value_delimiter = ',', default_value = "path,direct")]
    pub integrators: Vec<String>,
    /// Budgets, comma-separated and increasing: samples per pixel (`64`) or seconds of wall
    /// time (`30s`).
    #[arg(long, value_delimiter = ',', default_value = "4,16,64,256,1024")]
    pub budgets: Vec<String>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Renders each integrator with this many seeds (the scene's `integrator.seed`, then the
    /// next ones). A time to an error is then the time by which half of the seeds had reached
    /// it: one seed's time can hang on a single pixel (a highlight only a few samples find).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub seeds: u32,
    /// Stop a method's checkpoints once its relMSE against the reference is at most this (the
    /// later budgets are not rendered): for a time to one error, not the whole curve.
    #[arg(long)]
    pub until: Option<f64>,
    /// Where report.json, report.csv, report.md and report.png go.
    #[arg(short, long, default_value = "bench-report")]
    pub output: PathBuf,
}

/// Error levels (relMSE) whose time to reach the report gives.
const LEVELS: [f64; 4] = [1e-2, 3e-3, 1e-3, 3e-4];

#[derive(Debug, Clone, Copy, PartialEq)]
enum Budget {
    Samples(u32),
    Seconds(f64),
}

fn parse_budget(s: &str) -> anyhow::Result<Budget> {
    let t = s.trim();
    if let Some(secs) = t.strip_suffix('s') {
        let v: f64 = secs
            .parse()
            .ok()
            .filter(|v: &f64| *v > 0.0 && v.is_finite())
            .with_context(|| format!("--budgets: expected seconds like 30s, got \"{s}\""))?;
        return Ok(Budget::Seconds(v));
    }
    let v: u32 = t.parse().ok().filter(|v| *v >= 1).with_context(|| {
        format!("--budgets: expected samples per pixel (≥ 1) or seconds like 30s, got \"{s}\"")
    })?;
    Ok(Budget::Samples(v))
}

/// A method of `--integrators`, with its subsurface method if it names one.
fn integrator_kind(name: &str) -> anyhow::Result<(String, Option<SubsurfaceMethod>)> {
    let (kind, method) = match name.trim().split_once(':') {
        Some((k, m)) => (
            k,
            Some(
                crate::render::parse_subsurface(m)
                    .map_err(|e| anyhow::anyhow!("--integrators: {e}"))?,
            ),
        ),
        None => (name.trim(), None),
    };
    let kind =
        crate::render::parse_method(kind).map_err(|e| anyhow::anyhow!("--integrators: {e}"))?;
    Ok((kind, method))
}

/// One checkpoint of one integrator.
#[derive(Debug, Clone, Serialize)]
pub struct Run {
    pub integrator: String,
    pub seed: u64,
    pub budget: String,
    pub spp: u32,
    pub wall_s: f64,
    pub cpu_s: Option<f64>,
    pub rel_mse: f64,
    pub rmse: f64,
    pub mean_ratio: f64,
    /// relMSE estimated from the render's own per-pixel variance (no reference needed);
    /// `None` for SPPM, which keeps no per-pixel variance.
    pub estimated_rel_mse: Option<f64>,
}

/// Wall seconds an integrator needed to reach an error level (log-log interpolation between
/// checkpoints; the first time it did): with each seed, and the time by which half of the
/// seeds had (the lower median; `None` if fewer than half ever did within the budgets).
#[derive(Debug, Clone, Serialize)]
pub struct TimeToError {
    pub integrator: String,
    pub rel_mse: f64,
    pub wall_s: Option<f64>,
    /// In the order of [`Report::seeds`].
    pub per_seed: Vec<Option<f64>>,
}

#[derive(Debug, Serialize)]
struct Report {
    scene: String,
    reference: String,
    width: u32,
    height: u32,
    threads: usize,
    /// In the order given.
    integrators: Vec<String>,
    seeds: Vec<u64>,
    runs: Vec<Run>,
    time_to_error: Vec<TimeToError>,
    /// What `auto` chose with each seed, measuring for relMSE 1e-2.
    auto: Vec<AutoChoice>,
}

/// `auto`'s pilot in one run of the bench: its clock includes it.
#[derive(Debug, Serialize)]
struct AutoChoice {
    seed: u64,
    chosen: String,
    pilot_s: f64,
    /// Of which the render's own work (passes, photons), handed on to it.
    handed_s: f64,
    report: Vec<String>,
}

pub fn run(args: ErrorArgs) -> anyhow::Result<()> {
    let scene_path = args.scene.clone().context(
        "bench: expected a scene (tessera bench SCENE --reference REF.exr), or `farm` / `leases`",
    )?;
    let reference_path = args
        .reference
        .clone()
        .context("--reference: expected a converged reference EXR of the scene")?;
    let budgets: Vec<Budget> = args
        .budgets
        .iter()
        .map(|b| parse_budget(b))
        .collect::<anyhow::Result<_>>()?;
    ensure!(
        !budgets.is_empty(),
        "--budgets: expected at least one budget"
    );
    let kinds: Vec<(String, (String, Option<SubsurfaceMethod>))> = args
        .integrators
        .iter()
        .map(|n| Ok((n.trim().to_string(), integrator_kind(n)?)))
        .collect::<anyhow::Result<_>>()?;
    let mut base = tessera_scene::load(&scene_path)?;
    let reference = tessera_render::read_exr(&reference_path)?;
    base.film.width = reference.width;
    base.film.height = reference.height;
    let reference: Vec<glam::Vec3A> = reference.pixels.iter().map(|&p| p.into()).collect();
    let threads = crate::render::threads(args.threads)?;

    let seeds: Vec<u64> = (0..u64::from(args.seeds))
        .map(|i| base.integrator.seed.wrapping_add(i))
        .collect();
    let mut runs = Vec::new();
    let mut auto = Vec::new();
    let noop = |_: Progress| {};
    // Each method renders its first budget once, untimed and at a seed of its own, before its
    // timed runs: each is then timed in a process that has run it, as a farm worker that has
    // rendered before is, rather than the first paying alone for what a process does once
    // (its thread pool, tables built on first use, the allocator's first pages of the film
    // and of the method's own buffers) and the later ones running on what it left.
    const WARM_SEED: u64 = 1 << 32;
    for ((name, (method, subsurface)), seed, warming) in kinds.iter().flat_map(|k| {
        let warm = seeds.first().map(|&s| (k, s.wrapping_add(WARM_SEED), true));
        warm.into_iter()
            .chain(seeds.iter().map(move |&s| (k, s, false)))
    }) {
        let budgets = if warming { &budgets[..1] } else { &budgets[..] };
        let mut desc = base.clone();
        desc.integrator.method = method.clone();
        desc.integrator.seed = seed;
        if let Some(m) = subsurface {
            desc.integrator.subsurface = *m;
        }
        // The clock includes building the scene, `auto`'s pilot and any passes (photon maps,
        // irradiance records): time to an error is time from the scene file.
        let (start, cpu0) = (Instant::now(), crate::render::cpu_seconds());
        let mut scene = tessera_render::Scene::build(&desc);
        let mut built = Vec::new();
        if method == "auto" {
            let goal = pilot::Goal::Error(LEVELS[0]);
            let selection = pilot::select(&desc, &mut scene, 1, goal, threads)
                .map_err(|e| anyhow::anyhow!("--integrators auto: {e}"))?;
            let c = &selection.choice;
            c.apply(&mut desc);
            let chosen = match c.subsurface {
                Some(m) => format!("{}:{}", c.method, pilot::subsurface_name(m)),
                None => c.method.clone(),
            };
            if !warming {
                crate::print(&format!(
                    "{name:>8} chose {chosen} (pilot {:.2} s): {}\n",
                    selection.pilot_s,
                    c.report.join("\n           ")
                ))?;
                auto.push(AutoChoice {
                    seed,
                    chosen,
                    pilot_s: selection.pilot_s,
                    handed_s: selection.handed_s,
                    report: c.report.clone(),
                });
            }
            built = selection.artifacts;
        }
        // The first render goes to the first budget's samples (1 for a time budget); later
        // ones continue it where the method can, else render anew.
        let first = match budgets.first() {
            Some(Budget::Samples(n)) => *n,
            _ => 1,
        };
        let plan_for = |spp: u32| -> anyhow::Result<(tessera_scene::SceneDesc, Box<dyn Plan>)> {
            planned(&desc, spp).map_err(|e| anyhow::anyhow!("--integrators {name}: {e}"))
        };
        let (first_desc, plan) = plan_for(first)?;
        scene.set_settings(&first_desc);
        let local =
            Local::new(plan.as_ref(), &scene, &first_desc, threads, &noop).with_artifacts(built);
        for p in local.passes().map_err(anyhow::Error::msg)? {
            if warming {
                continue;
            }
            crate::print(&format!(
                "{name:>8} pass: {p} ({:.2} s setup)\n",
                start.elapsed().as_secs_f64()
            ))?;
        }
        let setup = (start.elapsed().as_secs_f64(), crate::render::cpu_seconds());
        let mut progressive = Progressive {
            local: &local,
            state: None,
            image: None,
            samples: 0,
            fresh: false,
        };
        // A continued render's clock runs from the start; a fresh one's is the setup plus
        // its last render.
        let mut last = (0.0, None);
        let clock = |last: (f64, Option<f64>), fresh: bool| {
            if fresh {
                (
                    setup.0 + last.0,
                    setup.1.zip(cpu0).zip(last.1).map(|((s, a), l)| s - a + l),
                )
            } else {
                (
                    start.elapsed().as_secs_f64(),
                    crate::render::cpu_seconds().zip(cpu0).map(|(b, a)| b - a),
                )
            }
        };
        for budget in budgets {
            let render = |p: &mut Progressive, n: u32| -> anyhow::Result<(f64, Option<f64>)> {
                let (t0, c0) = (Instant::now(), crate::render::cpu_seconds());
                p.render_to(n, &|spp| plan_for(spp), &scene, threads)?;
                Ok((
                    t0.elapsed().as_secs_f64(),
                    crate::render::cpu_seconds().zip(c0).map(|(b, a)| b - a),
                ))
            };
            match *budget {
                Budget::Samples(n) => last = render(&mut progressive, n)?,
                Budget::Seconds(limit) => {
                    // Double the samples until the wall time reaches the budget (at least one
                    // sample, even when the setup alone took longer).
                    while clock(last, progressive.fresh).0 < limit || progressive.samples == 0 {
                        let next = (progressive.samples * 2).max(progressive.samples + 1);
                        last = render(&mut progressive, next)?;
                    }
                }
            }
            let (wall_s, cpu_s) = clock(last, progressive.fresh);
            let image = progressive.image.as_ref().context("no image rendered")?;
            let rgb: Vec<glam::Vec3A> = image.pixels.iter().map(|p| p.rgb.into()).collect();
            let e = metrics::compare(&rgb, &reference);
            // Without any per-pixel variance (one batch, SPPM) there is no estimate.
            let has_variance = image
                .pixels
                .iter()
                .any(|p| p.variance.iter().any(|&v| v > 0.0));
            let run = Run {
                integrator: name.clone(),
                seed,
                budget: match budget {
                    Budget::Samples(n) => format!("{n} spp"),
                    Budget::Seconds(s) => format!("{s} s"),
                },
                spp: progressive.samples,
                wall_s,
                cpu_s,
                rel_mse: e.rel_mse,
                rmse: e.rmse,
                mean_ratio: e.mean_ratio,
                estimated_rel_mse: has_variance.then(|| metrics::estimated_rel_mse(image)),
            };
            if warming {
                break;
            }
            crate::print(&format!(
                "{:>8}{} {:>6} spp  {:8.2} s wall  relMSE {:.3e} (estimated {})  RMSE {:.3e}  mean/ref {:.4}\n",
                run.integrator,
                if seeds.len() > 1 {
                    format!(" seed {seed}")
                } else {
                    String::new()
                },
                run.spp,
                run.wall_s,
                run.rel_mse,
                estimate(run.estimated_rel_mse),
                run.rmse,
                run.mean_ratio
            ))?;
            let done = args.until.is_some_and(|u| run.rel_mse <= u);
            runs.push(run);
            if done {
                break;
            }
        }
    }
    let time_to_error = time_to_error(&kinds, &seeds, &runs);
    let report = Report {
        scene: scene_path.display().to_string(),
        reference: reference_path.display().to_string(),
        width: base.film.width,
        height: base.film.height,
        threads,
        integrators: kinds.iter().map(|(n, _)| n.clone()).collect(),
        seeds,
        runs,
        time_to_error,
        auto,
    };
    write_report(&args.output, &report)?;
    crate::print(&format!(
        "wrote {0}/report.json, report.csv, report.md and report.png\n",
        args.output.display()
    ))
}

/// Frame 1 of `desc` planned at `spp` samples per pixel, with the settings the plan applied.
fn planned(
    desc: &tessera_scene::SceneDesc,
    spp: u32,
) -> Result<(tessera_scene::SceneDesc, Box<dyn Plan>), String> {
    let settings = RenderSettings {
        spp: Some(spp),
        ..Default::default()
    };
    let limits = Limits::default();
    let c = job::compile(
        desc.clone(),
        &settings,
        FrameRange::single(1),
        job::Options::new(&limits),
    )?;
    Ok((c.job.desc, c.plan))
}

/// A render that can be continued where its method can (tiles, sample ranges, SPPM's
/// iterations: the frame's state takes the further samples), or is rendered anew for each
/// budget (Markov chains).
struct Progressive<'a> {
    local: &'a Local<'a>,
    state: Option<Box<dyn tessera_render::method::Payload>>,
    image: Option<tessera_render::Image>,
    samples: u32,
    /// The method cannot continue a frame.
    fresh: bool,
}

type PlanFor<'a> = dyn Fn(u32) -> anyhow::Result<(tessera_scene::SceneDesc, Box<dyn Plan>)> + 'a;

impl Progressive<'_> {
    fn render_to(
        &mut self,
        n: u32,
        plan_for: &PlanFor,
        scene: &tessera_render::Scene,
        threads: usize,
    ) -> anyhow::Result<()> {
        if !self.fresh {
            if self.state.is_none() {
                let (state, done) = self.local.frame_with_state(1).map_err(anyhow::Error::msg)?;
                self.state = Some(state);
                self.image = Some(done.image);
                self.samples = self.local.desc.integrator.spp;
                if self.samples >= n {
                    return Ok(());
                }
            }
            let state = self.state.as_mut().context("no frame to continue")?;
            match self.local.more(1, state.as_mut(), n) {
                Some(done) => {
                    self.image = Some(done.map_err(anyhow::Error::msg)?.image);
                    self.samples = n;
                    return Ok(());
                }
                None => self.fresh = true,
            }
        }
        let noop = |_: Progress| {};
        let (desc, plan) = plan_for(n)?;
        let local = Local::new(plan.as_ref(), scene, &desc, threads, &noop);
        local.passes().map_err(anyhow::Error::msg)?;
        self.image = Some(local.frame(1).map_err(anyhow::Error::msg)?.image);
        self.samples = n;
        Ok(())
    }
}

/// An estimated relMSE as the report prints it.
fn estimate(e: Option<f64>) -> String {
    e.map_or_else(|| "–".into(), |e| format!("{e:.3e}"))
}

fn time_to_error<T>(kinds: &[(String, T)], seeds: &[u64], runs: &[Run]) -> Vec<TimeToError> {
    let mut out = Vec::new();
    for (name, _) in kinds {
        for &level in &LEVELS {
            let per_seed: Vec<Option<f64>> = seeds
                .iter()
                .map(|&seed| {
                    let points: Vec<&Run> = runs
                        .iter()
                        .filter(|r| &r.integrator == name && r.seed == seed)
                        .collect();
                    first_reached(&points, level)
                })
                .collect();
            out.push(TimeToError {
                integrator: name.clone(),
                rel_mse: level,
                wall_s: half_reached(&per_seed),
                per_seed,
            });
        }
    }
    out
}

/// The first time `points` (one render's checkpoints) reached `level`, interpolating log error
/// against log time between the checkpoints either side.
fn first_reached(points: &[&Run], level: f64) -> Option<f64> {
    let i = points.iter().position(|r| r.rel_mse <= level)?;
    let r = points[i];
    Some(match i.checked_sub(1).map(|j| points[j]) {
        Some(p) if p.rel_mse > level && p.wall_s > 0.0 => {
            let f = (level.ln() - p.rel_mse.ln()) / (r.rel_mse.ln() - p.rel_mse.ln());
            (p.wall_s.ln() + f * (r.wall_s.ln() - p.wall_s.ln())).exp()
        }
        _ => r.wall_s,
    })
}

/// The time by which half of the seeds (rounded up) had reached a level: the ⌈n/2⌉-th
/// smallest of their times, a seed that never did counting as later than any.
fn half_reached(times: &[Option<f64>]) -> Option<f64> {
    let mut reached: Vec<f64> = times.iter().flatten().copied().collect();
    reached.sort_by(f64::total_cmp);
    reached
        .get(times.len().div_ceil(2).checked_sub(1)?)
        .copied()
}

fn write_report(dir: &Path, report: &Report) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let write = |name: &str, bytes: &[u8]| -> anyhow::Result<()> {
        let path = dir.join(name);
        std::fs::write(&path, bytes).with_context(|| format!("writing {}", path.display()))
    };
    write(
        "report.json",
        serde_json::to_string_pretty(report)?.as_bytes(),
    )?;

    let mut csv = String::from(
        "integrator,seed,budget,spp,wall_s,cpu_s,rel_mse,rmse,mean_ratio,estimated_rel_mse\n",
    );
    for r in &report.runs {
        let _ = writeln!(
            csv,
            "{},{},{},{},{:.4},{},{:.6e},{:.6e},{:.6},{}",
            r.integrator,
            r.seed,
            r.budget,
            r.spp,
            r.wall_s,
            r.cpu_s.map(|c| format!("{c:.4}")).unwrap_or_default(),
            r.rel_mse,
            r.rmse,
            r.mean_ratio,
            r.estimated_rel_mse
                .map(|e| format!("{e:.6e}"))
                .unwrap_or_default()
        );
    }
    write("report.csv", csv.as_bytes())?;

    let mut md = format!(
        "# Speed against error: {}\n\nReference `{}`, {}×{}, {} threads. relMSE = mean of (x − r)² / (r² + 0.01).\n\n",
        report.scene, report.reference, report.width, report.height, report.threads
    );
    md += "| integrator | seed | budget | spp | wall s | CPU s | relMSE | estimated relMSE | RMSE | mean / ref |\n|---|---:|---|---:|---:|---:|---:|---:|---:|---:|\n";
    for r in &report.runs {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {:.2} | {} | {:.3e} | {} | {:.3e} | {:.4} |",
            r.integrator,
            r.seed,
            r.budget,
            r.spp,
            r.wall_s,
            r.cpu_s
                .map(|c| format!("{c:.2}"))
                .unwrap_or_else(|| "–".into()),
            r.rel_mse,
            estimate(r.estimated_rel_mse),
            r.rmse,
            r.mean_ratio
        );
    }
    let n = report.seeds.len();
    md += &if n > 1 {
        format!(
            "\nWall seconds by which half of the {n} seeds had reached a relMSE (each seed's first time, interpolated in log-log between checkpoints; – fewer than half did):\n\n| integrator |"
        )
    } else {
        "\nWall seconds to reach a relMSE (interpolated in log-log between checkpoints; – not reached):\n\n| integrator |".to_string()
    };
    for l in LEVELS {
        let _ = write!(md, " {l:.0e} |");
    }
    md += "\n|---|";
    md += &"---:|".repeat(LEVELS.len());
    md += "\n";
    for name in &report.integrators {
        let _ = write!(md, "| {name} |");
        for t in report
            .time_to_error
            .iter()
            .filter(|t| &t.integrator == name)
        {
            match t.wall_s {
                Some(s) => {
                    let _ = write!(md, " {s:.2} |");
                }
                None => md += " – |",
            }
        }
        md += "\n";
    }
    if n > 1 {
        md += "\nEach seed's wall seconds (– not reached):\n\n| integrator | relMSE |";
        for s in &report.seeds {
            let _ = write!(md, " seed {s} |");
        }
        md += "\n|---|---:|";
        md += &"---:|".repeat(n);
        md += "\n";
        for t in &report.time_to_error {
            let _ = write!(md, "| {} | {:.0e} |", t.integrator, t.rel_mse);
            for s in &t.per_seed {
                match s {
                    Some(s) => {
                        let _ = write!(md, " {s:.2} |");
                    }
                    None => md += " – |",
                }
            }
            md += "\n";
        }
    }
    for a in &report.auto {
        let _ = write!(
            md,
            "\n`auto` with seed {} chose {} after a {:.2} s pilot ({:.2} s of it the render's own passes or photons, handed on; in its times above):\n\n",
            a.seed, a.chosen, a.pilot_s, a.handed_s
        );
        for line in &a.report {
            let _ = writeln!(md, "- {line}");
        }
    }
    md += "\n![relMSE against wall time](report.png)\n";
    write("report.md", md.as_bytes())?;

    // One line per integrator and seed, one colour per integrator.
    let series: Vec<(String, Vec<(f64, f64)>)> = report
        .integrators
        .iter()
        .flat_map(|n| report.seeds.iter().map(move |s| (n, s)))
        .map(|(n, &seed)| {
            let pts = report
                .runs
                .iter()
                .filter(|r| &r.integrator == n && r.seed == seed)
                .map(|r| (r.wall_s, r.rel_mse))
                .collect();
            (n.clone(), pts)
        })
        .collect();
    let png = super::plot::log_log("relMSE", "wall seconds", &series)?;
    write("report.png", &png)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(wall_s: f64, rel_mse: f64) -> Run {
        Run {
            integrator: "path".into(),
            seed: 0,
            budget: String::new(),
            spp: 1,
            wall_s,
            cpu_s: None,
            rel_mse,
            rmse: 0.0,
            mean_ratio: 1.0,
            estimated_rel_mse: None,
        }
    }

    #[test]
    fn first_reached_interpolates_log_error_against_log_time() {
        let (a, b, c) = (run(1.0, 1e-1), run(10.0, 1e-3), run(20.0, 1e-2));
        let points = [&a, &b, &c];
        // Halfway in log error between 1e-1 and 1e-3 is halfway in log time: √10 s.
        let t = first_reached(&points, 1e-2).expect("reached");
        assert!((t - 10f64.sqrt()).abs() < 1e-9, "{t}");
        // The first checkpoint already below: its time; never below: none.
        assert_eq!(first_reached(&points, 0.5), Some(1.0));
        assert_eq!(first_reached(&points, 1e-4), None);
        // A checkpoint exactly at the level: its own time. (Checkpoint c, also below 1e-2
        // but later, does not count: the first crossing does.)
        let t = first_reached(&points, 1e-3).expect("reached");
        assert!((t - 10.0).abs() < 1e-9, "{t}");
    }

    #[test]
    fn half_reached_is_the_time_by_which_half_of_the_seeds_got_there() {
        assert_eq!(
            half_reached(&[Some(3.0), None, Some(1.0), Some(2.0)]),
            Some(2.0)
        );
        assert_eq!(half_reached(&[Some(3.0), Some(1.0), Some(2.0)]), Some(2.0));
        // Two of three never did: fewer than half reached it.
        assert_eq!(half_reached(&[None, Some(1.0), None]), None);
        assert_eq!(half_reached(&[Some(4.0)]), Some(4.0));
        assert_eq!(half_reached(&[None]), None);
    }
}
