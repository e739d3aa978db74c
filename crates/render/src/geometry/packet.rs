//! Packets of up to eight rays through [`Accel`], one ray per AVX lane (Wald, Slusallek,
//! Benthin & Wagner, "Interactive Rendering with Coherent Ray Tracing", 2001; at the width of
//! Embree's hybrid traversal, Benthin, Wald, Woop, Ernst & Mark, "Combining Single and Packet
//! Ray Tracing for Arbitrary Ray Distributions on the Intel MIC Architecture", 2012).
//!
//! A node is entered once for all the rays that may hit it: each child's box is tested against
//! the eight rays at once, and a leaf's triangles one by one against the eight rays. Where
//! fewer than [`SINGLE_BELOW`] rays are left in a subtree, they finish it one at a time with
//! the single-ray traversal, which tests eight children (or four triangles) per instruction:
//! coherent rays (a pixel's samples, a tile's camera rays) share nodes, incoherent ones soon
//! split up. Rays whose directions are not within a narrow cone go one by one from the start.
//!
//! Every lane computes the single-ray tests' operations in their order — the slab test (its
//! near plane, the one the direction's sign picks, is the nearer of the two), Woop's watertight test in the ray's own
//! permuted axes with its f64 fallbacks and pbrt's bound on t — so each ray gets the hit
//! [`Accel::intersect`] gives it, except that of two triangles at exactly the same distance
//! either may be reported.

use std::arch::x86_64::*;
use std::mem::MaybeUninit;

use super::accel::{Accel, LANES, PrimHit, TriangleBest};
use super::bvh8::{BoxRay, Bvh8, Node, Ref, STACK, safe_inverse};
use super::triangle::{self, Triangle4, TriangleRay};
use crate::math::gamma;
use crate::ray::Ray;

/// Fewer rays than this left in a subtree finish it one by one.
const SINGLE_BELOW: u32 = 5;

type F8 = __m256;

/// The rays of a packet as structure of arrays, lane i for ray i.
struct Packet {
    o: [F8; 3],
    /// [`safe_inverse`] of the directions; the sign bit picks each axis's entry plane.
    inv: [F8; 3],
    /// Woop's test: origin and shear in each ray's own permuted axes ([`TriangleRay`]).
    po: [F8; 3],
    shear: [F8; 3],
    /// The dominant axis of every ray, or 3 where they differ; then the sign bit is set in
    /// lanes whose dominant axis is x (`kz0`), y (`kz1`).
    kz: usize,
    kz0: F8,
    kz1: F8,
}

/// Bits of the lanes set in `m`.
#[inline(always)]
fn lanes(mut m: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (m != 0).then(|| {
            let lane = m.trailing_zeros() as usize;
            m &= m - 1;
            lane
        })
    })
}

/// Whether the rays may stay together through the BVH: their directions within a narrow cone
/// of the first's (a pixel's camera rays, shadow rays from nearby points to a small light).
/// Other rays split up at once and go one by one from the start.
pub(super) fn coherent(rays: &[Ray]) -> bool {
    rays.iter().all(|r| r.d.dot(rays[0].d) > 0.9)
}

/// Each ray's data for the one-ray slab test (for the subtrees rays finish alone, and the
/// spheres), made once per packet; lanes without a ray repeat the first ray's. `None` for no
/// rays.
fn box_rays(rays: &[Ray]) -> Option<[BoxRay; LANES]> {
    let first = rays.first()?;
    Some(std::array::from_fn(|l| {
        let r = rays.get(l).unwrap_or(first);
        BoxRay::new(r.o, safe_inverse(r.d))
    }))
}

/// Permuted origin and shear of `TriangleRay::<KZ>`.
fn woop<const KZ: usize>(r: &Ray) -> ([f32; 3], [f32; 3]) {
    let t = TriangleRay::<KZ>::new(r.o, r.d);
    (t.o.to_array(), t.shear.to_array())
}

impl Packet {
    /// # Safety
    /// The CPU must have AVX.
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn new(rays: &[Ray]) -> Packet {
        // Rows: o, inv, po, shear (three each), kz0, kz1. Lanes without a ray stay zero; no
        // query ever reads them.
        let mut a = [[0.0f32; LANES]; 14];
        let mut uniform = None;
        for (i, r) in rays.iter().enumerate() {
            let inv = safe_inverse(r.d);
            let kz = triangle::dominant_axis(r.d);
            uniform = match uniform {
                None => Some(kz),
                Some(u) if u == kz => Some(kz),
                Some(_) => Some(3),
            };
            let (po, shear) = match kz {
                0 => woop::<0>(r),
                1 => woop::<1>(r),
                _ => woop::<2>(r),
            };
            for axis in 0..3 {
                a[axis][i] = r.o[axis];
                a[3 + axis][i] = inv[axis];
                a[6 + axis][i] = po[axis];
                a[9 + axis][i] = shear[axis];
            }
            a[12][i] = if kz == 0 { -1.0 } else { 0.0 };
            a[13][i] = if kz == 1 { -1.0 } else { 0.0 };
        }
        // SAFETY: each row holds eight floats.
        let load = |i: usize| unsafe { _mm256_loadu_ps(a[i].as_ptr()) };
        Packet {
            o: [load(0), load(1), load(2)],
            inv: [load(3), load(4), load(5)],
            po: [load(6), load(7), load(8)],
            shear: [load(9), load(10), load(11)],
            kz: uniform.unwrap_or(2),
            kz0: load(12),
            kz1: load(13),
        }
    }

    /// Entry distances of child `c` of `n` per ray, the mask of rays that hit it within
    /// [0, t_far] and the nearest entry among them: `BoxRay::test`'s operations, lane by lane.
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn test_child(&self, n: &Node, c: usize, t_far: F8) -> (F8, u32, f32) {
        let (g, l) = (c / 4, c % 4);
        let t = |plane: usize, axis: usize| {
            _mm256_mul_ps(
                _mm256_sub_ps(_mm256_set1_ps(n.b[plane][g][l]), self.o[axis]),
                self.inv[axis],
            )
        };
        // A positive direction enters an axis's slab through its minimum (plane `axis`),
        // a negative one through its maximum (`axis + 3`): for a box that is not empty
        // (every child up to `Node::len`), the smaller and larger of the two distances.
        let near_far = |axis: usize| {
            let (lo, hi) = (t(axis, axis), t(axis + 3, axis));
            (_mm256_min_ps(lo, hi), _mm256_max_ps(lo, hi))
        };
        let ((nx, fx), (ny, fy), (nz, fz)) = (near_far(0), near_far(1), near_far(2));
        let near = _mm256_max_ps(
            _mm256_max_ps(nx, ny),
            _mm256_max_ps(nz, _mm256_setzero_ps()),
        );
        let far = _mm256_min_ps(_mm256_min_ps(fx, fy), _mm256_min_ps(fz, t_far));
        let hit = _mm256_cmp_ps::<_CMP_LE_OQ>(near, far);
        // The nearest entry of the rays that hit (+∞ if none), for the visiting order.
        let v = _mm256_blendv_ps(_mm256_set1_ps(f32::INFINITY), near, hit);
        let v = _mm256_min_ps(v, _mm256_permute2f128_ps::<1>(v, v));
        let v = _mm256_min_ps(v, _mm256_permute_ps::<0b01_00_11_10>(v));
        let v = _mm256_min_ps(v, _mm256_permute_ps::<0b10_11_00_01>(v));
        (near, _mm256_movemask_ps(hit) as u32, _mm256_cvtss_f32(v))
    }

    /// Triangle `j` of `block` against the rays of `mask`, for 0 < t < `t_far`: `intersect4`'s
    /// operations lane by lane, each ray in its own permuted axes.
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn intersect_triangle(
        &self,
        rays: &[Ray],
        block: &Triangle4,
        j: usize,
        mask: u32,
        t_far: F8,
    ) -> TriangleHits {
        // SAFETY: the CPU has AVX (the caller's contract).
        unsafe {
            let splat = |v: f32| _mm256_set1_ps(v);
            let (sub, mul, add) = (
                |a, b| _mm256_sub_ps(a, b),
                |a, b| _mm256_mul_ps(a, b),
                |a, b| _mm256_add_ps(a, b),
            );
            let abs = |a: F8| _mm256_andnot_ps(splat(-0.0), a);
            let max = |a, b| _mm256_max_ps(a, b);
            let movemask = |a| _mm256_movemask_ps(a) as u32;
            // Vertex i in each lane's permuted order (x, y, z for dominant z; y, z, x for x;
            // z, x, y for y), translated to the origin and sheared.
            let transform = |i: usize| {
                let [x, y, z] = block.v[i].map(|c| splat(c[j]));
                let sel = |k2: F8, k0: F8, k1: F8| {
                    _mm256_blendv_ps(_mm256_blendv_ps(k2, k0, self.kz0), k1, self.kz1)
                };
                let (px, py, pz) = match self.kz {
                    0 => (y, z, x),
                    1 => (z, x, y),
                    2 => (x, y, z),
                    _ => (sel(x, y, z), sel(y, z, x), sel(z, x, y)),
                };
                let qz = sub(pz, self.po[2]);
                (
                    add(sub(px, self.po[0]), mul(self.shear[0], qz)),
                    add(sub(py, self.po[1]), mul(self.shear[1], qz)),
                    mul(qz, self.shear[2]),
                )
            };
            let (x0, y0, z0) = transform(0);
            let (x1, y1, z1) = transform(1);
            let (x2, y2, z2) = transform(2);
            let mut e0 = sub(mul(x1, y2), mul(y1, x2));
            let mut e1 = sub(mul(x2, y0), mul(y2, x0));
            let mut e2 = sub(mul(x0, y1), mul(y0, x1));
            let zero = |e| _mm256_cmp_ps::<_CMP_EQ_OQ>(e, _mm256_setzero_ps());
            let zeros = movemask(_mm256_or_ps(_mm256_or_ps(zero(e0), zero(e1)), zero(e2))) & mask;
            if zeros != 0 {
                // Edge functions that rounded to zero, recomputed in f64 as `intersect4` does.
                let arr = |v: F8| {
                    let mut a = [0.0f32; LANES];
                    // SAFETY: eight floats.
                    _mm256_storeu_ps(a.as_mut_ptr(), v);
                    a
                };
                let (ax0, ay0, ax1, ay1, ax2, ay2) =
                    (arr(x0), arr(y0), arr(x1), arr(y1), arr(x2), arr(y2));
                let (mut a0, mut a1, mut a2) = (arr(e0), arr(e1), arr(e2));
                for lane in lanes(zeros) {
                    let p = |x: &[f32; LANES], y: &[f32; LANES]| [x[lane], y[lane]];
                    [a0[lane], a1[lane], a2[lane]] =
                        triangle::edges_f64([p(&ax0, &ay0), p(&ax1, &ay1), p(&ax2, &ay2)]);
                }
                e0 = _mm256_loadu_ps(a0.as_ptr());
                e1 = _mm256_loadu_ps(a1.as_ptr());
                e2 = _mm256_loadu_ps(a2.as_ptr());
            }
            let zero8 = _mm256_setzero_ps();
            let lt0 = |e| _mm256_cmp_ps::<_CMP_LT_OQ>(e, zero8);
            let gt0 = |e| _mm256_cmp_ps::<_CMP_GT_OQ>(e, zero8);
            let negative = _mm256_or_ps(_mm256_or_ps(lt0(e0), lt0(e1)), lt0(e2));
            let positive = _mm256_or_ps(_mm256_or_ps(gt0(e0), gt0(e1)), gt0(e2));
            let det = add(add(e0, e1), e2);
            let t_scaled = add(add(mul(e0, z0), mul(e1, z1)), mul(e2, z2));
            let sign = _mm256_blendv_ps(splat(1.0), splat(-1.0), lt0(det));
            let (t_signed, det_abs) = (mul(t_scaled, sign), abs(det));
            let outside = movemask(_mm256_and_ps(negative, positive));
            let valid = !outside
                & movemask(_mm256_cmp_ps::<_CMP_NEQ_UQ>(det, zero8))
                & movemask(gt0(t_signed))
                & movemask(_mm256_cmp_ps::<_CMP_LT_OQ>(t_signed, mul(t_far, det_abs)))
                & mask;
            let mut hits = TriangleHits {
                valid,
                t: [0.0; LANES],
                e: [e0, e1, e2],
                det,
            };
            if valid == 0 {
                return hits;
            }
            let t = _mm256_div_ps(t_scaled, det);
            // pbrt-v3 §3.9.2's bound on t, as in `intersect4`.
            let max3 = |a, b, c| max(max(abs(a), abs(b)), abs(c));
            let (max_xt, max_yt, max_zt) = (max3(x0, x1, x2), max3(y0, y1, y2), max3(z0, z1, z2));
            let delta_z = mul(splat(gamma(3)), max_zt);
            let delta_x = mul(splat(gamma(5)), add(max_xt, max_zt));
            let delta_y = mul(splat(gamma(5)), add(max_yt, max_zt));
            let delta_e = mul(
                splat(2.0),
                add(
                    add(
                        mul(mul(splat(gamma(2)), max_xt), max_yt),
                        mul(delta_y, max_xt),
                    ),
                    mul(delta_x, max_yt),
                ),
            );
            let max_e = max3(e0, e1, e2);
            let delta_t = _mm256_div_ps(
                mul(
                    splat(3.0),
                    add(
                        add(
                            mul(mul(splat(gamma(3)), max_e), max_zt),
                            mul(delta_e, max_zt),
                        ),
                        mul(delta_z, max_e),
                    ),
                ),
                det_abs,
            );
            _mm256_storeu_ps(hits.t.as_mut_ptr(), t);
            let uncertain = valid & !movemask(_mm256_cmp_ps::<_CMP_GT_OQ>(t, delta_t));
            for lane in lanes(uncertain) {
                let v = block.triangle(j);
                let r = &rays[lane];
                let t = match triangle::dominant_axis(r.d) {
                    0 => triangle::distance_f64(&TriangleRay::<0>::new(r.o, r.d), &v),
                    1 => triangle::distance_f64(&TriangleRay::<1>::new(r.o, r.d), &v),
                    _ => triangle::distance_f64(&TriangleRay::<2>::new(r.o, r.d), &v),
                };
                match t {
                    Some(t) => hits.t[lane] = t,
                    None => hits.valid &= !(1 << lane),
                }
            }
            hits
        }
    }
}

/// Which rays of a packet hit one triangle, and where.
struct TriangleHits {
    valid: u32,
    t: [f32; LANES],
    /// Edge functions and their sum, for the barycentrics of a hit.
    e: [F8; 3],
    det: F8,
}

impl Bvh8 {
    /// Visits the leaves the rays of `active` may hit within [0, t_far], nearest first (by
    /// their nearest ray's entry): `leaf` gets a leaf's blocks, the rays that reach it and
    /// `t_far`, which it may lower; `single` gets a subtree that fewer than [`SINGLE_BELOW`]
    /// rays reach, which they finish one by one. Both get the caller's `state`.
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[allow(clippy::too_many_arguments)]
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn closest8<S>(
        &self,
        root: Ref,
        packet: &Packet,
        active: u32,
        t_far: &mut [f32; LANES],
        state: &mut S,
        mut leaf: impl FnMut(u32, u32, u32, &mut [f32; LANES], &mut S),
        mut single: impl FnMut(Ref, u32, &mut [f32; LANES], &mut S),
    ) {
        // SAFETY: the CPU has AVX (the caller's contract).
        unsafe {
            let mut stack = [MaybeUninit::<(Ref, u32, F8)>::uninit(); STACK];
            let mut top = 0usize;
            let (mut cur, mut mask) = (root, active);
            loop {
                if mask.count_ones() < SINGLE_BELOW {
                    single(cur, mask, t_far, state);
                } else if cur.is_leaf() {
                    let (first, count) = cur.blocks();
                    leaf(first, count, mask, t_far, state);
                } else {
                    let node = &self.nodes[cur.0 as usize];
                    let tf = _mm256_loadu_ps(t_far.as_ptr());
                    // The children some ray hits, with their nearest entry (sort key).
                    let mut kids = [MaybeUninit::<(Ref, u32, F8, f32)>::uninit(); 8];
                    let mut n = 0;
                    for c in 0..node.len as usize {
                        let (near, m, key) = packet.test_child(node, c, tf);
                        let m = m & mask;
                        if m != 0 {
                            // Insertion by key, farthest first.
                            let mut j = n;
                            // SAFETY: entries below `n` were written in this loop.
                            while j > 0 && kids[j - 1].assume_init().3 < key {
                                kids[j] = kids[j - 1];
                                j -= 1;
                            }
                            kids[j].write((node.child[c], m, near, key));
                            n += 1;
                        }
                    }
                    if n > 0 {
                        for kid in &kids[..n - 1] {
                            // SAFETY: written above.
                            let (r, m, near, _) = kid.assume_init();
                            stack[top].write((r, m, near));
                            top += 1;
                        }
                        // SAFETY: written above.
                        (cur, mask, _, _) = kids[n - 1].assume_init();
                        continue;
                    }
                }
                // Pop the next child some ray still enters in front of its closest hit.
                loop {
                    if top == 0 {
                        return;
                    }
                    top -= 1;
                    // SAFETY: entries below `top` were written above.
                    let (r, m, near) = stack[top].assume_init();
                    let tf = _mm256_loadu_ps(t_far.as_ptr());
                    let m = m & _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, tf)) as u32;
                    if m != 0 {
                        (cur, mask) = (r, m);
                        break;
                    }
                }
            }
        }
    }

    /// Visits the leaves the rays of `active` may hit within [0, t_far], in any order, until
    /// every ray is occluded: `leaf` gets a leaf's blocks and the rays not yet occluded that
    /// reach it, `single` a subtree fewer than [`SINGLE_BELOW`] such rays reach; both return
    /// the rays they found occluded. Returns the mask of occluded rays.
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn any8(
        &self,
        root: Ref,
        packet: &Packet,
        active: u32,
        t_far: F8,
        mut leaf: impl FnMut(u32, u32, u32) -> u32,
        mut single: impl FnMut(Ref, u32) -> u32,
    ) -> u32 {
        // SAFETY: the CPU has AVX (the caller's contract).
        unsafe {
            let mut stack = [MaybeUninit::<(Ref, u32)>::uninit(); STACK];
            let mut top = 0usize;
            let (mut cur, mut mask) = (root, active);
            let mut occluded = 0;
            loop {
                if mask.count_ones() < SINGLE_BELOW {
                    occluded |= single(cur, mask);
                } else if cur.is_leaf() {
                    let (first, count) = cur.blocks();
                    occluded |= leaf(first, count, mask);
                } else {
                    let node = &self.nodes[cur.0 as usize];
                    let mut next = None;
                    for c in 0..node.len as usize {
                        let m = packet.test_child(node, c, t_far).1 & mask;
                        if m != 0
                            && let Some(prev) = next.replace((node.child[c], m))
                        {
                            stack[top].write(prev);
                            top += 1;
                        }
                    }
                    if let Some(n) = next {
                        (cur, mask) = n;
                        continue;
                    }
                }
                if occluded == active {
                    return occluded;
                }
                loop {
                    if top == 0 {
                        return occluded;
                    }
                    top -= 1;
                    // SAFETY: entries below `top` were written above.
                    let (r, m) = stack[top].assume_init();
                    let m = m & !occluded;
                    if m != 0 {
                        (cur, mask) = (r, m);
                        break;
                    }
                }
            }
        }
    }
}

impl Accel {
    /// [`Accel::intersect8`] with AVX.
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[target_feature(enable = "avx")]
    pub(super) unsafe fn intersect8_avx(
        &self,
        rays: &[Ray],
        t_max: &[f32],
        hits: &mut [Option<PrimHit>],
    ) {
        let Some(box_rays) = box_rays(rays) else {
            return;
        };
        // Lanes without a ray have a negative limit, which no box test passes.
        let mut t_far = [-1.0f32; LANES];
        t_far[..rays.len()].copy_from_slice(t_max);
        let mut best: [TriangleBest; LANES] = [None; LANES];
        if let Some(root) = self.triangles.root {
            // SAFETY: this function runs only where the CPU has AVX.
            let packet = unsafe { Packet::new(rays) };
            let active = (1u32 << rays.len()) - 1;
            let leaf = |first: u32,
                        count: u32,
                        mask: u32,
                        t_far: &mut [f32; LANES],
                        best: &mut [TriangleBest; LANES]| {
                for block in first..first + count {
                    let tris = &self.blocks[block as usize];
                    for j in 0..4 {
                        if tris.v[0][0][j].is_nan() {
                            break;
                        }
                        // SAFETY: the CPU has AVX; `t_far` holds eight floats.
                        let h = unsafe {
                            let tf = _mm256_loadu_ps(t_far.as_ptr());
                            packet.intersect_triangle(rays, tris, j, mask, tf)
                        };
                        let nearer = lanes(h.valid)
                            .filter(|&l| h.t[l] < t_far[l])
                            .fold(0u32, |m, l| m | 1 << l);
                        if nearer == 0 {
                            continue;
                        }
                        // Barycentrics as `intersect4` computes them: e_i · (1 / det).
                        let mut b = [[0.0f32; LANES]; 3];
                        // SAFETY: the CPU has AVX; each row holds eight floats.
                        unsafe {
                            let inv_det = _mm256_div_ps(_mm256_set1_ps(1.0), h.det);
                            for (row, e) in b.iter_mut().zip(h.e) {
                                _mm256_storeu_ps(row.as_mut_ptr(), _mm256_mul_ps(e, inv_det));
                            }
                        }
                        for l in lanes(nearer) {
                            t_far[l] = h.t[l];
                            best[l] = Some((block as usize, j, [b[0][l], b[1][l], b[2][l]]));
                        }
                    }
                }
            };
            let single =
                |r: Ref, mask: u32, t_far: &mut [f32; LANES], best: &mut [TriangleBest; LANES]| {
                    for l in lanes(mask) {
                        let ray = &rays[l];
                        self.closest_triangle_from::<true>(
                            r,
                            ray,
                            &box_rays[l],
                            &mut t_far[l],
                            &mut best[l],
                        );
                    }
                };
            // SAFETY: the CPU has AVX.
            unsafe {
                self.triangles
                    .closest8(root, &packet, active, &mut t_far, &mut best, leaf, single)
            };
        }
        for (l, (ray, hit)) in rays.iter().zip(hits).enumerate() {
            *hit = self.nearest_with_spheres::<true>(ray, &box_rays[l], t_far[l], best[l]);
        }
    }

    /// [`Accel::occluded8`] with AVX.
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[target_feature(enable = "avx")]
    pub(super) unsafe fn occluded8_avx(&self, rays: &[Ray], t_max: &[f32]) -> u32 {
        let Some(box_rays) = box_rays(rays) else {
            return 0;
        };
        let active = (1u32 << rays.len()) - 1;
        let mut occluded = 0;
        if let Some(root) = self.triangles.root {
            // Lanes without a ray have a negative limit, which no box test passes.
            let mut limit = [-1.0f32; LANES];
            limit[..rays.len()].copy_from_slice(t_max);
            // SAFETY: this function runs only where the CPU has AVX; `limit` holds eight floats.
            let (packet, t_far) = unsafe { (Packet::new(rays), _mm256_loadu_ps(limit.as_ptr())) };
            let leaf = |first: u32, count: u32, mut mask: u32| {
                let mut hit = 0;
                for block in first..first + count {
                    let tris = &self.blocks[block as usize];
                    for j in 0..4 {
                        if mask == 0 || tris.v[0][0][j].is_nan() {
                            break;
                        }
                        // SAFETY: the CPU has AVX.
                        let h = unsafe { packet.intersect_triangle(rays, tris, j, mask, t_far) };
                        hit |= h.valid;
                        mask &= !h.valid;
                    }
                }
                hit
            };
            let single = |r: Ref, mask: u32| {
                let hit = lanes(mask).filter(|&l| {
                    let ray = &rays[l];
                    self.any_triangle_from::<true>(r, ray, &box_rays[l], t_max[l])
                });
                hit.map(|l| 1 << l).sum()
            };
            // SAFETY: the CPU has AVX.
            occluded = unsafe {
                self.triangles
                    .any8(root, &packet, active, t_far, leaf, single)
            };
        }
        for l in lanes(active & !occluded) {
            let ray = &rays[l];
            if self.any_sphere::<true>(ray, &box_rays[l], t_max[l]) {
                occluded |= 1 << l;
            }
        }
        occluded
    }
}
