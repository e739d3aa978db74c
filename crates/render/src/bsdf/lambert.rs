//! Lambertian reflection: f = ρ/π.

use glam::{Vec2, Vec3A};

use super::{Bsdf, BsdfFlags, BsdfSample, TransportMode};
use crate::math::INV_PI;
use crate::sampling::{cosine_hemisphere_pdf, square_to_cosine_hemisphere};
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
        let wi = square_to_cosine_hemisphere(u);
        if wi.z <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wi,
            f: self.albedo * INV_PI,
            pdf: cosine_hemisphere_pdf(wi.z),
            specular: false,
            transmission: false,
            eta: 1.0,
        })
    }

    fn pdf(&self, wo: Vec3A, wi: Vec3A, _: TransportMode) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            0.0
        } else {
            cosine_hemisphere_pdf(wi.z)
        }
    }

    fn albedo(&self) -> Spectrum {
        self.albedo
    }
}
