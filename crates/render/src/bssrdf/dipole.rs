//! The dipole diffusion approximation (Jensen, Marschner, Levoy & Hanrahan 2001, "A Practical
//! Model for Subsurface Light Transport", §2.4–2.5): light entering a semi-infinite
//! homogeneous medium at one point leaves at distance r with diffuse reflectance Rd(r), the
//! fluence of a real source at depth z_r = 1/σt′ and a negative virtual one at height z_v above
//! the surface, placed so that the fluence vanishes on the extrapolated boundary that the
//! Fresnel reflectance of the interface sets.
//!
//! Units: coefficients per unit length (the presets are per millimetre), r in the same unit,
//! Rd(r) per unit area; total diffuse reflectance is dimensionless.

/// A homogeneous scattering medium: reduced scattering σs′ = σs (1 − g) and absorption σa per
/// unit length, one value per RGB channel, and the relative index of refraction η.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Medium {
    pub sigma_s_prime: [f64; 3],
    pub sigma_a: [f64; 3],
    pub eta: f64,
}

impl Medium {
    /// A medium of reduced scattering σs′ and absorption σa per channel (per unit length) and
    /// relative index `eta`.
    pub fn new(sigma_s_prime: glam::Vec3, sigma_a: glam::Vec3, eta: f32) -> Self {
        Medium {
            sigma_s_prime: sigma_s_prime.to_array().map(f64::from),
            sigma_a: sigma_a.to_array().map(f64::from),
            eta: eta as f64,
        }
    }

    /// The shortest reduced mean free path 1/σt′ over the channels (the dipole's z_r).
    pub fn mean_free_path(&self) -> f32 {
        (0..3)
            .map(|c| 1.0 / (self.sigma_s_prime[c] + self.sigma_a[c]))
            .fold(f64::INFINITY, f64::min) as f32
    }

    /// A measured medium of Jensen et al. 2001 (`tessera_scene::media`), per millimetre.
    pub fn measured(m: &tessera_scene::media::MeasuredMedium) -> Self {
        Medium {
            sigma_s_prime: m.sigma_s_prime.map(f64::from),
            sigma_a: m.sigma_a.map(f64::from),
            eta: tessera_scene::media::MEASURED_ETA as f64,
        }
    }

    /// The measured medium named `name` (any spelling `tessera_scene::media::measured` takes).
    pub fn named(name: &str) -> Option<Self> {
        tessera_scene::media::measured(name).map(Self::measured)
    }
}

pub use tessera_scene::media::fdr;

/// The dipole of one channel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dipole {
    /// Reduced albedo α′ = σs′ / σt′.
    pub alpha_prime: f64,
    /// Effective transport coefficient σtr = √(3 σa σt′), per unit length.
    pub sigma_tr: f64,
    /// Depth of the real source, z_r = 1/σt′, and height of the virtual one,
    /// z_v = z_r (1 + 4A/3), A = (1 + Fdr)/(1 − Fdr).
    pub z_r: f64,
    pub z_v: f64,
}

impl Dipole {
    /// The dipole of channel `c` of `medium`.
    pub fn new(medium: &Medium, c: usize) -> Self {
        let sigma_t_prime = medium.sigma_s_prime[c] + medium.sigma_a[c];
        let f = fdr(medium.eta);
        let a = (1.0 + f) / (1.0 - f);
        let z_r = 1.0 / sigma_t_prime;
        Dipole {
            alpha_prime: medium.sigma_s_prime[c] / sigma_t_prime,
            sigma_tr: (3.0 * medium.sigma_a[c] * sigma_t_prime).sqrt(),
            z_r,
            z_v: z_r * (1.0 + 4.0 * a / 3.0),
        }
    }

    /// Rd(r) = α′/(4π) [z_r (σtr d_r + 1) e^(−σtr d_r) / d_r³ + z_v (σtr d_v + 1) e^(−σtr d_v) / d_v³],
    /// d = √(r² + z²): diffuse reflectance per unit area at distance r from where light
    /// entered (Jensen et al. 2001, eq. 4).
    pub fn rd(&self, r: f64) -> f64 {
        let term = |z: f64| {
            let d = (r * r + z * z).sqrt();
            z * (self.sigma_tr * d + 1.0) * (-self.sigma_tr * d).exp() / (d * d * d)
        };
        self.alpha_prime / (4.0 * std::f64::consts::PI) * (term(self.z_r) + term(self.z_v))
    }

    /// Total diffuse reflectance ∫ Rd(r) 2πr dr = (α′/2) (e^(−σtr z_r) + e^(−σtr z_v)) — the
    /// closed form Jensen et al. give as (α′/2)(1 + e^(−4/3 A √(3(1−α′)))) e^(−√(3(1−α′))).
    pub fn total(&self) -> f64 {
        0.5 * self.alpha_prime
            * ((-self.sigma_tr * self.z_r).exp() + (-self.sigma_tr * self.z_v).exp())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫ Rd(r) 2πr dr by the midpoint rule in u = ln r over [10⁻⁶, 10⁴] mean free paths, plus
    /// the exact tail beyond R (each source's ∫_R^∞ is 2π z e^(−σtr d)/d at d = √(R² + z²);
    /// without absorption, as spectralon, the profile falls only as 1/r³).
    fn integrate(d: &Dipole, mfp: f64) -> f64 {
        let (lo, hi, n) = ((1e-6 * mfp).ln(), (1e4 * mfp).ln(), 200_000);
        let h = (hi - lo) / n as f64;
        let body: f64 = (0..n)
            .map(|i| {
                let r = (lo + (i as f64 + 0.5) * h).exp();
                d.rd(r) * 2.0 * std::f64::consts::PI * r * r * h
            })
            .sum();
        let big_r = hi.exp();
        let tail = |z: f64| {
            let dist = (big_r * big_r + z * z).sqrt();
            z * (-d.sigma_tr * dist).exp() / dist
        };
        body + 0.5 * d.alpha_prime * (tail(d.z_r) + tail(d.z_v))
    }

    /// For every preset and channel, Rd(r) integrated over the plane equals the closed-form
    /// total diffuse reflectance (to the quadrature's 1e-6), which is the paper's α′-only
    /// expression; it lies in (0, 1] (1 for spectralon, which does not absorb).
    #[test]
    fn profile_integrates_to_the_closed_form_total_reflectance() {
        for preset in tessera_scene::media::MEASURED {
            let (name, m) = (preset.name, &Medium::measured(preset));
            for c in 0..3 {
                let d = Dipole::new(m, c);
                let total = d.total();
                let numeric = integrate(&d, d.z_r);
                assert!(
                    (numeric - total).abs() <= 1e-6 * total.max(1e-3),
                    "{name}[{c}]: ∫Rd = {numeric}, closed form {total}"
                );
                let a = (1.0 + fdr(m.eta)) / (1.0 - fdr(m.eta));
                let s = (3.0 * (1.0 - d.alpha_prime)).sqrt();
                let paper = 0.5 * d.alpha_prime * (1.0 + (-4.0 / 3.0 * a * s).exp()) * (-s).exp();
                assert!(
                    (paper - total).abs() <= 1e-12,
                    "{name}[{c}]: {paper} vs {total}"
                );
                assert!(total > 0.0 && total <= 1.0, "{name}[{c}]: {total}");
            }
        }
        // Marble absorbs blue most (relative to its scattering): its total reflectance falls
        // from red to blue, as its albedo α′ does.
        let marble = Medium::named("Marble").expect("marble");
        let t: Vec<f64> = (0..3).map(|c| Dipole::new(&marble, c).total()).collect();
        assert!(t[0] > t[1] && t[1] > t[2], "{t:?}");
    }

    /// The fit for Fdr against the hemispherical average of the exact Fresnel reflectance
    /// seen from inside, 2 ∫₀¹ F(−μ) μ dμ, for η = 1.3 and 1.5.
    #[test]
    fn diffuse_fresnel_fit_matches_the_exact_average() {
        for eta in [1.3f64, 1.5] {
            let exact = crate::bsdf::fresnel::hemispherical_reflectance(eta as f32, true, 100_000);
            let fit = fdr(eta);
            eprintln!("η {eta}: Fdr fit {fit:.4}, exact {exact:.4}");
            // The fit is good to 4e-4 at these η (0.4448 vs 0.4445, 0.5967 vs 0.5963).
            assert!(
                (fit - exact).abs() < 1e-3,
                "η {eta}: fit {fit}, exact {exact}"
            );
        }
    }
}
