//! Ray–sphere intersection, in f64 so that the root at a surface the ray just left is never
//! mistaken for a new hit; the hit point is reprojected onto the sphere and given an error
//! bound (pbrt-v4 §6.8.5).

use glam::{DVec3, Vec3A};

use crate::math::gamma;

/// Nearest hit distance in (0, t_max), if any. `d` must be a unit vector.
#[inline]
pub fn intersect(center: Vec3A, radius: f32, o: Vec3A, d: Vec3A, t_max: f32) -> Option<f32> {
    let f: DVec3 = o.as_dvec3() - center.as_dvec3();
    let d = d.as_dvec3();
    let r = radius as f64;
    // Numerically robust quadratic for a unit direction (Haines et al., "Precision Improvements
    // for Ray/Sphere Intersection", Ray Tracing Gems, 2019): b' = −f·d, Δ = r² − |f + b'd|².
    let b = -f.dot(d);
    let l = f + d * b;
    let disc = r * r - l.length_squared();
    if disc < 0.0 {
        return None;
    }
    let c = f.length_squared() - r * r;
    let q = b + b.signum() * disc.sqrt();
    let (t0, t1) = if q == 0.0 { (0.0, 0.0) } else { (c / q, q) };
    let (t0, t1) = if t0 <= t1 { (t0, t1) } else { (t1, t0) };
    let t = if t0 > 0.0 { t0 } else { t1 };
    (t > 0.0 && t < t_max as f64).then_some(t as f32)
}

/// Hit point on the sphere for distance `t`, reprojected onto the surface, with its error
/// bound and the outward unit normal.
#[inline]
pub fn point_and_error(
    center: Vec3A,
    radius: f32,
    o: Vec3A,
    d: Vec3A,
    t: f32,
) -> (Vec3A, Vec3A, Vec3A) {
    let c = center.as_dvec3();
    let local = (o.as_dvec3() + d.as_dvec3() * t as f64) - c;
    let n = local.normalize();
    let local = n * radius as f64;
    let p = (c + local).as_vec3a();
    let err = local.abs().as_vec3a() * gamma(5) + p.abs() * gamma(2);
    (p, err, n.as_vec3a())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_from_outside_and_inside() {
        let c = Vec3A::new(1.0, 2.0, 3.0);
        let t = intersect(c, 1.0, c - Vec3A::Z * 5.0, Vec3A::Z, f32::INFINITY).unwrap();
        assert!((t - 4.0).abs() < 1e-5);
        let t = intersect(c, 1.0, c, Vec3A::X, f32::INFINITY).unwrap();
        assert!((t - 1.0).abs() < 1e-6);
        assert!(intersect(c, 1.0, c - Vec3A::Z * 5.0, -Vec3A::Z, f32::INFINITY).is_none());
        assert!(intersect(c, 1.0, c - Vec3A::Z * 5.0, Vec3A::Z, 3.0).is_none());
    }

    #[test]
    fn a_ray_leaving_the_surface_does_not_hit_it_again() {
        let c = Vec3A::new(1e4, -3.0, 2.5);
        let r = 0.37;
        for i in 0..200 {
            let a = i as f32 * 0.31;
            let dir = Vec3A::new(a.cos(), (a * 1.7).sin(), (a * 0.3).cos()).normalize();
            let o = c - dir * 10.0;
            let t = intersect(c, r, o, dir, f32::INFINITY).unwrap();
            let (p, err, n) = point_and_error(c, r, o, dir, t);
            // Leave outwards (reflection) from the offset origin: no hit on this sphere.
            let out = crate::math::reflect(-dir, n);
            let po = crate::math::offset_ray_origin(p, err, n, out);
            assert!(
                intersect(c, r, po, out, f32::INFINITY).is_none(),
                "re-hit at {i}"
            );
            // Enter (refraction straight on): the far side, not the entry point.
            let pi = crate::math::offset_ray_origin(p, err, n, dir);
            let t2 = intersect(c, r, pi, dir, f32::INFINITY).unwrap();
            assert!(t2 > 1e-3 * r, "re-hit entering at {i}");
        }
    }
}
