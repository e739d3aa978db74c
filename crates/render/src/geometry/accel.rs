//! Ray queries against all primitives: an 8-wide BVH ([`Bvh8`]) over blocks of four
//! triangles, and one over spheres, both built with `obvhs`'s binary builder.
//!
//! The slab test rounds, and a ray through the edge of a flat box (an axis-aligned face)
//! could round its way out of it: primitive bounds are padded by 16 ulps of the scene's
//! largest coordinate, more than that rounding error for rays that start inside the scene.

use glam::Vec3A;
use obvhs::aabb::Aabb;

use super::bvh8::{BoxRay, Bvh8, Ref, Visit, avx_available, safe_inverse};
use super::sphere;
use super::triangle::{self, Triangle4, TriangleRay};
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

#[derive(Clone, Copy)]
struct Sphere {
    center: Vec3A,
    radius: f32,
}

/// A closest triangle hit, if any: block, lane in the block, barycentrics.
pub(super) type TriangleBest = Option<(usize, usize, [f32; 3])>;

/// Triangles in a leaf: one block.
const LEAF_TRIANGLES: u32 = 4;

/// Bounding volume hierarchies over a scene's triangles and spheres.
pub struct Accel {
    pub(super) triangles: Bvh8,
    /// Triangle blocks in leaf order, and each lane's triangle id (u32::MAX where unused).
    pub(super) blocks: Vec<Triangle4>,
    block_ids: Vec<[u32; 4]>,
    spheres: Bvh8,
    sphere_list: Vec<(Sphere, u32)>,
    /// Whether queries test a node's eight boxes in one AVX group (else in two SSE ones): the
    /// same hits either way.
    pub(super) avx: bool,
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
        // A primitive's bounds, padded for the traversal's rounding (see the module notes).
        let padded = |a: Vec3A, b: Vec3A| Aabb::new(a - pad, b + pad);

        let mut blocks = Vec::new();
        let mut block_ids = Vec::new();
        let tri_bvh = if triangles.is_empty() {
            Bvh8::default()
        } else {
            let bounds: Vec<Aabb> = triangles
                .iter()
                .map(|t| padded(t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2])))
                .collect();
            let mut bvh2 = super::build::build(&bounds);
            Bvh8::from_bvh2(&mut bvh2, LEAF_TRIANGLES, |ids| {
                let start = blocks.len() as u32;
                for chunk in ids.chunks(4) {
                    let tris: Vec<[Vec3A; 3]> =
                        chunk.iter().map(|&i| triangles[i as usize]).collect();
                    blocks.push(Triangle4::new(&tris));
                    let mut lanes = [u32::MAX; 4];
                    lanes[..chunk.len()].copy_from_slice(chunk);
                    block_ids.push(lanes);
                }
                (start, blocks.len() as u32 - start)
            })
        };
        let mut sphere_list = Vec::new();
        let sphere_bvh = if spheres.is_empty() {
            Bvh8::default()
        } else {
            let bounds: Vec<Aabb> = spheres
                .iter()
                .map(|&(c, r)| padded(c - Vec3A::splat(r), c + Vec3A::splat(r)))
                .collect();
            let mut bvh2 = super::build::build(&bounds);
            // Spheres are tested one by one: a leaf is one sphere.
            Bvh8::from_bvh2(&mut bvh2, 1, |ids| {
                let start = sphere_list.len() as u32;
                for &i in ids {
                    let (center, radius) = spheres[i as usize];
                    sphere_list.push((Sphere { center, radius }, i));
                }
                (start, ids.len() as u32)
            })
        };
        Accel {
            triangles: tri_bvh,
            blocks,
            block_ids,
            spheres: sphere_bvh,
            sphere_list,
            avx: avx_available(),
        }
    }

    pub fn triangle_count(&self) -> usize {
        self.block_ids
            .iter()
            .flatten()
            .filter(|&&id| id != u32::MAX)
            .count()
    }

    /// Inner nodes of the triangle BVH and its blocks of (up to) four triangles.
    pub fn triangle_bvh_size(&self) -> (usize, usize) {
        (self.triangles.node_count(), self.blocks.len())
    }

    pub fn sphere_count(&self) -> usize {
        self.sphere_list.len()
    }

    /// Every triangle's vertices, in the order of their ids.
    pub fn triangles(&self) -> Vec<[Vec3A; 3]> {
        let mut out = vec![[Vec3A::ZERO; 3]; self.triangle_count()];
        for (block, ids) in self.blocks.iter().zip(&self.block_ids) {
            for (lane, &id) in ids.iter().enumerate() {
                if id != u32::MAX {
                    out[id as usize] = block.triangle(lane);
                }
            }
        }
        out
    }

    /// The closest hit with 0 < t < `t_max`.
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<PrimHit> {
        #[cfg(target_arch = "x86_64")]
        if self.avx {
            // SAFETY: `avx` is set only where the CPU has AVX.
            return unsafe { self.intersect_avx(ray, t_max) };
        }
        self.intersect_with::<false>(ray, t_max)
    }

    /// [`Accel::intersect`] compiled for AVX, so that the node tests inline as one group.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn intersect_avx(&self, ray: &Ray, t_max: f32) -> Option<PrimHit> {
        self.intersect_with::<true>(ray, t_max)
    }

    #[inline(always)]
    fn intersect_with<const AVX: bool>(&self, ray: &Ray, t_max: f32) -> Option<PrimHit> {
        let box_ray = BoxRay::new(ray.o, safe_inverse(ray.d));
        let mut t_best = t_max;
        let mut best = None;
        if let Some(root) = self.triangles.root {
            self.closest_triangle_from::<AVX>(root, ray, &box_ray, &mut t_best, &mut best);
        }
        self.nearest_with_spheres::<AVX>(ray, &box_ray, t_best, best)
    }

    /// The closest hit given the closest triangle hit `best` (block, lane, barycentrics) at
    /// `t_best` (else the query's `t_max`): a nearer sphere's, or the triangle's.
    #[inline(always)]
    pub(super) fn nearest_with_spheres<const AVX: bool>(
        &self,
        ray: &Ray,
        box_ray: &BoxRay,
        mut t_best: f32,
        best: TriangleBest,
    ) -> Option<PrimHit> {
        let mut best_sphere = None;
        self.spheres
            .closest::<AVX>(box_ray, &mut t_best, |first, count, t_max| {
                for slot in first..first + count {
                    let (s, _) = self.sphere_list[slot as usize];
                    if let Some(t) = sphere::intersect(s.center, s.radius, ray.o, ray.d, *t_max) {
                        *t_max = t;
                        best_sphere = Some(slot as usize);
                    }
                }
                Visit::Continue
            });
        if let Some(slot) = best_sphere {
            let (s, id) = self.sphere_list[slot];
            let (p, p_error, n) = sphere::point_and_error(s.center, s.radius, ray.o, ray.d, t_best);
            return Some(PrimHit {
                t: t_best,
                prim: Prim::Sphere { id },
                p,
                p_error,
                n,
            });
        }
        let (block, lane, b) = best?;
        let v = self.blocks[block].triangle(lane);
        let (p, p_error) = triangle::point_off_edges(&v, b);
        Some(PrimHit {
            t: t_best,
            prim: Prim::Triangle {
                id: self.block_ids[block][lane],
                b,
            },
            p,
            p_error,
            n: (v[1] - v[0]).cross(v[2] - v[0]).normalize(),
        })
    }

    /// Lowers `t_max` to the closest triangle hit in the subtree at `root` and sets `best` to
    /// it (block, lane, barycentrics), if there is one nearer than `t_max`.
    #[inline(always)]
    pub(super) fn closest_triangle_from<const AVX: bool>(
        &self,
        root: Ref,
        ray: &Ray,
        box_ray: &BoxRay,
        t_max: &mut f32,
        best: &mut TriangleBest,
    ) {
        match triangle::dominant_axis(ray.d) {
            0 => self.closest_triangle::<0, AVX>(root, ray, box_ray, t_max, best),
            1 => self.closest_triangle::<1, AVX>(root, ray, box_ray, t_max, best),
            _ => self.closest_triangle::<2, AVX>(root, ray, box_ray, t_max, best),
        }
    }

    /// [`Accel::closest_triangle_from`] for rays whose dominant axis is `KZ`.
    #[inline(always)]
    fn closest_triangle<const KZ: usize, const AVX: bool>(
        &self,
        root: Ref,
        ray: &Ray,
        box_ray: &BoxRay,
        t_max: &mut f32,
        best: &mut TriangleBest,
    ) {
        let tr = TriangleRay::<KZ>::new(ray.o, ray.d);
        self.triangles
            .closest_from::<AVX>(root, box_ray, t_max, |first, count, t_max| {
                for block in first..first + count {
                    if let Some((lane, h)) =
                        triangle::intersect4(&tr, &self.blocks[block as usize], *t_max)
                    {
                        *t_max = h.t;
                        *best = Some((block as usize, lane, h.b));
                    }
                }
                Visit::Continue
            });
    }

    /// Whether anything is hit with 0 < t < `t_max`.
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.avx {
            // SAFETY: `avx` is set only where the CPU has AVX.
            return unsafe { self.occluded_avx(ray, t_max) };
        }
        self.occluded_with::<false>(ray, t_max)
    }

    /// [`Accel::occluded`] compiled for AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn occluded_avx(&self, ray: &Ray, t_max: f32) -> bool {
        self.occluded_with::<true>(ray, t_max)
    }

    #[inline(always)]
    fn occluded_with<const AVX: bool>(&self, ray: &Ray, t_max: f32) -> bool {
        let box_ray = BoxRay::new(ray.o, safe_inverse(ray.d));
        self.triangles
            .root
            .is_some_and(|root| self.any_triangle_from::<AVX>(root, ray, &box_ray, t_max))
            || self.any_sphere::<AVX>(ray, &box_ray, t_max)
    }

    /// Whether a sphere is hit with 0 < t < `t_max`.
    #[inline(always)]
    pub(super) fn any_sphere<const AVX: bool>(
        &self,
        ray: &Ray,
        box_ray: &BoxRay,
        t_max: f32,
    ) -> bool {
        self.spheres.any::<AVX>(box_ray, t_max, |first, count| {
            (first..first + count).any(|slot| {
                let (s, _) = self.sphere_list[slot as usize];
                sphere::intersect(s.center, s.radius, ray.o, ray.d, t_max).is_some()
            })
        })
    }

    /// Whether a triangle in the subtree at `root` is hit with 0 < t < `t_max`.
    #[inline(always)]
    pub(super) fn any_triangle_from<const AVX: bool>(
        &self,
        root: Ref,
        ray: &Ray,
        box_ray: &BoxRay,
        t_max: f32,
    ) -> bool {
        match triangle::dominant_axis(ray.d) {
            0 => self.any_triangle::<0, AVX>(root, ray, box_ray, t_max),
            1 => self.any_triangle::<1, AVX>(root, ray, box_ray, t_max),
            _ => self.any_triangle::<2, AVX>(root, ray, box_ray, t_max),
        }
    }

    #[inline(always)]
    fn any_triangle<const KZ: usize, const AVX: bool>(
        &self,
        root: Ref,
        ray: &Ray,
        box_ray: &BoxRay,
        t_max: f32,
    ) -> bool {
        let tr = TriangleRay::<KZ>::new(ray.o, ray.d);
        self.triangles
            .any_from::<AVX>(root, box_ray, t_max, |first, count| {
                (first..first + count).any(|block| {
                    triangle::intersect4(&tr, &self.blocks[block as usize], t_max).is_some()
                })
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed unit cube (12 triangles) scaled by `size` and moved to `offset`.
    fn cube(offset: Vec3A, size: f32) -> Vec<[Vec3A; 3]> {
        let (p, t) = tessera_scene::box_mesh(offset.into(), (offset + size).into());
        t.iter()
            .map(|t| t.map(|i| Vec3A::from(p[i as usize])))
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

    /// Every triangle lands in exactly one block lane, whatever subtrees became leaves.
    #[test]
    fn every_triangle_is_in_one_block() {
        let mut tris = cube(Vec3A::ZERO, 1.0);
        for i in 0..997u32 {
            let o = Vec3A::new((i % 10) as f32, (i / 10 % 10) as f32, (i / 100) as f32) * 3.0;
            tris.push([o, o + Vec3A::X, o + Vec3A::new(0.0, 1.0, 0.5)]);
        }
        let accel = Accel::build(&tris, &[]);
        assert_eq!(accel.triangle_count(), tris.len());
        assert_eq!(accel.triangles(), tris);
        let (_, blocks) = accel.triangle_bvh_size();
        assert!(blocks * 4 >= tris.len() && blocks <= tris.len());
    }

    /// The closest hit and occlusion of every ray equal a test of every primitive, through
    /// both forms of the node test (eight lanes with AVX, two groups of four without): a soup
    /// of thousands of triangles and some spheres, so that nodes are full and deep.
    /// Uniform numbers in [0, 1), a fixed sequence.
    fn uniform() -> impl FnMut() -> f32 {
        use crate::sampler::hash::{mix64, u32_to_unit};
        let mut k = 0u64;
        move || {
            k += 1;
            u32_to_unit(mix64(k) as u32)
        }
    }

    /// A soup of thousands of small triangles and some spheres in [0, 10]³, so that nodes are
    /// full and deep.
    fn soup(u: &mut impl FnMut() -> f32) -> (Vec<[Vec3A; 3]>, Vec<(Vec3A, f32)>) {
        let mut point = |scale: f32| Vec3A::new(u(), u(), u()) * scale;
        let mut tris = Vec::new();
        for _ in 0..3000 {
            let o = point(10.0);
            tris.push([o, o + point(0.8) - 0.4, o + point(0.8) - 0.4]);
        }
        let spheres: Vec<(Vec3A, f32)> = (0..40)
            .map(|i| (point(10.0), 0.05 + 0.01 * i as f32))
            .collect();
        (tris, spheres)
    }

    /// The closest hit by testing every primitive, one by one.
    fn brute(
        tris: &[[Vec3A; 3]],
        spheres: &[(Vec3A, f32)],
        ray: &Ray,
        t_max: f32,
    ) -> Option<(f32, Prim)> {
        let mut best: Option<(f32, Prim)> = None;
        for (i, t) in tris.iter().enumerate() {
            let block = Triangle4::new(&[*t]);
            let limit = best.map_or(t_max, |b| b.0);
            let hit = match triangle::dominant_axis(ray.d) {
                0 => triangle::intersect4(&TriangleRay::<0>::new(ray.o, ray.d), &block, limit),
                1 => triangle::intersect4(&TriangleRay::<1>::new(ray.o, ray.d), &block, limit),
                _ => triangle::intersect4(&TriangleRay::<2>::new(ray.o, ray.d), &block, limit),
            };
            if let Some((_, h)) = hit {
                best = Some((
                    h.t,
                    Prim::Triangle {
                        id: i as u32,
                        b: h.b,
                    },
                ));
            }
        }
        for (i, &(c, r)) in spheres.iter().enumerate() {
            let limit = best.map_or(t_max, |b| b.0);
            if let Some(t) = sphere::intersect(c, r, ray.o, ray.d, limit) {
                best = Some((t, Prim::Sphere { id: i as u32 }));
            }
        }
        best
    }

    /// Closest-hit and occlusion queries equal a test of every primitive, with each of
    /// both forms of the node test (eight lanes with AVX, two groups of four without).
    #[test]
    fn queries_equal_a_test_of_every_primitive_with_and_without_avx() {
        let mut u = uniform();
        let (tris, spheres) = soup(&mut u);
        let mut point = |scale: f32| Vec3A::new(u(), u(), u()) * scale;
        let mut accel = Accel::build(&tris, &spheres);
        let brute = |ray: &Ray, t_max: f32| brute(&tris, &spheres, ray, t_max);
        let rays: Vec<(Ray, f32)> = (0..2000)
            .map(|i| {
                let o = point(12.0) - 1.0;
                let d = (point(2.0) - 1.0).normalize();
                // Some rays end early, where the occlusion test must stop too.
                (Ray::new(o, d), if i % 3 == 0 { 2.0 } else { f32::INFINITY })
            })
            .collect();
        let mut forms = vec![false];
        if avx_available() {
            forms.push(true);
        }
        let mut hits = 0;
        for avx in forms {
            accel.avx = avx;
            for (ray, t_max) in &rays {
                let want = brute(ray, *t_max);
                let got = accel.intersect(ray, *t_max).map(|h| (h.t, h.prim));
                assert_eq!(got, want, "closest hit (avx {avx}) of {ray:?}");
                assert_eq!(
                    accel.occluded(ray, *t_max),
                    want.is_some(),
                    "occlusion (avx {avx}) of {ray:?}"
                );
                hits += want.is_some() as u32;
            }
        }
        // Neither all hits nor all misses: the comparison means something.
        assert!(hits > 200 && hits < 3800, "{hits} hits");
    }

    /// Inputs whose binary BVH comes out as deep chains (many copies of one triangle, shells
    /// nested around one point, zero-area slivers) are queried like any other: no traversal
    /// stack overflows, and hits are a test of every primitive's (distance and whether).
    #[test]
    fn coincident_nested_and_degenerate_triangles_are_traversed() {
        let tri = [Vec3A::ZERO, Vec3A::X, Vec3A::Y];
        let nested = |n: usize| -> Vec<[Vec3A; 3]> {
            (0..n)
                .map(|i| {
                    let s = 1.0 + i as f32 * 1e-3;
                    let c = Vec3A::splat(0.25);
                    tri.map(|v| c + (v - c) * s)
                })
                .collect()
        };
        let sliver = |n: usize| -> Vec<[Vec3A; 3]> {
            (0..n)
                .map(|i| {
                    let x = i as f32 * 1e-6;
                    [
                        Vec3A::new(x, 0.0, 0.0),
                        Vec3A::new(x, 1.0, 0.0),
                        Vec3A::new(x, 0.5, 0.0),
                    ]
                })
                .chain(std::iter::once(tri))
                .collect()
        };
        let cases: Vec<(&str, Vec<[Vec3A; 3]>)> = vec![
            ("2000 copies", vec![tri; 2000]),
            ("a million copies", vec![tri; 1_000_000]),
            ("100000 nested", nested(100_000)),
            ("100000 slivers", sliver(100_000)),
        ];
        for (name, tris) in cases {
            let accel = Accel::build(&tris, &[]);
            for k in 0..16 {
                let target = Vec3A::new(0.05 + 0.05 * k as f32, 0.2, 0.0);
                let o = Vec3A::new(0.1, 0.1, -1.0 - k as f32);
                let ray = Ray::new(o, (target - o).normalize());
                let want = brute(&tris, &[], &ray, f32::INFINITY).map(|(t, _)| t);
                let got = accel.intersect(&ray, f32::INFINITY).map(|h| h.t);
                assert_eq!(got, want, "{name}: closest hit of {ray:?}");
                assert_eq!(
                    accel.occluded(&ray, f32::INFINITY),
                    want.is_some(),
                    "{name}"
                );
            }
        }
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
