//! A thin dielectric sheet (a window pane, a soap film, glTF's thin-walled transmission): two
//! parallel interfaces of relative IOR η so close together that light leaves where it
//! entered. Light bounces between the faces; summing the geometric series of internal
//! reflections (pbrt-v4 §9.5.1, ThinDielectricBxDF), a sheet reflects
//!
//! R = F + (1 − F)² F / (1 − F²) = 2F / (1 + F),   T = 1 − R,
//!
//! with F the Fresnel reflectance of one face at the angle of incidence. Transmitted light is
//! not bent: it continues along −wo, scaled by `tint` (glTF's base colour on a thin-walled
//! transmissive material). The sheet is the same from either side.
//!
//! Rough (a frosted pane, in the thin-walled limit of the glTF specification): each
//! microfacet m is such a sheet, so reflection is the microfacet reflection lobe with R(wo·m)
//! in place of F, and transmission is that lobe mirrored through the surface plane with
//! T(wo·m): f = D(m) G(wo, wi′) X(wo·m) / (4 |cos θo cos θi|), wi′ = wi mirrored to wo's side,
//! m their half vector, X = R or T·tint. It is reciprocal (symmetric in wo and wi′) and never
//! creates energy (a GGX reflection lobe split in two). Sampled by visible normals, then
//! reflection or transmission chosen by R.

use glam::{Vec2, Vec3A};

use super::microfacet::Microfacet;
use super::{Bsdf, BsdfFlags, BsdfSample, TransportMode, fresnel};
use crate::math::reflect;
use crate::spectrum::Spectrum;

#[derive(Debug, Clone)]
pub struct ThinDielectric {
    eta: f32,
    /// `None`: smooth (delta reflection and transmission).
    mf: Option<Microfacet>,
    /// What transmission keeps per channel.
    tint: Spectrum,
}

/// `w` mirrored through the surface plane.
#[inline]
fn mirror(w: Vec3A) -> Vec3A {
    Vec3A::new(w.x, w.y, -w.z)
}

impl ThinDielectric {
    pub fn new(eta: f32, mf: Option<Microfacet>) -> Self {
        ThinDielectric {
            eta,
            mf,
            tint: Spectrum::ONE,
        }
    }

    /// The sheet with transmission scaled by `tint`.
    pub fn with_tint(self, tint: Spectrum) -> Self {
        ThinDielectric { tint, ..self }
    }

    /// 2F / (1 + F) at cosine `cos` (either side).
    #[inline]
    fn reflectance(&self, cos: f32) -> f32 {
        let f = fresnel::dielectric(cos.abs(), self.eta);
        2.0 * f / (1.0 + f)
    }

    /// (wo, wi) turned so that wo is above the surface, with wi mirrored onto wo's side if it
    /// was transmitted; and whether it was.
    #[inline]
    fn canonical(wo: Vec3A, wi: Vec3A) -> (Vec3A, Vec3A, bool) {
        let (wo, wi) = if wo.z < 0.0 {
            (mirror(wo), mirror(wi))
        } else {
            (wo, wi)
        };
        if wi.z < 0.0 {
            (wo, mirror(wi), true)
        } else {
            (wo, wi, false)
        }
    }
}

impl Bsdf for ThinDielectric {
    fn flags(&self) -> BsdfFlags {
        BsdfFlags {
            reflection: self.eta != 1.0,
            transmission: true,
            specular: self.mf.is_none(),
            smooth: self.mf.is_some(),
            diffuse: false,
        }
    }

    fn eval(&self, wo: Vec3A, wi: Vec3A, _: TransportMode) -> Spectrum {
        let Some(mf) = &self.mf else {
            return Spectrum::ZERO;
        };
        let (a, b, transmitted) = Self::canonical(wo, wi);
        if a.z <= 0.0 || b.z <= 0.0 {
            return Spectrum::ZERO;
        }
        let m = (a + b).normalize();
        let r = self.reflectance(a.dot(m));
        let s = mf.d(m) * mf.g(a, b) / (4.0 * a.z * b.z);
        let value = if transmitted {
            self.tint * ((1.0 - r) * s)
        } else {
            Spectrum::splat(r * s)
        };
        if value.is_finite() {
            value
        } else {
            Spectrum::ZERO
        }
    }

    fn sample(&self, wo: Vec3A, u_lobe: f32, u: Vec2, mode: TransportMode) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let Some(mf) = &self.mf else {
            let r = self.reflectance(wo.z);
            if u_lobe < r {
                let wi = Vec3A::new(-wo.x, -wo.y, wo.z);
                return Some(BsdfSample::specular_reflection(wi, Spectrum::splat(r), r));
            }
            let wi = -wo;
            let t = 1.0 - r;
            return Some(BsdfSample {
                wi,
                f: self.tint * (t / wi.z.abs()),
                pdf: t,
                specular: true,
                transmission: true,
                eta: 1.0,
            });
        };
        let a = if wo.z < 0.0 { mirror(wo) } else { wo };
        let m = mf.sample_m(a, u);
        if a.dot(m) <= 0.0 {
            return None;
        }
        let b = reflect(a, m);
        if b.z <= 0.0 {
            return None;
        }
        let transmission = u_lobe >= self.reflectance(a.dot(m));
        let b = if transmission { mirror(b) } else { b };
        let wi = if wo.z < 0.0 { mirror(b) } else { b };
        let pdf = self.pdf(wo, wi, mode);
        (pdf > 0.0).then(|| BsdfSample {
            wi,
            f: self.eval(wo, wi, mode),
            pdf,
            specular: false,
            transmission,
            eta: 1.0,
        })
    }

    fn pdf(&self, wo: Vec3A, wi: Vec3A, _: TransportMode) -> f32 {
        let Some(mf) = &self.mf else {
            return 0.0;
        };
        let (a, b, transmitted) = Self::canonical(wo, wi);
        if a.z <= 0.0 || b.z <= 0.0 {
            return 0.0;
        }
        let m = (a + b).normalize();
        let d = a.dot(m);
        if d <= 0.0 {
            return 0.0;
        }
        let r = self.reflectance(d);
        let pdf = mf.pdf_m(a, m) / (4.0 * d) * if transmitted { 1.0 - r } else { r };
        if pdf.is_finite() { pdf } else { 0.0 }
    }

    fn albedo(&self) -> Spectrum {
        self.tint
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tessera_scene::Distribution;

    #[test]
    fn a_smooth_sheet_passes_what_its_two_faces_and_their_echoes_pass() {
        // Normal incidence at η 1.5: F = 0.04 per face, so T = (1 − F)² Σ F^(2k) = 0.96²/(1 −
        // 0.04²) = 1 − 2F/(1 + F).
        let b = ThinDielectric::new(1.5, None).with_tint(Spectrum::new(1.0, 0.5, 0.25));
        let wo = Vec3A::new(0.0, 0.0, 1.0);
        let t = b
            .sample(wo, 0.999, Vec2::ZERO, TransportMode::Radiance)
            .unwrap();
        let expected = 0.96f32 * 0.96 / (1.0 - 0.04 * 0.04);
        assert!(t.transmission && (t.wi + wo).length() < 1e-6);
        assert!(
            (t.weight() - Spectrum::new(1.0, 0.5, 0.25))
                .abs()
                .max_element()
                < 1e-6
        );
        assert!((t.pdf - expected).abs() < 1e-6, "T {} vs {expected}", t.pdf);
        let r = b
            .sample(wo, 0.0, Vec2::ZERO, TransportMode::Radiance)
            .unwrap();
        assert!(!r.transmission && (r.pdf - (1.0 - expected)).abs() < 1e-6);
        // From below, the same.
        let t2 = b
            .sample(-wo, 0.999, Vec2::ZERO, TransportMode::Radiance)
            .unwrap();
        assert!((t2.wi - wo).length() < 1e-6 && (t2.pdf - expected).abs() < 1e-6);
    }

    #[test]
    fn a_rough_sheet_tends_to_the_smooth_one_as_it_gets_smooth() {
        // Nearly smooth: the transmitted share of samples at 40° is the smooth sheet's T.
        let b = ThinDielectric::new(1.5, Some(Microfacet::new(Distribution::Ggx, 1e-3, 1e-3)));
        let smooth = ThinDielectric::new(1.5, None);
        let (s, c) = 40f32.to_radians().sin_cos();
        let wo = Vec3A::new(s, 0.0, c);
        let n = 20_000;
        let (mut through, mut straight) = (0.0f64, 0);
        for i in 0..n {
            let u = (i as f32 + 0.5) / n as f32;
            if let Some(x) = b.sample(wo, u, Vec2::new(0.37, u), TransportMode::Radiance)
                && x.transmission
            {
                through += x.weight().x as f64 / n as f64;
                // Not bent (refraction into glass would turn it by 15°), but for GGX's tail.
                straight += ((x.wi + wo).length() < 0.02) as u32;
            }
        }
        let t = 1.0 - smooth.reflectance(c);
        assert!((through - t as f64).abs() < 5e-3, "{through} vs {t}");
        assert!(
            straight as f64 > 0.98 * t as f64 * n as f64,
            "{straight} straight on"
        );
    }
}
