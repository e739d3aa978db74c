//! Statistical tests every BSDF must pass, generated per BSDF configuration (all with
//! albedo 1, so energy conservation is tested at its limit):
//!
//! - **furnace**, per channel and from both sides: the mean of f·|cos θi|/pdf over `sample`
//!   (flux, i.e. importance transport) equals 1 within 3 standard errors for lossless BSDFs,
//!   is at most 1 + 3σ and at least a floor (every configuration is white) otherwise, and for
//!   BSDFs with a density equals ∫ f |cos θi| dω integrated from `eval`;
//! - **chi-square**: directions drawn by `sample` are distributed as `pdf` says. Bins uniform
//!   in θ and φ, expected counts by numerically integrating `pdf` and normalising over the
//!   successful samples, bins with fewer than 5 expected pooled. Significance 1 % for the
//!   whole suite, split over all chi-square tests with the Šidák correction;
//! - **consistency**: the f and pdf returned by `sample` equal `eval` and `pdf`;
//! - **pdf integral**: ∫ pdf dω ≤ 1, and equals the fraction of successful samples;
//! - **reciprocity**: f(wo, wi) = f(wi, wo) for reflection; for refraction the generalised
//!   form f(wo, wi)/η_o² = f(wi, wo)/η_i² (Veach's thesis, eq. 5.14).

use glam::{Vec2, Vec3A};
use statrs::distribution::{ChiSquared, ContinuousCDF};
use tessera_scene::Distribution;

use super::*;
use crate::math::PI;
use crate::sampler::hash::{mix64, u32_to_unit};

/// Independent uniform numbers from a fixed seed.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f32 {
        self.0 += 1;
        u32_to_unit(mix64(self.0 ^ 0x5eed) as u32)
    }
    fn next2(&mut self) -> Vec2 {
        Vec2::new(self.next(), self.next())
    }
}

fn dir(theta_deg: f32, phi: f32) -> Vec3A {
    let (st, ct) = theta_deg.to_radians().sin_cos();
    Vec3A::new(st * phi.cos(), st * phi.sin(), ct)
}

/// Outgoing directions to test: above the surface, and below for transmissive BSDFs.
///
/// Not grazing from inside: there, refraction through nearly horizontal microfacets sends
/// light into a thin ring where the transmission Jacobian's denominator (wi·m + wo·m/η′)²
/// vanishes, an integrable singularity of the pdf that `sample` and `pdf` agree on pointwise
/// but no fixed integration grid resolves (seen at θo = 100°: 0.04 % of samples within 0.1°).
fn outgoing(b: &dyn Bsdf) -> Vec<Vec3A> {
    let mut v: Vec<Vec3A> = [1.0, 30.0, 60.0, 82.0]
        .iter()
        .map(|&t| dir(t, 0.7))
        .collect();
    if b.flags().transmission {
        v.extend([120.0, 145.0, 170.0].iter().map(|&t| dir(t, 2.1)));
    }
    v
}

const FURNACE_SAMPLES: usize = 200_000;

/// Every configuration here is white in at least one channel (albedo or reflectance 1, F ≈ 1
/// for the conductors; tints leave one channel near 1): one that sends back less than this
/// of the light arriving within 60° of the normal, in its brightest channel, has lost it (a
/// BSDF whose f and samples were both zero would pass the other checks). Hanrahan–Krueger's
/// first-order layer loses all multiply scattered light and states its own floor.
const ALBEDO_FLOOR: f64 = 0.25;

/// ∫ f(wo, wi) |cos θi| dωi per channel (importance transport, as the furnace samples it) by
/// the midpoint rule over the sphere, in the chi-square test's cells: the albedo as `eval`
/// says it, independently of `sample`.
fn integrate_albedo(b: &dyn Bsdf, wo: Vec3A) -> [f64; 3] {
    let dt = std::f64::consts::PI / (THETA_BINS * SUB) as f64;
    let dp = 2.0 * std::f64::consts::PI / (PHI_BINS * SUB) as f64;
    let mut out = [0.0f64; 3];
    for ti in 0..THETA_BINS * SUB {
        let theta = (ti as f64 + 0.5) * dt;
        let (s, c) = theta.sin_cos();
        for pi in 0..PHI_BINS * SUB {
            let phi = (pi as f64 + 0.5) * dp;
            let wi = Vec3A::new((s * phi.cos()) as f32, (s * phi.sin()) as f32, c as f32);
            let f = b.eval(wo, wi, TransportMode::Importance);
            for (k, o) in out.iter_mut().enumerate() {
                *o += f[k] as f64 * c.abs() * s * dt * dp;
            }
        }
    }
    out
}

/// The furnace, per channel, from both sides: the mean of f·|cos θi|/pdf over `sample`
/// (importance transport) is at most 1, exactly 1 for a lossless BSDF, at least
/// `floor` in the brightest channel (within 60° of the normal), and — for a BSDF with a density — equal to
/// ∫ f |cos θi| dωi integrated from `eval` (so sampling and evaluation agree on how much
/// light goes out).
fn furnace(b: &dyn Bsdf, lossless: bool, floor: f64) {
    for wo in outgoing(b) {
        let mut rng = Rng(1);
        let (mut sum, mut sum2) = ([0.0f64; 3], [0.0f64; 3]);
        for _ in 0..FURNACE_SAMPLES {
            if let Some(s) = b.sample(wo, rng.next(), rng.next2(), TransportMode::Importance) {
                let w = s.weight();
                assert!(
                    w.is_finite() && w.min_element() >= 0.0,
                    "weight {w} for wo {wo}"
                );
                for k in 0..3 {
                    sum[k] += w[k] as f64;
                    sum2[k] += (w[k] as f64).powi(2);
                }
            }
        }
        let n = FURNACE_SAMPLES as f64;
        let integral = (b.flags().smooth && !b.flags().specular).then(|| integrate_albedo(b, wo));
        // Not grazing: there lobes about the mirror direction dip below the horizon.
        let brightest = (0..3).map(|k| sum[k] / n).fold(0.0, f64::max);
        assert!(
            wo.z.abs() < 0.5 || brightest >= floor,
            "albedo {brightest} in its brightest channel for wo {wo}: a white BSDF lost the light"
        );
        for k in 0..3 {
            let mean = sum[k] / n;
            let sigma = ((sum2[k] / n - mean * mean).max(0.0) / n).sqrt();
            if lossless {
                assert!(
                    (mean - 1.0).abs() <= 3.0 * sigma + 1e-4,
                    "lossless but albedo {mean} ± {sigma} in channel {k} for wo {wo}"
                );
            }
            assert!(
                mean <= 1.0 + 3.0 * sigma + 1e-4,
                "albedo {mean} ± {sigma} exceeds 1 in channel {k} for wo {wo}"
            );
            if let Some(integral) = integral {
                // The midpoint rule's error on the sharpest lobes here (see INTEGRATION_ERROR).
                assert!(
                    (mean - integral[k]).abs() <= 4.0 * sigma + 3.0 * INTEGRATION_ERROR,
                    "channel {k}, wo {wo}: sampling says albedo {mean} ± {sigma}, eval integrates to {}",
                    integral[k]
                );
            }
        }
    }
}

/// Number of chi-square tests in the suite (configurations × outgoing directions), for the
/// Šidák correction; overestimating it only makes each test slightly stricter about nothing.
const CHI2_TESTS: f64 = 200.0;
const CHI2_SIGNIFICANCE: f64 = 0.01;
const CHI2_SAMPLES: usize = 400_000;
const THETA_BINS: usize = 36;
const PHI_BINS: usize = 36;
/// Midpoint-rule cells per bin side: 0.25° in θ, so lobes a few degrees wide integrate well.
const SUB: usize = 20;
/// Error of that integration for the sharpest case here (rough glass at 82°, whose pdf is
/// steep at the horizon): a convergence study gave ∫pdf = 0.98109, 0.98237, 0.98301 with
/// 10, 40, 160 cells per bin, so 20 cells leave about 1e-3.
const INTEGRATION_ERROR: f64 = 1.5e-3;

fn bin_of(w: Vec3A) -> usize {
    let theta = w.z.clamp(-1.0, 1.0).acos();
    let t = (theta / PI * THETA_BINS as f32) as usize;
    let phi = w.y.atan2(w.x).rem_euclid(2.0 * PI);
    let p = (phi / (2.0 * PI) * PHI_BINS as f32) as usize;
    t.min(THETA_BINS - 1) * PHI_BINS + p.min(PHI_BINS - 1)
}

/// ∫ pdf over each (θ, φ) bin by the midpoint rule on SUB×SUB cells, dω = sin θ dθ dφ.
fn integrate_pdf(b: &dyn Bsdf, wo: Vec3A) -> Vec<f64> {
    let dt = std::f64::consts::PI / (THETA_BINS * SUB) as f64;
    let dp = 2.0 * std::f64::consts::PI / (PHI_BINS * SUB) as f64;
    let mut out = vec![0.0f64; THETA_BINS * PHI_BINS];
    for ti in 0..THETA_BINS * SUB {
        let theta = (ti as f64 + 0.5) * dt;
        let (s, c) = theta.sin_cos();
        for pi in 0..PHI_BINS * SUB {
            let phi = (pi as f64 + 0.5) * dp;
            let wi = Vec3A::new((s * phi.cos()) as f32, (s * phi.sin()) as f32, c as f32);
            let pdf = b.pdf(wo, wi, TransportMode::Radiance) as f64;
            out[(ti / SUB) * PHI_BINS + pi / SUB] += pdf * s * dt * dp;
        }
    }
    out
}

fn chi_square(b: &dyn Bsdf) {
    let alpha = 1.0 - (1.0 - CHI2_SIGNIFICANCE).powf(1.0 / CHI2_TESTS);
    for wo in outgoing(b) {
        let mut rng = Rng(2);
        // One bin per direction cell, and a last one for failed samples.
        let mut observed = vec![0.0f64; THETA_BINS * PHI_BINS + 1];
        let fail = observed.len() - 1;
        for _ in 0..CHI2_SAMPLES {
            match b.sample(wo, rng.next(), rng.next2(), TransportMode::Radiance) {
                // A delta lobe beside the smooth ones lies outside pdf's support.
                Some(s) if s.specular => observed[fail] += 1.0,
                Some(s) => {
                    // Consistency of the returned values with eval and pdf.
                    let pdf = b.pdf(wo, s.wi, TransportMode::Radiance);
                    let f = b.eval(wo, s.wi, TransportMode::Radiance);
                    assert!(
                        (pdf - s.pdf).abs() <= 1e-3 * pdf.max(s.pdf) + 1e-6,
                        "sampled pdf {} vs pdf() {pdf}",
                        s.pdf
                    );
                    assert!(
                        (f - s.f).abs().max_element()
                            <= 1e-3 * f.max_element().max(s.f.max_element()) + 1e-6
                    );
                    observed[bin_of(s.wi)] += 1.0;
                }
                None => observed[fail] += 1.0,
            }
        }
        let n = CHI2_SAMPLES as f64;
        let integrals = integrate_pdf(b, wo);
        let integral: f64 = integrals.iter().sum();
        let successes = n - observed.pop().unwrap_or(0.0);
        // ∫pdf must match the fraction of successful samples: binomial standard error plus the
        // midpoint rule's error.
        let p_success = successes / n;
        let tolerance = 4.0 * (p_success * (1.0 - p_success) / n).sqrt() + INTEGRATION_ERROR;
        assert!(integral <= 1.0 + 1e-3, "∫pdf = {integral} > 1 for wo {wo}");
        assert!(
            (integral - p_success).abs() <= tolerance,
            "∫pdf = {integral} but {p_success} of samples succeed, wo {wo}"
        );
        // The shape: successful samples against pdf normalised over the sphere.
        let expected: Vec<f64> = integrals.iter().map(|p| p / integral * successes).collect();

        // Pool bins with small expectations until the pool has at least 5.
        let (mut pool_e, mut pool_o) = (0.0, 0.0);
        let mut stat = 0.0;
        let mut cells = 0;
        for (&e, &o) in expected.iter().zip(&observed) {
            if e < 5.0 {
                pool_e += e;
                pool_o += o;
                continue;
            }
            stat += (o - e).powi(2) / e;
            cells += 1;
        }
        if pool_e >= 5.0 {
            stat += (pool_o - pool_e).powi(2) / pool_e;
            cells += 1;
        } else {
            assert!(
                pool_o <= 5.0 + 5.0 * pool_e,
                "{pool_o} samples where pdf expects {pool_e}, wo {wo}"
            );
        }
        let dof = (cells - 1).max(1) as f64;
        let p = 1.0 - ChiSquared::new(dof).unwrap().cdf(stat);
        assert!(
            p >= alpha,
            "chi-square {stat} with {dof} dof: p = {p:.2e} < {alpha:.2e}, wo {wo}"
        );
    }
}

/// η of the medium on the side of `w`: 1 above, `eta` below.
fn reciprocity(b: &dyn Bsdf, eta: f32) {
    let mut rng = Rng(3);
    let both_sides = b.flags().transmission;
    for _ in 0..5000 {
        let mut wo = crate::sampling::square_to_uniform_sphere(rng.next2());
        let mut wi = crate::sampling::square_to_uniform_sphere(rng.next2());
        if !both_sides {
            wo.z = wo.z.abs();
            wi.z = wi.z.abs();
        }
        let side = |w: Vec3A| if w.z > 0.0 { 1.0 } else { eta };
        let a = b.eval(wo, wi, TransportMode::Radiance) * side(wi).powi(2);
        let c = b.eval(wi, wo, TransportMode::Radiance) * side(wo).powi(2);
        let scale = a.max_element().max(c.max_element());
        assert!(
            (a - c).abs().max_element() <= 2e-3 * scale + 1e-6,
            "f(wo,wi)η_i² = {a} but f(wi,wo)η_o² = {c}: wo {wo} wi {wi}"
        );
    }
}

fn rough(d: Distribution, au: f32, av: f32) -> Microfacet {
    Microfacet::new(d, au, av)
}

/// A conductor whose Fresnel reflectance is 1 to six digits (huge extinction coefficient).
fn perfect_conductor(mf: Option<Microfacet>) -> Conductor {
    Conductor::new(Spectrum::ONE, Spectrum::splat(1e4), Spectrum::ONE, mf)
}

/// A white glTF BSDF of `metallic` and `roughness` with specular transmission `t` and diffuse
/// transmission `d` (white), thin-walled or into an interior of IOR 1.5.
fn gltf_transmitting(
    metallic: f32,
    roughness: f32,
    t: f32,
    d: f32,
    thin: bool,
) -> MetallicRoughness {
    MetallicRoughness::new(Spectrum::ONE, metallic, roughness, 1.5, Spectrum::ONE, 1.0)
        .with_transmission(&tessera_scene::PbrTransmission {
            specular: t,
            diffuse: d,
            diffuse_color: glam::Vec3::ONE,
            thin,
        })
}

macro_rules! bsdf_tests {
    ($($name:ident: $bsdf:expr, lossless: $lossless:expr, eta: $eta:expr $(, floor: $floor:expr)?;)*) => {$(
        mod $name {
            use super::*;

            fn bsdf() -> Box<dyn Bsdf> {
                Box::new($bsdf)
            }

            #[test]
            fn furnace() {
                #[allow(unused_mut, unused_assignments)]
                let mut floor = ALBEDO_FLOOR;
                $(floor = $floor;)?
                super::furnace(bsdf().as_ref(), $lossless, floor);
            }

            #[test]
            fn chi_square_and_consistency() {
                let b = bsdf();
                if b.flags().smooth {
                    super::chi_square(b.as_ref());
                }
            }

            #[test]
            fn reciprocity() {
                let b = bsdf();
                if b.flags().smooth {
                    super::reciprocity(b.as_ref(), $eta);
                }
            }
        }
    )*};
}

bsdf_tests! {
    lambert: Lambert::new(Spectrum::ONE), lossless: true, eta: 1.0;
    oren_nayar_20deg: OrenNayar::new(Spectrum::ONE, 20f32.to_radians()), lossless: false, eta: 1.0;
    oren_nayar_60deg: OrenNayar::new(Spectrum::ONE, 60f32.to_radians()), lossless: false, eta: 1.0;
    phong_n1: Phong::new(Spectrum::ZERO, Spectrum::ONE, PhongLobe::new(1.0)), lossless: false, eta: 1.0;
    phong_n30: Phong::new(Spectrum::ZERO, Spectrum::ONE, PhongLobe::new(30.0)), lossless: false, eta: 1.0;
    phong_mixed: Phong::new(Spectrum::splat(0.5), Spectrum::splat(0.5), PhongLobe::new(12.0)), lossless: false, eta: 1.0;
    blinn_phong_n8: BlinnPhong::new(Spectrum::ZERO, Spectrum::ONE, BlinnPhongLobe::new(8.0)), lossless: false, eta: 1.0;
    blinn_phong_mixed: BlinnPhong::new(Spectrum::splat(0.3), Spectrum::splat(0.7), BlinnPhongLobe::new(60.0)), lossless: false, eta: 1.0;
    ward_isotropic: Ward::new(Spectrum::ZERO, Spectrum::ONE, WardLobe::new(0.25, 0.25)), lossless: false, eta: 1.0;
    ward_anisotropic: Ward::new(Spectrum::ZERO, Spectrum::ONE, WardLobe::new(0.1, 0.4)), lossless: false, eta: 1.0;
    ward_mixed: Ward::new(Spectrum::splat(0.5), Spectrum::splat(0.5), WardLobe::new(0.3, 0.3)), lossless: false, eta: 1.0;
    conductor_ggx: perfect_conductor(Some(rough(Distribution::Ggx, 0.3, 0.3))), lossless: false, eta: 1.0;
    conductor_ggx_anisotropic: perfect_conductor(Some(rough(Distribution::Ggx, 0.08, 0.5))), lossless: false, eta: 1.0;
    conductor_ggx_alpha1: perfect_conductor(Some(rough(Distribution::Ggx, 1.0, 1.0))), lossless: false, eta: 1.0;
    conductor_beckmann: perfect_conductor(Some(rough(Distribution::Beckmann, 0.4, 0.2))), lossless: false, eta: 1.0;
    conductor_gold: Conductor::new(Vec3A::new(0.143, 0.374, 1.442), Vec3A::new(3.983, 2.385, 1.603), Spectrum::ONE, Some(rough(Distribution::Ggx, 0.2, 0.2))), lossless: false, eta: 1.0;
    conductor_smooth: perfect_conductor(None), lossless: false, eta: 1.0;
    rough_glass_ggx: RoughDielectric::new(1.5, rough(Distribution::Ggx, 0.3, 0.3)), lossless: false, eta: 1.5;
    rough_glass_beckmann: RoughDielectric::new(1.33, rough(Distribution::Beckmann, 0.5, 0.5)), lossless: false, eta: 1.33;
    rough_glass_inverted: RoughDielectric::new(1.0 / 1.5, rough(Distribution::Ggx, 0.2, 0.35)), lossless: false, eta: 1.0 / 1.5;
    smooth_glass: SmoothDielectric::new(1.5), lossless: true, eta: 1.5;
    smooth_ior_one: SmoothDielectric::new(1.0), lossless: true, eta: 1.0;
    mirror: Mirror::new(Spectrum::ONE), lossless: true, eta: 1.0;
    gltf_dielectric_rough: MetallicRoughness::new(Spectrum::ONE, 0.0, 0.5, 1.5, Spectrum::ONE, 1.0), lossless: false, eta: 1.0;
    gltf_dielectric_glossy: MetallicRoughness::new(Spectrum::ONE, 0.0, 0.3, 1.5, Spectrum::ONE, 1.0), lossless: false, eta: 1.0;
    gltf_metal: MetallicRoughness::new(Spectrum::ONE, 1.0, 0.4, 1.5, Spectrum::ONE, 1.0), lossless: false, eta: 1.0;
    gltf_half_metal: MetallicRoughness::new(Spectrum::ONE, 0.5, 0.3, 1.5, Spectrum::ONE, 1.0), lossless: false, eta: 1.0;
    gltf_specular_ext: MetallicRoughness::new(Spectrum::ONE, 0.0, 0.6, 2.0, Spectrum::new(1.0, 0.5, 0.2), 0.7), lossless: false, eta: 1.0;
    thin_glass_smooth: ThinDielectric::new(1.5, None), lossless: true, eta: 1.0;
    thin_glass_rough: ThinDielectric::new(1.5, Some(rough(Distribution::Ggx, 0.3, 0.3))), lossless: false, eta: 1.0;
    thin_glass_tinted: ThinDielectric::new(1.33, Some(rough(Distribution::Ggx, 0.1, 0.2))).with_tint(Spectrum::new(1.0, 0.6, 0.2)), lossless: false, eta: 1.0;
    rough_glass_tinted: RoughDielectric::new(1.5, rough(Distribution::Ggx, 0.25, 0.25)).with_tint(Spectrum::new(0.9, 0.5, 0.1)), lossless: false, eta: 1.5;
    gltf_transmission_solid: gltf_transmitting(0.0, 0.4, 0.6, 0.0, false), lossless: false, eta: 1.5;
    gltf_transmission_full: gltf_transmitting(0.0, 0.3, 1.0, 0.0, false), lossless: false, eta: 1.5;
    gltf_transmission_thin: gltf_transmitting(0.0, 0.3, 1.0, 0.0, true), lossless: false, eta: 1.0;
    gltf_diffuse_transmission: gltf_transmitting(0.0, 0.5, 0.0, 0.7, false), lossless: false, eta: 1.0;
    gltf_every_share_thin: gltf_transmitting(0.3, 0.35, 0.4, 0.5, true), lossless: false, eta: 1.0;
    hanrahan_krueger: HanrahanKrueger::new(Spectrum::splat(4.0), Spectrum::ZERO, 0.5, 0.3, 1.4, Spectrum::ONE), lossless: false, eta: 1.0, floor: 0.04;
    hanrahan_krueger_thick: HanrahanKrueger::new(Spectrum::splat(10.0), Spectrum::ZERO, 5.0, -0.5, 1.3, Spectrum::ZERO), lossless: false, eta: 1.0, floor: 0.15;
}

#[test]
fn ior_one_interface_passes_light_straight_through() {
    let b = SmoothDielectric::new(1.0);
    let wo = dir(37.0, 0.4);
    let s = b
        .sample(wo, 0.99, Vec2::splat(0.5), TransportMode::Radiance)
        .unwrap();
    assert!((s.wi + wo).length() < 1e-6 && (s.weight() - Spectrum::ONE).abs().max_element() < 1e-6);
}

#[test]
fn total_internal_reflection_reflects_everything() {
    let b = SmoothDielectric::new(1.5);
    let wo = dir(180.0 - 60.0, 0.0); // inside, beyond the critical angle of 41.8°
    for u in [0.0, 0.5, 0.999] {
        let s = b
            .sample(wo, u, Vec2::ZERO, TransportMode::Radiance)
            .unwrap();
        assert!(
            !s.transmission
                && s.wi.z < 0.0
                && (s.weight() - Spectrum::ONE).abs().max_element() < 1e-6
        );
    }
}

#[test]
fn lambert_albedo_scales_reflection() {
    // f = ρ/π exactly, so the furnace weight of every sample is ρ.
    let b = Lambert::new(Vec3A::new(0.2, 0.5, 0.8));
    let s = b
        .sample(
            dir(40.0, 1.0),
            0.0,
            Vec2::new(0.3, 0.6),
            TransportMode::Radiance,
        )
        .unwrap();
    assert!((s.weight() - Vec3A::new(0.2, 0.5, 0.8)).abs().max_element() < 1e-6);
}

/// A Lambertian BSDF whose `eval` says half of what its samples carry: the furnace must see
/// that sampling and evaluation disagree.
#[derive(Debug)]
struct HalfEval(Lambert);

impl Bsdf for HalfEval {
    fn flags(&self) -> BsdfFlags {
        self.0.flags()
    }
    fn eval(&self, wo: Vec3A, wi: Vec3A, mode: TransportMode) -> Spectrum {
        self.0.eval(wo, wi, mode) * 0.5
    }
    fn sample(&self, wo: Vec3A, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        self.0.sample(wo, u_lobe, u, mode)
    }
    fn pdf(&self, wo: Vec3A, wi: Vec3A, mode: TransportMode) -> f32 {
        self.0.pdf(wo, wi, mode)
    }
    fn albedo(&self) -> Spectrum {
        self.0.albedo()
    }
}

#[test]
#[should_panic(expected = "eval integrates to")]
fn the_furnace_fails_a_bsdf_whose_samples_and_eval_disagree() {
    furnace(&HalfEval(Lambert::new(Spectrum::ONE)), false, ALBEDO_FLOOR);
}

#[test]
#[should_panic(expected = "lost the light")]
fn the_furnace_fails_a_bsdf_that_reflects_nothing() {
    furnace(&Lambert::new(Spectrum::ZERO), false, ALBEDO_FLOOR);
}
