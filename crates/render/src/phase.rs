//! The Henyey–Greenstein phase function: how a scattering medium turns light, per steradian.

use glam::{Vec2, Vec3A};

use crate::math::Frame;

/// cos θ between the old and new direction, sampled from the Henyey–Greenstein phase function
/// with mean cosine `g` (uniform at g = 0) by inverting its CDF (pbrt-v4 §11.3.1).
pub fn hg_cos(g: f64, u: f64) -> f64 {
    if g.abs() < 1e-3 {
        1.0 - 2.0 * u
    } else {
        let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
        ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
    }
}

/// The Henyey–Greenstein phase function per steradian at cosine `cos` between the directions
/// of travel before and after scattering: (1 − g²) / (4π (1 + g² − 2g cos)^(3/2)).
#[inline]
pub fn hg(cos: f32, g: f32) -> f32 {
    let d = 1.0 + g * g - 2.0 * g * cos;
    (1.0 - g * g) / (4.0 * std::f32::consts::PI * d * d.sqrt())
}

/// A direction scattered from unit `d` by the Henyey–Greenstein phase function.
pub fn sample_hg(d: Vec3A, g: f32, u: Vec2) -> Vec3A {
    let cos = hg_cos(g as f64, u.x as f64) as f32;
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let (s, c) = (2.0 * std::f32::consts::PI * u.y).sin_cos();
    Frame::from_normal(d).to_world(Vec3A::new(sin * c, sin * s, cos))
}
