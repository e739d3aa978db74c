//! A Lambertian base plus one glossy lobe (Phong, Blinn–Phong, Ward): f = k_d/π + k_s·lobe.
//! Lobes are chosen for sampling in proportion to the luminance of k_d and k_s; the density is
//! the mixture of both (one-sample MIS).

use glam::{Vec2, Vec3A};

use super::{Bsdf, BsdfFlags, BsdfSample, TransportMode, diffuse_pdf, sample_diffuse};
use crate::math::INV_PI;
use crate::spectrum::{Spectrum, luminance};

/// The shape of a glossy lobe, defined for wo.z > 0.
pub trait GlossyLobe: Send + Sync + std::fmt::Debug {
    /// The lobe's BRDF for unit specular reflectance, wi.z > 0.
    fn eval(&self, wo: Vec3A, wi: Vec3A) -> f32;
    /// A direction distributed like the lobe (may lie below the surface: then rejected).
    fn sample(&self, wo: Vec3A, u: Vec2) -> Option<Vec3A>;
    /// Density of `sample`.
    fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32;
}

#[derive(Debug, Clone)]
pub struct WithDiffuse<L> {
    kd: Spectrum,
    ks: Spectrum,
    p_glossy: f32,
    lobe: L,
}

impl<L: GlossyLobe> WithDiffuse<L> {
    pub fn new(kd: Spectrum, ks: Spectrum, lobe: L) -> Self {
        let (d, s) = (luminance(kd), luminance(ks));
        let p_glossy = if d + s > 0.0 { s / (d + s) } else { 0.0 };
        WithDiffuse {
            kd,
            ks,
            p_glossy,
            lobe,
        }
    }
}

impl<L: GlossyLobe> Bsdf for WithDiffuse<L> {
    fn flags(&self) -> BsdfFlags {
        let any = self.kd.max_element() > 0.0 || self.ks.max_element() > 0.0;
        BsdfFlags {
            reflection: any,
            smooth: any,
            diffuse: self.kd.max_element() > 0.0,
            ..Default::default()
        }
    }

    fn eval(&self, wo: Vec3A, wi: Vec3A, _: TransportMode) -> Spectrum {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Spectrum::ZERO;
        }
        self.kd * INV_PI + self.ks * self.lobe.eval(wo, wi)
    }

    fn sample(&self, wo: Vec3A, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z <= 0.0 || self.flags() == BsdfFlags::default() {
            return None;
        }
        let wi = if u_lobe < self.p_glossy {
            self.lobe.sample(wo, u)?
        } else {
            sample_diffuse(u)?
        };
        if wi.z <= 0.0 {
            return None;
        }
        BsdfSample::reflection(self, wo, wi, mode)
    }

    fn pdf(&self, wo: Vec3A, wi: Vec3A, _: TransportMode) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let glossy = if self.p_glossy > 0.0 {
            self.lobe.pdf(wo, wi)
        } else {
            0.0
        };
        self.p_glossy * glossy + (1.0 - self.p_glossy) * diffuse_pdf(wo, wi)
    }

    fn albedo(&self) -> Spectrum {
        self.kd + self.ks
    }
}
