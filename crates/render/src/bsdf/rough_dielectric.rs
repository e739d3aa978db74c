//! Rough dielectric interface (Walter, Marschner, Li & Torrance, "Microfacet Models for
//! Refraction through Rough Surfaces", EGSR 2007), in the formulation of pbrt-v4 §9.7:
//! reflection f_r = D G F / (4 |cos θi cos θo|); transmission
//! f_t = D G (1 − F) |wi·m| |wo·m| / (|cos θi cos θo| (wi·m + wo·m/η′)²), divided by η′² when
//! transporting radiance. Sampled by visible normals of wo, then reflection or refraction
//! chosen by Fresnel. Transmission may be tinted (glTF's base colour), alike in both
//! directions.

use glam::{Vec2, Vec3A};

use super::microfacet::Microfacet;
use super::{Bsdf, BsdfFlags, BsdfSample, TransportMode, fresnel};
use crate::math::reflect;
use crate::spectrum::Spectrum;

#[derive(Debug, Clone)]
pub struct RoughDielectric {
    eta: f32,
    mf: Microfacet,
    /// What transmission keeps per channel.
    tint: Spectrum,
}

/// The generalised half vector of a pair of directions and the relative IOR η′ seen from wo.
struct Half {
    m: Vec3A,
    etap: f32,
    reflect: bool,
}

impl RoughDielectric {
    pub fn new(eta: f32, mf: Microfacet) -> Self {
        RoughDielectric {
            eta,
            mf,
            tint: Spectrum::ONE,
        }
    }

    /// The interface with transmission scaled by `tint`.
    pub fn with_tint(self, tint: Spectrum) -> Self {
        RoughDielectric { tint, ..self }
    }

    fn half(&self, wo: Vec3A, wi: Vec3A) -> Option<Half> {
        if wo.z == 0.0 || wi.z == 0.0 {
            return None;
        }
        let reflect = wo.z * wi.z > 0.0;
        let etap = if reflect {
            1.0
        } else if wo.z > 0.0 {
            self.eta
        } else {
            1.0 / self.eta
        };
        let m = wi * etap + wo;
        if m.length_squared() == 0.0 {
            return None;
        }
        let m = m.normalize();
        let m = if m.z < 0.0 { -m } else { m };
        // Microfacets seen from behind by either direction contribute nothing.
        if m.dot(wi) * wi.z < 0.0 || m.dot(wo) * wo.z < 0.0 {
            return None;
        }
        Some(Half { m, etap, reflect })
    }
}

impl Bsdf for RoughDielectric {
    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            reflection: true,
            transmission: true,
            specular: false,
            smooth: true,
            diffuse: false,
        }
    }

    fn eval(&self, wo: Vec3A, wi: Vec3A, mode: TransportMode) -> Spectrum {
        let Some(Half { m, etap, reflect }) = self.half(wo, wi) else {
            return Spectrum::ZERO;
        };
        // Fresnel is the same from either side of the microfacet; evaluating it from the
        // outside avoids the cancellation near total internal reflection and keeps f exactly
        // reciprocal.
        let outside = if wo.z > 0.0 { wo } else { wi };
        let f = fresnel::dielectric(outside.dot(m), self.eta);
        let dg = self.mf.d(m) * self.mf.g(wo, wi);
        let value = if reflect {
            dg * f / (4.0 * wi.z * wo.z).abs()
        } else {
            let denom = (wi.dot(m) + wo.dot(m) / etap).powi(2) * wi.z * wo.z;
            let mut ft = dg * (1.0 - f) * (wi.dot(m) * wo.dot(m) / denom).abs();
            if mode == TransportMode::Radiance {
                ft /= etap * etap;
            }
            ft
        };
        let value = Spectrum::splat(if value.is_finite() { value } else { 0.0 });
        if reflect { value } else { value * self.tint }
    }

    fn sample(&self, wo: Vec3A, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let m = self.mf.sample_m(wo, u);
        // Microfacets facing away from wo cannot scatter it (Beckmann draws them; visible-
        // normal sampling never does).
        if wo.dot(m) * wo.z <= 0.0 {
            return None;
        }
        let r = fresnel::dielectric(wo.dot(m), self.eta);
        let (wi, transmission, etap) = if u_lobe < r {
            let wi = reflect(wo, m);
            if wi.z * wo.z <= 0.0 {
                return None;
            }
            (wi, false, 1.0)
        } else {
            // Snell's law across the microfacet, from whichever side of it wo is on.
            let (etap, n) = if wo.dot(m) > 0.0 {
                (self.eta, m)
            } else {
                (1.0 / self.eta, -m)
            };
            let wi = fresnel::refract(wo, n, etap)?;
            if wi.z * wo.z >= 0.0 {
                return None;
            }
            (wi, true, etap)
        };
        let pdf = self.pdf(wo, wi, mode);
        (pdf > 0.0).then(|| BsdfSample {
            wi,
            f: self.eval(wo, wi, mode),
            pdf,
            specular: false,
            transmission,
            eta: etap,
        })
    }

    fn pdf(&self, wo: Vec3A, wi: Vec3A, _: TransportMode) -> f32 {
        let Some(Half { m, etap, reflect }) = self.half(wo, wi) else {
            return 0.0;
        };
        let r = fresnel::dielectric(wo.dot(m), self.eta);
        let pdf_m = self.mf.pdf_m(wo, m);
        let pdf = if reflect {
            pdf_m / (4.0 * wo.dot(m).abs()) * r
        } else {
            let dm_dwi = wi.dot(m).abs() / (wi.dot(m) + wo.dot(m) / etap).powi(2);
            pdf_m * dm_dwi * (1.0 - r)
        };
        if pdf.is_finite() { pdf } else { 0.0 }
    }

    fn albedo(&self) -> Spectrum {
        self.tint
    }
}
