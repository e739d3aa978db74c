//! More samples for the judges where their consensus cannot resolve the goal: a biased
//! candidate's floor is told against them, and under their own relMSE it cannot be, so the
//! photon map would go unmeasured (and unchosen) for want of a few more samples of a cheap
//! unbiased pilot. See the parent module's closing paragraph.

use tessera_scene::{FilmDesc, SceneDesc};

use super::Candidate;
use super::predict::judges;
use super::run::{Allowance, Halves, Pilot, Run, run};
use crate::scene::Scene;

/// The judges are deepened until their predicted relMSE is this share of the goal: under the
/// goal itself ([`super::predict`]'s `resolves`) with room for their own estimate's noise.
pub(super) const DEEPEN_TO: f64 = 0.7;
/// Samples a half of the probe the path tracer, measured first, renders before the rest of
/// its pilot ([`probed`]).
pub(super) const PROBE: u32 = 2;

/// Seed offsets of the pilots' extra samples (the halves take the job's seed and, where a
/// method cannot continue a frame, the next): a probe's extension and a judge's deepening
/// render the same candidate apart, so at seeds of their own.
const PROBE_SEED: u64 = 4;
const DEEPEN_SEED: u64 = 2;
/// The judges take at most this many times their samples. Deepening is worth its cost where
/// the judges' few samples came near the goal; one much further is a goal their consensus
/// would cost more to resolve than the candidates it judges (a render reaching it in a few
/// samples where the judges need hundreds) take to render.
pub(super) const MAX_DEEPEN: f64 = 3.0;

/// Where a pilot's further samples render: the pilot's scene (film and seed), the render's
/// film, and the scene, frame and threads its runs took.
pub(super) struct Again<'a> {
    pub(super) pilot: &'a SceneDesc,
    pub(super) film: FilmDesc,
    pub(super) scene: &'a mut Scene,
    pub(super) frame: u32,
    pub(super) threads: usize,
}

/// Whether judges of relMSE `judges_rel`, with `to_come` judges still to be measured, could
/// tell a floor under the goal `e` deepened: at best each judge to come is as quiet as the
/// consensus so far (their consensus's relMSE falls as 1 / (1 + `to_come`)), and all of them
/// take at most [`MAX_DEEPEN`] times their samples.
pub(super) fn within_reach(judges_rel: f64, e: f64, to_come: usize) -> bool {
    judges_rel / (1 + to_come) as f64 <= MAX_DEEPEN * DEEPEN_TO * e
}

/// More samples a half for each judge (index into `runs`, samples), for judges of relMSE
/// `judges_rel` to reach [`DEEPEN_TO`] of the goal `e`, and the seconds they are predicted to
/// take; an error where that is more than [`MAX_DEEPEN`] times their samples. Every judge
/// takes the same share more: their consensus's relMSE falls as 1 / k, and each judge's
/// variance is also measured against the others (paths its halves both missed), which
/// stays fair only while none is much quieter than the rest.
fn plan(
    candidates: &[Candidate],
    runs: &[(usize, Run)],
    judges_rel: f64,
    e: f64,
) -> Result<(Vec<(usize, u32)>, f64), String> {
    let factor = judges_rel / (DEEPEN_TO * e);
    if factor.is_nan() || factor <= 1.0 {
        return Err(format!(
            "the judges' relMSE {judges_rel:.2e} is already under {e:.2e}"
        ));
    }
    if factor > MAX_DEEPEN {
        return Err(format!(
            "their relMSE {judges_rel:.2e} would need {factor:.1} times their samples to tell a floor under {e:.2e}, more than {MAX_DEEPEN}"
        ));
    }
    let mut seconds = 0.0;
    let more = judges(candidates, runs)
        .into_iter()
        .map(|j| {
            let (i, r) = &runs[j];
            let k = candidates[*i].k;
            let more = (k as f64 * (factor - 1.0)).ceil() as u32;
            seconds += r.frame_s * more as f64 / k as f64;
            (j, more)
        })
        .collect();
    Ok((more, seconds))
}

/// Halves of `k` and `more` samples a half, independent of each other: the halves of all
/// k + more, each pixel the samples' mean.
fn merge(first: &Halves, k: u32, second: &Halves, more: u32) -> Halves {
    let (wa, wb) = {
        let n = (k + more) as f64;
        (k as f64 / n, more as f64 / n)
    };
    let mix = |x: &[[f64; 3]], y: &[[f64; 3]]| -> Vec<[f64; 3]> {
        x.iter()
            .zip(y)
            .map(|(p, q)| [0, 1, 2].map(|c| wa * p[c] + wb * q[c]))
            .collect()
    };
    let a = mix(&first.a, &second.a);
    let b = mix(&first.b, &second.b);
    let both = a
        .iter()
        .zip(&b)
        .map(|(p, q)| [0, 1, 2].map(|c| 0.5 * (p[c] + q[c])))
        .collect();
    Halves { a, b, both }
}

/// Deepens the judges, where their relMSE (`judges_rel`) is not under the goal `e` but comes
/// within [`MAX_DEEPEN`] of doing so and the extra samples fit in `left` seconds: renders each
/// judge's pilot again with more samples at seeds of its own and merges them into its run.
/// Returns what it did, for the report, or why not.
pub(super) fn deepen(
    candidates: &mut [Candidate],
    runs: &mut [(usize, Run)],
    judges_rel: f64,
    e: f64,
    left: f64,
    at: &mut Again,
) -> Result<String, String> {
    let (more, seconds) = plan(candidates, runs, judges_rel, e)?;
    if seconds > left {
        return Err(format!(
            "their relMSE {judges_rel:.2e} would need {seconds:.2} s more of their pilots to tell a floor under {e:.2e}, more than the {:.2} s left",
            left.max(0.0)
        ));
    }
    let mut done = Vec::new();
    for (j, more) in more {
        let label = candidates[runs[j].0].label.clone();
        let s = extend(candidates, runs, j, more, DEEPEN_SEED, at)?;
        done.push(format!("{label} {more} ({s:.2} s)"));
    }
    Ok(format!(
        "judges deepened so that they (relMSE {judges_rel:.2e}) can tell a floor under {e:.2e}: more samples a half of {}",
        done.join(", ")
    ))
}

/// A candidate measured at [`PROBE`] samples a half (`runs[j]`, `k` the samples it was
/// planned with; `judges_rel` the relMSE of its image, the only judge yet; `to_come` the
/// judges still to be measured whatever the pilot spends): where at `k` samples it could
/// resolve the goal `e`, with those to come and deepened ([`within_reach`]), it renders the
/// rest of them; where it could not, it is not the judge that settles the goal, and its probe
/// stands as its measurement, which saves the rest. The path tracer (`to_come` 0: it judges
/// alone or not at all) is probed first; where its probe stood, the scene's light is one it
/// finds too rarely, and the first bidirectional judge is probed too. Returns what it did,
/// for the report.
#[allow(clippy::too_many_arguments)]
pub(super) fn probed(
    candidates: &mut [Candidate],
    runs: &mut [(usize, Run)],
    j: usize,
    k: u32,
    judges_rel: f64,
    to_come: usize,
    e: f64,
    at: &mut Again,
) -> Result<String, String> {
    let label = candidates[runs[j].0].label.clone();
    let at_k = judges_rel * f64::from(PROBE) / f64::from(k);
    if !within_reach(at_k, e, to_come) {
        let with = match to_come {
            0 => String::new(),
            n => format!(" with the {n} still to come as quiet"),
        };
        return Ok(format!(
            "{label} measured at {PROBE} samples a half: at {k} its relMSE ({at_k:.2e}) could not tell a floor under {e:.2e}{with} even with {MAX_DEEPEN} times the samples"
        ));
    }
    let s = extend(candidates, runs, j, k - PROBE, PROBE_SEED, at)?;
    Ok(format!(
        "{label} probed at {PROBE} samples a half, then {} more ({s:.2} s)",
        k - PROBE
    ))
}

/// Renders `more` samples a half of the candidate of `runs[j]` at the pilot's seed plus
/// `seed` and merges them into its run; returns their wall seconds.
fn extend(
    candidates: &mut [Candidate],
    runs: &mut [(usize, Run)],
    j: usize,
    more: u32,
    seed: u64,
    at: &mut Again,
) -> Result<f64, String> {
    let i = runs[j].0;
    let mut other = at.pilot.clone();
    other.integrator.seed = other.integrator.seed.wrapping_add(seed);
    let extra = Candidate {
        k: more,
        ..candidates[i].clone()
    };
    let Pilot::Ran(second) = run(
        &extra,
        &other,
        at.film,
        at.scene,
        at.frame,
        at.threads,
        Allowance::UNLIMITED,
    )?
    else {
        return Err(format!("{}'s pilot did not run again", candidates[i].label));
    };
    let k = candidates[i].k;
    let first = &mut runs[j].1;
    first.images = merge(&first.images, k, &second.images, more);
    first.frame_s += second.frame_s;
    first.pixels_s = first.pixels_s.zip(second.pixels_s).map(|(a, b)| a + b);
    first.pilot_s += second.pilot_s;
    candidates[i].k = k + more;
    Ok(second.pilot_s)
}

#[cfg(test)]
mod tests {
    use super::super::predict::predict;
    use super::super::predict::tests::{Noise, PIXELS, candidate, run};
    use super::super::{Goal, Model};
    use super::*;

    /// Two judges whose consensus (relMSE 1.2e-2) cannot tell a floor under the goal 1e-2,
    /// one four times dearer a sample: both get the same share more samples, which brings
    /// the consensus to [`DEEPEN_TO`] of the goal, and once they are merged into their halves
    /// the judges resolve the goal and the photon map, unpredicted before, is predicted.
    /// Judges far from the goal are not deepened.
    #[test]
    fn judges_near_the_goal_are_deepened_until_they_resolve_it() {
        let mut noise = Noise(0x2545_f491_4f6c_dd1d);
        let e = 1e-2;
        // Pixels of 1 divide by 1.01: one sample's relMSE v = σ² / 1.01, and two judges of 4
        // samples a half make a consensus of v / 16.
        let v = 16.0 * 1.2e-2;
        let sigma = (v * 1.01_f64).sqrt();
        let mut candidates = vec![
            candidate("bdpt", Model::Unbiased, 4),
            candidate("vcm", Model::Unbiased, 4),
            candidate("photon", Model::Biased, 4),
        ];
        let mut runs = vec![
            (0, run(&mut noise, 1.0, sigma, 4.0)),
            (1, run(&mut noise, 1.0, sigma, 4.0)),
            (2, run(&mut noise, 1.0, 0.1, 4.0)),
        ];
        runs[0].1.frame_s = 4.0;
        let film = (40, PIXELS as u32 / 40);
        let p = predict(&candidates, &runs, Goal::Error(e), film, 4 * PIXELS as u64);
        assert!(!p.resolves(), "judges' relMSE {}", p.judges);
        assert!(p.measurements[2].predicted_s.is_none());

        // (Each judge's variance is the larger of two estimates: a little over.)
        assert!(
            (p.judges / 1.2e-2 - 1.0).abs() < 0.1,
            "judges' relMSE {}",
            p.judges
        );
        let (more, seconds) = plan(&candidates, &runs, 1.2e-2, e).expect("judges to deepen");
        // 1.2e-2 / (DEEPEN_TO e) times their 4 samples a half: the excess, rounded up.
        assert_eq!(more, vec![(0, 3), (1, 3)]);
        // Each run's frame_s (set above) over its 4 samples a half, times the samples added.
        assert!((seconds - 5.0 * 3.0 / 4.0).abs() < 1e-9, "{seconds} s");

        for (j, more) in more {
            let extra = run(&mut noise, 1.0, sigma, more as f64);
            runs[j].1.images = merge(&runs[j].1.images, 4, &extra.images, more);
            candidates[j].k += more;
        }
        let p = predict(&candidates, &runs, Goal::Error(e), film, 4 * PIXELS as u64);
        assert!(p.resolves(), "judges' relMSE {}", p.judges);
        assert!(
            (p.judges / (DEEPEN_TO * e) - 1.0).abs() < 0.15,
            "judges' relMSE {}, aimed at about {}",
            p.judges,
            DEEPEN_TO * e
        );
        assert!(p.measurements[2].predicted_s.is_some());

        // Judges at three times the goal would need over four times their samples.
        let far = plan(&candidates, &runs, 3.0 * e, e).expect_err("too far to deepen");
        assert!(far.contains("times their samples"), "{far}");
    }

    /// Judges are within reach where [`MAX_DEEPEN`] times their samples would bring them to
    /// [`DEEPEN_TO`] of the goal; each judge still to come, at best as quiet as the
    /// consensus so far, divides what they need.
    #[test]
    fn judges_to_come_bring_a_goal_within_reach() {
        let e = 1e-2;
        let edge = MAX_DEEPEN * DEEPEN_TO * e;
        assert!(within_reach(edge, e, 0));
        assert!(!within_reach(1.01 * edge, e, 0));
        assert!(within_reach(1.99 * edge, e, 1));
        assert!(!within_reach(2.01 * edge, e, 1));
        assert!(within_reach(2.99 * edge, e, 2));
        assert!(!within_reach(f64::INFINITY, e, 3));
    }

    fn flat(v: f64, n: usize) -> Vec<[f64; 3]> {
        vec![[v; 3]; n]
    }

    /// Merged halves weigh each run by its samples, and stay two halves: a of both runs' a,
    /// b of both runs' b.
    #[test]
    fn merged_halves_are_means_of_all_their_samples() {
        let first = Halves {
            a: flat(1.0, 4),
            b: flat(3.0, 4),
            both: flat(2.0, 4),
        };
        let second = Halves {
            a: flat(4.0, 4),
            b: flat(0.0, 4),
            both: flat(2.0, 4),
        };
        let m = merge(&first, 2, &second, 6);
        assert_eq!(m.a[0], [0.25 * 1.0 + 0.75 * 4.0; 3]);
        assert_eq!(m.b[3], [0.25 * 3.0; 3]);
        assert_eq!(m.both[1], [0.5 * (3.25 + 0.75); 3]);
    }
}
