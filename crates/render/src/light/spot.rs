//! Spot light: intensity I along its axis, a smooth-step fall-off from `cos_falloff_start` to
//! zero at `cos_cone` (pbrt-v4 §12.1.2).

use glam::{Vec2, Vec3A};

use super::point::{emit_from_point, from_point};
use super::{Aim, Emission, LightSample, Target, lum};
use crate::math::PI;
use crate::spectrum::Spectrum;

#[derive(Debug, Clone)]
pub struct SpotLight {
    position: Vec3A,
    direction: Vec3A,
    intensity: Spectrum,
    cos_falloff_start: f32,
    cos_cone: f32,
}

impl SpotLight {
    pub fn new(
        position: Vec3A,
        direction: Vec3A,
        intensity: Spectrum,
        cos_falloff_start: f32,
        cos_cone: f32,
    ) -> Self {
        SpotLight {
            position,
            direction,
            intensity,
            cos_falloff_start,
            cos_cone,
        }
    }

    /// Relative intensity toward a direction with cosine `cos` to the axis.
    fn falloff(&self, cos: f32) -> f32 {
        if cos <= self.cos_cone {
            return 0.0;
        }
        if cos >= self.cos_falloff_start {
            return 1.0;
        }
        let t = (cos - self.cos_cone) / (self.cos_falloff_start - self.cos_cone);
        t * t * (3.0 - 2.0 * t)
    }

    /// Radiant intensity toward unit direction `w`.
    pub fn intensity(&self, w: Vec3A) -> Spectrum {
        self.intensity * self.falloff(self.direction.dot(w))
    }

    pub fn sample_li(&self, p: Vec3A) -> Option<LightSample> {
        from_point(self.position, p, |w| {
            self.intensity * self.falloff(self.direction.dot(w))
        })
    }

    pub fn sample_le(&self, aim: &Aim, u_dir: Vec2, u_extra: f32) -> Option<Emission> {
        emit_from_point(self.position, aim, u_dir, u_extra, |w| {
            self.intensity * self.falloff(self.direction.dot(w))
        })
    }

    pub fn bounds(&self) -> Target {
        Target {
            center: self.position,
            radius: 0.0,
        }
    }

    /// Axis and half-angle of the cone outside which the light is dark.
    pub fn cone(&self) -> (Vec3A, f32) {
        (self.direction, self.cos_cone.clamp(-1.0, 1.0).acos())
    }

    pub fn power(&self) -> f32 {
        2.0 * PI * (1.0 - 0.5 * (self.cos_falloff_start + self.cos_cone)) * lum(self.intensity)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn falloff_is_one_inside_zero_outside_and_smooth_between() {
        let s = SpotLight::new(Vec3A::ZERO, Vec3A::Z, Spectrum::ONE, 0.9, 0.8);
        assert_eq!(s.falloff(0.95), 1.0);
        assert_eq!(s.falloff(0.7), 0.0);
        assert!((s.falloff(0.85) - 0.5).abs() < 1e-6);
        let hard = SpotLight::new(Vec3A::ZERO, Vec3A::Z, Spectrum::ONE, 0.8, 0.8);
        assert_eq!(hard.falloff(0.81), 1.0);
        assert_eq!(hard.falloff(0.79), 0.0);
    }
}
