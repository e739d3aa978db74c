//! Hanrahan & Krueger 1993, "Reflection from Layered Surfaces due to Subsurface Scattering":
//! a smooth dielectric coat (relative index η) over a layer of a scattering medium (σs, σa,
//! Henyey–Greenstein g, thickness d) over a Lambertian substrate, to first order — light
//! scattered once in the layer, or passed through it to the substrate and back, unscattered.
//!
//! With μ the cosines outside and μ′ = √(1 − (1 − μ²)/η²) the refracted ones, Ft = 1 − Fr and
//! τ = σt d, for wi and wo above the surface:
//!
//! f = Ft(μi) Ft(μo) / η² · [ α p(cos ψ) (1 − e^(−τ (1/μ′i + 1/μ′o))) / (μ′i + μ′o)
//!                             + ρ/π · e^(−τ (1/μ′i + 1/μ′o)) ],
//!
//! α = σs/σt, ψ the angle between the refracted directions of travel in and out. The 1/η² is
//! refraction's (étendue: a diffuse flux inside leaves through a cone of 1/η² of its
//! hemisphere), which the paper leaves to the reader; it is what makes the model lose the
//! light that internal reflection would return (first order has no internal reflection).
//! Plus the coat's specular reflection Fr(μo), a delta lobe.

use glam::{Vec2, Vec3A};

use super::{Bsdf, BsdfFlags, BsdfSample, TransportMode, diffuse_pdf, fresnel, sample_diffuse};
use crate::math::INV_PI;
use crate::phase::hg;
use crate::spectrum::Spectrum;

#[derive(Debug, Clone)]
pub struct HanrahanKrueger {
    /// σs/σt per channel (0 where σt is).
    single_albedo: Spectrum,
    /// Optical thickness σt d per channel.
    tau: Spectrum,
    g: f32,
    eta: f32,
    substrate: Spectrum,
    /// Directional albedo at normal incidence, specular reflection included.
    albedo: Spectrum,
}

impl HanrahanKrueger {
    /// σs and σa in any unit of inverse length, `thickness` in its unit.
    pub fn new(
        sigma_s: Spectrum,
        sigma_a: Spectrum,
        thickness: f32,
        g: f32,
        eta: f32,
        substrate: Spectrum,
    ) -> Self {
        let sigma_t = sigma_s + sigma_a;
        let single_albedo = Spectrum::select(
            sigma_t.cmpgt(Spectrum::ZERO),
            sigma_s / sigma_t,
            Spectrum::ZERO,
        );
        let mut hk = HanrahanKrueger {
            single_albedo,
            tau: sigma_t * thickness,
            g,
            eta,
            substrate,
            albedo: Spectrum::ZERO,
        };
        // ∫ f(z, wi) cos θi dωi: f depends on θi alone at normal incidence.
        let n = 256;
        let diffuse: Spectrum = (0..n)
            .map(|i| {
                let mu = (i as f32 + 0.5) / n as f32;
                let wi = Vec3A::new((1.0 - mu * mu).sqrt(), 0.0, mu);
                hk.eval(Vec3A::Z, wi, TransportMode::Radiance) * mu
            })
            .sum::<Spectrum>()
            * (2.0 * std::f32::consts::PI / n as f32);
        hk.albedo = diffuse + fresnel::dielectric(1.0, eta);
        hk
    }

    /// The refracted cosine of outside cosine `mu`.
    #[inline]
    fn refracted(&self, mu: f32) -> f32 {
        (1.0 - (1.0 - mu * mu) / (self.eta * self.eta))
            .max(0.0)
            .sqrt()
    }
}

impl Bsdf for HanrahanKrueger {
    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            reflection: true,
            specular: self.eta != 1.0,
            smooth: true,
            diffuse: true,
            ..Default::default()
        }
    }

    fn eval(&self, wo: Vec3A, wi: Vec3A, _: TransportMode) -> Spectrum {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Spectrum::ZERO;
        }
        let (mi, mo) = (self.refracted(wi.z), self.refracted(wo.z));
        let coat = (1.0 - fresnel::dielectric(wi.z, self.eta))
            * (1.0 - fresnel::dielectric(wo.z, self.eta))
            / (self.eta * self.eta);
        // In along the refraction of −wi, out along that of wo.
        let cos_psi = -(wi.x * wo.x + wi.y * wo.y) / (self.eta * self.eta) - mi * mo;
        let depth = self.tau * (1.0 / mi + 1.0 / mo);
        let through = Spectrum::from(depth.to_array().map(|x| (-x).exp()));
        let scattered = Spectrum::from(depth.to_array().map(|x| -(-x).exp_m1()));
        let single = self.single_albedo * scattered * (hg(cos_psi, self.g) / (mi + mo));
        (single + self.substrate * through * INV_PI) * coat
    }

    fn sample(&self, wo: Vec3A, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let r = fresnel::dielectric(wo.z, self.eta);
        if u_lobe < r {
            let wi = Vec3A::new(-wo.x, -wo.y, wo.z);
            return Some(BsdfSample::specular_reflection(wi, Spectrum::splat(r), r));
        }
        BsdfSample::reflection(self, wo, sample_diffuse(u)?, mode)
    }

    fn pdf(&self, wo: Vec3A, wi: Vec3A, _: TransportMode) -> f32 {
        (1.0 - fresnel::dielectric(wo.z, self.eta)) * diffuse_pdf(wo, wi)
    }

    fn albedo(&self) -> Spectrum {
        self.albedo
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::sample_hg;
    use crate::sampler::hash::{mix64, u32_to_unit};

    /// The fraction of light arriving from `wi` that the first-order model reflects, less the
    /// coat's specular part, simulated photon by photon in the layer's actual geometry: refract
    /// in, fly to a collision (scatter by HG, weight α) or to the substrate (reflect
    /// diffusely, weight ρ), fly up with no further collision, and leave with the Fresnel
    /// transmittance from inside (zero under total internal reflection). Mean and standard
    /// error; gray media.
    fn simulated_albedo(
        wi: Vec3A,
        (sigma_s, sigma_a, d, g, eta, rho): (f32, f32, f32, f32, f32, f32),
        n: u64,
    ) -> (f64, f64) {
        let mut state = 0u64;
        let mut next = || {
            state += 1;
            u32_to_unit(mix64(state ^ 0x4b) as u32)
        };
        let sigma_t = sigma_s + sigma_a;
        let t_in = fresnel::refract(wi, Vec3A::Z, eta).expect("from outside");
        let enter = 1.0 - fresnel::dielectric(wi.z, eta);
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let s = -(1.0 - next()).ln() / sigma_t;
            let depth = -s * t_in.z;
            let (weight, up, from) = if depth < d {
                let dir = sample_hg(t_in, g, Vec2::new(next(), next()));
                (sigma_s / sigma_t, dir, depth)
            } else {
                let dir = sample_diffuse(Vec2::new(next(), next())).unwrap_or(Vec3A::Z);
                (rho, dir, d)
            };
            let w = if up.z > 0.0 {
                let to_top = (-sigma_t * from / up.z).exp();
                weight * to_top * (1.0 - fresnel::dielectric(-up.z, eta))
            } else {
                0.0
            };
            let w = (enter * w) as f64;
            sum += w;
            sum2 += w * w;
        }
        let mean = sum / n as f64;
        (mean, ((sum2 / n as f64 - mean * mean) / n as f64).sqrt())
    }

    /// ∫ f(wo, wi) cos θo dωo by the midpoint rule over (μ, φ).
    fn model_albedo(b: &HanrahanKrueger, wi: Vec3A) -> f64 {
        let (nm, np) = (2000, 200);
        let mut sum = 0.0f64;
        for i in 0..nm {
            let mu = (i as f32 + 0.5) / nm as f32;
            let s = (1.0 - mu * mu).sqrt();
            for j in 0..np {
                let phi = (j as f32 + 0.5) / np as f32 * 2.0 * std::f32::consts::PI;
                let wo = Vec3A::new(s * phi.cos(), s * phi.sin(), mu);
                sum += (b.eval(wo, wi, TransportMode::Radiance).x * mu) as f64;
            }
        }
        sum * 2.0 * std::f64::consts::PI / (nm * np) as f64
    }

    #[test]
    fn first_order_albedo_matches_a_simulation_of_the_layer() {
        // A thin forward-scattering layer over a grey substrate, a thick backscattering one.
        let layers = [
            (2.0, 0.5, 0.3, 0.6, 1.4, 0.5),
            (5.0, 0.1, 2.0, -0.3, 1.3, 0.8),
        ];
        for p @ (sigma_s, sigma_a, d, g, eta, rho) in layers {
            let b = HanrahanKrueger::new(
                Spectrum::splat(sigma_s),
                Spectrum::splat(sigma_a),
                d,
                g,
                eta,
                Spectrum::splat(rho),
            );
            for theta in [0.0f32, 50.0, 75.0] {
                let t = theta.to_radians();
                let wi = Vec3A::new(t.sin(), 0.0, t.cos());
                let (sim, se) = simulated_albedo(wi, p, 400_000);
                let model = model_albedo(&b, wi);
                eprintln!(
                    "layer {p:?}, θi {theta}°: model {model:.5}, simulated {sim:.5} ± {se:.5}"
                );
                // Four standard errors, and 2e-4 for the quadrature.
                assert!(
                    (model - sim).abs() < 4.0 * se + 2e-4,
                    "{model} vs {sim} ± {se}"
                );
            }
        }
    }

    #[test]
    fn a_clear_layer_is_a_coated_lambertian() {
        // σs = σa = 0: only the substrate, seen through the coat twice.
        let b = HanrahanKrueger::new(Spectrum::ZERO, Spectrum::ZERO, 1.0, 0.0, 1.5, Spectrum::ONE);
        let (wo, wi) = (Vec3A::new(0.6, 0.0, 0.8), Vec3A::new(0.0, 0.28, 0.96));
        let expected = (1.0 - fresnel::dielectric(0.8, 1.5))
            * (1.0 - fresnel::dielectric(0.96, 1.5))
            / (1.5 * 1.5 * std::f32::consts::PI);
        let f = b.eval(wo, wi, TransportMode::Radiance);
        assert!(
            (f - Spectrum::splat(expected)).abs().max_element() < 1e-6,
            "{f} vs {expected}"
        );
    }
}
