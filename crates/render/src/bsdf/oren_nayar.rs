//! Oren–Nayar rough diffuse reflection, the "qualitative" model of Oren & Nayar,
//! "Generalization of Lambert's Reflectance Model", SIGGRAPH 1994 (eq. 30):
//! f = ρ/π (A + B max(0, cos(φi − φo)) sin α tan β), α = max(θi, θo), β = min(θi, θo),
//! A = 1 − σ²/(2(σ² + 0.33)), B = 0.45 σ²/(σ² + 0.09), σ the facet slope deviation (radians).

use glam::{Vec2, Vec3A};

use super::{Bsdf, BsdfFlags, BsdfSample, TransportMode, diffuse_pdf, sample_diffuse};
use crate::math::{INV_PI, safe_sqrt};
use crate::spectrum::{Spectrum, is_black};

#[derive(Debug, Clone)]
pub struct OrenNayar {
    albedo: Spectrum,
    a: f32,
    b: f32,
}

impl OrenNayar {
    pub fn new(albedo: Spectrum, sigma: f32) -> Self {
        let s2 = sigma * sigma;
        OrenNayar {
            albedo,
            a: 1.0 - s2 / (2.0 * (s2 + 0.33)),
            b: 0.45 * s2 / (s2 + 0.09),
        }
    }
}

impl Bsdf for OrenNayar {
    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            reflection: !is_black(self.albedo),
            smooth: !is_black(self.albedo),
            diffuse: !is_black(self.albedo),
            ..Default::default()
        }
    }

    fn eval(&self, wo: Vec3A, wi: Vec3A, _: TransportMode) -> Spectrum {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Spectrum::ZERO;
        }
        let sin_i = safe_sqrt(1.0 - wi.z * wi.z);
        let sin_o = safe_sqrt(1.0 - wo.z * wo.z);
        let max_cos = if sin_i > 1e-4 && sin_o > 1e-4 {
            ((wi.x * wo.x + wi.y * wo.y) / (sin_i * sin_o)).max(0.0)
        } else {
            0.0
        };
        let (sin_alpha, tan_beta) = if wi.z > wo.z {
            (sin_o, sin_i / wi.z)
        } else {
            (sin_i, sin_o / wo.z)
        };
        self.albedo * (INV_PI * (self.a + self.b * max_cos * sin_alpha * tan_beta))
    }

    fn sample(&self, wo: Vec3A, _: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        BsdfSample::reflection(self, wo, sample_diffuse(u)?, mode)
    }

    fn pdf(&self, wo: Vec3A, wi: Vec3A, _: TransportMode) -> f32 {
        diffuse_pdf(wo, wi)
    }

    fn albedo(&self) -> Spectrum {
        self.albedo
    }
}
