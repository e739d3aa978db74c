//! Directional (distant) light: irradiance E on surfaces facing it, from one direction.

use glam::{Vec2, Vec3A};

use super::{Aim, Emission, LightSample, ShadowTarget, emit_from_disk, lum};
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

    /// A photon from the disk of `aim` (other aims have no disk: no photon).
    pub fn sample_le(&self, aim: &Aim, u_pos: Vec2) -> Option<Emission> {
        match aim {
            Aim::Disk(target) => Some(emit_from_disk(
                *target,
                self.direction,
                self.irradiance,
                1.0,
                u_pos,
            )),
            _ => None,
        }
    }

    pub fn power(&self, scene_radius: f32) -> f32 {
        PI * scene_radius * scene_radius * lum(self.irradiance)
    }
}
