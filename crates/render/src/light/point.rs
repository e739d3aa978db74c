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
        from_point(self.position, p, |_| self.intensity)
    }

    pub fn power(&self) -> f32 {
        4.0 * PI * lum(self.intensity)
    }
}

/// Incident light at `p` from a point light at `position` whose intensity toward the unit
/// direction `w` (from the light) is `intensity(w)`: I / d², a delta light.
pub(super) fn from_point(
    position: Vec3A,
    p: Vec3A,
    intensity: impl FnOnce(Vec3A) -> Spectrum,
) -> Option<LightSample> {
    let to = position - p;
    let dist2 = to.length_squared();
    if dist2 == 0.0 {
        return None;
    }
    let wi = to / dist2.sqrt();
    let i = intensity(-wi);
    (i.max_element() > 0.0).then(|| LightSample {
        li: i / dist2,
        wi,
        pdf: 1.0,
        delta: true,
        target: ShadowTarget::Point {
            p: position,
            p_error: Vec3A::ZERO,
            n: Vec3A::ZERO,
        },
    })
}
