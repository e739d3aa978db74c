//! The measurement behind `auto`: which method reaches the job's error soonest on *this* scene.
//!
//! 1. **Features** rule methods out before anything is rendered: a scene without light, or
//!    whose every light path has one bounce, needs direct lighting only (exact); translucent
//!    materials leave only the path tracer, with each subsurface method. Caustics of a
//!    concentrated light (a point, spot or directional light, a small emitter, an
//!    environment's sun) put a caveat on the path tracer: it finds them only by hitting the
//!    light through the specular chain, rare bright samples a pilot does not see, so it is
//!    measured (its error at the job's spp may be the goal) but chosen only when nothing else
//!    can be.
//! 2. **Pilots**: each remaining candidate renders the scene at about 1/16 of its pixels (at
//!    least 256, at most 4096; a Mitchell filter as a box, whose weights cannot cancel) with
//!    `k` samples, then `k` more, as two independent halves A and B (where the method cannot
//!    continue a frame, a second render with the next seed). The relMSE of one half is
//!    estimated as mean((A − B)² / 2 / (R² + 0.01)) over pixels and channels, R being the
//!    consensus of the unbiased candidates (leaving out the path tracer where a bidirectional
//!    one was measured), their means weighted by the inverse of their variance; for an
//!    unbiased candidate, also as twice its mean's relMSE against the consensus of the others
//!    less that consensus's own (paths both halves missed show there), the larger counting.
//!    v = relMSE × k is the relative variance of one sample per pixel. For the photon
//!    map, what does not fall with samples (kernel bias, irradiance interpolation, the photon
//!    map's own noise): b = mean((Ā − R)² / (R² + 0.01)) − var(Ā) − var(R), floored at 0.
//!    SPPM renders k iterations with two seeds; the whole error e of a k-iteration image against
//!    R is taken to fall as n^(−2/3), the rate of progressive photon mapping with α = 2/3
//!    (Knaus & Zwicker 2011).
//! 3. **Prediction** at full size: samples to reach relMSE E are v / E (unbiased),
//!    v / (E − b) (photon map; none if b is near E), k (e/E)^(3/2) (SPPM); time is the
//!    passes' time (view-independent, so the pilot's) plus the samples at the pilot's time per
//!    sample and pixel. The goal is a relMSE (`target_error`), the error path tracing reaches
//!    at the job's spp (the same image quality, sooner), or the lowest error within a time.
//!
//! After the first three candidates, the pilot stops measuring once it has spent a tenth of
//! the best prediction so far (of a candidate without a caveat); candidates not measured are
//! said to be. Candidates run in the order path, BDPT, VCM (unbiased: the consensus needs
//! them), SPPM (one iteration's photons), photon map (a whole photon map), PSSMLT, MLT.

use std::time::Instant;

use tessera_scene::{FilterDesc, SceneDesc, SubsurfaceMethod};

use super::Choice;
use crate::analysis::{Analysis, analyze, concentrated_lights};
use crate::film::{Image, MAX_SPP};
use crate::method::local::{Local, Progress};
use crate::method::{Job, Loaded, plan};
use crate::scene::Scene;

/// What the job asks of its render.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Goal {
    /// A relMSE to reach (`target_error`).
    Error(f64),
    /// The lowest error within this many wall seconds (`time_limit`).
    Seconds(f64),
    /// The relMSE the path tracer reaches at this many samples per pixel (the job's `spp`).
    PathSpp(u32),
}

impl Goal {
    /// What `job` asks of its render: its target error, else the lowest error within its time
    /// limit, else the path tracer's error at its spp.
    pub fn of(job: &Job) -> Goal {
        match (job.target_error, job.time_limit) {
            (Some(e), _) => Goal::Error(e),
            (None, Some(t)) => Goal::Seconds(t.as_secs_f64()),
            (None, None) => Goal::PathSpp(job.desc.integrator.spp),
        }
    }
}

/// How a candidate's error falls with its samples n.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Model {
    /// v / n.
    Unbiased,
    /// v / n + b: b is kernel bias and the noise of a view-independent pass.
    Biased,
    /// e (2k / n)^(2/3): progressive photon mapping.
    Progressive,
}

struct Candidate {
    label: String,
    method: &'static str,
    subsurface: Option<SubsurfaceMethod>,
    model: Model,
    /// Pilot samples per half.
    k: u32,
    /// Why a pilot cannot measure this candidate's error: it is measured (the path tracer's
    /// error is the goal at a job's spp) but chosen only when nothing else can be.
    caveat: Option<String>,
}

/// One candidate as the pilot measured it, and what it predicts at full size.
#[derive(Debug, Clone)]
pub struct Measurement {
    pub label: String,
    /// Wall seconds of the pilot (both halves and the passes).
    pub pilot_s: f64,
    /// Wall seconds of the view-independent passes (photon maps, point clouds).
    pub setup_s: f64,
    /// Wall seconds per sample per pixel over the full film.
    pub sample_s: f64,
    /// relMSE of a one-sample image: variance only.
    pub rel_var: f64,
    /// relMSE that more samples do not remove (photon map), or SPPM's total relMSE at the
    /// pilot's iterations.
    pub floor: Option<f64>,
    /// Samples (iterations) predicted for the goal, and the wall seconds they take with the
    /// passes; `None` where the candidate cannot reach it.
    pub spp: Option<u32>,
    pub predicted_s: Option<f64>,
    /// The relMSE predicted at the end of its render.
    pub predicted_error: Option<f64>,
    /// Why it cannot reach the goal, when it cannot.
    pub note: Option<String>,
    /// Why its measurement is not trusted (see `Candidate::caveat`).
    pub caveat: Option<String>,
}

/// The choice, every candidate's measurement, and what was ruled out without one.
#[derive(Debug, Clone)]
pub struct Selection {
    pub choice: Choice,
    pub measurements: Vec<Measurement>,
    /// Wall seconds of all pilots.
    pub pilot_s: f64,
    /// The passes the chosen method's pilot built with the job's seed, by key: a render of
    /// the chosen method takes those whose key it shares (view-independent ones such as
    /// photon maps) instead of building them again.
    pub artifacts: Vec<(String, Loaded)>,
}

/// `dipole`, `hierarchical`, `random-walk`.
pub fn subsurface_name(s: SubsurfaceMethod) -> &'static str {
    match s {
        SubsurfaceMethod::Dipole => "dipole",
        SubsurfaceMethod::Hierarchical => "hierarchical",
        SubsurfaceMethod::RandomWalk => "random-walk",
    }
}

/// Pilot pixels: about 1/16 of the film, within these bounds.
const PILOT_PIXELS: (u64, u64) = (256, 4096);
/// The pilot stops once it has spent this share of the best prediction.
const PILOT_SHARE: f64 = 0.1;
/// The first candidates are measured whatever the pilot has spent: the path tracer, BDPT and
/// VCM need no passes, so cost little, and make the consensus that judges the biased ones.
const ALWAYS_MEASURED: usize = 3;
/// A biased candidate is said unable to reach an error its floor is this close to.
const FLOOR_MARGIN: f64 = 0.8;

/// Chooses a method for frame `frame` of `desc` (settings applied; `integrator.type` auto),
/// measuring on `scene` (built from `desc`, and left with its settings) with `threads` threads.
pub fn select(
    desc: &SceneDesc,
    scene: &mut Scene,
    frame: u32,
    goal: Goal,
    threads: usize,
) -> Result<Selection, String> {
    let selection = measure(desc, scene, frame, goal, threads);
    scene.set_settings(desc);
    selection
}

fn measure(
    desc: &SceneDesc,
    scene: &mut Scene,
    frame: u32,
    goal: Goal,
    threads: usize,
) -> Result<Selection, String> {
    let start = Instant::now();
    let analysis = analyze(desc);
    if analysis.method == "direct" {
        let reason = analysis
            .decisions
            .first()
            .map_or(String::new(), |d| d.reason.clone());
        return Ok(Selection {
            choice: Choice {
                method: "direct".into(),
                subsurface: None,
                spp: desc.integrator.spp,
                target_error: match goal {
                    Goal::Error(e) => Some(e),
                    _ => None,
                },
                report: vec![format!("chose direct without a pilot: {reason}")],
            },
            measurements: Vec::new(),
            pilot_s: 0.0,
            artifacts: Vec::new(),
        });
    }
    let (candidates, mut ruled_out) = candidates(desc, &analysis);
    let film = (desc.film.width as u64) * (desc.film.height as u64);
    let pilot = pilot_desc(desc);
    let photons = crate::photon::PhotonSettings::resolve(desc, &analysis)
        .0
        .photons as f64;

    let mut runs: Vec<(usize, Run)> = Vec::new();
    let mut measurements = Vec::new();
    let mut target = None;
    for (i, c) in candidates.iter().enumerate() {
        let spent = start.elapsed().as_secs_f64();
        let best = measurements
            .iter()
            .filter(|m: &&Measurement| m.caveat.is_none())
            .filter_map(|m| m.predicted_s)
            .fold(f64::INFINITY, f64::min);
        let budget = match goal {
            Goal::Seconds(t) => t,
            _ => best,
        };
        if i >= ALWAYS_MEASURED && spent > PILOT_SHARE * budget {
            ruled_out.push(format!(
                "{}: not measured: the pilot had spent {spent:.2} s, a tenth of the best prediction ({budget:.2} s)",
                c.label
            ));
            continue;
        }
        match run(c, &pilot, desc.film.width, scene, frame, threads) {
            Ok(r) => runs.push((i, r)),
            Err(e) => ruled_out.push(format!("{}: cannot run: {e}", c.label)),
        }
        let (m, t) = predict(
            &candidates,
            &runs,
            goal,
            (pilot.film.width, pilot.film.height),
            film,
            photons,
        );
        measurements = m;
        target = t;
    }
    let pilot_s = start.elapsed().as_secs_f64();
    let chosen = choose(&measurements, goal).ok_or_else(|| {
        format!(
            "auto: no candidate can reach the goal ({}); give integrator.type",
            ruled_out.join("; ")
        )
    })?;
    let m = &measurements[chosen];
    let c = candidates
        .iter()
        .find(|c| c.label == m.label)
        .ok_or("auto: the chosen candidate is not a candidate")?;
    let spp = m.spp.unwrap_or(1).clamp(1, MAX_SPP);
    // Where the method refines tiles, a target error stays adaptive.
    let adaptive = match goal {
        Goal::Error(e) => {
            let mut job = Job::new(pilot.clone(), frame);
            job.desc.integrator.method = c.method.into();
            job.target_error = Some(e);
            plan(&job).is_ok().then_some(e)
        }
        _ => None,
    };
    // Adaptive sampling stops at the target; its cap leaves room for the prediction to err.
    let spp = if adaptive.is_some() {
        spp.saturating_mul(2).min(MAX_SPP)
    } else {
        spp
    };
    let mut report = vec![format!(
        "chose {} at {spp} {}: predicted {:.2} s to {} (pilot {pilot_s:.2} s{})",
        m.label,
        if adaptive.is_some() {
            "spp at most, adaptive"
        } else {
            "spp"
        },
        m.predicted_s.unwrap_or(f64::NAN),
        match (goal, target) {
            (Goal::Seconds(t), _) => format!(
                "relMSE {:.2e} within {t} s",
                m.predicted_error.unwrap_or(f64::NAN)
            ),
            (_, Some(e)) => format!("relMSE {e:.2e}"),
            _ => "the goal".into(),
        },
        m.predicted_s
            .map(|t| format!(", {:.0} % of that", 100.0 * pilot_s / t))
            .unwrap_or_default(),
    )];
    for o in &measurements {
        report.push(describe(o));
    }
    report.extend(ruled_out);
    Ok(Selection {
        choice: Choice {
            method: c.method.into(),
            subsurface: c.subsurface,
            spp,
            target_error: adaptive,
            report,
        },
        artifacts: runs
            .into_iter()
            .find(|(i, _)| candidates[*i].label == m.label)
            .map(|(_, r)| r.artifacts)
            .unwrap_or_default(),
        measurements,
        pilot_s,
    })
}

/// The candidates the scene's features leave, in pilot order, and what they ruled out.
fn candidates(desc: &SceneDesc, analysis: &Analysis) -> (Vec<Candidate>, Vec<String>) {
    let c = |label: &str, method, subsurface, model, k| Candidate {
        label: label.to_string(),
        method,
        subsurface,
        model,
        k,
        caveat: None,
    };
    let translucent = desc.translucent_materials();
    if !translucent.is_empty() {
        // The scene's own subsurface method first: it is the path tracer a job's spp means.
        let mut methods = vec![
            desc.integrator.subsurface,
            SubsurfaceMethod::RandomWalk,
            SubsurfaceMethod::Dipole,
            SubsurfaceMethod::Hierarchical,
        ];
        let mut seen = Vec::new();
        methods.retain(|m| {
            let new = !seen.contains(m);
            seen.push(*m);
            new
        });
        let list = methods
            .into_iter()
            .map(|m| {
                let model = if m == SubsurfaceMethod::RandomWalk {
                    Model::Unbiased
                } else {
                    Model::Biased
                };
                c(
                    &format!("path:{}", subsurface_name(m)),
                    "path",
                    Some(m),
                    model,
                    4,
                )
            })
            .collect();
        return (
            list,
            vec![format!(
                "bdpt, vcm, photon, sppm, pssmlt, mlt: not candidates: they do not render translucent materials ({})",
                translucent.join(", ")
            )],
        );
    }
    // The unbiased methods without passes first: they are cheap to measure and make the
    // consensus. SPPM's iterations trace all their photons whatever the film: one each, less
    // than photon mapping's pass, which is measured at full cost (and reused by the render
    // when it wins).
    // Caustics of a concentrated light are paths the path tracer finds only by hitting the
    // light through the specular chain: rare, bright samples, which a pilot of a few thousand
    // paths does not see, so their variance cannot be measured. Light tracing (BDPT, VCM)
    // and photon maps find them from the light's side.
    let concentrated = if analysis.caustics {
        concentrated_lights(desc, analysis)
    } else {
        Vec::new()
    };
    let caveat = (!concentrated.is_empty()).then(|| {
        format!(
            "its caustics of {} are rare, bright samples a pilot does not see",
            concentrated.join(", ")
        )
    });
    let list = vec![
        Candidate {
            caveat,
            ..c("path", "path", None, Model::Unbiased, 16)
        },
        c("bdpt", "bdpt", None, Model::Unbiased, 4),
        c("vcm", "vcm", None, Model::Unbiased, 4),
        c("sppm", "sppm", None, Model::Progressive, 1),
        c("photon", "photon", None, Model::Biased, 4),
        c("pssmlt", "pssmlt", None, Model::Unbiased, 4),
        c("mlt", "mlt", None, Model::Unbiased, 4),
    ];
    (list, Vec::new())
}

/// The scene at about 1/16 of its pixels (within [`PILOT_PIXELS`]), same view. A filter with
/// negative lobes (Mitchell) becomes a box: with a pilot's few samples a pixel's Σ w can come
/// near 0 and its ratio Σ w·L / Σ w blow up, which says nothing of how the render's error
/// falls at the samples it will take.
fn pilot_desc(desc: &SceneDesc) -> SceneDesc {
    let (w, h) = (desc.film.width as f64, desc.film.height as f64);
    let film = w * h;
    let want = (film / 16.0).clamp(PILOT_PIXELS.0 as f64, PILOT_PIXELS.1 as f64);
    let s = (want / film).sqrt().min(1.0);
    let mut d = desc.clone();
    d.film.width = ((w * s).round() as u32).max(1);
    d.film.height = ((h * s).round() as u32).max(1);
    if let FilterDesc::Mitchell { .. } = d.film.filter {
        d.film.filter = FilterDesc::Box { radius: 0.5 };
    }
    d
}

/// A candidate's pilot images: two independent halves and their mean.
struct Halves {
    /// k samples, and k more (independent of the first).
    a: Vec<[f64; 3]>,
    b: Vec<[f64; 3]>,
    /// All 2k samples.
    both: Vec<[f64; 3]>,
}

impl Halves {
    /// relMSE of one half against the consensus `r`.
    fn half_rel_mse(&self, r: &[[f64; 3]]) -> f64 {
        rel(r, |p, c| {
            let d = self.a[p][c] - self.b[p][c];
            0.5 * d * d
        })
    }

    /// relMSE of the mean of both halves against `r`.
    fn rel_mse(&self, r: &[[f64; 3]]) -> f64 {
        rel(r, |p, c| {
            let d = self.both[p][c] - r[p][c];
            d * d
        })
    }
}

/// A candidate's pilot.
struct Run {
    images: Halves,
    /// The passes of the first half (the job's seed).
    artifacts: Vec<(String, Loaded)>,
    setup_s: f64,
    /// Wall seconds of the 2k samples.
    frame_s: f64,
    pilot_s: f64,
}

fn rgb(image: &Image) -> Vec<[f64; 3]> {
    image.pixels.iter().map(|p| p.rgb.map(f64::from)).collect()
}

/// Renders candidate `c`'s pilot of `pilot` (a film `width` pixels wide at full size).
fn run(
    c: &Candidate,
    pilot: &SceneDesc,
    width: u32,
    scene: &mut Scene,
    frame: u32,
    threads: usize,
) -> Result<Run, String> {
    let start = Instant::now();
    let mut desc = pilot.clone();
    desc.integrator.method = c.method.into();
    desc.integrator.spp = c.k;
    if let Some(s) = c.subsurface {
        desc.integrator.subsurface = s;
    }
    // Irradiance records are placed every `spacing` pixels: as many in the pilot as in the
    // render, or the pilot's cache interpolates over distances the render's never does.
    if let Some(ic) = &mut desc.integrator.photon.irradiance_cache {
        let scale = pilot.film.width as f64 / width.max(1) as f64;
        let spacing = ic.spacing.unwrap_or(crate::photon::DEFAULT_SPACING) as f64;
        ic.spacing = Some((spacing * scale).round().max(1.0) as u32);
    }
    let noop = |_: Progress| {};
    let job = Job::new(desc.clone(), frame);
    let p = plan(&job)?;
    scene.set_settings(&desc);
    let local = Local::new(p.as_ref(), scene, &desc, threads, &noop);
    local.passes()?;
    let setup_s = start.elapsed().as_secs_f64();
    let rendering = Instant::now();
    let (mut state, first) = local.frame_with_state(frame)?;
    let a = rgb(&first.image);
    // SPPM's later iterations are not a second sample of its first ones: it renders anew.
    let continued = match c.model {
        Model::Progressive => None,
        _ => local.more(frame, state.as_mut(), 2 * c.k),
    };
    let artifacts = local.artifacts();
    drop(local);
    let (b, both) = match continued {
        Some(done) => {
            let both = rgb(&done?.image);
            // The second half: the 2k mean less the first half's share.
            let b = both
                .iter()
                .zip(&a)
                .map(|(m, x)| [0, 1, 2].map(|i| 2.0 * m[i] - x[i]))
                .collect();
            (b, both)
        }
        None => {
            let mut other = desc.clone();
            other.integrator.seed = other.integrator.seed.wrapping_add(1);
            let job = Job::new(other.clone(), frame);
            let p = plan(&job)?;
            scene.set_settings(&other);
            let local = Local::new(p.as_ref(), scene, &other, threads, &noop);
            local.passes()?;
            let b = rgb(&local.frame(frame)?.image);
            let both = a
                .iter()
                .zip(&b)
                .map(|(x, y)| [0, 1, 2].map(|i| 0.5 * (x[i] + y[i])))
                .collect();
            (b, both)
        }
    };
    Ok(Run {
        images: Halves { a, b, both },
        artifacts,
        setup_s,
        frame_s: rendering.elapsed().as_secs_f64(),
        pilot_s: start.elapsed().as_secs_f64(),
    })
}

/// mean over pixels and channels of f(pixel, channel) / (r² + 0.01).
fn rel(r: &[[f64; 3]], f: impl Fn(usize, usize) -> f64) -> f64 {
    let mut sum = 0.0;
    for (p, rp) in r.iter().enumerate() {
        for (ch, &v) in rp.iter().enumerate() {
            sum += f(p, ch) / (v * v + 0.01);
        }
    }
    sum / (3 * r.len().max(1)) as f64
}

/// The unbiased candidates' means weighted by the inverse of their variance, and the
/// consensus's own relMSE; empty without an unbiased candidate.
fn consensus(unbiased: &[&Halves]) -> (Vec<[f64; 3]>, f64) {
    let Some(first) = unbiased.first() else {
        return (Vec::new(), f64::INFINITY);
    };
    let n = first.both.len();
    let mut r: Vec<[f64; 3]> = vec![[0.0; 3]; n];
    for u in unbiased {
        for (x, y) in r.iter_mut().zip(&u.both) {
            for c in 0..3 {
                x[c] += y[c] / unbiased.len() as f64;
            }
        }
    }
    // Once more with weights: the variance of a mean of both halves is half a half's.
    let weights: Vec<f64> = unbiased
        .iter()
        .map(|u| 2.0 / u.half_rel_mse(&r).max(1e-12))
        .collect();
    let total: f64 = weights.iter().sum();
    let mut weighted: Vec<[f64; 3]> = vec![[0.0; 3]; n];
    for (u, w) in unbiased.iter().zip(&weights) {
        for (x, y) in weighted.iter_mut().zip(&u.both) {
            for c in 0..3 {
                x[c] += w / total * y[c];
            }
        }
    }
    (weighted, 1.0 / total)
}

/// relMSE of `h` beyond its own noise and the consensus's, against the consensus of
/// `unbiased`: what more samples do not remove.
fn floor_of(h: &Halves, unbiased: &[&Halves]) -> f64 {
    let (r, var_r) = consensus(unbiased);
    (h.rel_mse(&r) - 0.5 * h.half_rel_mse(&r) - var_r).max(0.0)
}

/// Every measured candidate's prediction for `goal`, and the relMSE aimed at (none for a
/// time goal).
fn predict(
    candidates: &[Candidate],
    runs: &[(usize, Run)],
    goal: Goal,
    pilot: (u32, u32),
    film: u64,
    photons: f64,
) -> (Vec<Measurement>, Option<f64>) {
    let pixels: Vec<&Halves> = runs.iter().map(|(_, r)| &r.images).collect();
    // The consensus leaves the path tracer out where a bidirectional method was measured:
    // paths it finds too rarely to see in a pilot (caustics of small lights, light seen
    // through glass) make its pilot's variance look small and its image dark there.
    let judges_of = |all: bool| -> Vec<usize> {
        runs.iter()
            .enumerate()
            .filter(|(_, (i, _))| candidates[*i].model == Model::Unbiased)
            .filter(|(_, (i, _))| all || candidates[*i].label != "path")
            .map(|(j, _)| j)
            .collect()
    };
    let judged = match judges_of(false) {
        j if j.is_empty() => judges_of(true),
        j => j,
    };
    let unbiased: Vec<&Halves> = judged.iter().map(|&j| pixels[j]).collect();
    let (r, _) = consensus(&unbiased);
    if r.is_empty() {
        return (Vec::new(), None);
    }
    let pilot_film = (pilot.0 as f64) * (pilot.1 as f64);
    let ratio = film as f64 / pilot_film;
    let mut out: Vec<Measurement> = runs
        .iter()
        .enumerate()
        .map(|(j, (i, run))| {
            let c = &candidates[*i];
            let k = c.k as f64;
            let half = pixels[j].half_rel_mse(&r);
            // SPPM's iterations trace a fixed number of photons besides a path per pixel.
            let scale = if c.model == Model::Progressive {
                (photons + film as f64) / (photons + pilot_film)
            } else {
                ratio
            };
            // An unbiased pilot's halves agree where both miss the same rare paths; against
            // the other judges (leaving itself out) the paths it missed show as error. Its
            // variance is the larger of the two measures.
            let others: Vec<&Halves> = judged
                .iter()
                .filter(|&&o| o != j)
                .map(|&o| pixels[o])
                .collect();
            let half = match c.model {
                Model::Unbiased if !others.is_empty() => {
                    let (r, var_r) = consensus(&others);
                    // Of both halves (2k samples): twice that for one half.
                    let against = pixels[j].rel_mse(&r) - var_r;
                    half.max(2.0 * against)
                }
                _ => half,
            };
            let floor = match c.model {
                Model::Unbiased => None,
                Model::Biased => Some(floor_of(pixels[j], &unbiased)),
                // A k-iteration image's whole error: its noise and its (shrinking) bias.
                Model::Progressive => Some(half + floor_of(pixels[j], &unbiased)),
            };
            Measurement {
                label: c.label.clone(),
                pilot_s: run.pilot_s,
                setup_s: run.setup_s,
                sample_s: run.frame_s / (2.0 * k) * scale,
                rel_var: half * k,
                floor,
                spp: None,
                predicted_s: None,
                predicted_error: None,
                note: None,
                caveat: c.caveat.clone(),
            }
        })
        .collect();
    // The path tracer with the scene's own settings is the first candidate.
    let reference = out.first().map(|m| m.rel_var);
    let target = match goal {
        Goal::Error(e) => Some(e),
        Goal::PathSpp(n) => reference.map(|v| v / n.max(1) as f64),
        Goal::Seconds(_) => None,
    };
    for (m, (i, _)) in out.iter_mut().zip(runs) {
        let c = &candidates[*i];
        let k = c.k as f64;
        let samples = |n: f64| -> Option<u32> {
            (n.is_finite() && n <= MAX_SPP as f64).then(|| n.ceil().max(1.0) as u32)
        };
        let error_at = |n: f64| match (c.model, m.floor) {
            (Model::Unbiased, _) => m.rel_var / n,
            (Model::Biased, Some(b)) => m.rel_var / n + b,
            (Model::Progressive, Some(e)) => e * (k / n).powf(2.0 / 3.0),
            _ => f64::INFINITY,
        };
        match (goal, target) {
            (Goal::Seconds(t), _) => {
                let n = ((t - m.setup_s) / m.sample_s).floor();
                if n >= 1.0 {
                    m.spp = samples(n);
                    m.predicted_s = m.spp.map(|n| m.setup_s + n as f64 * m.sample_s);
                    m.predicted_error = m.spp.map(|n| error_at(n as f64));
                } else {
                    m.note = Some(format!("its passes and one sample take longer than {t} s"));
                }
            }
            (_, Some(e)) => {
                let n = match (c.model, m.floor) {
                    (Model::Unbiased, _) => Some(m.rel_var / e),
                    (Model::Biased, Some(b)) if b < FLOOR_MARGIN * e => Some(m.rel_var / (e - b)),
                    (Model::Biased, Some(b)) => {
                        m.note = Some(format!(
                            "its bias and photon-map noise (relMSE {b:.2e}) leave no room under {e:.2e}"
                        ));
                        None
                    }
                    (Model::Progressive, Some(t)) => Some(k * (t / e).powf(1.5)),
                    _ => None,
                };
                m.spp = n.and_then(samples);
                if n.is_some() && m.spp.is_none() {
                    m.note = Some(format!("it would need more than {MAX_SPP} samples"));
                }
                m.predicted_s = m.spp.map(|n| m.setup_s + n as f64 * m.sample_s);
                m.predicted_error = m.spp.map(|n| error_at(n as f64));
            }
            _ => {}
        }
    }
    (out, target)
}

/// The candidate with the soonest prediction (the lowest error for a time goal); one with a
/// caveat only when no other has a prediction.
fn choose(measurements: &[Measurement], goal: Goal) -> Option<usize> {
    let key = |m: &Measurement| match goal {
        Goal::Seconds(_) => m.predicted_error,
        _ => m.predicted_s,
    };
    let best = |trusted: bool| {
        measurements
            .iter()
            .enumerate()
            .filter(|(_, m)| !trusted || m.caveat.is_none())
            .filter_map(|(i, m)| key(m).filter(|v| v.is_finite()).map(|v| (i, v)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i)
    };
    best(true).or_else(|| best(false))
}

/// One line for a candidate.
fn describe(m: &Measurement) -> String {
    let floor = m
        .floor
        .map(|b| format!(", floor {b:.2e}"))
        .unwrap_or_default();
    let measured = format!(
        "1-spp relMSE {:.2e}{floor}, {:.3} s per spp, passes {:.2} s; pilot {:.2} s",
        m.rel_var, m.sample_s, m.setup_s, m.pilot_s
    );
    let caveat = m
        .caveat
        .as_ref()
        .map(|c| format!("; chosen only if nothing else can be: {c}"))
        .unwrap_or_default();
    match (m.spp, m.predicted_s, &m.note) {
        (Some(n), Some(t), _) => format!(
            "{}: {n} spp in {t:.2} s predicted, relMSE {:.2e} ({measured}){caveat}",
            m.label,
            m.predicted_error.unwrap_or(f64::NAN)
        ),
        (_, _, Some(note)) => format!("{}: cannot reach the goal: {note} ({measured})", m.label),
        _ => format!("{}: no prediction ({measured})", m.label),
    }
}
