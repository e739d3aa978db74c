//! How SPPM's radii shrink on *this* scene, from the photons the pilot's iterations found at
//! each pixel: the rate its kernel bias falls at (see the parent module, step 3).
//!
//! Hachisuka & Jensen's update after an iteration in which a pixel's radius r holds M photons
//! is N' = N + αM, r'² = r² (N + αM) / (N + M), nothing changing where M = 0. Photons arrive
//! at each pixel as a Poisson process whose mean per iteration, μ = λ π r², falls with the
//! radius (λ the density of photons an iteration lands about the pixel's visible points). A
//! pixel where photons are dense shrinks as Knaus & Zwicker's r² ∝ n^(α − 1); one where an
//! iteration's mean is well under a photon, as under a sun and sky most of whose photons never
//! bounce towards the camera, waits iterations for each, and shrinks slower.

use super::predict::divisor;
use crate::integrator::sppm::SppmState;

/// Iterations followed one by one; beyond them the squared radius falls at the dense rate.
const FOLLOWED: usize = 1024;
/// Pixels followed at most: an even sample of those that found photons.
const PIXELS: usize = 256;
/// Where an iteration's mean photons μ are above this, or its count is a small part of those
/// gathered so far (N above this times μ), the update at M = μ stands for its expectation.
const DENSE: f64 = 16.0;

/// The mean over pixels of the expected squared radius after n iterations, as a share of
/// the initial one, for n = 1, 2, …, [`FOLLOWED`].
#[derive(Debug, Clone, PartialEq)]
pub struct Shrinkage {
    /// `g[n − 1]`.
    g: Vec<f64>,
    alpha: f64,
}

impl Shrinkage {
    /// From `state` after its first `k` iterations, all gathered at the initial radius
    /// (a pilot of one iteration a half: k = 1). Each pixel's photons per iteration at the
    /// initial radius, μ₀, is taken as the mean of the photons found over its 3 × 3
    /// neighbourhood (N / α, over k iterations), one iteration's count being too noisy a
    /// rate where it is a few photons. Pixels whose neighbourhood found none have no photon
    /// estimate and no kernel bias: they are left out. `None` where no pixel found any.
    pub fn measure(state: &SppmState, k: u32, alpha: f64) -> Option<Shrinkage> {
        let rates: Vec<f64> = followed(state, k, alpha).map(|(_, r)| r).collect();
        (!rates.is_empty()).then(|| Self::of_rates(&rates, alpha))
    }

    /// The mean expected shrinkage of pixels whose mean photons per iteration at the initial
    /// radius are `rates`. Each pixel is followed as one trajectory of (N, r²) whose step is
    /// the update's expectation over the Poisson count at the current radius.
    pub fn of_rates(rates: &[f64], alpha: f64) -> Shrinkage {
        let mut g = vec![0.0; FOLLOWED];
        for &mu0 in rates {
            let (mut n, mut q) = (0.0_f64, 1.0_f64);
            for gi in g.iter_mut() {
                let mu = mu0 * q;
                let ratio = if mu > DENSE || n > DENSE * mu {
                    (n + alpha * mu) / (n + mu)
                } else {
                    expected_ratio(n, mu, alpha)
                };
                n += alpha * mu;
                q *= ratio;
                *gi += q / rates.len() as f64;
            }
        }
        Shrinkage { g, alpha }
    }

    /// The mean squared radius after `n` iterations as a share of the initial one (1 at
    /// n = 0); past the iterations followed, falling as n^(α − 1).
    pub fn at(&self, n: f64) -> f64 {
        if n < 1.0 {
            return 1.0;
        }
        let last = self.g.len();
        if n <= last as f64 {
            // Between whole iterations, the earlier one's.
            return self.g[(n.floor() as usize).clamp(1, last) - 1];
        }
        self.g[last - 1] * (n / last as f64).powf(self.alpha - 1.0)
    }
}

/// The pixels [`Shrinkage::measure`] follows (an even sample of at most [`PIXELS`] of those
/// whose neighbourhood found photons) and their photons per iteration at the initial radius.
fn followed(state: &SppmState, k: u32, alpha: f64) -> impl Iterator<Item = (usize, f64)> {
    let found: Vec<[f64; 3]> = state
        .n
        .iter()
        .map(|&n| [n / alpha / k.max(1) as f64; 3])
        .collect();
    let rates: Vec<(usize, f64)> = divisor(&found, state.width as usize)
        .into_iter()
        .enumerate()
        .filter(|(_, r)| r[0] > 0.0)
        .map(|(p, r)| (p, r[0]))
        .collect();
    let step = rates.len().div_ceil(PIXELS).max(1);
    rates.into_iter().step_by(step)
}

/// E[(N + αM) / (N + M)] over M ~ Poisson(μ), counting 1 where M = 0 (nothing changes), and
/// α where N = 0 and M > 0.
fn expected_ratio(n: f64, mu: f64, alpha: f64) -> f64 {
    let mut p = (-mu).exp();
    let mut sum = p;
    let mut total = p;
    let mut m = 0.0;
    // Terms up to where what is left of the distribution is negligible.
    while total < 1.0 - 1e-9 && m < mu + 12.0 * mu.sqrt() + 12.0 {
        m += 1.0;
        p *= mu / m;
        total += p;
        sum += p * (n + alpha * m) / (n + m);
    }
    sum + (1.0 - total) * (n + alpha * mu) / (n + mu).max(f64::MIN_POSITIVE)
}

#[cfg(test)]
mod tests {
    use super::super::tests::{built, scene};
    use super::*;
    use crate::analysis::analyze;
    use crate::camera::Camera;
    use crate::integrator::sppm::{Sppm, SppmSettings};

    const ALPHA: f64 = 2.0 / 3.0;

    /// Where photons are dense the expectation is the deterministic update at M = μ, whose
    /// squared radius after n iterations is α ∏_{i=1}^{n−1} (i + α) / (i + 1) of the first
    /// (N grows by αμ₀ r² each iteration: Hachisuka & Jensen's recurrence with M ∝ r²).
    #[test]
    fn dense_pixels_shrink_at_the_recurrences_rate() {
        let s = Shrinkage::of_rates(&[1.0e6], ALPHA);
        let mut expected = ALPHA;
        for n in 1..=200u32 {
            if n > 1 {
                expected *= (n as f64 - 1.0 + ALPHA) / n as f64;
            }
            let got = s.at(n as f64);
            assert!(
                (got / expected - 1.0).abs() < 1e-3,
                "n {n}: {got} against {expected}"
            );
        }
        // Past the iterations followed, the same rate n^(α − 1).
        let far = s.at(8.0 * FOLLOWED as f64) / s.at(FOLLOWED as f64);
        assert!((far - 8f64.powf(ALPHA - 1.0)).abs() < 1e-12);
    }

    /// Where an iteration brings a tenth of a photon, each photon shrinks the radius as a
    /// dense iteration would, but they come ten iterations apart: after 100 iterations the
    /// radius is about where a dense pixel's is after a tenth as many, well above it.
    #[test]
    fn sparse_pixels_shrink_slower() {
        let dense = Shrinkage::of_rates(&[1.0e6], ALPHA);
        let sparse = Shrinkage::of_rates(&[0.1], ALPHA);
        assert!(sparse.at(100.0) > 1.5 * dense.at(100.0));
        assert!(sparse.at(100.0) < 1.0);
        // Monotone, and the first iteration shrinks by α only where it finds a photon.
        let first = 1.0 - (1.0 - ALPHA) * (1.0 - (-0.1f64).exp());
        assert!((sparse.at(1.0) - first).abs() < 1e-9);
        for n in 1..FOLLOWED {
            assert!(sparse.at(n as f64 + 1.0) <= sparse.at(n as f64));
        }
    }

    /// The expectation over the Poisson count, against its sum taken far out.
    #[test]
    fn the_expected_ratio_is_the_poisson_mean() {
        for &(n, mu) in &[(0.0f64, 0.3f64), (5.0, 2.0), (40.0, 30.0), (3.0, 0.01)] {
            let mut p = (-mu).exp();
            let mut direct = p;
            for m in 1..400 {
                p *= mu / m as f64;
                direct += p * (n + ALPHA * m as f64) / (n + m as f64);
            }
            let got = expected_ratio(n, mu, ALPHA);
            assert!(
                (got - direct).abs() < 1e-9,
                "N {n}, μ {mu}: {got} vs {direct}"
            );
        }
    }

    /// A state whose pixels found photons at two rates: the rates come from N / α, averaged
    /// over each pixel's neighbourhood, and pixels with none about them are left out.
    #[test]
    fn rates_are_read_from_the_photons_found() {
        let mut state = SppmState::new(8, 8, 1.0, 1.0);
        for (i, n) in state.n.iter_mut().enumerate() {
            *n = if i % 8 < 4 { 0.0 } else { ALPHA * 50.0 };
        }
        let s = Shrinkage::measure(&state, 1, ALPHA).expect("photons found");
        // Columns 0–2 have no photons about them; column 3 has one column of three with
        // them, column 4 two, the last (two columns about it) both.
        let rates: Vec<f64> = (0..8)
            .flat_map(|_| [50.0 / 3.0, 50.0 * 2.0 / 3.0, 50.0, 50.0, 50.0])
            .collect();
        let expected = Shrinkage::of_rates(&rates, ALPHA);
        for n in [1.0, 10.0, 100.0] {
            assert!((s.at(n) - expected.at(n)).abs() < 1e-9);
        }
        let none = SppmState::new(4, 4, 1.0, 1.0);
        assert_eq!(Shrinkage::measure(&none, 1, ALPHA), None);
    }

    /// Against SPPM itself: `scenes/NAME` at `w` × `h` with the default photons, one
    /// iteration measured, then `n` in all run; the mean squared radius (a share of the
    /// initial) of the pixels followed, as predicted and as it came out.
    fn predicted_and_run(name: &str, w: u32, h: u32, n: u32) -> (f64, f64) {
        let mut desc = scene(name);
        desc.film.width = w;
        desc.film.height = h;
        desc.integrator.method = "sppm".into();
        let built = built(&desc);
        let (photon, settings) = SppmSettings::resolve(&desc, &analyze(&desc));
        let sppm = Sppm::new(&built, &photon, settings);
        let camera = Camera::new(&desc.camera_at(1), &desc.film);
        let r0 = settings.initial_radius as f64;
        let mut state = SppmState::new(w, h, settings.initial_radius, 1.0);
        let alpha = settings.alpha as f64;
        sppm.iterate(&camera, &mut state);
        let pixels: Vec<usize> = followed(&state, 1, alpha).map(|(p, _)| p).collect();
        let predicted = Shrinkage::measure(&state, 1, alpha)
            .expect("photons found")
            .at(n as f64);
        for _ in 1..n {
            sppm.iterate(&camera, &mut state);
        }
        let run = pixels
            .iter()
            .map(|&p| (state.r[p] / r0).powi(2))
            .sum::<f64>()
            / pixels.len() as f64;
        (predicted, run)
    }

    /// The indirect room, where photons are dense, and the material spheres, where most of
    /// the sun's and sky's photons never bounce towards the camera and the radii shrink
    /// slower: the prediction from one iteration's photons follows SPPM's own radii over 24
    /// iterations on both, and tells them apart.
    #[test]
    fn one_iteration_predicts_how_the_radii_shrink() {
        let (dense, dense_run) = predicted_and_run("indirect-room", 48, 36, 24);
        let (sparse, sparse_run) = predicted_and_run("material-spheres", 64, 32, 24);
        for (p, r) in [(dense, dense_run), (sparse, sparse_run)] {
            assert!((p / r - 1.0).abs() < 0.1, "predicted {p}, run {r}");
        }
        assert!(
            sparse_run > 1.15 * dense_run,
            "{sparse_run} against {dense_run}"
        );
    }
}
