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

use glam::{DVec3, Vec3A, Vec3Swizzles, Vec4};

use crate::math::gamma;

/// Four triangles stored as structure-of-arrays: `v[i][axis]` holds coordinate `axis` of
/// vertex i of each triangle, one per lane. The test transforms all twelve vertices and
/// computes all twelve edge functions with a few SIMD operations. Unused lanes are NaN, which
/// fails every comparison and so never hits.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(16))]
pub struct Triangle4 {
    pub(super) v: [[Vec4; 3]; 3],
}

impl Triangle4 {
    /// Packs one to four triangles.
    pub fn new(tris: &[[Vec3A; 3]]) -> Self {
        assert!(
            (1..=4).contains(&tris.len()),
            "a block holds one to four triangles"
        );
        let mut v = [[Vec4::NAN; 3]; 3];
        for (lane, t) in tris.iter().enumerate() {
            for (i, vertex) in t.iter().enumerate() {
                for axis in 0..3 {
                    v[i][axis][lane] = vertex[axis];
                }
            }
        }
        Triangle4 { v }
    }

    /// The vertices of the triangle in `lane`.
    pub fn triangle(&self, lane: usize) -> [Vec3A; 3] {
        [0, 1, 2].map(|i| Vec3A::new(self.v[i][0][lane], self.v[i][1][lane], self.v[i][2][lane]))
    }

    /// The three coordinate arrays of vertex i in permuted order: axis `KZ` last.
    #[inline(always)]
    fn permuted<const KZ: usize>(&self, i: usize) -> (Vec4, Vec4, Vec4) {
        let [x, y, z] = self.v[i];
        match KZ {
            0 => (y, z, x),
            1 => (z, x, y),
            _ => (x, y, z),
        }
    }
}

/// Per-ray data for [`intersect`]: origin, direction and shear, with coordinates permuted so
/// that the direction's largest axis comes last (`KZ` names that axis; a constant, so the
/// permutation costs nothing at run time).
#[derive(Debug, Clone, Copy)]
pub struct TriangleRay<const KZ: usize> {
    /// Origin and direction in permuted order.
    pub(super) o: Vec3A,
    pub(super) d: Vec3A,
    pub(super) shear: Vec3A,
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
        let inv_z = 1.0 / d.z;
        TriangleRay {
            o,
            d,
            shear: Vec3A::new(-d.x * inv_z, -d.y * inv_z, inv_z),
        }
    }
}

/// Barycentric coordinates (of v0, v1, v2) and distance of a hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleHit {
    pub t: f32,
    pub b: [f32; 3],
}

/// Intersects the ray with the four triangles of `block` for 0 < t < `t_max`: the nearest
/// hit's lane and its distance and barycentrics. Both faces are hit; degenerate (zero-area)
/// triangles never are.
#[inline(always)]
pub fn intersect4<const KZ: usize>(
    ray: &TriangleRay<KZ>,
    block: &Triangle4,
    t_max: f32,
) -> Option<(usize, TriangleHit)> {
    let (ox, oy, oz) = (
        Vec4::splat(ray.o.x),
        Vec4::splat(ray.o.y),
        Vec4::splat(ray.o.z),
    );
    let (sx, sy, sz) = (
        Vec4::splat(ray.shear.x),
        Vec4::splat(ray.shear.y),
        Vec4::splat(ray.shear.z),
    );
    // Translate to the origin and shear: vertex i of the four triangles.
    let transform = |i: usize| {
        let (x, y, z) = block.permuted::<KZ>(i);
        let qz = z - oz;
        ((x - ox) + sx * qz, (y - oy) + sy * qz, qz * sz)
    };
    let (x0, y0, z0) = transform(0);
    let (x1, y1, z1) = transform(1);
    let (x2, y2, z2) = transform(2);
    let mut e0 = x1 * y2 - y1 * x2;
    let mut e1 = x2 * y0 - y2 * x0;
    let mut e2 = x0 * y1 - y0 * x1;
    let zero = e0.cmpeq(Vec4::ZERO) | e1.cmpeq(Vec4::ZERO) | e2.cmpeq(Vec4::ZERO);
    if zero.any() {
        // Edge functions that rounded to zero are recomputed in f64, lane by lane.
        let mut m = zero.bitmask();
        while m != 0 {
            let lane = m.trailing_zeros() as usize;
            m &= m - 1;
            let p = |x: Vec4, y: Vec4| [x[lane], y[lane]];
            [e0[lane], e1[lane], e2[lane]] = edges_f64([p(x0, y0), p(x1, y1), p(x2, y2)]);
        }
    }
    let negative = e0.cmplt(Vec4::ZERO) | e1.cmplt(Vec4::ZERO) | e2.cmplt(Vec4::ZERO);
    let positive = e0.cmpgt(Vec4::ZERO) | e1.cmpgt(Vec4::ZERO) | e2.cmpgt(Vec4::ZERO);
    let det = e0 + e1 + e2;
    let t_scaled = e0 * z0 + e1 * z1 + e2 * z2;
    // Compare t·|det| with 0 and t_max·|det| without dividing: flip signs where det < 0.
    let sign = Vec4::select(det.cmplt(Vec4::ZERO), Vec4::NEG_ONE, Vec4::ONE);
    let (t_signed, det_abs) = (t_scaled * sign, det.abs());
    let inside = !(negative & positive);
    let valid = inside
        & det.cmpne(Vec4::ZERO)
        & t_signed.cmpgt(Vec4::ZERO)
        & t_signed.cmplt(Vec4::splat(t_max) * det_abs);
    if !valid.any() {
        return None;
    }
    let t = t_scaled / det;

    // Reject hits whose t is not certainly positive given the rounding above (pbrt-v3 §3.9.2);
    // where f32 cannot decide, the distance is recomputed in f64.
    let max3 = |a: Vec4, b: Vec4, c: Vec4| a.abs().max(b.abs()).max(c.abs());
    let (max_xt, max_yt, max_zt) = (max3(x0, x1, x2), max3(y0, y1, y2), max3(z0, z1, z2));
    let delta_z = gamma(3) * max_zt;
    let delta_x = gamma(5) * (max_xt + max_zt);
    let delta_y = gamma(5) * (max_yt + max_zt);
    let delta_e = 2.0 * (gamma(2) * max_xt * max_yt + delta_y * max_xt + delta_x * max_yt);
    let max_e = max3(e0, e1, e2);
    let delta_t = 3.0 * (gamma(3) * max_e * max_zt + delta_e * max_zt + delta_z * max_e) / det_abs;

    let (t, delta_t) = (t.to_array(), delta_t.to_array());
    let mut best: Option<(usize, f32)> = None;
    let mut m = valid.bitmask();
    while m != 0 {
        let lane = m.trailing_zeros() as usize;
        m &= m - 1;
        let t_lane = if t[lane] > delta_t[lane] {
            t[lane]
        } else {
            match distance_f64(ray, &block.triangle(lane)) {
                Some(t) => t,
                None => continue,
            }
        };
        if best.is_none_or(|(_, b)| t_lane < b) {
            best = Some((lane, t_lane));
        }
    }
    let (lane, t) = best?;
    let (e0, e1, e2, det) = (e0.to_array(), e1.to_array(), e2.to_array(), det.to_array());
    let inv_det = 1.0 / det[lane];
    Some((
        lane,
        TriangleHit {
            t,
            b: [e0[lane] * inv_det, e1[lane] * inv_det, e2[lane] * inv_det],
        },
    ))
}

/// The edge functions of transformed vertices `p` (x, y of vertex 0, 1, 2), computed in f64:
/// where their f32 values round to zero, the sign decides which of two triangles sharing the
/// edge the ray hits.
#[inline]
pub(super) fn edges_f64(p: [[f32; 2]; 3]) -> [f32; 3] {
    let [p0, p1, p2] = p.map(|[x, y]| (x as f64, y as f64));
    let dop = |a: (f64, f64), b: (f64, f64)| (a.0 * b.1 - a.1 * b.0) as f32;
    [dop(p1, p2), dop(p2, p0), dop(p0, p1)]
}

/// The same transform, edge functions and distance in f64, with the same error bound in f64
/// unit roundoff: the distance, if the hit is certainly in front of the origin.
#[cold]
pub(super) fn distance_f64<const KZ: usize>(
    ray: &TriangleRay<KZ>,
    tri: &[Vec3A; 3],
) -> Option<f32> {
    let g = |n: f64| n * f64::EPSILON * 0.5 / (1.0 - n * f64::EPSILON * 0.5);
    let d = ray.d.as_dvec3();
    let (sx, sy, sz) = (-d.x / d.z, -d.y / d.z, 1.0 / d.z);
    let p = tri.map(|v| {
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
    // Distance to the edge opposite vertex i is b_i · 2A / |edge_i|; compare squares, so the
    // common case (far from every edge) needs no square root.
    let twice_area2 = (v[1] - v[0]).cross(v[2] - v[0]).length_squared();
    let margin2 = 4.0 * err.length_squared();
    let edge2 = [
        (v[2] - v[1]).length_squared(),
        (v[0] - v[2]).length_squared(),
        (v[1] - v[0]).length_squared(),
    ];
    let near = |i: usize| b[i] * b[i] * twice_area2 < margin2 * edge2[i];
    if twice_area2 == 0.0 || !(near(0) || near(1) || near(2)) {
        return (p, err);
    }
    let (twice_area, margin) = (twice_area2.sqrt(), margin2.sqrt());
    let mut b2 = b;
    for (i, bi) in b2.iter_mut().enumerate() {
        let min = (margin * edge2[i].sqrt() / twice_area).min(1.0 / 3.0);
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
        let block = Triangle4::new(&[*v]);
        let h = match dominant_axis(d) {
            0 => intersect4(&TriangleRay::<0>::new(o, d), &block, f32::INFINITY),
            1 => intersect4(&TriangleRay::<1>::new(o, d), &block, f32::INFINITY),
            _ => intersect4(&TriangleRay::<2>::new(o, d), &block, f32::INFINITY),
        };
        h.map(|(lane, h)| {
            assert_eq!(lane, 0);
            h
        })
    }

    #[test]
    fn a_block_reports_its_nearest_lane() {
        let tri = |z: f32| {
            [
                Vec3A::new(-1.0, -1.0, z),
                Vec3A::new(1.0, -1.0, z),
                Vec3A::new(0.0, 1.0, z),
            ]
        };
        let block = Triangle4::new(&[tri(5.0), tri(2.0), tri(-1.0), tri(3.0)]);
        let ray = TriangleRay::<2>::new(Vec3A::ZERO, Vec3A::Z);
        let (lane, h) = intersect4(&ray, &block, f32::INFINITY).unwrap();
        assert_eq!((lane, h.t), (1, 2.0));
        assert!(intersect4(&ray, &block, 1.5).is_none());
        // Unused lanes (NaN) never hit.
        let partial = Triangle4::new(&[tri(4.0)]);
        assert_eq!(intersect4(&ray, &partial, f32::INFINITY).unwrap().0, 0);
        assert_eq!(partial.triangle(0), tri(4.0));
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
