//! Perfect mirror: reflects every ray about the normal, scaled by a reflectance.

use glam::{Vec2, Vec3A};

use super::{Bsdf, BsdfFlags, BsdfSample, TransportMode};
use crate::spectrum::{Spectrum, is_black};

#[derive(Debug, Clone)]
pub struct Mirror {
    reflectance: Spectrum,
}

impl Mirror {
    pub fn new(reflectance: Spectrum) -> Self {
        Mirror { reflectance }
    }
}

impl Bsdf for Mirror {
    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            reflection: !is_black(self.reflectance),
            specular: !is_black(self.reflectance),
            ..Default::default()
        }
    }

    fn eval(&self, _: Vec3A, _: Vec3A, _: TransportMode) -> Spectrum {
        Spectrum::ZERO
    }

    fn sample(&self, wo: Vec3A, _: f32, _: Vec2, _: TransportMode) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = Vec3A::new(-wo.x, -wo.y, wo.z);
        Some(BsdfSample::specular_reflection(wi, self.reflectance, 1.0))
    }

    fn pdf(&self, _: Vec3A, _: Vec3A, _: TransportMode) -> f32 {
        0.0
    }

    fn albedo(&self) -> Spectrum {
        self.reflectance
    }
}
