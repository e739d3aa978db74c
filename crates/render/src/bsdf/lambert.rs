//! Lambertian reflection: f = ρ/π.

use glam::{Vec2, Vec3A};

use super::{Bsdf, BsdfFlags, BsdfSample, TransportMode, diffuse_pdf, sample_diffuse};
use crate::math::INV_PI;
use crate::spectrum::{Spectrum, is_black};

#[derive(Debug, Clone)]
pub struct Lambert {
    albedo: Spectrum,
}

impl Lambert {
    pub fn new(albedo: Spectrum) -> Self {
        Lambert { albedo }
    }
}

impl Bsdf for Lambert {
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
        self.albedo * INV_PI
    }

    fn sample(&self, wo: Vec3A, _: f32, u: Vec2, _: TransportMode) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = sample_diffuse(u)?;
        Some(BsdfSample {
            wi,
            f: self.albedo * INV_PI,
            pdf: diffuse_pdf(wo, wi),
            specular: false,
            transmission: false,
            eta: 1.0,
        })
    }

    fn pdf(&self, wo: Vec3A, wi: Vec3A, _: TransportMode) -> f32 {
        diffuse_pdf(wo, wi)
    }

    fn albedo(&self) -> Spectrum {
        self.albedo
    }

    fn lambertian(&self) -> Option<Spectrum> {
        Some(self.albedo)
    }
}
