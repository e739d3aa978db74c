//! Conductors: exact Fresnel for a complex IOR η + ik, either smooth (a delta reflection) or
//! rough with a Cook–Torrance microfacet lobe f = D(h) G(wo, wi) F(wo·h) / (4 cos θo cos θi)
//! (Cook & Torrance 1982; Walter et al. 2007), sampled by visible normals.

use glam::{Vec2, Vec3A};

use super::microfacet::Microfacet;
use super::{Bsdf, BsdfFlags, BsdfSample, TransportMode, fresnel, reflected_pdf};
use crate::math::reflect;
use crate::spectrum::Spectrum;

#[derive(Debug, Clone)]
pub struct Conductor {
    eta: Spectrum,
    k: Spectrum,
    specular: Spectrum,
    /// `None`: perfectly smooth.
    microfacet: Option<Microfacet>,
}

impl Conductor {
    pub fn new(
        eta: Spectrum,
        k: Spectrum,
        specular: Spectrum,
        microfacet: Option<Microfacet>,
    ) -> Self {
        Conductor {
            eta,
            k,
            specular,
            microfacet,
        }
    }

    #[inline]
    fn fresnel(&self, cos: f32) -> Spectrum {
        fresnel::conductor(cos, self.eta, self.k) * self.specular
    }
}

impl Bsdf for Conductor {
    fn flags(&self) -> BsdfFlags {
        let smooth = self.microfacet.is_some();
        BsdfFlags {
            reflection: true,
            specular: !smooth,
            smooth,
            ..Default::default()
        }
    }

    fn eval(&self, wo: Vec3A, wi: Vec3A, _: TransportMode) -> Spectrum {
        let Some(mf) = &self.microfacet else {
            return Spectrum::ZERO;
        };
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Spectrum::ZERO;
        }
        let h = (wo + wi).normalize();
        self.fresnel(wo.dot(h)) * (mf.d(h) * mf.g(wo, wi) / (4.0 * wo.z * wi.z))
    }

    fn sample(&self, wo: Vec3A, _: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let Some(mf) = &self.microfacet else {
            let wi = Vec3A::new(-wo.x, -wo.y, wo.z);
            return Some(BsdfSample::specular_reflection(wi, self.fresnel(wo.z), 1.0));
        };
        let m = mf.sample_m(wo, u);
        if wo.dot(m) <= 0.0 {
            return None;
        }
        let wi = reflect(wo, m);
        if wi.z <= 0.0 {
            return None;
        }
        BsdfSample::reflection(self, wo, wi, mode)
    }

    fn pdf(&self, wo: Vec3A, wi: Vec3A, _: TransportMode) -> f32 {
        let Some(mf) = &self.microfacet else {
            return 0.0;
        };
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        reflected_pdf(wo, wi, |h| mf.pdf_m(wo, h))
    }

    fn albedo(&self) -> Spectrum {
        self.fresnel(1.0)
    }
}
