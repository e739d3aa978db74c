//! Small numeric helpers: constants, floating-point error bounds, orthonormal frames.

use glam::Vec3A;

pub use std::f32::consts::PI;
pub const INV_PI: f32 = 1.0 / PI;
pub const INV_2PI: f32 = 0.5 / PI;
pub const INV_4PI: f32 = 0.25 / PI;

/// γ(n) = n·ε / (1 − n·ε), the bound on relative error after n floating-point operations
/// (Higham; pbrt-v4 §6.8.1), with ε the unit roundoff 2⁻²⁴.
#[inline]
pub const fn gamma(n: i32) -> f32 {
    let e = f32::EPSILON * 0.5;
    (n as f32 * e) / (1.0 - n as f32 * e)
}

/// The next representable f32 above `v` (−0 and +0 both step to the smallest positive).
#[inline]
pub fn next_float_up(v: f32) -> f32 {
    if v.is_infinite() && v > 0.0 {
        return v;
    }
    let v = if v == -0.0 { 0.0 } else { v };
    let bits = v.to_bits();
    f32::from_bits(if v >= 0.0 { bits + 1 } else { bits - 1 })
}

/// The next representable f32 below `v`.
#[inline]
pub fn next_float_down(v: f32) -> f32 {
    if v.is_infinite() && v < 0.0 {
        return v;
    }
    let v = if v == 0.0 { -0.0 } else { v };
    let bits = v.to_bits();
    f32::from_bits(if v > 0.0 { bits - 1 } else { bits + 1 })
}

/// Moves a ray origin off a surface so that the ray cannot re-hit it (pbrt-v4 §6.8.6): the
/// offset along the geometric normal `n` exceeds the error bound `p_error` of the point, on
/// the side `w` leaves to, and is rounded away from the surface. No magic epsilon: the offset
/// scales with the floating-point error of the point itself.
#[inline]
pub fn offset_ray_origin(p: Vec3A, p_error: Vec3A, n: Vec3A, w: Vec3A) -> Vec3A {
    let d = n.abs().dot(p_error);
    let mut offset = n * d;
    if w.dot(n) < 0.0 {
        offset = -offset;
    }
    let po = p + offset;
    let round = |v: f32, o: f32| {
        if o > 0.0 {
            next_float_up(v)
        } else if o < 0.0 {
            next_float_down(v)
        } else {
            v
        }
    };
    Vec3A::new(
        round(po.x, offset.x),
        round(po.y, offset.y),
        round(po.z, offset.z),
    )
}

#[inline]
pub fn safe_sqrt(x: f32) -> f32 {
    x.max(0.0).sqrt()
}

/// An orthonormal frame (s, t, n); BSDFs work in it with the normal along +z.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    pub s: Vec3A,
    pub t: Vec3A,
    pub n: Vec3A,
}

impl Frame {
    /// A frame around unit `n` whose tangent `s` is the world X axis projected onto the tangent
    /// plane (Z where `n` is close to X), so anisotropic materials have a predictable direction.
    #[inline]
    pub fn from_normal(n: Vec3A) -> Frame {
        let axis = if n.x.abs() < 0.9 { Vec3A::X } else { Vec3A::Z };
        let s = (axis - n * n.dot(axis)).normalize();
        Frame {
            s,
            t: n.cross(s),
            n,
        }
    }

    /// Some frame around unit `n`, for sampling that needs no particular tangent: Duff et
    /// al. 2017, "Building an Orthonormal Basis, Revisited" (one division, no square root,
    /// no branch on the axis).
    #[inline]
    pub fn around(n: Vec3A) -> Frame {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        Frame {
            s: Vec3A::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
            t: Vec3A::new(b, sign + n.y * n.y * a, -n.y),
            n,
        }
    }

    /// The same frame seen from the other side (normal flipped, still right-handed).
    #[inline]
    pub fn flipped(&self) -> Frame {
        Frame {
            s: self.s,
            t: -self.t,
            n: -self.n,
        }
    }

    #[inline]
    pub fn to_local(&self, v: Vec3A) -> Vec3A {
        Vec3A::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    #[inline]
    pub fn to_world(&self, v: Vec3A) -> Vec3A {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// Reflection of `w` about the unit vector `n`.
#[inline]
pub fn reflect(w: Vec3A, n: Vec3A) -> Vec3A {
    -w + n * (2.0 * w.dot(n))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn next_float_steps_one_ulp() {
        assert!(next_float_up(1.0) > 1.0 && next_float_up(1.0) - 1.0 == f32::EPSILON);
        assert!(next_float_down(1.0) < 1.0);
        assert!(next_float_up(0.0) > 0.0 && next_float_up(-0.0) > 0.0);
        assert!(next_float_down(0.0) < 0.0);
    }

    #[test]
    fn frame_is_orthonormal_and_round_trips() {
        let normals = [
            Vec3A::X,
            -Vec3A::Z,
            Vec3A::new(0.3, -0.8, 0.52).normalize(),
            Vec3A::new(0.95, 0.1, 0.1).normalize(),
            // Duff et al.'s frame near its seam (n.z about −0): still orthonormal.
            Vec3A::new(0.6, 0.8, -1e-7).normalize(),
        ];
        for (n, f) in normals
            .into_iter()
            .flat_map(|n| [(n, Frame::from_normal(n)), (n, Frame::around(n))])
        {
            assert!((f.s.length() - 1.0).abs() < 1e-6 && (f.t.length() - 1.0).abs() < 1e-6);
            assert!(f.s.dot(f.t).abs() < 1e-6 && f.s.dot(n).abs() < 1e-6);
            assert!(
                (f.s.cross(f.t) - n).length() < 1e-6,
                "right-handed around {n}"
            );
            let v = Vec3A::new(0.2, 0.5, -0.7);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-6);
            assert!((f.to_local(n) - Vec3A::Z).length() < 1e-6);
            let g = f.flipped();
            assert!((g.s.cross(g.t) - g.n).length() < 1e-6);
        }
    }

    #[test]
    fn offset_origin_leaves_the_surface_on_the_requested_side() {
        let p = Vec3A::new(1.0e5, 2.0, -3.0);
        let err = Vec3A::splat(gamma(7)) * p.abs();
        let n = Vec3A::Y;
        let up = offset_ray_origin(p, err, n, Vec3A::new(0.0, 1.0, 0.0));
        let down = offset_ray_origin(p, err, n, Vec3A::new(0.0, -1.0, 0.0));
        assert!(up.y > p.y + err.y && down.y < p.y - err.y);
        assert_eq!(up.x, p.x);
    }
}
