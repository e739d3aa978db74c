//! Ray queries against all primitives: compressed wide BVHs (CWBVH8) built with `obvhs`,
//! one over triangles and one over spheres.
//!
//! Nodes are tested with our own slab test ([`intersect_node`]) rather than obvhs's, because
//! obvhs's culls nodes whose entry distance is below an absolute 1e-4 (hiding geometry near
//! the ray origin in a scene 10⁻³ units across) and converts the quantised child bounds one
//! value at a time (about half of all traversal instructions). The slab test rounds, and a
//! ray through the edge of a flat box (an axis-aligned face) could round its way out of it:
//! primitive bounds are padded by 16 ulps of the scene's largest coordinate, more than that
//! rounding error for rays that start inside the scene.

use std::time::Duration;

use glam::{UVec2, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::{CwBvh, builder::build_cwbvh};
use obvhs::{Boundable, BvhBuildParams};

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
    Triangle {
        id: u32,
        b: [f32; 3],
    },
    Sphere {
        id: u32,
    },
}

struct TriangleBvh {
    bvh: CwBvh,
    /// Triangles in BVH leaf order.
    tris: Vec<triangle::Triangle>,
    /// BVH leaf slot → triangle id.
    ids: Vec<u32>,
}

#[derive(Clone, Copy)]
struct Sphere {
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
    spheres: Vec<Sphere>,
    ids: Vec<u32>,
}

/// Bounding volume hierarchies over a scene's triangles and spheres.
pub struct Accel {
    triangles: Option<TriangleBvh>,
    spheres: Option<SphereBvh>,
}

/// Per-ray data for node tests.
#[derive(Debug, Clone, Copy)]
struct NodeRay {
    o: Vec3A,
    inv: Vec3A,
    /// The direction is negative along x, y, z (the maximum plane is entered first).
    negative: [bool; 3],
    /// Octant code for obvhs's child ordering.
    oct_inv4: u32,
}

impl NodeRay {
    #[inline]
    fn new(ray: &Ray) -> Self {
        // A huge finite inverse for zero components: (plane − o)·inv never becomes NaN.
        let inv = |c: f32| {
            if c == 0.0 {
                1.0e30f32.copysign(c)
            } else {
                1.0 / c
            }
        };
        let d = ray.d;
        let neg = [
            d.x.is_sign_negative(),
            d.y.is_sign_negative(),
            d.z.is_sign_negative(),
        ];
        let oct_inv4 = (if neg[0] { 0 } else { 0x0404_0404 })
            | (if neg[1] { 0 } else { 0x0202_0202 })
            | (if neg[2] { 0 } else { 0x0101_0101 });
        NodeRay {
            o: ray.o,
            inv: Vec3A::new(inv(d.x), inv(d.y), inv(d.z)),
            negative: neg,
            oct_inv4,
        }
    }
}

/// Tests a ray against the eight children of a compressed wide node for 0 ≤ t ≤ `t_max` and
/// returns obvhs's hit mask (child bits placed by traversal priority). The quantised bounds
/// are widened eight at a time (bytes → 16 → 32-bit integers → floats) with SSE2.
#[inline(always)]
fn intersect_node(n: &CwBvhNode, r: &NodeRay, t_max: f32) -> u32 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        // Child bounds along an axis are p + q·e, so t = q·(e·inv) + (p − o)·inv.
        let scale = n.compute_extent() * r.inv;
        let offset = (Vec3A::from(n.p) - r.o) * r.inv;
        // SAFETY: SSE2 is part of the x86_64 baseline; all operands are plain values.
        let mask = unsafe {
            let widen = |bytes: [u8; 8]| {
                let z = _mm_setzero_si128();
                let w = _mm_unpacklo_epi8(_mm_cvtsi64_si128(i64::from_le_bytes(bytes)), z);
                (
                    _mm_cvtepi32_ps(_mm_unpacklo_epi16(w, z)),
                    _mm_cvtepi32_ps(_mm_unpackhi_epi16(w, z)),
                )
            };
            let axis = |lo: [u8; 8], hi: [u8; 8], neg: bool, a: f32, b: f32| {
                let (near, far) = if neg { (hi, lo) } else { (lo, hi) };
                let (n0, n1) = widen(near);
                let (f0, f1) = widen(far);
                let (a, b) = (_mm_set1_ps(a), _mm_set1_ps(b));
                (
                    _mm_add_ps(_mm_mul_ps(n0, a), b),
                    _mm_add_ps(_mm_mul_ps(n1, a), b),
                    _mm_add_ps(_mm_mul_ps(f0, a), b),
                    _mm_add_ps(_mm_mul_ps(f1, a), b),
                )
            };
            let x = axis(
                n.child_min_x,
                n.child_max_x,
                r.negative[0],
                scale.x,
                offset.x,
            );
            let y = axis(
                n.child_min_y,
                n.child_max_y,
                r.negative[1],
                scale.y,
                offset.y,
            );
            let z = axis(
                n.child_min_z,
                n.child_max_z,
                r.negative[2],
                scale.z,
                offset.z,
            );
            let zero = _mm_setzero_ps();
            let tmax = _mm_set1_ps(t_max);
            let near0 = _mm_max_ps(_mm_max_ps(x.0, y.0), _mm_max_ps(z.0, zero));
            let near1 = _mm_max_ps(_mm_max_ps(x.1, y.1), _mm_max_ps(z.1, zero));
            let far0 = _mm_min_ps(_mm_min_ps(x.2, y.2), _mm_min_ps(z.2, tmax));
            let far1 = _mm_min_ps(_mm_min_ps(x.3, y.3), _mm_min_ps(z.3, tmax));
            (_mm_movemask_ps(_mm_cmple_ps(near0, far0))
                | (_mm_movemask_ps(_mm_cmple_ps(near1, far1)) << 4)) as u32
        };
        let (child_bits8, bit_index8) = n.get_child_and_index_bits(r.oct_inv4);
        let mut hit_mask = 0u32;
        let mut m = mask;
        while m != 0 {
            let child = m.trailing_zeros() as u64;
            m &= m - 1;
            hit_mask |= (((child_bits8 >> (child * 8)) & 0xff) as u32)
                << ((bit_index8 >> (child * 8)) & 0xff);
        }
        hit_mask
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        let ray = obvhs::ray::Ray::new(r.o, 1.0 / r.inv, 0.0, t_max);
        n.intersect_ray(&ray, r.oct_inv4)
    }
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
        // 16 ulps of the largest coordinate.
        let pad = Vec3A::splat(lo.abs().max(hi.abs()).max_element() * (16.0 * f32::EPSILON));
        let params = BvhBuildParams::medium_build();
        let padded = |a: Vec3A, b: Vec3A| Padded {
            lo: a - pad,
            hi: b + pad,
        };

        let triangles = (!triangles.is_empty()).then(|| {
            let bounds: Vec<Padded> = triangles
                .iter()
                .map(|t| padded(t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2])))
                .collect();
            let bvh = build_cwbvh(&bounds, params, &mut Duration::default());
            let ids = bvh.primitive_indices.clone();
            TriangleBvh {
                tris: ids
                    .iter()
                    .map(|&i| triangle::Triangle::new(triangles[i as usize]))
                    .collect(),
                ids,
                bvh,
            }
        });
        let spheres = (!spheres.is_empty()).then(|| {
            let spheres: Vec<Sphere> = spheres
                .iter()
                .map(|&(center, radius)| Sphere { center, radius })
                .collect();
            let bounds: Vec<Padded> = spheres
                .iter()
                .map(|s| {
                    padded(
                        s.center - Vec3A::splat(s.radius),
                        s.center + Vec3A::splat(s.radius),
                    )
                })
                .collect();
            let bvh = build_cwbvh(&bounds, params, &mut Duration::default());
            let ids = bvh.primitive_indices.clone();
            SphereBvh {
                spheres: ids.iter().map(|&i| spheres[i as usize]).collect(),
                ids,
                bvh,
            }
        });
        Accel { triangles, spheres }
    }

    /// The closest hit with 0 < t < `t_max`.
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<PrimHit> {
        let nr = NodeRay::new(ray);
        let mut t_best = t_max;
        let mut best = None;
        if let Some(tb) = &self.triangles {
            best = match triangle::dominant_axis(ray.d) {
                0 => tb.closest::<0>(ray, &nr, &mut t_best),
                1 => tb.closest::<1>(ray, &nr, &mut t_best),
                _ => tb.closest::<2>(ray, &nr, &mut t_best),
            };
        }
        let mut best_sphere = None;
        if let Some(sb) = &self.spheres {
            let mut state = sb.bvh.new_traversal(ray.d);
            let mut node;
            obvhs::traverse!(sb.bvh, node, state, intersect_node(node, &nr, t_best), {
                let slot = state.primitive_id as usize;
                let s = sb.spheres[slot];
                if let Some(t) = sphere::intersect(s.center, s.radius, ray.o, ray.d, t_best) {
                    t_best = t;
                    best_sphere = Some(slot);
                }
            });
        }
        if let (Some(slot), Some(sb)) = (best_sphere, &self.spheres) {
            let s = sb.spheres[slot];
            let (p, p_error, n) = sphere::point_and_error(s.center, s.radius, ray.o, ray.d, t_best);
            return Some(PrimHit {
                t: t_best,
                prim: Prim::Sphere { id: sb.ids[slot] },
                p,
                p_error,
                n,
            });
        }
        let (slot, b) = best?;
        let tb = self.triangles.as_ref()?;
        let v = tb.tris[slot].vertices();
        let (p, p_error) = triangle::point_off_edges(&v, b);
        Some(PrimHit {
            t: t_best,
            prim: Prim::Triangle {
                id: tb.ids[slot],
                b,
            },
            p,
            p_error,
            n: (v[1] - v[0]).cross(v[2] - v[0]).normalize(),
        })
    }

    /// Whether anything is hit with 0 < t < `t_max`.
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        let nr = NodeRay::new(ray);
        if let Some(tb) = &self.triangles {
            let hit = match triangle::dominant_axis(ray.d) {
                0 => tb.any::<0>(ray, &nr, t_max),
                1 => tb.any::<1>(ray, &nr, t_max),
                _ => tb.any::<2>(ray, &nr, t_max),
            };
            if hit {
                return true;
            }
        }
        let mut hit = false;
        if let Some(sb) = &self.spheres {
            let mut state = sb.bvh.new_traversal(ray.d);
            let mut node;
            obvhs::traverse!(sb.bvh, node, state, intersect_node(node, &nr, t_max), {
                let s = sb.spheres[state.primitive_id as usize];
                if sphere::intersect(s.center, s.radius, ray.o, ray.d, t_max).is_some() {
                    hit = true;
                    break;
                }
            });
        }
        hit
    }
}

impl TriangleBvh {
    /// Closest triangle hit (BVH slot and barycentrics), lowering `t_max`, for rays whose
    /// dominant axis is `KZ`.
    #[inline]
    fn closest<const KZ: usize>(
        &self,
        ray: &Ray,
        nr: &NodeRay,
        t_max: &mut f32,
    ) -> Option<(usize, [f32; 3])> {
        let tr = triangle::TriangleRay::<KZ>::new(ray.o, ray.d);
        let mut state = self.bvh.new_traversal(ray.d);
        let mut best = None;
        let mut node;
        obvhs::traverse!(self.bvh, node, state, intersect_node(node, nr, *t_max), {
            let slot = state.primitive_id as usize;
            if let Some(h) = triangle::intersect(&tr, &self.tris[slot], *t_max) {
                *t_max = h.t;
                best = Some((slot, h.b));
            }
        });
        best
    }

    /// Whether any triangle is hit within `t_max`.
    #[inline]
    fn any<const KZ: usize>(&self, ray: &Ray, nr: &NodeRay, t_max: f32) -> bool {
        let tr = triangle::TriangleRay::<KZ>::new(ray.o, ray.d);
        let mut state = self.bvh.new_traversal(ray.d);
        let mut node;
        let mut hit = false;
        obvhs::traverse!(self.bvh, node, state, intersect_node(node, nr, t_max), {
            if triangle::intersect(&tr, &self.tris[state.primitive_id as usize], t_max).is_some() {
                hit = true;
                break;
            }
        });
        hit
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed unit cube (12 triangles) scaled by `size` and moved to `offset`.
    fn cube(offset: Vec3A, size: f32) -> Vec<[Vec3A; 3]> {
        let c = |i: u32| {
            offset + Vec3A::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32) * size
        };
        let quads = [
            [0, 4, 6, 2],
            [1, 3, 7, 5],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 2, 3, 1],
            [4, 5, 7, 6],
        ];
        quads
            .iter()
            .flat_map(|q| [[c(q[0]), c(q[1]), c(q[2])], [c(q[0]), c(q[2]), c(q[3])]])
            .collect()
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
            crate::sampling::square_to_uniform_sphere(glam::Vec2::new(
                u32_to_unit(h as u32),
                u32_to_unit((h >> 32) as u32),
            ))
        };
        // Corners and points along every edge.
        for c in 0..8u32 {
            let corner = offset
                + Vec3A::new((c & 1) as f32, (c >> 1 & 1) as f32, (c >> 2 & 1) as f32) * size;
            for k in 0..=16 {
                let target = corner + (center - corner) * Vec3A::new(0.0, 0.0, k as f32 / 8.0);
                let d = (target - inner).normalize();
                assert!(
                    accel
                        .intersect(&Ray::new(inner, d), f32::INFINITY)
                        .is_some(),
                    "ray to {target} slipped out"
                );
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
        let accel = Accel::build(
            &tris,
            &[
                (Vec3A::new(0.0, 0.0, 2.0), 0.5),
                (Vec3A::new(0.0, 0.0, 9.0), 0.5),
            ],
        );
        let h = accel
            .intersect(&Ray::new(Vec3A::ZERO, Vec3A::Z), f32::INFINITY)
            .unwrap();
        assert!(matches!(h.prim, Prim::Sphere { id: 0 }));
        assert!((h.t - 1.5).abs() < 1e-5);
        let h = accel
            .intersect(
                &Ray::new(Vec3A::new(0.0, 0.0, 3.0), Vec3A::Z),
                f32::INFINITY,
            )
            .unwrap();
        assert!(matches!(h.prim, Prim::Triangle { .. }));
        assert!((h.t - 2.0).abs() < 1e-5);
        assert!(accel.occluded(&Ray::new(Vec3A::ZERO, Vec3A::Z), 1.6));
        assert!(!accel.occluded(&Ray::new(Vec3A::ZERO, Vec3A::Z), 1.4));
        assert!(
            accel
                .intersect(&Ray::new(Vec3A::ZERO, -Vec3A::Z), f32::INFINITY)
                .is_none()
        );
    }
}
