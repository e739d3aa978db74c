//! Measured scattering media, for translucent (`subsurface`) materials by name.

/// A homogeneous medium measured by Jensen, Marschner, Levoy & Hanrahan 2001 ("A Practical
/// Model for Subsurface Light Transport", Figure 5): reduced scattering σs′ and absorption σa
/// in mm⁻¹ per RGB channel; the paper uses η = 1.3 for all of them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasuredMedium {
    pub name: &'static str,
    pub sigma_s_prime: [f32; 3],
    pub sigma_a: [f32; 3],
}

/// The relative index of refraction the paper gives its measured media.
pub const MEASURED_ETA: f32 = 1.3;

const fn m(name: &'static str, sigma_s_prime: [f32; 3], sigma_a: [f32; 3]) -> MeasuredMedium {
    MeasuredMedium {
        name,
        sigma_s_prime,
        sigma_a,
    }
}

/// The paper's Figure 5, in its order.
pub const MEASURED: &[MeasuredMedium] = &[
    m("apple", [2.29, 2.39, 1.97], [0.0030, 0.0034, 0.046]),
    m("chicken1", [0.15, 0.21, 0.38], [0.015, 0.077, 0.19]),
    m("chicken2", [0.19, 0.25, 0.32], [0.018, 0.088, 0.20]),
    m("cream", [7.38, 5.47, 3.15], [0.0002, 0.0028, 0.0163]),
    m("ketchup", [0.18, 0.07, 0.03], [0.061, 0.97, 1.45]),
    m("marble", [2.19, 2.62, 3.00], [0.0021, 0.0041, 0.0071]),
    m("potato", [0.68, 0.70, 0.55], [0.0024, 0.0090, 0.12]),
    m("skim-milk", [0.70, 1.22, 1.90], [0.0014, 0.0025, 0.0142]),
    m("skin1", [0.74, 0.88, 1.01], [0.032, 0.17, 0.48]),
    m("skin2", [1.09, 1.59, 1.79], [0.013, 0.070, 0.145]),
    m("spectralon", [11.6, 20.4, 14.9], [0.0, 0.0, 0.0]),
    m("whole-milk", [2.55, 3.21, 3.77], [0.0011, 0.0024, 0.014]),
];

/// The measured medium named `name`, ignoring case, dashes, underscores and spaces
/// ("Skim milk", "skim_milk" and "skimmilk" alike).
pub fn measured(name: &str) -> Option<&'static MeasuredMedium> {
    let key = |s: &str| s.to_ascii_lowercase().replace(['-', '_', ' '], "");
    MEASURED.iter().find(|m| key(m.name) == key(name))
}

/// Diffuse Fresnel reflectance of the interface seen from inside a medium of relative index
/// η > 1 (the polynomial fit Jensen et al. 2001 use, eq. 5 after Egan & Hilgeman):
/// −1.440/η² + 0.710/η + 0.668 + 0.0636 η.
pub fn fdr(eta: f64) -> f64 {
    -1.440 / (eta * eta) + 0.710 / eta + 0.668 + 0.0636 * eta
}

/// The dipole's total diffuse reflectance of a medium of reduced albedo α′ behind an interface
/// of relative index η (Jensen et al. 2001, §2.5):
/// Rd = (α′/2) (1 + e^(−(4/3) A √(3(1 − α′)))) e^(−√(3(1 − α′))), A = (1 + Fdr)/(1 − Fdr).
pub fn total_diffuse_reflectance(alpha_prime: f64, eta: f64) -> f64 {
    let f = fdr(eta);
    let a = (1.0 + f) / (1.0 - f);
    let s = (3.0 * (1.0 - alpha_prime)).max(0.0).sqrt();
    0.5 * alpha_prime * (1.0 + (-4.0 / 3.0 * a * s).exp()) * (-s).exp()
}

/// The coefficients (σs′, σa, per unit of `mean_free_path`) of a medium with total diffuse
/// reflectance `rd` and diffuse mean free path ℓd = 1/σtr, per channel — the artist's
/// parameters of Jensen & Buhler 2002 ("A Rapid Hierarchical Rendering Technique for
/// Translucent Materials", §4): α′ from Rd by inverting [`total_diffuse_reflectance`]
/// (monotonic in α′; bisection), then σt′ = 1 / (ℓd √(3(1 − α′))), σs′ = α′ σt′,
/// σa = σt′ − σs′. Rd is clamped below what α′ = 1 reaches (a medium that absorbs nothing).
pub fn from_diffuse_reflectance(
    rd: [f32; 3],
    mean_free_path: f32,
    eta: f32,
) -> ([f32; 3], [f32; 3]) {
    let eta = eta as f64;
    let (mut sigma_s_prime, mut sigma_a) = ([0.0f32; 3], [0.0f32; 3]);
    for c in 0..3 {
        let target = (rd[c] as f64).max(1e-4);
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if total_diffuse_reflectance(mid, eta) < target {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        // Keep a little absorption so that σtr, and so ℓd, stays finite.
        let alpha_prime = (0.5 * (lo + hi)).min(1.0 - 1e-6);
        let sigma_t_prime = 1.0 / (mean_free_path as f64 * (3.0 * (1.0 - alpha_prime)).sqrt());
        sigma_s_prime[c] = (alpha_prime * sigma_t_prime) as f32;
        sigma_a[c] = ((1.0 - alpha_prime) * sigma_t_prime) as f32;
    }
    (sigma_s_prime, sigma_a)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn media_are_found_by_any_spelling_of_their_name() {
        assert_eq!(measured("skimmilk").map(|m| m.name), Some("skim-milk"));
        assert_eq!(measured("Whole milk").map(|m| m.name), Some("whole-milk"));
        assert_eq!(measured("SKIN_1").map(|m| m.name), Some("skin1"));
        assert!(measured("jade").is_none());
    }

    #[test]
    fn coefficients_from_reflectance_give_back_that_reflectance_and_free_path() {
        let rd = [0.8f32, 0.5, 0.1];
        let (s, a) = from_diffuse_reflectance(rd, 2.0, 1.4);
        for c in 0..3 {
            let t = (s[c] + a[c]) as f64;
            let alpha = s[c] as f64 / t;
            let got = total_diffuse_reflectance(alpha, 1.4);
            assert!((got - rd[c] as f64).abs() < 1e-4, "Rd {got} vs {}", rd[c]);
            // σtr = √(3 σa σt′) = 1/ℓd.
            let sigma_tr = (3.0 * a[c] as f64 * t).sqrt();
            assert!((1.0 / sigma_tr - 2.0).abs() < 1e-3, "ℓd {}", 1.0 / sigma_tr);
        }
    }
}
