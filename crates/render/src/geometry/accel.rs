//! Ray queries against all primitives: compressed wide BVHs (CWBVH8) built with `obvhs`,
//! one over triangles and one over spheres.
//!
//! Two things make obvhs's traversal safe for rendering:
//! - it culls nodes whose entry distance is below an absolute 1e-4, which would hide geometry
//!   near the ray origin in small scenes (a scene 10⁻³ units across). The BVHs are therefore
//!   built in a copy of the scene scaled by an exact power of two, chosen so that the scene's
//!   diagonal is about 2¹⁶; scaling by 2^k changes no rounding, so intersections are the same
//!   as in world space and that cut-off falls far below float resolution;
//! - its slab test is not conservative: a ray through the edge of a flat box (an axis-aligned
//!   face) can round its way out of the box. Primitive bounds are therefore padded by a few
//!   ulps of the scene's largest coordinate, more than the slab test's rounding error.

use std::time::Duration;

use glam::{UVec2, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::{builder::build_cwbvh, CwBvh};
use obvhs::{BvhBuildParams, Boundable};

use super::{sphere, triangle};
use crate::ray::Ray;

/// What a ray hit, in world space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PrimHit {
    pub t: f32,
    pub prim: Prim,
    pub p: Vec3A,
    /// Bound on the floating-point error of `p`, per axis.
    pub p_error: Vec3A,
    /// Unit geometric normal: the triangle's winding normal, or the sphere's outward normal.
    pub n: Vec3A,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Prim {
    /// Triangle `id` (in the order given to [`Accel::build`]) at barycentrics `b`.
    Triangle { id: u32, b: [f32; 3] },
    Sphere { id: u32 },
}

struct TriangleBvh {
    bvh: CwBvh,
    /// Scaled vertices in BVH leaf order.
    verts: Vec<[Vec3A; 3]>,
    /// BVH leaf slot → triangle id.
    ids: Vec<u32>,
}

#[derive(Clone, Copy)]
struct ScaledSphere {
    center: Vec3A,
    radius: f32,
}

/// A primitive's bounds, padded for the traversal's rounding (see the module notes).
struct Padded {
    lo: Vec3A,
    hi: Vec3A,
}

impl Boundable for Padded {
    fn aabb(&self) -> Aabb {
        Aabb::new(self.lo, self.hi)
    }
}

struct SphereBvh {
    bvh: CwBvh,
    spheres: Vec<ScaledSphere>,
    ids: Vec<u32>,
}

/// Bounding volume hierarchies over a scene's triangles and spheres.
pub struct Accel {
    scale: f32,
    inv_scale: f32,
    triangles: Option<TriangleBvh>,
    spheres: Option<SphereBvh>,
}

/// 2^k with k the integer nearest to log2(target / extent), within f32's safe range.
fn power_of_two_scale(extent: f32) -> f32 {
    if !(extent > 0.0 && extent.is_finite()) {
        return 1.0;
    }
    let k = (65536.0f32 / extent).log2().round().clamp(-60.0, 60.0) as i32;
    2.0f32.powi(k)
}

impl Accel {
    /// Builds BVHs over `triangles` (world-space vertices) and `spheres` (center, radius).
    pub fn build(triangles: &[[Vec3A; 3]], spheres: &[(Vec3A, f32)]) -> Accel {
        let mut lo = Vec3A::splat(f32::INFINITY);
        let mut hi = Vec3A::splat(f32::NEG_INFINITY);
        for v in triangles.iter().flatten() {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
        for &(c, r) in spheres {
            lo = lo.min(c - Vec3A::splat(r));
            hi = hi.max(c + Vec3A::splat(r));
        }
        let scale = power_of_two_scale((hi - lo).length());
        // 16 ulps of the largest scaled coordinate.
        let pad = Vec3A::splat(lo.abs().max(hi.abs()).max_element() * scale * (16.0 * f32::EPSILON));
        let params = BvhBuildParams::medium_build();
        let padded = |a: Vec3A, b: Vec3A| Padded { lo: a - pad, hi: b + pad };

        let triangles = (!triangles.is_empty()).then(|| {
            let scaled: Vec<[Vec3A; 3]> = triangles.iter().map(|t| t.map(|v| v * scale)).collect();
            let bounds: Vec<Padded> =
                scaled.iter().map(|t| padded(t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]))).collect();
            let bvh = build_cwbvh(&bounds, params, &mut Duration::default());
            let ids = bvh.primitive_indices.clone();
            TriangleBvh { verts: ids.iter().map(|&i| scaled[i as usize]).collect(), ids, bvh }
        });
        let spheres = (!spheres.is_empty()).then(|| {
            let scaled: Vec<ScaledSphere> =
                spheres.iter().map(|&(c, r)| ScaledSphere { center: c * scale, radius: r * scale }).collect();
            let bounds: Vec<Padded> =
                scaled.iter().map(|s| padded(s.center - Vec3A::splat(s.radius), s.center + Vec3A::splat(s.radius))).collect();
            let bvh = build_cwbvh(&bounds, params, &mut Duration::default());
            let ids = bvh.primitive_indices.clone();
            SphereBvh { spheres: ids.iter().map(|&i| scaled[i as usize]).collect(), ids, bvh }
        });
        Accel { scale, inv_scale: 1.0 / scale, triangles, spheres }
    }

    fn bvh_ray(&self, ray: &Ray, t_max: f32) -> obvhs::ray::Ray {
        obvhs::ray::Ray::new(ray.o * self.scale, ray.d, 0.0, t_max * self.scale)
    }

    /// The closest hit with 0 < t < `t_max`.
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<PrimHit> {
        let r = self.bvh_ray(ray, t_max);
        let mut best_t = r.tmax;
        let mut best: Option<(usize, [f32; 3])> = None;
        if let Some(tb) = &self.triangles {
            let tr = triangle::TriangleRay::new(r.origin, r.direction);
            let mut state = tb.bvh.new_traversal(r.direction);
            let mut traverse_ray = r;
            let mut node;
            obvhs::traverse!(tb.bvh, node, state, node.intersect_ray(&traverse_ray, state.oct_inv4), {
                let slot = state.primitive_id as usize;
                if let Some(h) = triangle::intersect(&tr, &tb.verts[slot], traverse_ray.tmax) {
                    traverse_ray.tmax = h.t;
                    best_t = h.t;
                    best = Some((slot, h.b));
                }
            });
        }
        let mut best_sphere = None;
        if let Some(sb) = &self.spheres {
            let mut state = sb.bvh.new_traversal(r.direction);
            let mut traverse_ray = r;
            traverse_ray.tmax = best_t;
            let mut node;
            obvhs::traverse!(sb.bvh, node, state, node.intersect_ray(&traverse_ray, state.oct_inv4), {
                let slot = state.primitive_id as usize;
                let s = sb.spheres[slot];
                if let Some(t) = sphere::intersect(s.center, s.radius, r.origin, r.direction, traverse_ray.tmax) {
                    traverse_ray.tmax = t;
                    best_t = t;
                    best_sphere = Some(slot);
                }
            });
        }

        if let (Some(slot), Some(sb)) = (best_sphere, &self.spheres) {
            let s = sb.spheres[slot];
            let (p, err, n) = sphere::point_and_error(s.center, s.radius, r.origin, r.direction, best_t);
            return Some(PrimHit {
                t: best_t * self.inv_scale,
                prim: Prim::Sphere { id: sb.ids[slot] },
                p: p * self.inv_scale,
                p_error: err * self.inv_scale,
                n,
            });
        }
        let (slot, b) = best?;
        let tb = self.triangles.as_ref()?;
        let v = &tb.verts[slot];
        let (p, err) = triangle::point_and_error(v, b);
        Some(PrimHit {
            t: best_t * self.inv_scale,
            prim: Prim::Triangle { id: tb.ids[slot], b },
            p: p * self.inv_scale,
            p_error: err * self.inv_scale,
            n: (v[1] - v[0]).cross(v[2] - v[0]).normalize(),
        })
    }

    /// Whether anything is hit with 0 < t < `t_max`.
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        let r = self.bvh_ray(ray, t_max);
        if let Some(tb) = &self.triangles {
            let tr = triangle::TriangleRay::new(r.origin, r.direction);
            let mut state = tb.bvh.new_traversal(r.direction);
            let mut node;
            let mut hit = false;
            obvhs::traverse!(tb.bvh, node, state, node.intersect_ray(&r, state.oct_inv4), {
                if triangle::intersect(&tr, &tb.verts[state.primitive_id as usize], r.tmax).is_some() {
                    hit = true;
                    break;
                }
            });
            if hit {
                return true;
            }
        }
        if let Some(sb) = &self.spheres {
            let mut state = sb.bvh.new_traversal(r.direction);
            let mut node;
            let mut hit = false;
            obvhs::traverse!(sb.bvh, node, state, node.intersect_ray(&r, state.oct_inv4), {
                let s = sb.spheres[state.primitive_id as usize];
                if sphere::intersect(s.center, s.radius, r.origin, r.direction, r.tmax).is_some() {
                    hit = true;
                    break;
                }
            });
            return hit;
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed unit cube (12 triangles) scaled by `size` and moved to `offset`.
    fn cube(offset: Vec3A, size: f32) -> Vec<[Vec3A; 3]> {
        let c = |i: u32| offset + Vec3A::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32) * size;
        let quads = [[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]];
        quads.iter().flat_map(|q| [[c(q[0]), c(q[1]), c(q[2])], [c(q[0]), c(q[2]), c(q[3])]]).collect()
    }

    /// Rays inside a closed box must always hit it: rays from an interior point aimed exactly
    /// at corners and along edges (watertightness), and rays re-spawned from each hit in a new
    /// direction into the box (no self-intersection, no slipping out near the surface). (A hit
    /// within an ulp of a corner can still leave through the neighbouring face, as in every
    /// renderer that offsets along one normal; random directions make that vanishingly rare.)
    fn assert_closed(offset: Vec3A, size: f32) {
        let tris = cube(offset, size);
        let accel = Accel::build(&tris, &[]);
        let center = offset + Vec3A::splat(size * 0.5);
        let inner = offset + Vec3A::new(0.31, 0.52, 0.47) * size;
        let random_dir = |i: u32| {
            use crate::sampler::hash::{mix64, u32_to_unit};
            let h = mix64(i as u64 + 1);
            crate::sampling::square_to_uniform_sphere(glam::Vec2::new(u32_to_unit(h as u32), u32_to_unit((h >> 32) as u32)))
        };
        // Corners and points along every edge.
        for c in 0..8u32 {
            let corner = offset + Vec3A::new((c & 1) as f32, (c >> 1 & 1) as f32, (c >> 2 & 1) as f32) * size;
            for k in 0..=16 {
                let target = corner + (center - corner) * Vec3A::new(0.0, 0.0, k as f32 / 8.0);
                let d = (target - inner).normalize();
                assert!(accel.intersect(&Ray::new(inner, d), f32::INFINITY).is_some(), "ray to {target} slipped out");
            }
        }
        // Random walk inside the box.
        let mut p = center;
        let mut n = Vec3A::ZERO;
        let mut err = Vec3A::ZERO;
        for i in 0..20_000u32 {
            let mut d = random_dir(i);
            let o = if n == Vec3A::ZERO {
                p
            } else {
                let inward = if (center - p).dot(n) > 0.0 { n } else { -n };
                if d.dot(inward) < 0.0 {
                    d = -d;
                }
                crate::math::offset_ray_origin(p, err, n, d)
            };
            let hit = accel.intersect(&Ray::new(o, d), f32::INFINITY);
            let hit = hit.unwrap_or_else(|| panic!("ray {i} leaked out of the box at {offset} size {size}: from {p} n {n} err {err} o {o} d {d}"));
            assert!(hit.t > 0.0);
            p = hit.p;
            err = hit.p_error;
            n = hit.n;
        }
    }

    #[test]
    fn closed_box_does_not_leak_at_ordinary_scale() {
        assert_closed(Vec3A::new(-0.3, 0.2, 0.7), 1.0);
    }

    #[test]
    fn closed_box_does_not_leak_far_from_the_origin() {
        assert_closed(Vec3A::new(1e5, -1e5, 1e5), 500.0);
    }

    #[test]
    fn closed_box_does_not_leak_when_tiny() {
        assert_closed(Vec3A::new(2e-3, 0.0, -1e-3), 1e-3);
    }

    #[test]
    fn nearest_hit_among_triangles_and_spheres() {
        let tris = cube(Vec3A::new(-1.0, -1.0, 5.0), 2.0);
        let accel = Accel::build(&tris, &[(Vec3A::new(0.0, 0.0, 2.0), 0.5), (Vec3A::new(0.0, 0.0, 9.0), 0.5)]);
        let h = accel.intersect(&Ray::new(Vec3A::ZERO, Vec3A::Z), f32::INFINITY).unwrap();
        assert!(matches!(h.prim, Prim::Sphere { id: 0 }));
        assert!((h.t - 1.5).abs() < 1e-5);
        let h = accel.intersect(&Ray::new(Vec3A::new(0.0, 0.0, 3.0), Vec3A::Z), f32::INFINITY).unwrap();
        assert!(matches!(h.prim, Prim::Triangle { .. }));
        assert!((h.t - 2.0).abs() < 1e-5);
        assert!(accel.occluded(&Ray::new(Vec3A::ZERO, Vec3A::Z), 1.6));
        assert!(!accel.occluded(&Ray::new(Vec3A::ZERO, Vec3A::Z), 1.4));
        assert!(accel.intersect(&Ray::new(Vec3A::ZERO, -Vec3A::Z), f32::INFINITY).is_none());
    }
}
