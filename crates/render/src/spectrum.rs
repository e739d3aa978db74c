//! RGB radiometric quantities in linear Rec.709, stored as SIMD-friendly `Vec3A`.

use glam::Vec3A;

/// An RGB spectrum (radiance, reflectance, throughput) in linear Rec.709.
pub type Spectrum = Vec3A;

/// Rec.709 luminance.
#[inline]
pub fn luminance(s: Spectrum) -> f32 {
    s.dot(Vec3A::new(0.2126, 0.7152, 0.0722))
}

#[inline]
pub fn is_black(s: Spectrum) -> bool {
    s.cmpeq(Vec3A::ZERO).all()
}
