//! Microfacet normal distributions with Smith masking–shadowing (Walter, Marschner, Li &
//! Torrance, "Microfacet Models for Refraction through Rough Surfaces", EGSR 2007; Heitz,
//! "Understanding the Masking-Shadowing Function", JCGT 2014). All directions are local
//! (normal +z); widths α_u, α_v are along the frame's s and t axes.

use glam::{Vec2, Vec3A};
use tessera_scene::Distribution;

use crate::math::{PI, safe_sqrt};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Microfacet {
    pub distribution: Distribution,
    pub alpha_u: f32,
    pub alpha_v: f32,
}

/// Error function (Abramowitz & Stegun 7.1.26; absolute error below 1.5e-7).
fn erf(x: f32) -> f32 {
    let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
    let y = 1.0
        - (((((1.061_405_4 * t - 1.453_152_1) * t) + 1.421_413_7) * t - 0.284_496_74) * t
            + 0.254_829_6)
            * t
            * (-x * x).exp();
    y.copysign(x)
}

impl Microfacet {
    /// Widths are clamped to at least 1e-4 so that nearly smooth surfaces stay finite.
    pub fn new(distribution: Distribution, alpha_u: f32, alpha_v: f32) -> Self {
        Microfacet {
            distribution,
            alpha_u: alpha_u.max(1e-4),
            alpha_v: alpha_v.max(1e-4),
        }
    }

    /// tan²θ_m (cos²φ/α_u² + sin²φ/α_v²) for a microfacet normal m.
    #[inline]
    fn slope2(&self, m: Vec3A) -> f32 {
        let (x, y) = (m.x / self.alpha_u, m.y / self.alpha_v);
        (x * x + y * y) / (m.z * m.z)
    }

    /// Distribution of normals D(m), normalised so that ∫ D(m) cos θ_m dm = 1.
    #[inline]
    pub fn d(&self, m: Vec3A) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let cos4 = (m.z * m.z) * (m.z * m.z);
        let e = self.slope2(m);
        let norm = PI * self.alpha_u * self.alpha_v * cos4;
        let d = match self.distribution {
            Distribution::Ggx => 1.0 / (norm * (1.0 + e) * (1.0 + e)),
            Distribution::Beckmann => (-e).exp() / norm,
        };
        if d.is_finite() { d } else { 0.0 }
    }

    /// Smith's Λ(w), so that G₁(w) = 1 / (1 + Λ(w)).
    #[inline]
    pub fn lambda(&self, w: Vec3A) -> f32 {
        let (x, y) = (w.x * self.alpha_u, w.y * self.alpha_v);
        let a2t2 = (x * x + y * y) / (w.z * w.z); // α(w)² tan²θ
        if !a2t2.is_finite() {
            return if w.z == 0.0 { f32::INFINITY } else { 0.0 };
        }
        match self.distribution {
            Distribution::Ggx => 0.5 * ((1.0 + a2t2).sqrt() - 1.0),
            Distribution::Beckmann => {
                if a2t2 == 0.0 {
                    return 0.0;
                }
                let a = 1.0 / a2t2.sqrt();
                0.5 * (erf(a) - 1.0) + (-a * a).exp() / (2.0 * a * PI.sqrt())
            }
        }
    }

    #[inline]
    pub fn g1(&self, w: Vec3A) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking–shadowing G(wo, wi) = 1 / (1 + Λ(wo) + Λ(wi)).
    #[inline]
    pub fn g(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// Samples a microfacet normal for direction `w`: visible normals for GGX (Heitz,
    /// "Sampling the GGX Distribution of Visible Normals", JCGT 2018), D(m)cos θ_m for
    /// Beckmann. Directions below the surface are treated as seen from the other side.
    #[inline]
    pub fn sample_m(&self, w: Vec3A, u: Vec2) -> Vec3A {
        match self.distribution {
            Distribution::Ggx => {
                let mut wh = Vec3A::new(self.alpha_u * w.x, self.alpha_v * w.y, w.z).normalize();
                if wh.z < 0.0 {
                    wh = -wh;
                }
                let lensq = wh.x * wh.x + wh.y * wh.y;
                let t1 = if lensq > 0.0 {
                    Vec3A::new(-wh.y, wh.x, 0.0) / lensq.sqrt()
                } else {
                    Vec3A::X
                };
                let t2 = wh.cross(t1);
                let p = crate::sampling::square_to_disk(u);
                let h = safe_sqrt(1.0 - p.x * p.x);
                let s = 0.5 * (1.0 + wh.z);
                let py = (1.0 - s) * h + s * p.y;
                let pz = safe_sqrt(1.0 - p.x * p.x - py * py);
                let nh = t1 * p.x + t2 * py + wh * pz;
                Vec3A::new(self.alpha_u * nh.x, self.alpha_v * nh.y, nh.z.max(1e-6)).normalize()
            }
            Distribution::Beckmann => {
                let (s, c) = (2.0 * PI * u.y).sin_cos();
                let phi = (self.alpha_v * s).atan2(self.alpha_u * c);
                let (sp, cp) = phi.sin_cos();
                let k = (cp / self.alpha_u).powi(2) + (sp / self.alpha_v).powi(2);
                let tan2 = -(1.0 - u.x).max(f32::MIN_POSITIVE).ln() / k;
                let cos_t = 1.0 / (1.0 + tan2).sqrt();
                let sin_t = safe_sqrt(1.0 - cos_t * cos_t);
                Vec3A::new(sin_t * cp, sin_t * sp, cos_t)
            }
        }
    }

    /// Density of [`Self::sample_m`] with respect to solid angle of m.
    #[inline]
    pub fn pdf_m(&self, w: Vec3A, m: Vec3A) -> f32 {
        match self.distribution {
            Distribution::Ggx => {
                if w.z == 0.0 {
                    return 0.0;
                }
                self.g1(w) / w.z.abs() * self.d(m) * w.dot(m).abs()
            }
            Distribution::Beckmann => self.d(m) * m.z,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::hash::{mix64, u32_to_unit};

    fn u(i: u64) -> Vec2 {
        let h = mix64(i);
        Vec2::new(u32_to_unit(h as u32), u32_to_unit((h >> 32) as u32))
    }

    /// ∫ D(m) cos θ_m dm = 1 and ∫ D(m)(w·m) dm over visible m = cos θ_w (projected area),
    /// estimated by uniform hemisphere sampling.
    #[test]
    fn normalisation_and_projected_area() {
        for dist in [Distribution::Ggx, Distribution::Beckmann] {
            for (au, av) in [(0.3, 0.3), (0.2, 0.6), (0.9, 0.9)] {
                let mf = Microfacet::new(dist, au, av);
                let n = 400_000;
                let w = Vec3A::new(0.5, 0.2, 0.6).normalize();
                let (mut norm, mut proj) = (0.0f64, 0.0f64);
                for i in 0..n {
                    let m = crate::sampling::square_to_cosine_hemisphere(u(i));
                    let pdf = m.z / PI;
                    norm += (mf.d(m) * m.z / pdf) as f64;
                    proj += (mf.g1(w) * mf.d(m) * w.dot(m).max(0.0) / pdf) as f64;
                }
                norm /= n as f64;
                proj /= n as f64;
                assert!(
                    (norm - 1.0).abs() < 0.02,
                    "{dist:?} {au} {av}: ∫D cos = {norm}"
                );
                assert!(
                    (proj - w.z as f64).abs() < 0.02,
                    "{dist:?} {au} {av}: ∫G1 D (w·m) = {proj}"
                );
            }
        }
    }

    #[test]
    fn sampled_normals_are_unit_and_upper() {
        for dist in [Distribution::Ggx, Distribution::Beckmann] {
            let mf = Microfacet::new(dist, 0.4, 0.1);
            for i in 0..1000 {
                let w = crate::sampling::square_to_uniform_sphere(u(i + 77));
                let m = mf.sample_m(w, u(i));
                assert!((m.length() - 1.0).abs() < 1e-4 && m.z > 0.0);
            }
        }
    }
}
