//! The measurement behind `auto`: which method reaches the job's error soonest on *this* scene.
//!
//! 1. **Features** rule methods out before anything is rendered: a scene without light, or
//!    whose every light path has one bounce, needs direct lighting only (exact); translucent
//!    materials leave only the path tracer, with each subsurface method. Caustics of a
//!    concentrated light (a point, spot or directional light, a small emitter, an
//!    environment's sun) put a caveat on the path tracer: it finds them only by hitting the
//!    light through the specular chain, rare bright samples a pilot does not see, so it is
//!    measured (its error at the job's spp may be the goal) but chosen only when nothing else
//!    can be. Where the camera also sees a specular surface, BDPT carries the same caveat:
//!    caustics seen in it are specular–diffuse–specular paths, which none of its connections
//!    join (it stays a judge: its mean is unbiased). Whether that surface shows a caustic is
//!    not checked; where it does not, VCM, which has BDPT's strategies, stays a candidate.
//! 2. **Pilots**: each remaining candidate renders the scene at about 1/32 of its pixels (at
//!    least 256, at most 4096; a Mitchell filter as a box, whose weights cannot cancel) with
//!    `k` samples, then `k` more, as two independent halves A and B (where the method cannot
//!    continue a frame, a second render with the next seed). The relMSE of one half is
//!    estimated as mean((A − B)² / 2 / (R̄² + 0.01)) over pixels and channels, R being the
//!    consensus of the unbiased candidates (leaving out the path tracer where a bidirectional
//!    one was measured), their means weighted by the inverse of their variance, and R̄ its
//!    3 × 3-pixel mean (dividing by a noisy R would inflate the estimate where R came out
//!    low, which is where the noisiest candidate differs most); every relMSE below divides
//!    by R̄ likewise. For an unbiased candidate it is also estimated as twice its mean's
//!    relMSE against the consensus of the others less that consensus's own (paths both
//!    halves missed show there), the larger counting.
//!    v = relMSE × k is the relative variance of one sample per pixel. For the photon
//!    map, what does not fall with samples (kernel bias, irradiance interpolation, the photon
//!    map's own noise): b = mean((Ā − R)² / (R̄² + 0.01)) − var(Ā) − var(R), floored at 0.
//!    SPPM renders k iterations with the job's seed, and as the second half the photons of
//!    its iterations k..2k gathered from the initial radii at the next seed's camera paths
//!    (the same estimator on independent samples): v from their difference as above, and b,
//!    its kernel bias, as for the photon map but only where it exceeds var(R) as the judges'
//!    v put it (a consensus of a few bidirectional samples is often noisier than SPPM's first
//!    iterations, and its halves' agreement where both miss rare paths would pass for bias).
//!    The photons of those 2k iterations (shot whatever the film) are the render's first 2k
//!    iterations' and are handed on to it. Its noise falls as 1/n while each pixel's radius
//!    holds photons of many iterations, its bias as n^(−2/3) (the radii's rate with α = 2/3:
//!    Knaus & Zwicker 2011).
//! 3. **Prediction** at full size: samples to reach relMSE E are v / E (unbiased),
//!    v / (E − b) (photon map; none if b is near E, or if the judges' own relMSE is, under
//!    which b cannot be told from their noise), the least n with
//!    v / n + b (k / n)^(2/3) ≤ E (SPPM); time is what the render pays once (the passes,
//!    view-independent, and a Metropolis frame's bootstrap, both as the pilot timed them) plus
//!    the samples at the pilot's time per sample and pixel (SPPM's photons, shot whatever the film, at the pilot's time per
//!    iteration). The goal is a relMSE (`target_error`), the error path tracing reaches
//!    at the job's spp (the same image quality, sooner), or the lowest error within a time.
//!
//! The first three candidates are measured whatever the pilot spends, until the judges
//! measured so far resolve the goal (their own relMSE under it, so a floor at the goal can
//! be told from their noise; on the Cornell box the path tracer alone does): the unbiased
//! ones left then go after the biased ones ([`judged`]). Where the judges do not resolve it,
//! a biased candidate such as the photon map (whose floor they could not tell, so it could
//! not be chosen) waits behind
//! the judges still to come, and is not measured if none is ([`defer`]). After the first
//! candidates, whose cost is sunk, the pilot stops measuring once it has spent a tenth of
//! the best prediction so far (of a candidate without a caveat) on the others, or would
//! with SPPM's photons (timed on their first chunk), a
//! candidate's passes (timed on their first tasks, with what follows the tasks estimated
//! from them: the photon map's) or a Metropolis pilot's frames (timed on one group of
//! chains); the photons and passes, which the render takes over where that candidate wins,
//! count at the odds of that candidate losing ([`Allowance::of`]). Candidates not measured
//! are said to be. A Metropolis frame's bootstrap, which grows with neither pixels nor
//! samples, counts with the passes as paid once. Candidates run in the order path, BDPT,
//! VCM (unbiased: the consensus needs them), SPPM (two iterations' photons), photon map (a
//! whole photon map: where the scene sets no photon count, first of [`FEW_PHOTONS`], then of
//! the default count only where the few cannot reach the goal, the render taking the count
//! of the one chosen), PSSMLT, MLT — the photon map before SPPM where the film has more
//! pixels than an SPPM iteration has photons, and a path tracer with a caveat last unless
//! the goal is its own error at the job's spp; the photons and the photon map are reused by
//! the render where that method wins.

use std::time::Instant;

use glam::Vec2;
use tessera_scene::{FilmDesc, FilterDesc, SceneDesc, SubsurfaceMethod};

use super::Choice;
use crate::analysis::{Analysis, analyze, concentrated_lights};
use crate::camera::Camera;
use crate::film::{Image, MAX_SPP};
use crate::integrator::metropolis::{GROUPS, Metropolis};
use crate::integrator::sppm::{self, SppmSettings};
use crate::method::local::{Built, Local, Progress};
use crate::method::{Job, Loaded, plan};
use crate::photon::DEFAULT_PHOTONS;
use crate::scene::Scene;

mod predict;
mod progressive;
use predict::{choose, describe, predict, rel};
use progressive::{sppm_photons, sppm_second_half};

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
    /// v / n + b (k / n)^(2/3): progressive photon mapping, whose noise falls as a mean's
    /// while its radii still hold photons from many iterations, and whose kernel bias falls
    /// with the radii.
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
    /// Photons of the photon map it renders with, where the scene leaves the count to the
    /// pilot ([`FEW_PHOTONS`]).
    photons: Option<u32>,
}

impl Candidate {
    /// Whether its pilot judges the others (is part of their consensus): the unbiased
    /// candidates but the path tracer, whose pilot does not see the paths it finds too rarely
    /// (caustics of small lights, light seen through glass), which make its image dark there
    /// and its variance look small. It judges only where no other unbiased candidate was
    /// measured.
    fn judges(&self) -> bool {
        self.model == Model::Unbiased && self.label != "path"
    }
}

/// One candidate as the pilot measured it, and what it predicts at full size.
#[derive(Debug, Clone)]
pub struct Measurement {
    pub label: String,
    /// Wall seconds of the pilot (both halves and the passes).
    pub pilot_s: f64,
    /// Wall seconds the render pays once, whatever its pixels and samples: the
    /// view-independent passes (photon maps, point clouds) and a Metropolis frame's bootstrap.
    pub setup_s: f64,
    /// Wall seconds per sample per pixel over the full film.
    pub sample_s: f64,
    /// relMSE of a one-sample image: variance only.
    pub rel_var: f64,
    /// relMSE that more samples do not remove (photon map), or SPPM's bias at the pilot's
    /// iterations (0 where the consensus is too noisy to tell it).
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

/// The pilot's share of the film's pixels, within [`PILOT_PIXELS`]. The first candidates
/// are measured whatever the pilot spends, at a few samples a pixel: on a film whose best
/// method reaches the goal in a few whole-film iterations, their cost is the pilot's
/// overhead, and it grows with this share. A smaller share leaves fewer pixels to estimate
/// from and larger ones to alias (which a low-noise method's variance shows most: see the
/// README's "What remains, measured"); at 1/64 the glass box's consensus could no longer tell
/// the photon map's floor.
const PILOT_FRACTION: f64 = 32.0;
/// Pilot pixels: the film's over [`PILOT_FRACTION`], within these bounds (the upper one sets
/// the pilot of every film above 131 072 pixels).
const PILOT_PIXELS: (u64, u64) = (256, 4096);
/// The pilot stops once it has spent this share of the best prediction on the candidates
/// after those it measures whatever it spends ([`ALWAYS_MEASURED`]).
const PILOT_SHARE: f64 = 0.1;
/// The first candidates are measured whatever the pilot has spent (until their consensus
/// resolves the goal: [`judged`]): the path tracer, BDPT and VCM need no passes, so cost
/// little, and make the consensus that judges the biased ones (the path tracer only where it
/// has no caveat: see [`measured_first`]).
const ALWAYS_MEASURED: usize = 3;
/// What a candidate's pilot may spend once the first candidates are measured: `left` seconds
/// of the pilot's share, and `reusable`, the most seconds of work the render takes over from
/// it (passes, SPPM's photons) that `left` allows.
#[derive(Debug, Clone, Copy)]
struct Allowance {
    left: f64,
    reusable: f64,
}

impl Allowance {
    const UNLIMITED: Allowance = Allowance {
        left: f64::INFINITY,
        reusable: f64::INFINITY,
    };

    /// `left` seconds, `budget` being the best prediction so far. Reusable work is lost only
    /// where its candidate loses. Before it is measured, all that is known of a candidate
    /// whose reusable work takes w seconds is that it takes at least w; its time is taken as
    /// equally likely anywhere in [w, w + budget], so it loses with probability w / budget and
    /// the work's expected loss is w² / budget: at most `left` where w ≤ √(left × budget).
    /// Cheap passes beside a slow best are measured; a pass near the best prediction counts
    /// nearly in full.
    fn of(left: f64, budget: f64) -> Allowance {
        let reusable = if left <= 0.0 {
            0.0
        } else {
            (left * budget).sqrt()
        };
        Allowance { left, reusable }
    }
}

/// Photons of the photon map measured first where the scene does not set their count: a
/// final gather reads the map one bounce away, behind which most of its noise and kernel bias
/// is hidden, so a map of a few photons often reaches the error the default count does, at a
/// fraction of the pass. The default count is measured only where this one cannot reach the
/// goal ([`more_photons_needed`]).
pub const FEW_PHOTONS: u32 = DEFAULT_PHOTONS / 8;

/// The photon-map candidate with `photons` photons: `photon` with the few the pilot tries
/// first, `photon:N` with more.
fn photon_label(photons: u32) -> String {
    if photons == FEW_PHOTONS {
        "photon".into()
    } else {
        format!("photon:{photons}")
    }
}

/// Whether the photon map's candidate with more photons than the first is worth measuring:
/// not where the first reaches the goal, since more photons lower only a floor already under
/// it, at the cost of a dearer pass (a time limit's lowest error may still want them).
fn more_photons_needed(c: &Candidate, measurements: &[Measurement], goal: Goal) -> bool {
    let few = photon_label(FEW_PHOTONS);
    match c.photons {
        Some(n) if n > FEW_PHOTONS && !matches!(goal, Goal::Seconds(_)) => !measurements
            .iter()
            .any(|m| m.label == few && m.predicted_s.is_some()),
        _ => true,
    }
}

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
                photons: None,
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
    let seen = sees_specular(desc, scene, frame);
    let (mut candidates, mut ruled_out) = candidates(desc, &analysis, seen);
    let mut always = measured_first(&mut candidates, goal);
    let film = (desc.film.width as u64) * (desc.film.height as u64);
    let pilot = pilot_desc(desc);

    let mut runs: Vec<(usize, Run)> = Vec::new();
    let mut measurements = Vec::new();
    let mut target = None;
    // Candidates by index into `candidates`, in the order they are measured.
    let mut order: Vec<usize> = (0..candidates.len()).collect();
    // When the candidates measured whatever the pilot spends were done: the share is of what
    // the pilot spends after them (their cost is sunk; what is left to decide is whether the
    // others are worth measuring).
    let mut judges_done: Option<f64> = None;
    // Whether the judges measured so far cannot tell a floor at the goal from their noise.
    let mut unresolved = false;
    let mut n = 0;
    while let Some(&i) = order.get(n) {
        let c = &candidates[i];
        let elapsed = start.elapsed().as_secs_f64();
        let best = measurements
            .iter()
            .filter(|m: &&Measurement| m.caveat.is_none())
            .filter_map(|m| m.predicted_s)
            .fold(f64::INFINITY, f64::min);
        let budget = match goal {
            Goal::Seconds(t) => t,
            _ => best,
        };
        n += 1;
        if !more_photons_needed(c, &measurements, goal) {
            ruled_out.push(format!(
                "{}: not measured: the photon map of {FEW_PHOTONS} photons reaches the goal; more photons lower only its floor, at the cost of their pass",
                c.label
            ));
            continue;
        }
        let anyway = n <= always;
        if !anyway && unresolved && c.model == Model::Biased {
            if defer(&candidates, &mut order, n - 1) {
                // The next candidate now sits where this one was.
                n -= 1;
            } else {
                ruled_out.push(format!(
                    "{}: not measured: the judges measured cannot tell its bias under the goal, and none is left to measure (it could not be chosen)",
                    c.label
                ));
            }
            continue;
        }
        let spent = if anyway {
            0.0
        } else {
            elapsed - *judges_done.get_or_insert(elapsed)
        };
        if !anyway && spent > PILOT_SHARE * budget {
            ruled_out.push(format!(
                "{}: not measured: the pilot had spent {spent:.2} s on the candidates after the first {always}, a tenth of the best prediction ({budget:.2} s)",
                c.label
            ));
            continue;
        }
        // What is left of the share, for a candidate that can tell its cost before its pilot.
        let allowance = if anyway {
            Allowance::UNLIMITED
        } else {
            Allowance::of(PILOT_SHARE * budget - spent, budget)
        };
        match run(c, &pilot, desc.film, scene, frame, threads, allowance) {
            Ok(Pilot::Ran(r)) => runs.push((i, r)),
            Ok(Pilot::TooDear(why)) => ruled_out.push(format!(
                "{}: not measured: {why}, past a tenth of the best prediction ({budget:.2} s)",
                c.label
            )),
            Err(e) => ruled_out.push(format!("{}: cannot run: {e}", c.label)),
        }
        let p = predict(
            &candidates,
            &runs,
            goal,
            (pilot.film.width, pilot.film.height),
            film,
        );
        if n <= always && p.resolves() {
            always = n;
            judged(&candidates, &mut order[n..]);
        }
        unresolved = p.target.is_some() && !p.resolves();
        measurements = p.measurements;
        target = p.target;
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
        "chose {}{} at {spp} {}: predicted {:.2} s to {} (pilot {pilot_s:.2} s{})",
        m.label,
        c.photons
            .map(|n| format!(" with {n} photons"))
            .unwrap_or_default(),
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
            photons: c.photons,
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
/// `seen`: whether the camera sees a specular surface ([`sees_specular`]).
fn candidates(desc: &SceneDesc, analysis: &Analysis, seen: bool) -> (Vec<Candidate>, Vec<String>) {
    let c = |label: &str, method, subsurface, model, k| Candidate {
        label: label.to_string(),
        method,
        subsurface,
        model,
        k,
        caveat: None,
        photons: None,
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
    // consensus. SPPM's iterations trace all their photons whatever the film: two, less than
    // photon mapping's pass, which is measured at full cost (both reused by the render when
    // they win), so SPPM goes first unless the film is large (`photon_map_first`).
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
    // Seen in a specular surface, those caustics are specular–diffuse–specular paths: no
    // connection of BDPT's subpaths can join them (each end of the join is specular), so it
    // too finds them only by hitting the light, where VCM merges and photon maps gather.
    let bdpt_caveat = (!concentrated.is_empty() && seen).then(|| {
        format!(
            "its caustics of {} seen in a specular surface are rare, bright samples a pilot does not see",
            concentrated.join(", ")
        )
    });
    let mut list = vec![
        Candidate {
            caveat,
            ..c("path", "path", None, Model::Unbiased, 16)
        },
        Candidate {
            caveat: bdpt_caveat,
            ..c("bdpt", "bdpt", None, Model::Unbiased, 4)
        },
        c("vcm", "vcm", None, Model::Unbiased, 4),
        c("sppm", "sppm", None, Model::Progressive, 1),
    ];
    // The photon map with a few photons, then (where those cannot reach the goal) with the
    // default count, unless the scene sets its own.
    if desc.integrator.photon.photons.is_some() {
        list.push(c("photon", "photon", None, Model::Biased, 4));
    } else {
        list.extend([FEW_PHOTONS, DEFAULT_PHOTONS].map(|n| Candidate {
            photons: Some(n),
            ..c(&photon_label(n), "photon", None, Model::Biased, 4)
        }));
    }
    list.extend([
        c("pssmlt", "pssmlt", None, Model::Unbiased, 4),
        c("mlt", "mlt", None, Model::Unbiased, 4),
    ]);
    if photon_map_first(desc) {
        let at = |label: &str| list.iter().position(|c| c.label == label);
        if let (Some(sppm), Some(photon)) = (at("sppm"), at("photon")) {
            list.swap(sppm, photon);
        }
    }
    (list, Vec::new())
}

/// Puts the candidates with a caveat that judge no other (the path tracer: the consensus
/// leaves it out where a bidirectional method is measured) last, unless the goal is the path
/// tracer's error at the job's spp (which its pilot measures): chosen only where nothing else
/// can be, they are measured only if the pilot has time left. Returns how many candidates are
/// measured whatever the pilot has spent: the first [`ALWAYS_MEASURED`] less those moved.
fn measured_first(candidates: &mut [Candidate], goal: Goal) -> usize {
    let first = ALWAYS_MEASURED.min(candidates.len());
    if matches!(goal, Goal::PathSpp(_)) {
        return first;
    }
    let last = |c: &Candidate| c.caveat.is_some() && !c.judges();
    let moved = candidates[..first].iter().filter(|c| last(c)).count();
    candidates.sort_by_key(last);
    first - moved
}

/// Orders the candidates still to measure (`rest`, indices into `candidates`) once the
/// judges measured so far resolve the goal (their own relMSE is under it), which ends the
/// candidates measured whatever the pilot spends: more judges are not needed to tell a floor,
/// so the unbiased candidates left are measured after the biased ones, as the share allows.
/// The photon map goes before SPPM: a goal the judges resolve at a pilot's few samples is one
/// the render reaches in few, where the photon map pays its photons once and hides its
/// kernel's bias behind a gather bounce, while SPPM pays photons every iteration and its
/// first iterations' radii are its widest.
fn judged(candidates: &[Candidate], rest: &mut [usize]) {
    rest.sort_by_key(|&j| match candidates[j].model {
        Model::Biased => 0,
        Model::Progressive => 1,
        Model::Unbiased => 2,
    });
}

/// Moves the candidate at `order[at]` to the end of `order` where a judge is still to be
/// measured after it, and says whether it did. For a biased candidate whose turn comes while
/// the judges measured so far cannot tell a floor at the goal from their noise: its prediction
/// would say just that, and it could not be chosen, unless a judge still to come resolves the
/// goal; where none is, it is not measured.
fn defer(candidates: &[Candidate], order: &mut Vec<usize>, at: usize) -> bool {
    if !order[at + 1..].iter().any(|&j| candidates[j].judges()) {
        return false;
    }
    let i = order.remove(at);
    order.push(i);
    true
}

/// For a Metropolis candidate with `left` seconds (finite) to spend: renders one group of a
/// pilot frame's chains (its share of the bootstrap and of the mutations; see
/// [`crate::integrator::metropolis::GROUPS`]) and returns what the pilot's two frames would
/// take at that pace when it is more than `left`.
fn metropolis_pilot_s(
    c: &Candidate,
    desc: &SceneDesc,
    scene: &Scene,
    frame: u32,
    left: f64,
) -> Result<Option<f64>, String> {
    let Some(m) = Metropolis::new(c.method, desc).filter(|_| left.is_finite()) else {
        return Ok(None);
    };
    let camera = Camera::new(&desc.camera_at(frame), &desc.film);
    let probe = Instant::now();
    m.chains(scene, &camera, c.k, 0, &|_| {})?;
    let all = probe.elapsed().as_secs_f64() * 2.0 * GROUPS as f64;
    Ok((all > left).then_some(all))
}

/// Whether the camera sees a specular surface: a grid of rays through frame `frame`'s film.
fn sees_specular(desc: &SceneDesc, scene: &Scene, frame: u32) -> bool {
    const GRID: u32 = 32;
    let camera = Camera::new(&desc.camera_at(frame), &desc.film);
    let (w, h) = (desc.film.width as f32, desc.film.height as f32);
    (0..GRID * GRID).any(|i| {
        let film = Vec2::new(
            ((i % GRID) as f32 + 0.5) / GRID as f32 * w,
            ((i / GRID) as f32 + 0.5) / GRID as f32 * h,
        );
        scene
            .intersect(&camera.generate_ray(film, Vec2::splat(0.5)))
            .is_some_and(|si| scene.material(si.material).flags.specular)
    })
}

/// Whether the photon map is measured before SPPM: where the film has more pixels than an
/// SPPM iteration has photons. Each SPPM iteration then costs more than a camera path per
/// pixel, its photons aside, where the photon map traces its photons once and the film once
/// (with final gathering); SPPM's few cheap iterations are what win it small films. Measured
/// first, the likelier winner lets the tenth-of-the-best rule skip the other: SPPM's pilot
/// iterations are wasted where the photon map wins, the photon map's whole pass where SPPM
/// does.
fn photon_map_first(desc: &SceneDesc) -> bool {
    let film = u64::from(desc.film.width) * u64::from(desc.film.height);
    film > u64::from(sppm::photons_per_iteration(desc))
}

/// The scene at about 1/[`PILOT_FRACTION`] of its pixels (within [`PILOT_PIXELS`]), same view. A filter with
/// negative lobes (Mitchell) becomes a box: with a pilot's few samples a pixel's Σ w can come
/// near 0 and its ratio Σ w·L / Σ w blow up, which says nothing of how the render's error
/// falls at the samples it will take.
fn pilot_desc(desc: &SceneDesc) -> SceneDesc {
    let (w, h) = (desc.film.width as f64, desc.film.height as f64);
    let film = w * h;
    let want = (film / PILOT_FRACTION).clamp(PILOT_PIXELS.0 as f64, PILOT_PIXELS.1 as f64);
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
    /// relMSE of one half (its variance), divided by `d` (see [`predict::divisor`]).
    fn half_rel_mse(&self, d: &[[f64; 3]]) -> f64 {
        rel(d, |p, c| {
            let x = self.a[p][c] - self.b[p][c];
            0.5 * x * x
        })
    }

    /// relMSE of the mean of both halves against `r`, divided by `d`.
    fn rel_mse(&self, r: &[[f64; 3]], d: &[[f64; 3]]) -> f64 {
        rel(d, |p, c| {
            let x = self.both[p][c] - r[p][c];
            x * x
        })
    }
}

/// A candidate's pilot.
struct Run {
    images: Halves,
    /// The passes of the first half (the job's seed).
    artifacts: Vec<(String, Loaded)>,
    /// Wall seconds the render pays once: the passes, and a frame's work that grows with
    /// neither pixels nor samples ([`crate::method::Finished::fixed_s`]).
    setup_s: f64,
    /// Wall seconds of the 2k samples (less their frames' fixed work), and of the part of them that grows with the pixels
    /// (see [`crate::method::Finished::pixels_s`]).
    frame_s: f64,
    pixels_s: Option<f64>,
    pilot_s: f64,
}

/// What a candidate's pilot came to.
enum Pilot {
    Ran(Run),
    /// Not measured: what it would cost, and why that is too much.
    TooDear(String),
}

/// The pixel-wise mean of two images.
fn mean(a: &[[f64; 3]], b: &[[f64; 3]]) -> Vec<[f64; 3]> {
    a.iter()
        .zip(b)
        .map(|(x, y)| [0, 1, 2].map(|i| 0.5 * (x[i] + y[i])))
        .collect()
}

fn rgb(image: &Image) -> Vec<[f64; 3]> {
    image.pixels.iter().map(|p| p.rgb.map(f64::from)).collect()
}

/// Renders candidate `c`'s pilot of `pilot` (the scene at a smaller film than the render's
/// `film`).
fn run(
    c: &Candidate,
    pilot: &SceneDesc,
    film: FilmDesc,
    scene: &mut Scene,
    frame: u32,
    threads: usize,
    Allowance { left, reusable }: Allowance,
) -> Result<Pilot, String> {
    let start = Instant::now();
    let mut desc = pilot.clone();
    super::set_method(&mut desc, c.method, c.subsurface, c.photons);
    desc.integrator.spp = c.k;
    let noop = |_: Progress| {};
    let job = Job {
        cache_film: Some(film),
        ..Job::new(desc.clone(), frame)
    };
    let p = plan(&job)?;
    scene.set_settings(&desc);
    let local = Local::new(p.as_ref(), scene, &desc, threads, &noop);
    // The passes (a photon map, its irradiance cache) are the render's where it wins, and
    // built here whatever the film: timed on their first tasks (and their finish estimated
    // from those tasks' results), they stop there when dearer than what is left.
    if let Built::TooDear(all) = local.passes_within(reusable)? {
        return Ok(Pilot::TooDear(format!(
            "its passes would take at least {all:.2} s at their first tasks' pace, with their finish, more than {:.2} s ({:.2} s left, the render reusing them where it wins)",
            reusable.max(0.0),
            left.max(0.0)
        )));
    }
    let setup_s = start.elapsed().as_secs_f64();
    // A Metropolis frame's bootstrap costs the same whatever the film: timed on one of its
    // groups, it stops here when its two frames would cost more than is left.
    if let Some(all) = metropolis_pilot_s(c, &desc, scene, frame, left)? {
        return Ok(Pilot::TooDear(format!(
            "its two frames would take {all:.2} s at its first group's pace, more than the {:.2} s left",
            left.max(0.0)
        )));
    }
    let rendering = Instant::now();
    // SPPM's photons do not depend on the film: the pilot's are the render's first 2k
    // iterations', shot here and handed on with the passes, unless they cost more than is left.
    let sppm =
        (c.model == Model::Progressive).then(|| SppmSettings::resolve(&desc, &analyze(&desc)));
    let photons = match &sppm {
        Some((photon, settings)) => {
            match sppm_photons(scene, photon, *settings, frame, 2 * c.k, reusable) {
                Ok(photons) => photons,
                Err(all) => {
                    return Ok(Pilot::TooDear(format!(
                        "its photons would take {all:.2} s at its first chunk's pace, more than {:.2} s ({:.2} s left, the render reusing them where it wins)",
                        reusable.max(0.0),
                        left.max(0.0)
                    )));
                }
            }
        }
        None => Vec::new(),
    };
    let local = local.with_artifacts(photons.iter().cloned());
    let (mut state, first) = local.frame_with_state(frame)?;
    let a = rgb(&first.image);
    let mut pixels_s = first.pixels_s;
    // Work that grows with neither pixels nor samples: its seconds over the frames rendered,
    // and how many frames.
    let mut fixed = (first.fixed_s, 1.0);
    let continued = match c.model {
        // SPPM's later iterations gather in smaller radii: not a second sample of its first.
        Model::Progressive => None,
        _ => local.more(frame, state.as_mut(), 2 * c.k),
    };
    let mut frame_s = rendering.elapsed().as_secs_f64();
    let artifacts = local.artifacts();
    drop(local);
    let (b, both) = match continued {
        Some(done) => {
            let done = done?;
            // The continued frame's are the whole frame's.
            pixels_s = done.pixels_s;
            fixed = (done.fixed_s, 1.0);
            let both = rgb(&done.image);
            // The second half: the 2k mean less the first half's share.
            let b = both
                .iter()
                .zip(&a)
                .map(|(m, x)| [0, 1, 2].map(|i| 2.0 * m[i] - x[i]))
                .collect();
            (b, both)
        }
        None => {
            let b = if let Some((photon, settings)) = &sppm {
                let second = Instant::now();
                let (b, b_pixels_s) =
                    sppm_second_half(&desc, scene, photon, *settings, frame, c.k, &photons)?;
                frame_s += second.elapsed().as_secs_f64();
                pixels_s = pixels_s.map(|a| a + b_pixels_s);
                b
            } else {
                let mut other = desc.clone();
                other.integrator.seed = other.integrator.seed.wrapping_add(1);
                let job = Job::new(other.clone(), frame);
                let p = plan(&job)?;
                scene.set_settings(&other);
                let local = Local::new(p.as_ref(), scene, &other, threads, &noop);
                local.passes()?;
                let second = Instant::now();
                let other = local.frame(frame)?;
                frame_s += second.elapsed().as_secs_f64();
                pixels_s = pixels_s.zip(other.pixels_s).map(|(a, b)| a + b);
                fixed = (fixed.0 + other.fixed_s, 2.0);
                rgb(&other.image)
            };
            let both = mean(&a, &b);
            (b, both)
        }
    };
    Ok(Pilot::Ran(Run {
        images: Halves { a, b, both },
        artifacts,
        // A frame's fixed work is paid once by the render, as its passes are.
        setup_s: setup_s + fixed.0 / fixed.1,
        frame_s: frame_s - fixed.0,
        pixels_s,
        pilot_s: start.elapsed().as_secs_f64(),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scene description of `scenes/NAME/scene.json`.
    pub(super) fn scene(name: &str) -> SceneDesc {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(format!("../../scenes/{name}/scene.json"));
        tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
    }

    /// SPPM is measured before the photon map unless the film has more pixels than an SPPM
    /// iteration has photons.
    #[test]
    fn photon_map_goes_first_on_films_larger_than_an_iteration() {
        let mut desc = scene("cornell-box");
        let order = |desc: &SceneDesc| -> Vec<String> {
            let (list, _) = candidates(desc, &analyze(desc), false);
            list.into_iter()
                .map(|c| c.label)
                .filter(|l| l == "sppm" || l == "photon")
                .collect()
        };
        desc.film.width = 256;
        desc.film.height = 256;
        assert_eq!(order(&desc), ["sppm", "photon"]);
        desc.film.width = 1920;
        desc.film.height = 1080;
        assert_eq!(order(&desc), ["photon", "sppm"]);
        desc.integrator.photon.photons = Some(1920 * 1080);
        assert_eq!(order(&desc), ["sppm", "photon"]);
    }

    /// Candidate `method` (its own label) with one pilot sample a half.
    fn one_sample(method: &'static str, model: Model) -> Candidate {
        Candidate {
            label: method.into(),
            method,
            subsurface: None,
            model,
            k: 1,
            caveat: None,
            photons: None,
        }
    }

    /// A Metropolis frame's bootstrap (100 000 brightness samples and as many bootstrap
    /// paths, whatever the film) is paid once by the render: the pilot counts it with the
    /// passes, not with the samples it scales to the full film. On a 16×16 film with one
    /// mutation per pixel a half, it is most of the pilot. Timed on one group of chains
    /// first, the pilot stops there when its frames cost more than is left.
    /// No time left, nor reusable work.
    const NOTHING_LEFT: Allowance = Allowance {
        left: 0.0,
        reusable: 0.0,
    };

    #[test]
    fn a_metropolis_pilot_counts_its_bootstrap_once_and_apart_from_its_samples() {
        let mut desc = scene("cornell-box");
        desc.film.width = 16;
        desc.film.height = 16;
        let mut built = built(&desc);
        for method in ["pssmlt", "mlt"] {
            let c = one_sample(method, Model::Unbiased);
            let Ok(Pilot::Ran(r)) =
                run(&c, &desc, desc.film, &mut built, 1, 2, Allowance::UNLIMITED)
            else {
                panic!("{method}'s pilot did not run");
            };
            assert!(
                r.setup_s > r.frame_s && r.frame_s > 0.0,
                "{method}: setup {} s, samples {} s",
                r.setup_s,
                r.frame_s
            );
            // With no time left it stops after one group of chains.
            match run(&c, &desc, desc.film, &mut built, 1, 2, NOTHING_LEFT) {
                Ok(Pilot::TooDear(why)) => assert!(why.contains("its two frames"), "{why}"),
                Ok(Pilot::Ran(_)) => panic!("{method}'s pilot ran with no time left"),
                Err(e) => panic!("{e}"),
            }
        }
    }

    /// The photon map's pilot times its passes' first tasks and stops there when they would
    /// cost more than is left, as SPPM's photons do; with time enough it builds them and
    /// hands them on.
    #[test]
    fn a_photon_map_pilot_stops_at_its_first_tasks_when_its_passes_cost_more_than_is_left() {
        let mut desc = scene("cornell-box");
        desc.film.width = 32;
        desc.film.height = 32;
        let mut built = built(&desc);
        let c = one_sample("photon", Model::Biased);
        match run(&c, &desc, desc.film, &mut built, 1, 2, NOTHING_LEFT) {
            Ok(Pilot::TooDear(why)) => assert!(why.contains("its passes would take"), "{why}"),
            Ok(Pilot::Ran(_)) => panic!("the photon map's pilot ran with no time left"),
            Err(e) => panic!("{e}"),
        }
        match run(&c, &desc, desc.film, &mut built, 1, 2, Allowance::UNLIMITED) {
            Ok(Pilot::Ran(r)) => assert!(!r.artifacts.is_empty(), "no photon map handed on"),
            Ok(Pilot::TooDear(why)) => panic!("{why}"),
            Err(e) => panic!("{e}"),
        }
    }

    /// The photon map's pilot renders its small film from the render's irradiance cache:
    /// built from the render's film under the render's key, so that the render takes every
    /// pass of the pilot's as its own, and the records are those the render would make. With
    /// the few photons the pilot measures first, the render the choice plans has the same
    /// keys.
    #[test]
    fn a_photon_map_pilot_builds_the_render_s_irradiance_cache() {
        let mut desc = scene("cornell-box");
        desc.film.width = 96;
        desc.film.height = 96;
        let pilot = pilot_desc(&desc);
        assert!(
            pilot.film.width < desc.film.width,
            "the pilot's film is the render's"
        );
        let mut built = built(&desc);
        let c = Candidate {
            photons: Some(FEW_PHOTONS),
            ..one_sample("photon", Model::Biased)
        };
        let Ok(Pilot::Ran(r)) = run(
            &c,
            &pilot,
            desc.film,
            &mut built,
            1,
            2,
            Allowance::UNLIMITED,
        ) else {
            panic!("the photon map's pilot did not run");
        };
        let mut render = desc.clone();
        Choice {
            method: "photon".into(),
            subsurface: None,
            photons: c.photons,
            spp: 1,
            target_error: None,
            report: Vec::new(),
        }
        .apply(&mut render);
        let job = Job::new(render.clone(), 1);
        let p = plan(&job).expect("the render plans");
        built.set_settings(&render);
        let local = Local::new(p.as_ref(), &built, &render, 2, &|_| {});
        local.passes().expect("the render's passes");
        let own = local.artifacts();
        let passes = p.passes();
        assert_eq!(passes.len(), 2, "photon maps and an irradiance cache");
        for pass in passes {
            let find = |a: &[(String, Loaded)]| {
                a.iter()
                    .find(|(k, _)| k == pass.key())
                    .map(|(_, l)| l.clone())
                    .unwrap_or_else(|| panic!("{} not among the artifacts", pass.name()))
            };
            let (pilot, render) = (find(&r.artifacts), find(&own));
            if let (Some(a), Some(b)) = (
                pilot.downcast_ref::<crate::irradiance::IrradianceCache>(),
                render.downcast_ref::<crate::irradiance::IrradianceCache>(),
            ) {
                assert!(!b.is_empty(), "the render's cache has records");
                assert_eq!(
                    a.records(),
                    b.records(),
                    "the pilot's records are the render's"
                );
            }
        }
    }

    /// The scene built from `desc`, with its settings.
    pub(super) fn built(desc: &SceneDesc) -> Scene {
        let mut scene = Scene::build(desc);
        scene.set_settings(desc);
        scene
    }

    /// The pool's path tracer has a caveat (caustics of a small light): for a target error it
    /// is measured last and the first two candidates (BDPT, VCM) whatever the pilot has
    /// spent; for the path tracer's own error at the job's spp it stays first. BDPT's caveat
    /// (the caustics are seen through the water) does not move it: it judges the others.
    #[test]
    fn a_path_tracer_with_a_caveat_is_measured_last_unless_its_error_is_the_goal() {
        let desc = scene("pool");
        let seen = sees_specular(&desc, &built(&desc), 1);
        assert!(seen);
        let labels = |goal| {
            let (mut list, _) = candidates(&desc, &analyze(&desc), seen);
            let always = measured_first(&mut list, goal);
            assert!(
                list.iter()
                    .find(|c| c.label == "bdpt")
                    .is_some_and(|c| c.caveat.is_some())
            );
            (
                always,
                list.into_iter().map(|c| c.label).collect::<Vec<_>>(),
            )
        };
        let (always, order) = labels(Goal::Error(0.01));
        assert_eq!(always, 2);
        assert_eq!(order[..2], ["bdpt", "vcm"]);
        assert_eq!(order.last().map(String::as_str), Some("path"));
        let (always, order) = labels(Goal::PathSpp(16));
        assert_eq!(always, ALWAYS_MEASURED);
        assert_eq!(order[..3], ["path", "bdpt", "vcm"]);
    }

    /// On the Cornell box, once the path tracer judges the goal alone, the photon map, then
    /// SPPM, are measured before BDPT, VCM and the Metropolis methods.
    #[test]
    fn once_the_judges_resolve_the_goal_the_biased_candidates_go_next() {
        let desc = scene("cornell-box");
        let (mut list, _) = candidates(&desc, &analyze(&desc), false);
        assert_eq!(
            measured_first(&mut list, Goal::Error(0.01)),
            ALWAYS_MEASURED
        );
        let mut order: Vec<usize> = (0..list.len()).collect();
        judged(&list, &mut order[1..]);
        let labels: Vec<&str> = order.iter().map(|&i| list[i].label.as_str()).collect();
        assert_eq!(
            labels,
            [
                "path",
                "photon",
                "photon:200000",
                "sppm",
                "bdpt",
                "vcm",
                "pssmlt",
                "mlt"
            ]
        );
    }

    /// A biased candidate whose turn comes while the judges cannot resolve the goal waits
    /// behind the judges still to come (PSSMLT, MLT), in its order; with none left after it,
    /// it is not measured.
    #[test]
    fn a_biased_candidate_waits_for_judges_that_can_tell_its_floor() {
        let desc = scene("cornell-glass");
        let (mut list, _) = candidates(&desc, &analyze(&desc), true);
        measured_first(&mut list, Goal::Error(0.01));
        let mut order: Vec<usize> = (0..list.len()).collect();
        let labels = |order: &[usize]| -> Vec<String> {
            order.iter().map(|&i| list[i].label.clone()).collect()
        };
        assert_eq!(
            labels(&order),
            [
                "bdpt",
                "vcm",
                "sppm",
                "photon",
                "photon:200000",
                "pssmlt",
                "mlt",
                "path"
            ]
        );
        assert!(defer(&list, &mut order, 3));
        assert!(defer(&list, &mut order, 3));
        assert_eq!(
            labels(&order),
            [
                "bdpt",
                "vcm",
                "sppm",
                "pssmlt",
                "mlt",
                "path",
                "photon",
                "photon:200000"
            ]
        );
        assert!(!defer(&list, &mut order, 6));
        assert!(!defer(&list, &mut order, 7));
        assert_eq!(labels(&order)[6..], ["photon", "photon:200000"]);
    }

    /// The photon map with the default count is measured only where the few photons' map
    /// cannot reach the goal (or the goal is a time's lowest error); a scene that sets its
    /// count has one photon-map candidate, with that count.
    #[test]
    fn more_photons_are_measured_only_where_few_cannot_reach_the_goal() {
        let desc = scene("cornell-box");
        let (list, _) = candidates(&desc, &analyze(&desc), false);
        let photon: Vec<_> = list.iter().filter(|c| c.method == "photon").collect();
        assert_eq!(photon.len(), 2);
        let (few, more) = (photon[0], photon[1]);
        assert_eq!(
            (few.photons, more.photons),
            (Some(FEW_PHOTONS), Some(DEFAULT_PHOTONS))
        );
        let measured = |predicted_s: Option<f64>| Measurement {
            label: few.label.clone(),
            pilot_s: 0.1,
            setup_s: 0.1,
            sample_s: 0.1,
            rel_var: 0.01,
            floor: Some(0.0),
            spp: predicted_s.map(|_| 2),
            predicted_s,
            predicted_error: None,
            note: None,
            caveat: None,
        };
        let e = Goal::Error(0.01);
        assert!(!more_photons_needed(more, &[measured(Some(0.5))], e));
        assert!(more_photons_needed(more, &[measured(None)], e));
        assert!(more_photons_needed(more, &[], e));
        assert!(more_photons_needed(
            more,
            &[measured(Some(0.5))],
            Goal::Seconds(1.0)
        ));
        assert!(more_photons_needed(few, &[measured(Some(0.5))], e));

        let mut own = desc.clone();
        own.integrator.photon.photons = Some(50_000);
        let (list, _) = candidates(&own, &analyze(&own), false);
        let photon: Vec<_> = list.iter().filter(|c| c.method == "photon").collect();
        assert_eq!(photon.len(), 1);
        assert_eq!(
            (photon[0].label.as_str(), photon[0].photons),
            ("photon", None)
        );
    }

    /// BDPT has a caveat where caustics of a concentrated light are seen in a specular
    /// surface: the glass box's camera sees its sphere, the plain box's sees nothing specular
    /// (and has no such caustics).
    #[test]
    fn bdpt_has_a_caveat_where_caustics_are_seen_in_a_specular_surface() {
        let caveat = |name: &str| {
            let desc = scene(name);
            let seen = sees_specular(&desc, &built(&desc), 1);
            let (list, _) = candidates(&desc, &analyze(&desc), seen);
            let bdpt = list.into_iter().find(|c| c.label == "bdpt");
            (seen, bdpt.and_then(|c| c.caveat))
        };
        let (seen, glass) = caveat("cornell-glass");
        assert!(seen);
        assert!(
            glass
                .as_ref()
                .is_some_and(|c| c.contains("seen in a specular surface")),
            "{glass:?}"
        );
        assert_eq!(caveat("cornell-box"), (false, None));
        // The same caustics unseen: no caveat.
        let desc = scene("cornell-glass");
        let (list, _) = candidates(&desc, &analyze(&desc), false);
        assert!(list.iter().all(|c| c.label != "bdpt" || c.caveat.is_none()));
    }
}
