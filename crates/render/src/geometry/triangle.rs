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

use glam::{DVec3, Vec3A, Vec3Swizzles};

use crate::math::gamma;

/// A triangle stored as structure-of-arrays: lane i of `x`, `y`, `z` holds vertex i. The
/// intersection test then transforms all three vertices at once and computes the three edge
/// functions in one multiply–subtract on rotated lanes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Triangle {
    pub x: Vec3A,
    pub y: Vec3A,
    pub z: Vec3A,
}

impl Triangle {
    pub fn new(v: [Vec3A; 3]) -> Self {
        Triangle {
            x: Vec3A::new(v[0].x, v[1].x, v[2].x),
            y: Vec3A::new(v[0].y, v[1].y, v[2].y),
            z: Vec3A::new(v[0].z, v[1].z, v[2].z),
        }
    }

    pub fn vertices(&self) -> [Vec3A; 3] {
        [0, 1, 2].map(|i| Vec3A::new(self.x[i], self.y[i], self.z[i]))
    }

    /// The lanes in permuted order: axis `KZ` last, cyclic order kept.
    #[inline(always)]
    fn permuted<const KZ: usize>(&self) -> (Vec3A, Vec3A, Vec3A) {
        match KZ {
            0 => (self.y, self.z, self.x),
            1 => (self.z, self.x, self.y),
            _ => (self.x, self.y, self.z),
        }
    }
}

/// Per-ray data for [`intersect`]: origin, direction and shear, with coordinates permuted so
/// that the direction's largest axis comes last (`KZ` names that axis; a constant, so the
/// permutation costs nothing at run time).
#[derive(Debug, Clone, Copy)]
pub struct TriangleRay<const KZ: usize> {
    /// Origin and direction in permuted order.
    o: Vec3A,
    d: Vec3A,
    shear: Vec3A,
}

/// The axis along which `d` is largest in magnitude: the `KZ` to use for it.
#[inline]
pub fn dominant_axis(d: Vec3A) -> usize {
    let a = d.abs();
    if a.x > a.y {
        if a.x > a.z { 0 } else { 2 }
    } else if a.y > a.z {
        1
    } else {
        2
    }
}

/// Permutes (x, y, z) so that axis `KZ` comes last, keeping the cyclic order.
#[inline(always)]
fn permute<const KZ: usize>(v: Vec3A) -> Vec3A {
    match KZ {
        0 => v.yzx(),
        1 => v.zxy(),
        _ => v,
    }
}

impl<const KZ: usize> TriangleRay<KZ> {
    #[inline]
    pub fn new(o: Vec3A, d: Vec3A) -> Self {
        let (o, d) = (permute::<KZ>(o), permute::<KZ>(d));
        TriangleRay {
            o,
            d,
            shear: Vec3A::new(-d.x / d.z, -d.y / d.z, 1.0 / d.z),
        }
    }
}

/// Barycentric coordinates (of v0, v1, v2) and distance of a hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleHit {
    pub t: f32,
    pub b: [f32; 3],
}

/// Intersects the ray with `tri` for 0 < t < `t_max`. Both faces are hit; degenerate
/// (zero-area) triangles never are.
#[inline]
pub fn intersect<const KZ: usize>(
    ray: &TriangleRay<KZ>,
    tri: &Triangle,
    t_max: f32,
) -> Option<TriangleHit> {
    let (vx, vy, vz) = tri.permuted::<KZ>();
    // Translate to the origin and shear: lanes are the three transformed vertices.
    let qz = vz - Vec3A::splat(ray.o.z);
    let px = (vx - Vec3A::splat(ray.o.x)) + Vec3A::splat(ray.shear.x) * qz;
    let py = (vy - Vec3A::splat(ray.o.y)) + Vec3A::splat(ray.shear.y) * qz;
    // Edge functions e_i = p_{i+1}.x p_{i+2}.y − p_{i+1}.y p_{i+2}.x, all three at once.
    let mut e = px.yzx() * py.zxy() - py.yzx() * px.zxy();
    if e.cmpeq(Vec3A::ZERO).any() {
        let v = |i: usize| (px[i] as f64, py[i] as f64);
        let dop = |a: (f64, f64), b: (f64, f64)| (a.0 * b.1 - a.1 * b.0) as f32;
        e = Vec3A::new(dop(v(1), v(2)), dop(v(2), v(0)), dop(v(0), v(1)));
    }
    if e.cmplt(Vec3A::ZERO).any() && e.cmpgt(Vec3A::ZERO).any() {
        return None;
    }
    let det = e.x + e.y + e.z;
    if det == 0.0 {
        return None;
    }
    let pz = qz * ray.shear.z;
    let ez = e * pz;
    let t_scaled = ez.x + ez.y + ez.z;
    if det < 0.0 && (t_scaled >= 0.0 || t_scaled < t_max * det) {
        return None;
    }
    if det > 0.0 && (t_scaled <= 0.0 || t_scaled > t_max * det) {
        return None;
    }
    let inv_det = 1.0 / det;
    let t = t_scaled * inv_det;

    // Reject hits whose t is not certainly positive given the rounding above (pbrt-v3 §3.9.2).
    let max_zt = pz.abs().max_element();
    let max_xt = px.abs().max_element();
    let max_yt = py.abs().max_element();
    let delta_z = gamma(3) * max_zt;
    let delta_x = gamma(5) * (max_xt + max_zt);
    let delta_y = gamma(5) * (max_yt + max_zt);
    let delta_e = 2.0 * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = e.abs().max_element();
    let delta_t =
        3.0 * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) * inv_det.abs();
    let t = if t > delta_t {
        t
    } else {
        distance_f64(ray, tri)?
    };
    let b = e * inv_det;
    Some(TriangleHit {
        t,
        b: [b.x, b.y, b.z],
    })
}

/// The same transform, edge functions and distance in f64, with the same error bound in f64
/// unit roundoff: the distance, if the hit is certainly in front of the origin.
#[cold]
fn distance_f64<const KZ: usize>(ray: &TriangleRay<KZ>, tri: &Triangle) -> Option<f32> {
    let g = |n: f64| n * f64::EPSILON * 0.5 / (1.0 - n * f64::EPSILON * 0.5);
    let d = ray.d.as_dvec3();
    let (sx, sy, sz) = (-d.x / d.z, -d.y / d.z, 1.0 / d.z);
    let p = tri.vertices().map(|v| {
        let q = permute::<KZ>(v).as_dvec3() - ray.o.as_dvec3();
        DVec3::new(q.x + sx * q.z, q.y + sy * q.z, q.z * sz)
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

/// A hit point moved off its triangle's edges: where the point lies within its error bound of
/// an edge, its barycentric coordinate for that edge is raised so that it lies inside by at
/// least twice the bound. A ray leaving the surface there (from an origin offset along the
/// normal) then starts strictly on the inner side of the neighbouring face of a closed mesh,
/// instead of on that face's plane, where it could leave through it at t = 0 — a leak seen at
/// 10⁵ units from the origin, where the bound is 0.04 units. The point moves by at most twice
/// its error bound, and only near edges.
#[inline]
pub fn point_off_edges(v: &[Vec3A; 3], b: [f32; 3]) -> (Vec3A, Vec3A) {
    let (p, err) = point_and_error(v, b);
    let twice_area = (v[1] - v[0]).cross(v[2] - v[0]).length();
    let margin = 2.0 * err.length();
    // Distance to the edge opposite vertex i is b_i · 2A / |edge_i|.
    let edge_len2 = [
        (v[2] - v[1]).length_squared(),
        (v[0] - v[2]).length_squared(),
        (v[1] - v[0]).length_squared(),
    ];
    let near = |i: usize| b[i] * twice_area < margin * edge_len2[i].sqrt();
    if !(near(0) || near(1) || near(2)) || twice_area == 0.0 {
        return (p, err);
    }
    let mut b2 = b;
    for (i, bi) in b2.iter_mut().enumerate() {
        let min = (margin * edge_len2[i].sqrt() / twice_area).min(1.0 / 3.0);
        *bi = bi.max(min);
    }
    let sum = b2[0] + b2[1] + b2[2];
    point_and_error(v, b2.map(|x| x / sum))
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
        let v = &Triangle::new(*v);
        match dominant_axis(d) {
            0 => intersect(&TriangleRay::<0>::new(o, d), v, f32::INFINITY),
            1 => intersect(&TriangleRay::<1>::new(o, d), v, f32::INFINITY),
            _ => intersect(&TriangleRay::<2>::new(o, d), v, f32::INFINITY),
        }
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
        for r in &ring {
            for k in 1..8 {
                let s = k as f32 / 8.0;
                targets.push(c + (*r - c) * s); // along a shared edge
            }
        }
        for target in targets {
            let d = (target - o).normalize();
            assert!(
                tris.iter().any(|t| hit(o, d, t).is_some()),
                "slipped through at {target}"
            );
        }
    }

    #[test]
    fn hits_very_close_to_the_origin_are_kept_and_self_hits_rejected() {
        // A unit triangle 1e-6 in front of the origin, at a shallow angle: f32's bound cannot
        // tell t = 1e-6 from 0, f64's can.
        let v = [
            Vec3A::new(-0.5, -0.5, 1e-6),
            Vec3A::new(1.0, 0.0, 1e-6),
            Vec3A::new(0.0, 1.0, 1e-6),
        ];
        let d = Vec3A::new(0.7, 0.1, 0.2).normalize();
        let h = hit(Vec3A::ZERO, d, &v).expect("near hit lost");
        assert!((h.t - 1e-6 / d.z).abs() < 1e-9);
        // The origin just behind the plane, going away: no hit.
        assert!(hit(Vec3A::new(0.0, 0.0, 2e-6), d, &v).is_none());
    }

    #[test]
    fn points_near_edges_move_inside_by_their_error_bound() {
        let v = [
            Vec3A::new(1e5, 1e5, 1e5),
            Vec3A::new(1e5 + 500.0, 1e5, 1e5),
            Vec3A::new(1e5, 1e5 + 500.0, 1e5),
        ];
        // On the edge v0–v1 (b2 = 0): moved inside, by about twice the error bound.
        let (p, err) = point_off_edges(&v, [0.7, 0.3, 0.0]);
        assert!(
            p.y - 1e5 >= 1.5 * err.length(),
            "{} vs {}",
            p.y - 1e5,
            err.length()
        );
        assert!(p.y - 1e5 <= 3.0 * err.length() + 0.01);
        // Away from the edges: unchanged.
        let b = [0.3, 0.3, 0.4];
        assert_eq!(point_off_edges(&v, b), point_and_error(&v, b));
    }

    #[test]
    fn error_bound_covers_the_true_point() {
        let v = [
            Vec3A::new(1e5, 3.0, 7.0),
            Vec3A::new(1e5 + 1.0, 3.0, 7.0),
            Vec3A::new(1e5, 4.0, 7.5),
        ];
        let b = [0.2, 0.3, 0.5];
        let (p, err) = point_and_error(&v, b);
        let exact = |i: usize| {
            v.iter()
                .zip(b)
                .map(|(v, b)| v[i] as f64 * b as f64)
                .sum::<f64>()
        };
        for i in 0..3 {
            assert!((p[i] as f64 - exact(i)).abs() <= err[i] as f64);
        }
    }
}
