//! Photometric and colorimetric conversions, done once when a scene is loaded.
//!
//! Internal radiometric unit: "luminous-equivalent watts": an RGB radiance with Rec.709
//! luminance Y corresponds to a photometric luminance of `K_M · Y` cd/m². Lumens therefore
//! convert to watts by dividing by `K_M`.

use glam::{DVec3, Vec3};

/// Maximum luminous efficacy of radiation, lm/W (at 555 nm; CIE).
pub const K_M: f64 = 683.002;

/// Rec.709 / sRGB luminance of a linear RGB colour.
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// CIE 1931 2° colour-matching functions x̄, ȳ, z̄ at `lambda_nm`, by the multi-lobe
/// piecewise-Gaussian fit of Wyman, Sloan & Shirley, "Simple Analytic Approximations to the
/// CIE XYZ Color Matching Functions", JCGT 2(2), 2013 (their eq. 2; error about 1 %).
pub fn cie_xyz_bar(lambda_nm: f64) -> DVec3 {
    // g(λ; μ, σ₁, σ₂): a Gaussian with σ₁ left of μ and σ₂ right of it.
    let g = |mu: f64, s1: f64, s2: f64| {
        let t = (lambda_nm - mu) / if lambda_nm < mu { s1 } else { s2 };
        (-0.5 * t * t).exp()
    };
    DVec3::new(
        1.056 * g(599.8, 37.9, 31.0) + 0.362 * g(442.0, 16.0, 26.7) - 0.065 * g(501.1, 20.4, 26.2),
        0.821 * g(568.8, 46.9, 40.5) + 0.286 * g(530.9, 16.3, 31.1),
        1.217 * g(437.0, 11.8, 36.0) + 0.681 * g(459.0, 26.0, 13.8),
    )
}

/// Spectral radiance of a black body (Planck's law), W·sr⁻¹·m⁻²·nm⁻¹.
pub fn planck(lambda_nm: f64, kelvin: f64) -> f64 {
    const H: f64 = 6.626_070_15e-34; // J·s
    const C: f64 = 299_792_458.0; // m/s
    const KB: f64 = 1.380_649e-23; // J/K
    let l = lambda_nm * 1e-9;
    let b = 2.0 * H * C * C / (l.powi(5) * ((H * C / (l * KB * kelvin)).exp_m1()));
    b * 1e-9
}

/// The visible band over which colours and radiant watts are integrated, nm.
const BAND: (u32, u32) = (360, 830);

/// Integrates `f(λ)` over the visible band with 1 nm steps (trapezoidal rule).
fn integrate_band<T: std::ops::Add<Output = T> + std::ops::Mul<f64, Output = T> + Default>(
    f: impl Fn(f64) -> T,
) -> T {
    let mut sum = T::default();
    for l in BAND.0..=BAND.1 {
        let w = if l == BAND.0 || l == BAND.1 { 0.5 } else { 1.0 };
        sum = sum + f(l as f64) * w;
    }
    sum
}

/// CIE XYZ → linear Rec.709 (sRGB primaries, D65 white).
pub fn xyz_to_rec709(xyz: DVec3) -> DVec3 {
    DVec3::new(
        3.240_454_2 * xyz.x - 1.537_138_5 * xyz.y - 0.498_531_4 * xyz.z,
        -0.969_266_0 * xyz.x + 1.876_010_8 * xyz.y + 0.041_556_0 * xyz.z,
        0.055_643_4 * xyz.x - 0.204_025_9 * xyz.y + 1.057_225_2 * xyz.z,
    )
}

/// CIE XYZ tristimulus values of a black body at `kelvin`, normalised to Y = 1.
pub fn blackbody_xyz(kelvin: f64) -> DVec3 {
    let xyz = integrate_band(|l| cie_xyz_bar(l) * planck(l, kelvin));
    xyz / xyz.y
}

/// Linear Rec.709 colour of a black body at `kelvin`, with luminance 1. Components outside
/// the Rec.709 gamut (very low or high temperatures) are clipped to zero before normalising.
pub fn blackbody_rgb(kelvin: f64) -> Vec3 {
    let rgb = xyz_to_rec709(blackbody_xyz(kelvin))
        .max(DVec3::ZERO)
        .as_vec3();
    rgb / luminance(rgb)
}

/// Luminous efficacy (lm/W) of black-body radiation at `kelvin`, counting only the radiant
/// power inside the visible band 360–830 nm: `K_M ∫ȳ B dλ / ∫ B dλ`.
pub fn blackbody_efficacy(kelvin: f64) -> f64 {
    let y = integrate_band(|l| cie_xyz_bar(l).y * planck(l, kelvin));
    let total = integrate_band(|l| planck(l, kelvin));
    K_M * y / total
}

/// Multiplier from radiance (luminous-equivalent W·sr⁻¹·m⁻²) to pixel value for a camera at
/// `iso`, shutter `seconds` and `f_number`: pixel value 1 is sensor saturation.
/// Saturation-based sensitivity (ISO 12232): L_sat = 78 N² / (q t S), with lens/vignetting
/// factor q = 0.65, i.e. exposure = t S / (120 N²) per cd/m² (Lagarde & de Rousiers,
/// "Moving Frostbite to PBR", 2014, §4.1).
pub fn exposure_scale(iso: f64, seconds: f64, f_number: f64) -> f64 {
    K_M * seconds * iso / (120.0 * f_number * f_number)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chromaticity(xyz: DVec3) -> (f64, f64) {
        let s = xyz.x + xyz.y + xyz.z;
        (xyz.x / s, xyz.y / s)
    }

    #[test]
    fn equal_energy_white_is_near_one_third() {
        let (x, y) = chromaticity(integrate_band(cie_xyz_bar));
        assert!(
            (x - 1.0 / 3.0).abs() < 0.005 && (y - 1.0 / 3.0).abs() < 0.005,
            "{x} {y}"
        );
    }

    #[test]
    fn blackbody_chromaticities_match_cie_illuminant_a_and_planckian_locus() {
        // CIE illuminant A is a 2856 K black body: x = 0.44757, y = 0.40745.
        let (x, y) = chromaticity(blackbody_xyz(2856.0));
        assert!(
            (x - 0.44757).abs() < 0.004 && (y - 0.40745).abs() < 0.004,
            "{x} {y}"
        );
        // 6500 K on the Planckian locus: x ≈ 0.3135, y ≈ 0.3237.
        let (x, y) = chromaticity(blackbody_xyz(6500.0));
        assert!(
            (x - 0.3135).abs() < 0.004 && (y - 0.3237).abs() < 0.004,
            "{x} {y}"
        );
    }

    #[test]
    fn blackbody_rgb_has_unit_luminance_and_warms_with_lower_temperature() {
        for t in [1500.0, 2856.0, 6500.0, 12000.0] {
            let c = blackbody_rgb(t);
            assert!((luminance(c) - 1.0).abs() < 1e-5);
            assert!(c.min_element() >= 0.0);
        }
        let warm = blackbody_rgb(2700.0);
        let cool = blackbody_rgb(9000.0);
        assert!(warm.x > warm.z && cool.z > cool.x);
    }

    #[test]
    fn efficacy_is_below_the_maximum_and_peaks_near_daylight() {
        let e2856 = blackbody_efficacy(2856.0);
        let e6500 = blackbody_efficacy(6500.0);
        assert!(
            e2856 > 100.0 && e2856 < e6500 && e6500 < 0.5 * K_M,
            "{e2856} {e6500}"
        );
    }

    #[test]
    fn exposure_of_sunny_16_is_about_middle_grey() {
        // "Sunny 16": ISO 100, 1/100 s, f/16 exposes a sunlit grey card (about 4000 cd/m²
        // for 18 % reflectance) to a mid tone, well below saturation.
        let pixel = exposure_scale(100.0, 0.01, 16.0) * 4000.0 / K_M;
        assert!(pixel > 0.05 && pixel < 0.5, "{pixel}");
    }
}
