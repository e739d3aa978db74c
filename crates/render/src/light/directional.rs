//! Directional (distant) light: irradiance E on surfaces facing it, from one direction.

use glam::Vec3A;

use super::{LightSample, ShadowTarget, lum};
use crate::math::PI;
use crate::spectrum::Spectrum;

#[derive(Debug, Clone)]
pub struct DirectionalLight {
    /// Direction the light travels.
    direction: Vec3A,
    irradiance: Spectrum,
}

impl DirectionalLight {
    pub fn new(direction: Vec3A, irradiance: Spectrum) -> Self {
        DirectionalLight {
            direction,
            irradiance,
        }
    }

    pub fn sample_li(&self) -> Option<LightSample> {
        Some(LightSample {
            li: self.irradiance,
            wi: -self.direction,
            pdf: 1.0,
            delta: true,
            target: ShadowTarget::Infinite,
        })
    }

    pub fn power(&self, scene_radius: f32) -> f32 {
        PI * scene_radius * scene_radius * lum(self.irradiance)
    }
}
