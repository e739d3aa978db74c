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
//!    least 256, at most 4096; a Mitchell filter as a box, whose weights cannot cancel, but for
//!    SPPM, whose pixels divide by T·E[w] and whose weights' noise is part of its error; in
//!    tiles small enough for every thread to have some) with
//!    `k` samples, then `k` more, as two independent halves A and B (where the method cannot
//!    continue a frame, a second render with the next seed). The relMSE of one half is
//!    estimated as mean((A − B)² / 2 / (R̄² + 0.01)) over pixels and channels (this mean, and
//!    every relMSE below, counts its largest pixel as the next largest: one rare bright path
//!    caught by a pilot does not rate a method alone; [`predict::rel`]), R being the
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
//!    holds photons of many iterations, its bias with the mean squared radius s(n) (a share of
//!    the initial one), which the radii module follows from the photons each pixel of the
//!    first half found: dense pixels shrink as Knaus & Zwicker's n^(α − 1), sparse ones slower.
//!    Kernel bias falls as r⁴ where the radiance is smooth and as r across its edges; r², what
//!    is taken, fitted the material spheres' errors at two iteration counts, though their bias, split
//!    from their variance with a second seed, falls slower still.
//! 3. **Prediction** at full size: samples to reach relMSE E are v / E (unbiased),
//!    v / (E − b) (photon map; none if b is near E, or if the judges' own relMSE is, under
//!    which b cannot be told from their noise), the least n with
//!    v / n + b s(n) / s̄ ≤ E (SPPM; s̄ the mean of s over the pilot's k iterations); time is
//!    what the render pays once (the passes, view-independent, and a Metropolis frame's
//!    bootstrap, both as the pilot timed them) plus the samples at the pilot's time per sample
//!    and pixel (SPPM's photons, shot whatever the film, at the pilot's time per iteration).
//!    The goal is a relMSE (`target_error`), the error path tracing reaches at the job's spp
//!    (the same image quality, sooner), or the lowest error within a time. The candidate
//!    chosen ends soonest from the pilot's end: its time less the pilot's work its render
//!    takes over ([`Measurement::handed_s`]), which is done.
//!
//! The first three candidates are measured whatever the pilot spends, until the judges measured
//! so far resolve the goal (their own relMSE under it, so a floor at the goal can be told from
//! their noise; on the Cornell box the path tracer alone does), or could not even with the
//! judges still to come as quiet as their consensus and deepened as below
//! ([`deepen::within_reach`]; after BDPT on the indirect room): the unbiased ones left then go
//! after the biased ones ([`judged`]), within the shares. The path tracer, first for a target
//! error, renders a probe of [`deepen::PROBE`] samples a half, and the rest of its samples only
//! where at all of them it could resolve the goal alone ([`deepen::probed`]); where it could
//! not, the bidirectional judges after it are the consensus, and its probe stands as its
//! measurement (of a method then far behind); the first of those judges is then probed too,
//! and stands at its probe where even at all its samples, with the judges still to come as
//! quiet, it could not resolve the goal (on the indirect room). Where they do not, and a
//! biased candidate is still to come, every judge renders more samples at seeds of its own
//! until their relMSE is predicted at [`deepen::DEEPEN_TO`] of the goal, if that takes at most [`deepen::MAX_DEEPEN`] times
//! their samples and fits in the pilot's shares below ([`deepen()`], which the report names):
//! a near miss of a cheap measure, such as the glass's judges at a few samples, would
//! otherwise leave the photon map unmeasured. Where the judges still do not resolve the goal,
//! a biased candidate such as the photon map (whose floor they could not tell, so it could not
//! be chosen) waits behind the judges still to come, and is not measured if none is
//! ([`defer`]). After the first candidates, whose cost is sunk, the pilot stops measuring once
//! it has spent a tenth of the best prediction so far (of a candidate without a caveat) on the
//! others, or once the whole pilot has cost a fifteenth of it beyond the work that candidate's
//! render would take over from it ([`PILOT_OVERHEAD`]: on a long render the first candidates
//! count too; it does not stop a biased candidate, whose pilot is mostly work its render takes
//! over), or would with SPPM's photons (timed on their first chunk), a candidate's passes
//! (timed on their first tasks, with what follows the tasks estimated from them: the photon
//! map's) or a Metropolis pilot's frames
//! (timed on one group of chains); the photons and passes, which the render takes over where
//! that candidate wins, count at the odds of that candidate losing ([`Allowance::of`]).
//! Candidates not measured are said to be. A Metropolis frame's bootstrap, which grows with
//! neither pixels nor samples, counts with the passes as paid once. Candidates run in the order
//! path, BDPT, VCM (unbiased: the consensus needs them), SPPM (two iterations' photons), photon
//! map (a whole photon map: where the scene sets no photon count, first of [`FEW_PHOTONS`],
//! then of the default count only where the few cannot reach the goal, the render taking the
//! count of the one chosen), PSSMLT, MLT — the photon map before SPPM where the film has more
//! pixels than an SPPM iteration has photons, and a path tracer with a caveat last unless the
//! goal is its own error at the job's spp; the photons and the photon map are reused by the
//! render where that method wins.

use std::time::Instant;

use tessera_scene::{SceneDesc, SubsurfaceMethod};

use super::Choice;
use crate::analysis::analyze;
use crate::film::MAX_SPP;
use crate::method::{Job, Loaded, Model, Probe, Transport, plan};
use crate::scene::Scene;

mod deepen;
mod order;
mod predict;
mod progressive;
mod radii;
mod run;
use deepen::{Again, MAX_DEEPEN, PROBE, deepen, probed, within_reach};
pub use order::FEW_PHOTONS;
use order::{candidates, defer, judged, measured_first, more_photons_needed, sees_specular};
use predict::{choose, describe, predict};
use run::{Allowance, Halves, Pilot, Run, pilot_desc, run};

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

#[derive(Clone)]
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
    /// Whether its pilot judges the others (is part of their consensus): the unbiased
    /// candidates whose pilot sees every path, or where none does, every unbiased one. A
    /// pilot that traces from the camera only does not see the paths it finds too rarely
    /// (caustics of small lights, light seen through glass), which make its image dark there
    /// and its variance look small ([`crate::method::Sight`]).
    judges: bool,
    /// Times a small part of its pilot first ([`crate::method::PilotInfo::probe`]).
    probe: Option<Probe>,
}

impl Candidate {
    /// Whether its pilot judges the others ([`Candidate::judges`](struct@Candidate)); one
    /// that does not judges only where no judge was measured.
    fn judges(&self) -> bool {
        self.judges
    }
}

/// One candidate as the pilot measured it, and what it predicts at full size.
#[derive(Debug, Clone)]
pub struct Measurement {
    pub label: String,
    /// Wall seconds of the pilot (both halves and the passes).
    pub pilot_s: f64,
    /// Wall seconds of the pilot's work the render takes over where this candidate wins (its
    /// passes, SPPM's photons): not a cost of the pilot then.
    pub handed_s: f64,
    /// Wall seconds the render pays once, whatever its pixels and samples: the
    /// view-independent passes (photon maps, point clouds) and a Metropolis frame's bootstrap.
    pub setup_s: f64,
    /// Wall seconds per sample per pixel over the full film.
    pub sample_s: f64,
    /// relMSE of a one-sample image: variance only.
    pub rel_var: f64,
    /// relMSE that more samples do not remove (photon map), or SPPM's bias at the pilot's
    /// iterations (0 where the consensus is too noisy to tell it: see `untold`).
    pub floor: Option<f64>,
    /// The judges' relMSE, where SPPM's bias came out under it and was taken as 0: it may be
    /// anything up to about that, which the prediction does not count.
    pub untold: Option<f64>,
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
    /// Wall seconds of them that the render takes over: the chosen candidate's passes and
    /// photons ([`Measurement::handed_s`]).
    pub handed_s: f64,
    /// The passes the chosen method's pilot built with the job's seed, by key: a render of
    /// the chosen method takes those whose key it shares (view-independent ones such as
    /// photon maps) instead of building them again.
    pub artifacts: Vec<(String, Loaded)>,
}

/// How much of a pilot the render took over ([`Selection::handed_s`]), as the summaries say
/// it after the pilot's seconds: nothing where it took over none.
pub fn handed_on(handed_s: f64) -> String {
    if handed_s >= 0.005 {
        format!(", {handed_s:.2} s of it the render's own passes or photons")
    } else {
        String::new()
    }
}

/// `dipole`, `hierarchical`, `random-walk`.
pub fn subsurface_name(s: SubsurfaceMethod) -> &'static str {
    match s {
        SubsurfaceMethod::Dipole => "dipole",
        SubsurfaceMethod::Hierarchical => "hierarchical",
        SubsurfaceMethod::RandomWalk => "random-walk",
    }
}

/// The pilot stops once it has spent this share of the best prediction on the candidates
/// after those it measures whatever it spends ([`order::ALWAYS_MEASURED`]).
const PILOT_SHARE: f64 = 0.1;
/// It also stops once the whole pilot, those first candidates included, has cost this share
/// of the best prediction, less the work the render would take over from it (the best
/// candidate's passes or photons, [`Measurement::handed_s`]): a long render's pilot stays
/// under a tenth of it, with room for the prediction to err and for the last candidate
/// measured to overshoot. It stops the unbiased candidates only: a biased one's pilot is
/// mostly work its render takes over (the photon map's passes, SPPM's photons, the
/// hierarchical method's point cloud; the dipole's, without any, is a few path-traced
/// samples), which the tenth counts at the odds that it loses ([`Allowance::of`]).
const PILOT_OVERHEAD: f64 = 1.0 / 15.0;
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

/// What the pilot's shares are of: the goal's time, else the soonest prediction of a
/// candidate without a caveat (infinite where there is none); and the pilot's work that
/// candidate's render would take over ([`Measurement::handed_s`]).
fn pilot_budget(measurements: &[Measurement], goal: Goal) -> (f64, f64) {
    let (best, handed) = measurements
        .iter()
        .filter(|m| m.caveat.is_none())
        .filter_map(|m| Some((m.predicted_s?, m.handed_s)))
        .fold((f64::INFINITY, 0.0), |a, b| if b.0 < a.0 { b } else { a });
    match goal {
        Goal::Seconds(t) => (t, handed),
        _ => (best, handed),
    }
}

/// Seconds the pilot may still spend under both shares of `budget`, having spent `spent` on
/// the candidates after the first and `overhead` on work the render would not take over.
fn shares_left(budget: f64, spent: f64, overhead: f64) -> f64 {
    (PILOT_SHARE * budget - spent).min(PILOT_OVERHEAD * budget - overhead)
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
    if analysis.transport == Transport::Direct {
        let reason = analysis
            .decisions
            .first()
            .map_or(String::new(), |d| d.reason.clone());
        let method = crate::method::for_transport(analysis.transport)?.name;
        return Ok(Selection {
            choice: Choice {
                method: method.into(),
                subsurface: None,
                photons: None,
                spp: desc.integrator.spp,
                target_error: match goal {
                    Goal::Error(e) => Some(e),
                    _ => None,
                },
                report: vec![format!("chose {method} without a pilot: {reason}")],
            },
            measurements: Vec::new(),
            pilot_s: 0.0,
            handed_s: 0.0,
            artifacts: Vec::new(),
        });
    }
    let seen = sees_specular(desc, scene, frame);
    let (mut candidates, mut ruled_out) = candidates(desc, &analysis, seen);
    let mut always = measured_first(&mut candidates, goal);
    let film = (desc.film.width as u64) * (desc.film.height as u64);
    let pilot = pilot_desc(desc);
    let predicted = |candidates: &[Candidate], runs: &[(usize, Run)]| {
        predict(
            candidates,
            runs,
            goal,
            (pilot.film.width, pilot.film.height),
            film,
        )
    };

    let mut runs: Vec<(usize, Run)> = Vec::new();
    let mut measurements = Vec::new();
    // What the pilot did beyond measuring each candidate once, for the report.
    let mut notes: Vec<String> = Vec::new();
    let mut target = None;
    // Candidates by index into `candidates`, in the order they are measured.
    let mut order: Vec<usize> = (0..candidates.len()).collect();
    // When the candidates measured whatever the pilot spends were done: the share is of what
    // the pilot spends after them (their cost is sunk; what is left to decide is whether the
    // others are worth measuring).
    let mut judges_done: Option<f64> = None;
    // Whether the judges measured so far cannot tell a floor at the goal from their noise.
    let mut unresolved = false;
    // Whether the path tracer's probe stood as its measurement ([`probed`]).
    let mut path_probe_stood = false;
    // Where the candidates' pilots render: their probes, extensions and deepening too.
    let mut at = Again {
        pilot: &pilot,
        film: desc.film,
        scene,
        frame,
        threads,
    };
    let mut n = 0;
    while let Some(&i) = order.get(n) {
        let c = &candidates[i];
        let elapsed = start.elapsed().as_secs_f64();
        let (budget, handed) = pilot_budget(&measurements, goal);
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
        // The whole pilot less what the best candidate's render would take over from it;
        // it stops unbiased candidates only ([`PILOT_OVERHEAD`]).
        let overhead = elapsed - handed;
        if !anyway && c.model == Model::Unbiased && overhead > PILOT_OVERHEAD * budget {
            ruled_out.push(format!(
                "{}: not measured: the pilot had cost {overhead:.2} s beyond the work the render would take over from it, a fifteenth of the best prediction ({budget:.2} s)",
                c.label
            ));
            continue;
        }
        // What is left of both shares, for a candidate that can tell its cost before its
        // pilot: its reusable work counts against the first only, as it did.
        let allowance = if anyway {
            Allowance::UNLIMITED
        } else {
            Allowance {
                left: shares_left(budget, spent, overhead),
                ..Allowance::of(PILOT_SHARE * budget - spent, budget)
            }
        };
        // The path tracer, measured first for a target error, renders a probe before the
        // rest of its pilot ([`probed`]); so does the first judge after a probe that stood
        // (a scene whose light the path tracer could not find at a few samples).
        let first_judge =
            c.judges() && path_probe_stood && !runs.iter().any(|(j, _)| candidates[*j].judges());
        let probe = match goal {
            Goal::Error(e)
                if anyway
                    && c.k > PROBE
                    && c.model == Model::Unbiased
                    && (!c.judges() || first_judge) =>
            {
                Some((e, c.k))
            }
            _ => None,
        };
        let c = Candidate {
            k: probe.map_or(c.k, |_| PROBE),
            ..c.clone()
        };
        match run(&c, at.pilot, at.film, at.scene, at.frame, at.threads, allowance) {
            Ok(Pilot::Ran(r)) => {
                candidates[i].k = c.k;
                runs.push((i, r));
            }
            Ok(Pilot::TooDear(why)) => ruled_out.push(format!(
                "{}: not measured: {why}, past the pilot's shares of the best prediction ({budget:.2} s)",
                c.label
            )),
            Err(e) => ruled_out.push(format!("{}: cannot run: {e}", c.label)),
        }
        let mut p = predicted(&candidates, &runs);
        // The judges measured whatever the pilot spends that are still to come.
        let to_come = order[n..always.max(n)]
            .iter()
            .filter(|&&j| candidates[j].judges())
            .count();
        if let Some((e, k)) = probe.filter(|_| runs.last().is_some_and(|(j, _)| *j == i)) {
            let j = runs.len() - 1;
            let probe = probed(
                &mut candidates,
                &mut runs,
                j,
                k,
                p.judges,
                if c.judges() { to_come } else { 0 },
                e,
                &mut at,
            );
            notes.push(probe.unwrap_or_else(|why| {
                format!(
                    "{}: measured at its probe's {PROBE} samples a half: {why}",
                    c.label
                )
            }));
            path_probe_stood |= !c.judges() && candidates[i].k == PROBE;
            p = predicted(&candidates, &runs);
        }
        // A judge measured whatever the pilot spends, after which the judges still to come
        // could not resolve the goal even as quiet as the consensus so far and deepened: more
        // of them would tell no floor, so they are measured as the others, within the shares.
        if let Some(e) = p.target.filter(|&e| {
            anyway
                && c.judges()
                && to_come > 0
                && !p.resolves()
                && !within_reach(p.judges, e, to_come)
        }) {
            notes.push(format!(
                "judges measured whatever the pilot spends stopped after {}: their relMSE {:.2e} could not tell a floor under {e:.2e} with the {to_come} still to come as quiet and {MAX_DEEPEN} times the samples; those are measured as the others",
                c.label, p.judges
            ));
            always = n;
            judged(&candidates, &mut order[n..]);
        }
        // The first candidates measured, their consensus cannot tell a floor at the goal,
        // and a biased candidate is still to come: more samples of every judge may let it,
        // within the pilot's shares (they count as spent on the candidates after them).
        if let Some(e) = p.target.filter(|_| {
            n == always
                && !p.resolves()
                && order[n..]
                    .iter()
                    .any(|&j| candidates[j].model == Model::Biased)
        }) {
            let elapsed = start.elapsed().as_secs_f64();
            judges_done = Some(elapsed);
            let (budget, handed) = pilot_budget(&p.measurements, goal);
            let left = shares_left(budget, 0.0, elapsed - handed);
            let deepened = deepen(&mut candidates, &mut runs, p.judges, e, left, &mut at);
            match deepened {
                Ok(what) => {
                    notes.push(what);
                    p = predicted(&candidates, &runs);
                }
                Err(why) => notes.push(format!("judges not deepened: {why}")),
            }
        }
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
    // Where the method refines tiles, or stops at the target (SPPM, where the pilot told no
    // bias: its estimate, which the stop reads, is its variance alone, as the prediction
    // was), a target error stays adaptive.
    let adaptive = match goal {
        Goal::Error(e) if c.model != Model::Progressive || m.floor.is_none_or(|b| b == 0.0) => {
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
    // A bias the judges could not tell from their noise, at the goal or over it.
    let untold = match (m.untold, target) {
        (Some(j), Some(e)) if j >= e => format!(
            "; its bias could not be told from the judges' noise (relMSE {j:.2e}) and was taken as 0, so the error it reaches may be higher"
        ),
        _ => String::new(),
    };
    let mut report = vec![format!(
        "chose {}{} at {spp} {}: predicted {:.2} s to {} (pilot {pilot_s:.2} s{}{}){untold}",
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
        handed_on(m.handed_s),
        m.predicted_s
            .map(|t| format!(
                "; the rest {:.0} % of that",
                100.0 * (pilot_s - m.handed_s) / t
            ))
            .unwrap_or_default(),
    )];
    for o in &measurements {
        report.push(describe(o));
    }
    report.extend(notes);
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
        handed_s: m.handed_s,
        measurements,
        pilot_s,
    })
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

    /// Candidate `method` (its own label) with one pilot sample a half.
    pub(super) fn one_sample(method: &'static str, model: Model) -> Candidate {
        let pilot = crate::method::lookup(method).ok().and_then(|m| m.pilot);
        Candidate {
            label: method.into(),
            method,
            subsurface: None,
            model,
            k: 1,
            caveat: None,
            photons: None,
            judges: model == Model::Unbiased
                && pilot.is_none_or(|p| p.sight != crate::method::Sight::CameraOnly),
            probe: pilot.and_then(|p| p.probe),
        }
    }

    /// The scene built from `desc`, with its settings.
    pub(super) fn built(desc: &SceneDesc) -> Scene {
        let mut scene = Scene::build(desc);
        scene.set_settings(desc);
        scene
    }
}
