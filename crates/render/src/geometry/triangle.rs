//! Watertight ray–triangle intersection (Woop, Benthin & Wald, "Watertight Ray/Triangle
//! Intersection", JCGT 2(1), 2013), with the conservative `t > 0` bound of pbrt-v3 §3.9.
//!
//! The ray is translated to the origin, permuted so its dominant axis is z and sheared to +z;
//! the edge functions of a shared edge are then computed from the same operands in both
//! triangles, so a ray can never slip between them. Edge functions that round to exactly zero
//! are recomputed in f64.
//!
//! Whether a hit lies certainly in front of the origin (t > 0) is decided with pbrt's error
//! bound; where f32 cannot decide (the bound grows with the triangle's size, about 1e-5 for a
//! unit triangle), the distance is recomputed in f64 from the exact inputs, whose bound is some
//! 10⁹ times tighter. Without that, a ray leaving a surface next to a corner passes through
//! the neighbouring face.

use glam::{DVec3, Vec3A};

use crate::math::gamma;

/// Per-ray data for [`intersect`]: origin, axis permutation and shear.
#[derive(Debug, Clone, Copy)]
pub struct TriangleRay {
    o: Vec3A,
    d: Vec3A,
    k: [usize; 3],
    shear: Vec3A,
}

impl TriangleRay {
    #[inline]
    pub fn new(o: Vec3A, d: Vec3A) -> Self {
        let a = d.abs();
        let kz = if a.x > a.y { if a.x > a.z { 0 } else { 2 } } else if a.y > a.z { 1 } else { 2 };
        let kx = if kz == 2 { 0 } else { kz + 1 };
        let ky = if kx == 2 { 0 } else { kx + 1 };
        let dp = Vec3A::new(d[kx], d[ky], d[kz]);
        TriangleRay { o, d, k: [kx, ky, kz], shear: Vec3A::new(-dp.x / dp.z, -dp.y / dp.z, 1.0 / dp.z) }
    }

    #[inline]
    fn transform(&self, p: Vec3A) -> Vec3A {
        let q = p - self.o;
        let [kx, ky, kz] = self.k;
        let (x, y, z) = (q[kx], q[ky], q[kz]);
        Vec3A::new(x + self.shear.x * z, y + self.shear.y * z, z)
    }
}

/// Barycentric coordinates (of v0, v1, v2) and distance of a hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleHit {
    pub t: f32,
    pub b: [f32; 3],
}

/// Intersects the ray with triangle `v` for 0 < t < `t_max`. Both faces are hit; degenerate
/// (zero-area) triangles never are.
#[inline]
pub fn intersect(ray: &TriangleRay, v: &[Vec3A; 3], t_max: f32) -> Option<TriangleHit> {
    let p0 = ray.transform(v[0]);
    let p1 = ray.transform(v[1]);
    let p2 = ray.transform(v[2]);
    let mut e0 = p1.x * p2.y - p1.y * p2.x;
    let mut e1 = p2.x * p0.y - p2.y * p0.x;
    let mut e2 = p0.x * p1.y - p0.y * p1.x;
    if e0 == 0.0 || e1 == 0.0 || e2 == 0.0 {
        let dop = |a: f32, b: f32, c: f32, d: f32| (a as f64 * b as f64 - c as f64 * d as f64) as f32;
        e0 = dop(p1.x, p2.y, p1.y, p2.x);
        e1 = dop(p2.x, p0.y, p2.y, p0.x);
        e2 = dop(p0.x, p1.y, p0.y, p1.x);
    }
    if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
        return None;
    }
    let det = e0 + e1 + e2;
    if det == 0.0 {
        return None;
    }
    let sz = ray.shear.z;
    let (z0, z1, z2) = (p0.z * sz, p1.z * sz, p2.z * sz);
    let t_scaled = e0 * z0 + e1 * z1 + e2 * z2;
    if det < 0.0 && (t_scaled >= 0.0 || t_scaled < t_max * det) {
        return None;
    }
    if det > 0.0 && (t_scaled <= 0.0 || t_scaled > t_max * det) {
        return None;
    }
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;

    // Reject hits whose t is not certainly positive given the rounding above (pbrt-v3 §3.9.2).
    let max_zt = z0.abs().max(z1.abs()).max(z2.abs());
    let delta_z = gamma(3) * max_zt;
    let max_xt = p0.x.abs().max(p1.x.abs()).max(p2.x.abs());
    let max_yt = p0.y.abs().max(p1.y.abs()).max(p2.y.abs());
    let delta_x = gamma(5) * (max_xt + max_zt);
    let delta_y = gamma(5) * (max_yt + max_zt);
    let delta_e = 2.0 * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = e0.abs().max(e1.abs()).max(e2.abs());
    let delta_t = 3.0 * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv_det.abs();
    let t = if t > delta_t { t } else { distance_f64(ray, v)? };
    Some(TriangleHit { t, b: [e0 * inv_det, e1 * inv_det, e2 * inv_det] })
}

/// The same transform, edge functions and distance in f64, with the same error bound in f64
/// unit roundoff: the distance, if the hit is certainly in front of the origin.
#[cold]
fn distance_f64(ray: &TriangleRay, v: &[Vec3A; 3]) -> Option<f32> {
    let g = |n: f64| n * f64::EPSILON * 0.5 / (1.0 - n * f64::EPSILON * 0.5);
    let [kx, ky, kz] = ray.k;
    let d = ray.d.as_dvec3();
    let (sx, sy, sz) = (-d[kx] / d[kz], -d[ky] / d[kz], 1.0 / d[kz]);
    let p = v.map(|v| {
        let q = v.as_dvec3() - ray.o.as_dvec3();
        DVec3::new(q[kx] + sx * q[kz], q[ky] + sy * q[kz], q[kz] * sz)
    });
    let e = [
        p[1].x * p[2].y - p[1].y * p[2].x,
        p[2].x * p[0].y - p[2].y * p[0].x,
        p[0].x * p[1].y - p[0].y * p[1].x,
    ];
    let det = e[0] + e[1] + e[2];
    if det == 0.0 {
        return None;
    }
    let t = (e[0] * p[0].z + e[1] * p[1].z + e[2] * p[2].z) / det;
    let max = |f: fn(&DVec3) -> f64| p.iter().map(|q| f(q).abs()).fold(0.0, f64::max);
    let (max_xt, max_yt, max_zt) = (max(|q| q.x), max(|q| q.y), max(|q| q.z));
    let delta_z = g(3.0) * max_zt;
    let delta_x = g(5.0) * (max_xt + max_zt);
    let delta_y = g(5.0) * (max_yt + max_zt);
    let delta_e = 2.0 * (g(2.0) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = e.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    let delta_t = 3.0 * (g(3.0) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) / det.abs();
    (t > delta_t && t as f32 > 0.0).then_some(t as f32)
}

/// The point at barycentrics `b` and a bound on its floating-point error (pbrt-v4 §6.8.5).
#[inline]
pub fn point_and_error(v: &[Vec3A; 3], b: [f32; 3]) -> (Vec3A, Vec3A) {
    let (a, c, d) = (v[0] * b[0], v[1] * b[1], v[2] * b[2]);
    let p = a + c + d;
    (p, (a.abs() + c.abs() + d.abs()) * gamma(7))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hit(o: Vec3A, d: Vec3A, v: &[Vec3A; 3]) -> Option<TriangleHit> {
        intersect(&TriangleRay::new(o, d), v, f32::INFINITY)
    }

    #[test]
    fn hits_front_and_back_and_reports_barycentrics() {
        let v = [Vec3A::ZERO, Vec3A::X, Vec3A::Y];
        let h = hit(Vec3A::new(0.25, 0.25, 1.0), -Vec3A::Z, &v).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6);
        assert!((h.b[1] - 0.25).abs() < 1e-6 && (h.b[2] - 0.25).abs() < 1e-6);
        assert!(hit(Vec3A::new(0.25, 0.25, -1.0), Vec3A::Z, &v).is_some());
        assert!(hit(Vec3A::new(0.75, 0.75, 1.0), -Vec3A::Z, &v).is_none());
        assert!(hit(Vec3A::new(0.25, 0.25, 1.0), Vec3A::Z, &v).is_none());
    }

    #[test]
    fn degenerate_triangles_are_never_hit() {
        let v = [Vec3A::ZERO, Vec3A::X, Vec3A::X * 2.0];
        assert!(hit(Vec3A::new(0.5, 0.0, 1.0), -Vec3A::Z, &v).is_none());
        let v = [Vec3A::ONE; 3];
        assert!(hit(Vec3A::new(1.0, 1.0, 2.0), -Vec3A::Z, &v).is_none());
    }

    #[test]
    fn rays_through_shared_edges_and_vertices_never_slip_through() {
        // A fan of thin triangles around a vertex at an awkward position: every ray aimed at
        // the shared vertex or along shared edges must hit at least one triangle.
        let c = Vec3A::new(0.1, 0.7, 0.3);
        let n = 37;
        let ring: Vec<Vec3A> = (0..n)
            .map(|i| {
                let a = i as f32 / n as f32 * std::f32::consts::TAU;
                c + Vec3A::new(a.cos() * 1.3, a.sin() * 0.9, 0.05 * a.sin())
            })
            .collect();
        let tris: Vec<[Vec3A; 3]> = (0..n).map(|i| [c, ring[i], ring[(i + 1) % n]]).collect();
        let o = Vec3A::new(0.31, 0.45, 5.0);
        let mut targets = vec![c];
        for i in 0..n {
            for k in 1..8 {
                let s = k as f32 / 8.0;
                targets.push(c + (ring[i] - c) * s); // along a shared edge
            }
        }
        for target in targets {
            let d = (target - o).normalize();
            let r = TriangleRay::new(o, d);
            assert!(tris.iter().any(|t| intersect(&r, t, f32::INFINITY).is_some()), "slipped through at {target}");
        }
    }

    #[test]
    fn hits_very_close_to_the_origin_are_kept_and_self_hits_rejected() {
        // A unit triangle 1e-6 in front of the origin, at a shallow angle: f32's bound cannot
        // tell t = 1e-6 from 0, f64's can.
        let v = [Vec3A::new(-0.5, -0.5, 1e-6), Vec3A::new(1.0, 0.0, 1e-6), Vec3A::new(0.0, 1.0, 1e-6)];
        let d = Vec3A::new(0.7, 0.1, 0.2).normalize();
        let h = hit(Vec3A::ZERO, d, &v).expect("near hit lost");
        assert!((h.t - 1e-6 / d.z).abs() < 1e-9);
        // The origin just behind the plane, going away: no hit.
        assert!(hit(Vec3A::new(0.0, 0.0, 2e-6), d, &v).is_none());
    }

    #[test]
    fn error_bound_covers_the_true_point() {
        let v = [Vec3A::new(1e5, 3.0, 7.0), Vec3A::new(1e5 + 1.0, 3.0, 7.0), Vec3A::new(1e5, 4.0, 7.5)];
        let b = [0.2, 0.3, 0.5];
        let (p, err) = point_and_error(&v, b);
        let exact = |i: usize| v.iter().zip(b).map(|(v, b)| v[i] as f64 * b as f64).sum::<f64>();
        for i in 0..3 {
            assert!((p[i] as f64 - exact(i)).abs() <= err[i] as f64);
        }
    }
}
