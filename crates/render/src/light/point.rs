//! Isotropic point light with radiant intensity I (W/sr, already per scene unit²).

use glam::Vec3A;

use super::{LightSample, ShadowTarget, lum};
use crate::math::PI;
use crate::spectrum::Spectrum;

#[derive(Debug, Clone)]
pub struct PointLight {
    position: Vec3A,
    intensity: Spectrum,
}

impl PointLight {
    pub fn new(position: Vec3A, intensity: Spectrum) -> Self {
        PointLight {
            position,
            intensity,
        }
    }

    pub fn sample_li(&self, p: Vec3A) -> Option<LightSample> {
        let to = self.position - p;
        let dist2 = to.length_squared();
        (dist2 > 0.0).then(|| LightSample {
            li: self.intensity / dist2,
            wi: to / dist2.sqrt(),
            pdf: 1.0,
            delta: true,
            target: ShadowTarget::Point {
                p: self.position,
                p_error: Vec3A::ZERO,
                n: Vec3A::ZERO,
            },
        })
    }

    pub fn power(&self) -> f32 {
        4.0 * PI * lum(self.intensity)
    }
}
