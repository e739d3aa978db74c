//! Smooth dielectric interface: delta reflection and refraction weighted by the exact Fresnel
//! reflectance, with total internal reflection. `eta` is the IOR inside (opposite the normal)
//! over outside; η = 1 makes the interface invisible. Transmission may be tinted (glTF's base
//! colour on a transmissive material), the same way in both directions, so f stays
//! reciprocal.

use glam::{Vec2, Vec3A};

use super::{Bsdf, BsdfFlags, BsdfSample, TransportMode, fresnel};
use crate::spectrum::Spectrum;

#[derive(Debug, Clone)]
pub struct SmoothDielectric {
    eta: f32,
    /// What transmission keeps per channel.
    tint: Spectrum,
}

impl SmoothDielectric {
    pub fn new(eta: f32) -> Self {
        SmoothDielectric {
            eta,
            tint: Spectrum::ONE,
        }
    }

    /// The interface with transmission scaled by `tint`.
    pub fn with_tint(self, tint: Spectrum) -> Self {
        SmoothDielectric { tint, ..self }
    }
}

impl Bsdf for SmoothDielectric {
    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            reflection: self.eta != 1.0,
            transmission: true,
            specular: true,
            smooth: false,
            diffuse: false,
        }
    }

    fn eval(&self, _: Vec3A, _: Vec3A, _: TransportMode) -> Spectrum {
        Spectrum::ZERO
    }

    fn sample(&self, wo: Vec3A, u_lobe: f32, _: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let r = fresnel::dielectric(wo.z, self.eta);
        if u_lobe < r {
            let wi = Vec3A::new(-wo.x, -wo.y, wo.z);
            return Some(BsdfSample::specular_reflection(wi, Spectrum::splat(r), r));
        }
        // Relative IOR seen from wo's side, and the normal on wo's side.
        let (etap, n) = if wo.z > 0.0 {
            (self.eta, Vec3A::Z)
        } else {
            (1.0 / self.eta, -Vec3A::Z)
        };
        let wi = fresnel::refract(wo, n, etap)?;
        let t = 1.0 - r;
        let mut f = t / wi.z.abs();
        if mode == TransportMode::Radiance {
            f /= etap * etap;
        }
        Some(BsdfSample {
            wi,
            f: self.tint * f,
            pdf: t,
            specular: true,
            transmission: true,
            eta: etap,
        })
    }

    fn pdf(&self, _: Vec3A, _: Vec3A, _: TransportMode) -> f32 {
        0.0
    }

    fn albedo(&self) -> Spectrum {
        self.tint
    }
}
