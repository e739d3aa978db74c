//! Isotropic point light with radiant intensity I (W/sr, already per scene unit²).

use glam::{Vec2, Vec3A};

use super::{Aim, Emission, LightSample, ShadowTarget, Target, lum};
use crate::math::PI;
use crate::ray::Ray;
use crate::sampling::square_to_uniform_sphere;
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

    /// Radiant intensity (the same in every direction).
    pub fn intensity(&self) -> Spectrum {
        self.intensity
    }

    pub fn sample_li(&self, p: Vec3A) -> Option<LightSample> {
        from_point(self.position, p, |_| self.intensity)
    }

    pub fn power(&self) -> f32 {
        4.0 * PI * lum(self.intensity)
    }

    pub fn sample_le(&self, aim: &Aim, u_dir: Vec2, u_extra: f32) -> Option<Emission> {
        emit_from_point(self.position, aim, u_dir, u_extra, |_| self.intensity)
    }

    pub fn bounds(&self) -> Target {
        Target {
            center: self.position,
            radius: 0.0,
        }
    }
}

/// A photon from a point light at `position` with intensity `intensity(w)` toward `w`:
/// I / pdf, with the direction uniform over the sphere or over a projection map's cells.
pub(super) fn emit_from_point(
    position: Vec3A,
    aim: &Aim,
    u_dir: Vec2,
    u_extra: f32,
    intensity: impl FnOnce(Vec3A) -> Spectrum,
) -> Option<Emission> {
    let (d, pdf) = match aim {
        Aim::Projection(map) => map.sample(u_extra, u_dir)?,
        _ => (
            square_to_uniform_sphere(u_dir),
            crate::sampling::UNIFORM_SPHERE_PDF,
        ),
    };
    let le = intensity(d);
    Some(Emission {
        ray: Ray::new(position, d),
        flux: le / pdf,
        le,
        n: Vec3A::ZERO,
        pdf_pos: 1.0,
        pdf_dir: pdf,
    })
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
