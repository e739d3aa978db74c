//! Fresnel equations for unpolarised light.

use glam::Vec3A;

use crate::math::safe_sqrt;
use crate::spectrum::Spectrum;

/// The cosine-weighted hemispherical average of [`dielectric`], 2 ∫₀¹ Fr(±μ) μ dμ (twice the
/// first Fresnel moment), for light arriving from outside or, with `inside`, from inside: the
/// midpoint rule on `n` steps in μ.
pub fn hemispherical_reflectance(eta: f32, inside: bool, n: u32) -> f64 {
    let sign = if inside { -1.0 } else { 1.0 };
    (0..n)
        .map(|i| {
            let mu = (i as f64 + 0.5) / n as f64;
            2.0 * dielectric(sign * mu as f32, eta) as f64 * mu
        })
        .sum::<f64>()
        / n as f64
}

/// Fresnel reflectance of a dielectric interface with relative IOR `eta` (inside/outside),
/// for a direction with cosine `cos_i` to the normal (negative: arriving from inside).
/// Returns 1 under total internal reflection.
#[inline]
pub fn dielectric(cos_i: f32, eta: f32) -> f32 {
    if eta == 1.0 {
        return 0.0;
    }
    let (cos_i, eta) = if cos_i < 0.0 {
        (-cos_i, 1.0 / eta)
    } else {
        (cos_i, eta)
    };
    let cos_i = cos_i.min(1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = safe_sqrt(1.0 - sin2_t);
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_parl * r_parl + r_perp * r_perp)
}

/// Refracts `wi` (pointing away from the surface) through the interface with normal `n`
/// (same side as `wi`) and relative IOR `eta`; `None` under total internal reflection.
#[inline]
pub fn refract(wi: Vec3A, n: Vec3A, eta: f32) -> Option<Vec3A> {
    let cos_i = n.dot(wi);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = safe_sqrt(1.0 - sin2_t);
    Some(-wi / eta + n * (cos_i / eta - cos_t))
}

#[derive(Clone, Copy)]
struct Complex {
    re: f32,
    im: f32,
}

impl Complex {
    fn mul(self, o: Complex) -> Complex {
        Complex {
            re: self.re * o.re - self.im * o.im,
            im: self.re * o.im + self.im * o.re,
        }
    }
    fn div(self, o: Complex) -> Complex {
        let d = o.re * o.re + o.im * o.im;
        Complex {
            re: (self.re * o.re + self.im * o.im) / d,
            im: (self.im * o.re - self.re * o.im) / d,
        }
    }
    fn add(self, o: Complex) -> Complex {
        Complex {
            re: self.re + o.re,
            im: self.im + o.im,
        }
    }
    fn sub(self, o: Complex) -> Complex {
        Complex {
            re: self.re - o.re,
            im: self.im - o.im,
        }
    }
    fn norm(self) -> f32 {
        self.re * self.re + self.im * self.im
    }
    fn sqrt(self) -> Complex {
        let n = self.norm().sqrt();
        if n == 0.0 {
            return Complex { re: 0.0, im: 0.0 };
        }
        let t1 = (0.5 * (n + self.re.abs())).sqrt();
        let t2 = 0.5 * self.im / t1;
        if self.re >= 0.0 {
            Complex { re: t1, im: t2 }
        } else {
            Complex {
                re: t2.abs(),
                im: t1.copysign(self.im),
            }
        }
    }
}

/// Fresnel reflectance of a conductor with complex IOR η + ik, for one wavelength.
fn conductor_1(cos_i: f32, eta: f32, k: f32) -> f32 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let eta = Complex { re: eta, im: k };
    let sin2_i = 1.0 - cos_i * cos_i;
    let sin2_t = Complex {
        re: sin2_i,
        im: 0.0,
    }
    .div(eta.mul(eta));
    let cos_t = Complex { re: 1.0, im: 0.0 }.sub(sin2_t).sqrt();
    let ci = Complex { re: cos_i, im: 0.0 };
    let r_parl = eta.mul(ci).sub(cos_t).div(eta.mul(ci).add(cos_t));
    let r_perp = ci.sub(eta.mul(cos_t)).div(ci.add(eta.mul(cos_t)));
    0.5 * (r_parl.norm() + r_perp.norm())
}

/// Fresnel reflectance of a conductor, per RGB channel.
#[inline]
pub fn conductor(cos_i: f32, eta: Spectrum, k: Spectrum) -> Spectrum {
    Vec3A::new(
        conductor_1(cos_i, eta.x, k.x),
        conductor_1(cos_i, eta.y, k.y),
        conductor_1(cos_i, eta.z, k.z),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dielectric_values() {
        // Normal incidence: ((η − 1)/(η + 1))² = 0.04 for glass.
        assert!((dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        assert_eq!(dielectric(0.3, 1.0), 0.0);
        // From inside beyond the critical angle (41.8° for 1.5): total internal reflection.
        assert_eq!(dielectric(-0.5, 1.5), 1.0);
        assert!((dielectric(0.0, 1.5) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn conductor_reduces_to_dielectric_without_absorption() {
        for c in [0.1, 0.5, 0.9] {
            assert!((conductor_1(c, 1.5, 0.0) - dielectric(c, 1.5)).abs() < 1e-5);
        }
        // Gold at normal incidence, red channel: ((η−1)² + k²)/((η+1)² + k²).
        let (n, k) = (0.143f32, 3.983f32);
        let expect = ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
        assert!((conductor_1(1.0, n, k) - expect).abs() < 1e-5);
    }

    #[test]
    fn refraction_obeys_snell() {
        let wi = Vec3A::new(0.6, 0.0, 0.8);
        let wt = refract(wi, Vec3A::Z, 1.5).unwrap();
        assert!((wt.length() - 1.0).abs() < 1e-6 && wt.z < 0.0);
        assert!((0.6 - 1.5 * wt.x.abs()).abs() < 1e-6);
        assert!(refract(Vec3A::new(0.8, 0.0, 0.6), Vec3A::Z, 1.0 / 1.5).is_none());
    }
}
