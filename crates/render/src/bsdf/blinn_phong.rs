//! Normalised Blinn–Phong lobe in the form of Neumann, Neumann & Szirmay-Kalos ("Compact
//! Metallic Reflectance Models", Eurographics 1999): f = k_s (n + 1)/(8π) cos^n θ_h /
//! max(cos θi, cos θo). Reciprocal; since cos θi / max(cos θi, cos θo) ≤ 1 and
//! ∫ (n + 1)/(2π) cos^n θ_h dω_h = 1 with dω_i = 4 (wo·h) dω_h ≤ 4 dω_h, its albedo never
//! exceeds k_s. Sampling draws h with density (n + 1)/(2π) cos^n θ_h and reflects wo.

use glam::{Vec2, Vec3A};

use super::glossy::{GlossyLobe, WithDiffuse};
use super::reflected_pdf;
use crate::math::{INV_2PI, PI, reflect, safe_sqrt};

pub type BlinnPhong = WithDiffuse<BlinnPhongLobe>;

#[derive(Debug, Clone)]
pub struct BlinnPhongLobe {
    exponent: f32,
}

impl BlinnPhongLobe {
    pub fn new(exponent: f32) -> Self {
        BlinnPhongLobe { exponent }
    }

    #[inline]
    fn pdf_h(&self, cos_h: f32) -> f32 {
        (self.exponent + 1.0) * INV_2PI * cos_h.max(0.0).powf(self.exponent)
    }
}

impl GlossyLobe for BlinnPhongLobe {
    fn eval(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        let h = (wo + wi).normalize();
        self.pdf_h(h.z) / (4.0 * wo.z.max(wi.z))
    }

    fn sample(&self, wo: Vec3A, u: Vec2) -> Option<Vec3A> {
        let cos_h = u.x.powf(1.0 / (self.exponent + 1.0));
        let sin_h = safe_sqrt(1.0 - cos_h * cos_h);
        let (s, c) = (2.0 * PI * u.y).sin_cos();
        let h = Vec3A::new(sin_h * c, sin_h * s, cos_h);
        (wo.dot(h) > 0.0).then(|| reflect(wo, h))
    }

    fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        reflected_pdf(wo, wi, |h| self.pdf_h(h.z))
    }
}
