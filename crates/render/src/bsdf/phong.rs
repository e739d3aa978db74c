//! Normalised (modified) Phong lobe (Lafortune & Willems, "Using the Modified Phong
//! Reflectance Model for Physically Based Rendering", 1994):
//! f = k_s (n + 2)/(2π) cos^n α, α the angle between wi and the mirror direction of wo.
//! The albedo is largest at normal incidence, where it equals k_s; sampling draws cos α with
//! density (n + 1)/(2π) cos^n α around the mirror direction.

use glam::{Vec2, Vec3A};

use super::glossy::{GlossyLobe, WithDiffuse};
use crate::math::{Frame, INV_2PI, PI, safe_sqrt};

pub type Phong = WithDiffuse<PhongLobe>;

#[derive(Debug, Clone)]
pub struct PhongLobe {
    exponent: f32,
}

impl PhongLobe {
    pub fn new(exponent: f32) -> Self {
        PhongLobe { exponent }
    }

    #[inline]
    fn cos_alpha(wo: Vec3A, wi: Vec3A) -> f32 {
        Vec3A::new(-wo.x, -wo.y, wo.z).dot(wi).max(0.0)
    }
}

impl GlossyLobe for PhongLobe {
    fn eval(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        (self.exponent + 2.0) * INV_2PI * Self::cos_alpha(wo, wi).powf(self.exponent)
    }

    fn sample(&self, wo: Vec3A, u: Vec2) -> Option<Vec3A> {
        let cos_a = u.x.powf(1.0 / (self.exponent + 1.0));
        let sin_a = safe_sqrt(1.0 - cos_a * cos_a);
        let (s, c) = (2.0 * PI * u.y).sin_cos();
        let r = Vec3A::new(-wo.x, -wo.y, wo.z);
        Some(Frame::from_normal(r).to_world(Vec3A::new(sin_a * c, sin_a * s, cos_a)))
    }

    fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        (self.exponent + 1.0) * INV_2PI * Self::cos_alpha(wo, wi).powf(self.exponent)
    }
}
