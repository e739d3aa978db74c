//! Where light leaves a translucent object after subsurface transport: the directional part
//! of a separable BSSRDF, Sw(ωi) = (1 − Fr(cos θi)) / (c π), c = 1 − 2 F̄m1 = 2∫₀¹ (1 − Fr(μ)) μ dμ
//! (pbrt-v3 §11.4's normalisation of Jensen et al. 2001's Ft(ωi)/π, so that ∫ Sw cos θ dω = 1:
//! the dipole's Rd then gives the exitance exactly). The surface's frame faces outward.

use glam::{Vec2, Vec3A};

use super::{Bsdf, BsdfFlags, BsdfSample, TransportMode, diffuse_pdf, fresnel, sample_diffuse};
use crate::math::INV_PI;
use crate::spectrum::Spectrum;

#[derive(Debug, Clone)]
pub struct SubsurfaceExit {
    eta: f32,
    /// 1 / c.
    inv_c: f32,
}

impl SubsurfaceExit {
    pub fn new(eta: f32) -> Self {
        let c = 1.0 - fresnel::hemispherical_reflectance(eta, false, 4096);
        SubsurfaceExit {
            eta,
            inv_c: (1.0 / c) as f32,
        }
    }
}

impl Bsdf for SubsurfaceExit {
    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            reflection: true,
            smooth: true,
            diffuse: true,
            ..Default::default()
        }
    }

    fn eval(&self, _: Vec3A, wi: Vec3A, _: TransportMode) -> Spectrum {
        if wi.z <= 0.0 {
            return Spectrum::ZERO;
        }
        Spectrum::splat((1.0 - fresnel::dielectric(wi.z, self.eta)) * self.inv_c * INV_PI)
    }

    fn sample(&self, wo: Vec3A, _: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        BsdfSample::reflection(self, wo, sample_diffuse(u)?, mode)
    }

    fn pdf(&self, wo: Vec3A, wi: Vec3A, _: TransportMode) -> f32 {
        diffuse_pdf(wo, wi)
    }

    fn albedo(&self) -> Spectrum {
        Spectrum::ONE
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫ Sw cos θ dω = 1 over the hemisphere (the normalisation), checked by cosine sampling:
    /// the mean of f cos/pdf over a stratified grid.
    #[test]
    fn exit_lobe_is_normalised() {
        for eta in [1.0f32, 1.3, 1.5] {
            let b = SubsurfaceExit::new(eta);
            let n = 256;
            let mut sum = 0.0f64;
            for i in 0..n {
                for j in 0..n {
                    let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                    if let Some(s) = b.sample(Vec3A::Z, 0.0, u, TransportMode::Radiance) {
                        sum += s.weight().x as f64;
                    }
                }
            }
            let mean = sum / (n * n) as f64;
            assert!((mean - 1.0).abs() < 2e-3, "η {eta}: ∫Sw cos = {mean}");
        }
    }
}
