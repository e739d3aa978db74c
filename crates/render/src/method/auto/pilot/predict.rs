//! From the pilots' images to predictions: the consensus of the unbiased candidates, each
//! candidate's variance per sample and floor (bias) against it, its samples and time to the
//! goal (the models of [`Model`]), and the choice.

use super::{Candidate, FLOOR_MARGIN, Goal, Halves, MAX_SPP, Measurement, Model, Run};

/// mean over pixels and channels of f(pixel, channel) / (r² + 0.01), the pixel with the
/// largest term counted as the next largest.
///
/// A pilot of a few thousand samples that catches one rare bright path (a caustic of a sun,
/// seen in a mirror) in one pixel would otherwise be rated by that path alone: its square
/// outweighs the thousands of others, and whether a pilot catches it is luck, so the
/// candidate's predicted time would follow the seed. Where such paths are common enough to
/// weigh in the render, several pixels show them and the estimate keeps all but one.
pub(super) fn rel(r: &[[f64; 3]], f: impl Fn(usize, usize) -> f64) -> f64 {
    let (mut sum, mut first, mut second) = (0.0, 0.0_f64, 0.0_f64);
    for (p, rp) in r.iter().enumerate() {
        let term: f64 = rp
            .iter()
            .enumerate()
            .map(|(ch, &v)| f(p, ch) / (v * v + 0.01))
            .sum();
        sum += term;
        if term > first {
            second = first;
            first = term;
        } else if term > second {
            second = term;
        }
    }
    let sum = if r.len() > 1 {
        sum - first + second
    } else {
        sum
    };
    sum / (3 * r.len().max(1)) as f64
}

/// What relMSE divides by: each pixel of `r` (rows of `width`) averaged with its 3 × 3
/// neighbours inside the image. A pilot's consensus has few samples a pixel, and 1 / (r² +
/// 0.01) of a noisy r is largest (Jensen) where r came out low, which is where the noisiest
/// candidate differs most; the neighbourhood's mean is about as high as r's expectation but
/// several times quieter.
pub(super) fn divisor(r: &[[f64; 3]], width: usize) -> Vec<[f64; 3]> {
    let width = width.max(1);
    let height = r.len().div_ceil(width);
    let mut out = vec![[0.0; 3]; r.len()];
    for (p, o) in out.iter_mut().enumerate() {
        let (x, y) = (p % width, p / width);
        let mut n = 0.0;
        for ny in y.saturating_sub(1)..(y + 2).min(height) {
            for nx in x.saturating_sub(1)..(x + 2).min(width) {
                if let Some(v) = r.get(ny * width + nx) {
                    for c in 0..3 {
                        o[c] += v[c];
                    }
                    n += 1.0;
                }
            }
        }
        for v in o.iter_mut() {
            *v /= n;
        }
    }
    out
}

/// The unbiased candidates' means weighted by the inverse of their variance, and the
/// consensus's own relMSE; empty without an unbiased candidate. Images are rows of `width`.
fn consensus(unbiased: &[&Halves], width: usize) -> (Vec<[f64; 3]>, f64) {
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
    let d = divisor(&r, width);
    let weights: Vec<f64> = unbiased
        .iter()
        .map(|u| 2.0 / u.half_rel_mse(&d).max(1e-12))
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

/// relMSE of `h` beyond its own noise and the consensus's, against the consensus `r` of
/// relMSE `var_r` (divided by `d`, [`divisor`]): what more samples do not remove.
fn floor_of(h: &Halves, r: &[[f64; 3]], d: &[[f64; 3]], var_r: f64) -> f64 {
    (h.rel_mse(r, d) - 0.5 * h.half_rel_mse(d) - var_r).max(0.0)
}

/// What the pilots so far predict.
pub(super) struct Prediction {
    /// Every measured candidate's.
    pub measurements: Vec<Measurement>,
    /// The relMSE aimed at (none for a time goal).
    pub target: Option<f64>,
    /// The judges' own relMSE (of their consensus, both halves): a floor under it cannot be
    /// told from their noise.
    pub judges: f64,
}

impl Prediction {
    /// Whether the judges resolve the goal ([`resolves`]).
    pub fn resolves(&self) -> bool {
        self.target.is_some_and(|e| resolves(self.judges, e))
    }
}

/// Whether judges of relMSE `judges` can tell a floor at the goal `e` from their noise: their
/// own relMSE is under it.
fn resolves(judges: f64, e: f64) -> bool {
    judges < e
}

/// The runs (indices into `runs`) whose consensus judges the others: the judges
/// ([`Candidate::judges`]), else every unbiased candidate.
pub(super) fn judges(candidates: &[Candidate], runs: &[(usize, Run)]) -> Vec<usize> {
    let of = |all: bool| -> Vec<usize> {
        runs.iter()
            .enumerate()
            .filter(|(_, (i, _))| {
                let c = &candidates[*i];
                c.judges() || (all && c.model == Model::Unbiased)
            })
            .map(|(j, _)| j)
            .collect()
    };
    match of(false) {
        j if j.is_empty() => of(true),
        j => j,
    }
}

/// Every measured candidate's prediction for `goal`.
pub(super) fn predict(
    candidates: &[Candidate],
    runs: &[(usize, Run)],
    goal: Goal,
    pilot: (u32, u32),
    film: u64,
) -> Prediction {
    let pixels: Vec<&Halves> = runs.iter().map(|(_, r)| &r.images).collect();
    let judged = judges(candidates, runs);
    let unbiased: Vec<&Halves> = judged.iter().map(|&j| pixels[j]).collect();
    let width = pilot.0 as usize;
    let (r, var_consensus) = consensus(&unbiased, width);
    if r.is_empty() {
        return Prediction {
            measurements: Vec::new(),
            target: None,
            judges: f64::INFINITY,
        };
    }
    let d = divisor(&r, width);
    let pilot_film = (pilot.0 as f64) * (pilot.1 as f64);
    let ratio = film as f64 / pilot_film;
    let mut out: Vec<Measurement> = runs
        .iter()
        .enumerate()
        .map(|(j, (i, run))| {
            let c = &candidates[*i];
            let k = c.k as f64;
            let half = pixels[j].half_rel_mse(&d);
            // What the pixels cost grows with them (SPPM's photons do not).
            let per_pixels = run.pixels_s.unwrap_or(run.frame_s).min(run.frame_s);
            let sample_s = (run.frame_s + per_pixels * (ratio - 1.0)) / (2.0 * k);
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
                    let (r, var_r) = consensus(&others, width);
                    // Of both halves (2k samples): twice that for one half.
                    let against = pixels[j].rel_mse(&r, &divisor(&r, width)) - var_r;
                    half.max(2.0 * against)
                }
                _ => half,
            };
            let floor = match c.model {
                Model::Unbiased => None,
                // SPPM's is its bias, dropped below where the consensus is too noisy to tell it.
                Model::Biased | Model::Progressive => {
                    Some(floor_of(pixels[j], &r, &d, var_consensus))
                }
            };
            Measurement {
                label: c.label.clone(),
                pilot_s: run.pilot_s,
                handed_s: run.handed_s,
                setup_s: run.setup_s,
                sample_s,
                rel_var: half * k,
                floor,
                untold: None,
                spp: None,
                predicted_s: None,
                predicted_error: None,
                note: None,
                caveat: c.caveat.clone(),
            }
        })
        .collect();
    // A consensus of a few bidirectional samples is often noisier than SPPM's first
    // iterations, its halves agreeing where both miss rare paths: SPPM's error against it
    // beyond the consensus's variance (the judges' as measured above, which counts what their
    // halves missed) is bias only when more than that variance.
    let var_r = 1.0
        / judged
            .iter()
            .map(|&j| 2.0 * candidates[runs[j].0].k as f64 / out[j].rel_var.max(1e-12))
            .sum::<f64>();
    for (m, (i, _)) in out.iter_mut().zip(runs) {
        if candidates[*i].model == Model::Progressive && m.floor.is_some_and(|b| b <= var_r) {
            m.floor = Some(0.0);
            m.untold = Some(var_r);
        }
    }
    // The path tracer with the scene's own settings is the first candidate.
    let reference = out.first().map(|m| m.rel_var);
    let target = match goal {
        Goal::Error(e) => Some(e),
        Goal::PathSpp(n) => reference.map(|v| v / n.max(1) as f64),
        Goal::Seconds(_) => None,
    };
    for (m, (i, run)) in out.iter_mut().zip(runs) {
        let c = &candidates[*i];
        let k = c.k as f64;
        let samples = |n: f64| -> Option<u32> {
            (n.is_finite() && n <= MAX_SPP as f64).then(|| n.ceil().max(1.0) as u32)
        };
        // SPPM's bias falls with its mean squared radius, from what it was over the pilot's k
        // iterations, at which its floor was measured.
        let radius2 = |n: f64| run.shrinkage.as_ref().map_or(1.0, |s| s.at(n));
        let measured_at = (0..c.k).map(|t| radius2(t as f64)).sum::<f64>() / k;
        let error_at = |n: f64| match (c.model, m.floor) {
            (Model::Unbiased, _) => m.rel_var / n,
            (Model::Biased, Some(b)) => m.rel_var / n + b,
            (Model::Progressive, Some(b)) => m.rel_var / n + b * radius2(n) / measured_at,
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
                    // Its bias is measured against the judges: below their own error it
                    // cannot be told from their noise, and a floor of zero is no evidence.
                    (Model::Biased, Some(_)) if !resolves(var_r, e) => {
                        m.note = Some(format!(
                            "its bias cannot be told under {e:.2e} by judges of relMSE {var_r:.2e}"
                        ));
                        None
                    }
                    (Model::Biased, Some(b)) if b < FLOOR_MARGIN * e => Some(m.rel_var / (e - b)),
                    (Model::Biased, Some(b)) => {
                        m.note = Some(format!(
                            "its bias and photon-map noise (relMSE {b:.2e}) leave no room under {e:.2e}"
                        ));
                        None
                    }
                    (Model::Progressive, Some(_)) => {
                        // The first n whose error is at most e (it falls with n).
                        let (mut lo, mut hi) = (1.0_f64, MAX_SPP as f64 + 1.0);
                        if error_at(lo) <= e {
                            Some(lo)
                        } else if error_at(MAX_SPP as f64) > e {
                            Some(hi)
                        } else {
                            while hi - lo > 1.0 {
                                let mid = ((lo + hi) / 2.0).floor();
                                if error_at(mid) <= e {
                                    hi = mid
                                } else {
                                    lo = mid
                                }
                            }
                            Some(hi)
                        }
                    }
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
    Prediction {
        measurements: out,
        target,
        judges: var_r,
    }
}

/// The candidate whose render is predicted to end soonest from now, less the pilot's work it
/// takes over (its passes, SPPM's photons: already done); the lowest error for a time goal.
/// One with a caveat only when no other has a prediction.
pub(super) fn choose(measurements: &[Measurement], goal: Goal) -> Option<usize> {
    let key = |m: &Measurement| match goal {
        Goal::Seconds(_) => m.predicted_error,
        _ => m.predicted_s.map(|t| (t - m.handed_s).max(0.0)),
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
pub(super) fn describe(m: &Measurement) -> String {
    let floor = match (m.floor, m.untold) {
        (_, Some(j)) => format!(", floor under the judges' relMSE {j:.2e}, taken as 0"),
        (Some(b), None) => format!(", floor {b:.2e}"),
        (None, None) => String::new(),
    };
    let measured = format!(
        "1-spp relMSE {:.2e}{floor}, {:.3} s per spp, setup {:.2} s; pilot {:.2} s",
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

#[cfg(test)]
pub(super) mod tests {
    use super::super::{Candidate, Goal, Halves, Measurement, Model, Run};
    use super::{choose, describe, predict};

    /// Gaussian noise from a fixed seed (xorshift, Box–Muller).
    pub(in super::super) struct Noise(pub(in super::super) u64);
    impl Noise {
        fn uniform(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn normal(&mut self) -> f64 {
            let (u, v) = (self.uniform(), self.uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        }
    }

    pub(in super::super) const PIXELS: usize = 2000;

    /// Two halves of k samples each about `mean`, each sample of standard deviation `sigma`.
    pub(in super::super) fn run(noise: &mut Noise, mean: f64, sigma: f64, k: f64) -> Run {
        let mut half = || -> Vec<[f64; 3]> {
            (0..PIXELS)
                .map(|_| [0; 3].map(|_| mean + sigma / k.sqrt() * noise.normal()))
                .collect()
        };
        let (a, b) = (half(), half());
        let both = a
            .iter()
            .zip(&b)
            .map(|(x, y)| [0, 1, 2].map(|c| 0.5 * (x[c] + y[c])))
            .collect();
        Run {
            images: Halves { a, b, both },
            artifacts: Vec::new(),
            setup_s: 0.0,
            frame_s: 1.0,
            pixels_s: None,
            pilot_s: 1.0,
            handed_s: 0.0,
            shrinkage: None,
        }
    }

    pub(in super::super) fn candidate(label: &str, model: Model, k: u32) -> Candidate {
        Candidate {
            label: label.into(),
            method: "path",
            subsurface: None,
            model,
            k,
            caveat: None,
            photons: None,
            judges: model == Model::Unbiased && label != "path",
            probe: None,
        }
    }

    /// SPPM's measurement, `offset` on every pixel of value 1, as the pilot sees it beside two
    /// unbiased judges of per-sample deviation `judges`.
    fn sppm_measured(offset: f64, judges: f64) -> Measurement {
        let mut noise = Noise(0x9e37_79b9_7f4a_7c15);
        let candidates = [
            candidate("bdpt", Model::Unbiased, 4),
            candidate("vcm", Model::Unbiased, 4),
            candidate("sppm", Model::Progressive, 1),
        ];
        let runs = vec![
            (0, run(&mut noise, 1.0, judges, 4.0)),
            (1, run(&mut noise, 1.0, judges, 4.0)),
            (2, run(&mut noise, 1.0 + offset, 0.05, 1.0)),
        ];
        let p = predict(&candidates, &runs, Goal::Error(1e-2), (40, 50), 4 * 2000);
        p.measurements[2].clone()
    }

    /// SPPM's floor as [`sppm_measured`] measures it.
    fn sppm_floor(offset: f64, judges: f64) -> f64 {
        sppm_measured(offset, judges)
            .floor
            .expect("sppm has a floor")
    }

    /// One rare bright path caught in one pixel of a pilot (a firefly of a thousand times the
    /// pixel's value) does not rate the method: its variance comes out within the noise of
    /// what it is without the path (which alone would make it several hundred times that);
    /// two such pixels are two paths, and the second counts.
    #[test]
    fn one_firefly_in_a_pilot_does_not_rate_the_method() {
        let mut noise = Noise(0x9e37_79b9_7f4a_7c15);
        let candidates = [
            candidate("bdpt", Model::Unbiased, 4),
            candidate("vcm", Model::Unbiased, 4),
        ];
        let measure = |fireflies: usize, noise: &mut Noise| {
            let mut runs = vec![
                (0, run(noise, 0.5, 0.5, 4.0)),
                (1, run(noise, 0.5, 0.5, 4.0)),
            ];
            let h = &mut runs[1].1.images;
            for p in 0..fireflies {
                let p = 100 + 700 * p;
                h.a[p] = [500.0; 3];
                h.both[p] = [0, 1, 2].map(|c| 0.5 * (h.a[p][c] + h.b[p][c]));
            }
            predict(&candidates, &runs, Goal::Error(1e-2), (40, 50), 4 * 2000).measurements[1]
                .rel_var
        };
        let truth = 0.5f64.powi(2) / (0.5f64.powi(2) + 0.01);
        let (none, one, two) = (
            measure(0, &mut noise),
            measure(1, &mut noise),
            measure(2, &mut noise),
        );
        for (got, what) in [(none, "none"), (one, "one")] {
            assert!(
                (got / truth - 1.0).abs() < 0.15,
                "vcm 1-spp relMSE {got} with {what} firefly, truth {truth}"
            );
        }
        assert!(two > 100.0 * truth, "two fireflies: {two}");
    }

    /// A judge whose few samples are noisy against its mean (BDPT, σ 0.4 a sample about 0.2,
    /// 4 a half) beside a quieter path tracer: its variance per sample is σ² / (0.2² + 0.01).
    /// Divided by its own noisy mean pixel by pixel it would come out half as large again.
    #[test]
    fn a_noisy_judge_is_measured_at_its_variance_not_inflated_by_dividing_by_its_own_noise() {
        let mut noise = Noise(0x2545_f491_4f6c_dd1d);
        let candidates = [
            candidate("path", Model::Unbiased, 16),
            candidate("bdpt", Model::Unbiased, 4),
        ];
        let runs = vec![
            (0, run(&mut noise, 0.2, 0.1, 16.0)),
            (1, run(&mut noise, 0.2, 0.4, 4.0)),
        ];
        let m = predict(&candidates, &runs, Goal::Error(1e-2), (40, 50), 4 * 2000).measurements;
        let truth = 0.4f64.powi(2) / (0.2f64.powi(2) + 0.01);
        let got = m[1].rel_var;
        assert!(
            (got / truth - 1.0).abs() < 0.15,
            "bdpt 1-spp relMSE {got}, truth {truth}"
        );
    }

    /// A path tracer judging alone (k = 16 a half, so its relMSE is σ² / 1.01 / 32 per pixel
    /// of value 1) beside a photon map without bias: under the goal (here 0.9 of it) the
    /// judge resolves it and the photon map is predicted; over it (1.2 of it) the photon map's
    /// floor cannot be told from the judge's noise, and it gets no prediction.
    #[test]
    fn a_floor_is_told_only_by_judges_whose_own_error_is_under_the_goal() {
        let e = 1e-2;
        let predicted = |judge_error: f64| {
            let mut noise = Noise(0x853c_49e6_748f_ea9b);
            let candidates = [
                candidate("path", Model::Unbiased, 16),
                candidate("photon", Model::Biased, 4),
            ];
            let sigma = (judge_error * 1.01 * 32.0).sqrt();
            let runs = vec![
                (0, run(&mut noise, 1.0, sigma, 16.0)),
                (1, run(&mut noise, 1.0, 0.05, 4.0)),
            ];
            let p = predict(&candidates, &runs, Goal::Error(e), (40, 50), 4 * 2000);
            assert!(
                (p.judges / judge_error - 1.0).abs() < 0.05,
                "judges' relMSE {}, expected {judge_error}",
                p.judges
            );
            (p.resolves(), p.measurements[1].clone())
        };
        let (resolves, photon) = predicted(0.9 * e);
        assert!(resolves);
        assert!(photon.spp.is_some(), "{photon:?}");
        let (resolves, photon) = predicted(1.2 * e);
        assert!(!resolves);
        assert_eq!(photon.spp, None);
        assert!(
            photon
                .note
                .as_deref()
                .is_some_and(|n| n.contains("cannot be told")),
            "{photon:?}"
        );
    }

    /// A measurement predicted to take `predicted_s`, `handed_s` of it done by the pilot.
    fn predicted(label: &str, predicted_s: f64, handed_s: f64) -> Measurement {
        let mut m = sppm_measured(0.0, 0.02);
        m.label = label.into();
        m.predicted_s = Some(predicted_s);
        m.handed_s = handed_s;
        m
    }

    /// Of two renders predicted alike, the one whose passes the pilot has built ends sooner:
    /// they are not built again (the Cornell glass's photon map against VCM). Without them, the
    /// sooner prediction.
    #[test]
    fn the_pilot_s_work_the_render_takes_over_is_not_counted_twice() {
        let goal = Goal::Error(1e-2);
        let photon = predicted("photon", 0.58, 0.10);
        let vcm = predicted("vcm", 0.57, 0.0);
        assert_eq!(choose(&[vcm.clone(), photon.clone()], goal), Some(1));
        let built_again = predicted("photon", 0.58, 0.0);
        assert_eq!(choose(&[vcm, built_again], goal), Some(0));
    }

    /// relMSE of an offset d on a pixel of value 1: d² / 1.01.
    #[test]
    fn sppm_bias_counts_only_where_the_consensus_can_tell_it_from_its_own_noise() {
        let bias = 0.1f64.powi(2) / 1.01;
        // Precise judges (consensus variance 0.02² / 16 per pixel): the offset is bias, within
        // the noise of the estimate (SPPM's 0.05² / 2 per pixel, over 6000 values).
        let seen = sppm_floor(0.1, 0.02);
        assert!(
            (seen - bias).abs() < 0.1 * bias,
            "floor {seen}, bias {bias}"
        );
        // Noisy judges (consensus variance about 0.7 / 16 per pixel, above the bias): the
        // difference cannot be told from the consensus's noise, and counts for nothing; the
        // report says so, with the judges' relMSE under which it may lie.
        let noisy = sppm_measured(0.1, 0.85);
        assert_eq!(noisy.floor, Some(0.0));
        let judges = noisy.untold.expect("an untold floor");
        assert!(judges > bias, "judges' relMSE {judges}, bias {bias}");
        assert!(describe(&noisy).contains("floor under the judges' relMSE"));
        assert_eq!(sppm_measured(0.1, 0.02).untold, None);
        // Without an offset, the floor is small whatever the judges.
        assert!(sppm_floor(0.0, 0.02) < 0.05 * bias);
    }
}
