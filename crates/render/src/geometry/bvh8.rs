//! An 8-wide BVH with uncompressed bounds (the layout of Embree's BVH8; Wald et al., "Getting
//! Rid of Packets", 2008, at width eight): eight children's bounds per node, stored plane by
//! plane, tested with one eight-lane slab test where the CPU has AVX (chosen at run time) and
//! as two four-lane tests where it has only SSE — the same operations lane by lane, so the
//! same hits. Built from a binary BVH of one primitive per leaf (`build`, top-down SAH):
//! each node opens the largest inner children until it has eight, and small subtrees become
//! leaves by the surface area heuristic with the cost of a four-wide leaf test
//! ([`Collapse`]). Leaves are ranges of primitive *blocks* whose meaning belongs to the caller
//! (four triangles, or one sphere).
//!
//! Traversal visits the nearest hit child next without pushing it and pushes the others
//! farthest first; shadow rays skip the ordering. Empty child slots have bounds (+∞, −∞),
//! which every slab test misses. The slab test's rounding is covered by the primitives'
//! padded bounds (see `accel`).

use std::mem::MaybeUninit;

use glam::{Vec3A, Vec4};
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;

use super::depth;

/// A reference to a child: an inner node, or a leaf (first block and block count).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ref(pub(super) u32);

const LEAF: u32 = 1 << 31;
const COUNT_SHIFT: u32 = 27;
/// Largest number of blocks in one leaf.
pub const MAX_LEAF_BLOCKS: u32 = 1 << (31 - COUNT_SHIFT);
const FIRST_MASK: u32 = (1 << COUNT_SHIFT) - 1;

impl Ref {
    fn leaf(first: u32, count: u32) -> Ref {
        assert!(
            (1..=MAX_LEAF_BLOCKS).contains(&count) && first <= FIRST_MASK,
            "leaf of {count} blocks at {first}"
        );
        Ref(LEAF | ((count - 1) << COUNT_SHIFT) | first)
    }
    #[inline(always)]
    pub(super) fn is_leaf(self) -> bool {
        self.0 & LEAF != 0
    }
    #[inline(always)]
    pub(super) fn blocks(self) -> (u32, u32) {
        (self.0 & FIRST_MASK, ((self.0 & !LEAF) >> COUNT_SHIFT) + 1)
    }
}

/// Children per node.
pub(super) const WIDTH: usize = 8;
/// Entries of a traversal stack: a level pushes at most seven children, and a tree is at
/// most [`depth::MAX_DEPTH`] levels deep ([`Bvh8::from_bvh2`] bounds it).
pub(super) const STACK: usize = (WIDTH - 1) * depth::MAX_DEPTH as usize + 1;

/// Four-wide SIMD groups per node.
const GROUPS: usize = WIDTH / 4;

/// Eight children: `b[axis][g]` the minima of children 4g..4g+4 and `b[axis + 3][g]` their
/// maxima along x, y, z. Children fill the first `len` slots.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
pub(super) struct Node {
    pub(super) b: [[Vec4; GROUPS]; 6],
    pub(super) child: [Ref; WIDTH],
    pub(super) len: u32,
}

// `BoxRay::test_avx` loads each plane of eight bounds as one aligned 32-byte row.
const _: () = assert!(std::mem::align_of::<Node>() >= 32);

/// Per-ray data for the slab tests.
#[derive(Debug, Clone, Copy)]
pub struct BoxRay {
    o: [Vec4; 3],
    inv: [Vec4; 3],
    /// Index into `Node::b` of each axis's near and far plane (by the direction's sign).
    near: [usize; 3],
    far: [usize; 3],
}

/// 1/d per component, with a huge finite value for zero components so that (plane − o)·inv
/// never becomes NaN.
#[inline]
pub fn safe_inverse(d: Vec3A) -> Vec3A {
    let inv = Vec3A::ONE / d;
    Vec3A::select(d.cmpeq(Vec3A::ZERO), Vec3A::splat(1.0e30).copysign(d), inv)
}

impl BoxRay {
    /// `inv` is [`safe_inverse`] of the direction.
    #[inline]
    pub fn new(o: Vec3A, inv: Vec3A) -> Self {
        // A negative direction enters an axis's slab through its maximum (b[axis + 3]).
        let (nx, ny, nz) = (
            inv.x.is_sign_negative() as usize,
            inv.y.is_sign_negative() as usize,
            inv.z.is_sign_negative() as usize,
        );
        BoxRay {
            o: [Vec4::splat(o.x), Vec4::splat(o.y), Vec4::splat(o.z)],
            inv: [Vec4::splat(inv.x), Vec4::splat(inv.y), Vec4::splat(inv.z)],
            near: [3 * nx, 1 + 3 * ny, 2 + 3 * nz],
            far: [3 * (1 - nx), 1 + 3 * (1 - ny), 2 + 3 * (1 - nz)],
        }
    }

    /// Entry distances of a node's children and the mask of those hit within [0, t_max]:
    /// eight lanes at once with `AVX` (the caller has checked the CPU has it, see
    /// [`avx_available`]), else as two four-wide groups. Both give the same bits: the same
    /// IEEE operations, lane by lane.
    #[inline(always)]
    fn test<const AVX: bool>(&self, n: &Node, t_max: f32) -> ([f32; WIDTH], u32) {
        #[cfg(target_arch = "x86_64")]
        if AVX {
            // SAFETY: `AVX` is true only where the CPU has AVX (`avx_available`).
            return unsafe { self.test_avx(n, t_max) };
        }
        let mut entry = [0.0f32; WIDTH];
        let mut mask = 0;
        for g in 0..GROUPS {
            let t = |plane: usize, axis: usize| (n.b[plane][g] - self.o[axis]) * self.inv[axis];
            let near = t(self.near[0], 0)
                .max(t(self.near[1], 1))
                .max(t(self.near[2], 2).max(Vec4::ZERO));
            let far = t(self.far[0], 0)
                .min(t(self.far[1], 1))
                .min(t(self.far[2], 2).min(Vec4::splat(t_max)));
            entry[4 * g..4 * g + 4].copy_from_slice(&near.to_array());
            mask |= near.cmple(far).bitmask() << (4 * g);
        }
        (entry, mask)
    }

    /// [`BoxRay::test`] in one eight-lane group.
    ///
    /// # Safety
    /// The CPU must have AVX. Its intrinsics inline only into a caller compiled for AVX
    /// (`Accel`'s `*_avx` entry points), which this always-inlined body becomes part of.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn test_avx(&self, n: &Node, t_max: f32) -> ([f32; WIDTH], u32) {
        use std::arch::x86_64::*;
        // SAFETY: the CPU has AVX (the caller's contract). `Node` is 64-byte aligned and each
        // plane's eight floats are a 32-byte row of it, so the loads are aligned and inside
        // the node; `entry` holds eight floats.
        unsafe {
            let plane = |i: usize| _mm256_load_ps(n.b[i].as_ptr().cast::<f32>());
            let splat = |v: Vec4| _mm256_broadcast_ps(&__m128::from(v));
            let t = |p: usize, axis: usize| {
                _mm256_mul_ps(
                    _mm256_sub_ps(plane(p), splat(self.o[axis])),
                    splat(self.inv[axis]),
                )
            };
            let near = _mm256_max_ps(
                _mm256_max_ps(t(self.near[0], 0), t(self.near[1], 1)),
                _mm256_max_ps(t(self.near[2], 2), _mm256_setzero_ps()),
            );
            let far = _mm256_min_ps(
                _mm256_min_ps(t(self.far[0], 0), t(self.far[1], 1)),
                _mm256_min_ps(t(self.far[2], 2), _mm256_set1_ps(t_max)),
            );
            let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
            let mut entry = [0.0f32; WIDTH];
            _mm256_storeu_ps(entry.as_mut_ptr(), near);
            (entry, mask)
        }
    }
}

/// Whether this CPU runs [`BoxRay::test`]'s eight-lane form (AVX).
pub fn avx_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

#[derive(Debug, Clone, Default)]
pub struct Bvh8 {
    pub(super) nodes: Vec<Node>,
    pub(super) root: Option<Ref>,
}

/// Cost of testing one leaf of up to four primitives (one SIMD block), in units of one
/// node's box test, for [`Collapse`].
const LEAF_COST: f32 = 2.0;

/// Which nodes of a binary BVH become leaves: every binary leaf, and every subtree of at most
/// `max_leaf` primitives whose expected cost as one leaf, area × [`LEAF_COST`], is no more than
/// as a subtree, area × 1 (its node) + its children's costs (the surface area heuristic,
/// MacDonald & Booth 1990, with areas relative to the root). A block tests four triangles for
/// the price of one, so small subtrees collapse unless their children are much smaller than
/// they are (two distant walls of a room stay apart).
struct Collapse {
    leaf: Vec<bool>,
}

impl Collapse {
    fn new(bvh2: &Bvh2, max_leaf: u32) -> Self {
        let n = bvh2.nodes.len();
        let mut leaf = vec![false; n];
        let mut count = vec![0u32; n];
        let mut cost = vec![0f32; n];
        // Post-order without recursion: a node is finished once both children are.
        let mut stack = vec![(0usize, false)];
        while let Some((i, children_done)) = stack.pop() {
            let node = &bvh2.nodes[i];
            let area = node.aabb.half_area();
            if node.prim_count > 0 {
                leaf[i] = true;
                count[i] = node.prim_count;
                cost[i] = area * LEAF_COST * node.prim_count.div_ceil(4) as f32;
                continue;
            }
            let (l, r) = (node.first_index as usize, node.first_index as usize + 1);
            if !children_done {
                stack.extend([(i, true), (l, false), (r, false)]);
                continue;
            }
            count[i] = count[l] + count[r];
            let split = area + cost[l] + cost[r];
            let as_leaf = area * LEAF_COST;
            if count[i] <= max_leaf && as_leaf <= split {
                leaf[i] = true;
                cost[i] = as_leaf;
            } else {
                cost[i] = split;
            }
        }
        Collapse { leaf }
    }

    fn is_leaf(&self, i: usize) -> bool {
        self.leaf[i]
    }
}

/// The primitives (indices into the binary BVH's input) of the subtree at node `i`.
fn collect_prims(bvh2: &Bvh2, i: usize, out: &mut Vec<u32>) {
    let node = &bvh2.nodes[i];
    if node.prim_count > 0 {
        let first = node.first_index as usize;
        out.extend_from_slice(&bvh2.primitive_indices[first..first + node.prim_count as usize]);
    } else {
        collect_prims(bvh2, node.first_index as usize, out);
        collect_prims(bvh2, node.first_index as usize + 1, out);
    }
}

/// What a leaf callback tells the traversal.
pub enum Visit {
    Continue,
    Stop,
}

impl Bvh8 {
    /// Inner nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Collapses a binary BVH of one primitive per leaf into eight-wide nodes. A subtree of at
    /// most `max_leaf` primitives becomes one leaf where the surface area heuristic prefers
    /// it (see [`Collapse`]); `leaf` appends a leaf's primitives (indices into the binary
    /// BVH's input) to the caller's storage and returns the range of blocks they take.
    /// Subtrees deeper than the traversal stack holds are first rebuilt balanced
    /// ([`depth::bound_depth`]), so no input can overflow it.
    pub fn from_bvh2(
        bvh2: &mut Bvh2,
        max_leaf: u32,
        mut leaf: impl FnMut(&[u32]) -> (u32, u32),
    ) -> Bvh8 {
        let mut out = Bvh8::default();
        depth::bound_depth(bvh2, depth::MAX_DEPTH);
        let bvh2 = &*bvh2;
        if !bvh2.nodes.is_empty() {
            let collapse = Collapse::new(bvh2, max_leaf);
            let root = out.convert(bvh2, &collapse, 0, &mut leaf, &mut Vec::new());
            out.root = Some(root);
        }
        out
    }

    fn convert(
        &mut self,
        bvh2: &Bvh2,
        collapse: &Collapse,
        i: usize,
        leaf: &mut impl FnMut(&[u32]) -> (u32, u32),
        prims: &mut Vec<u32>,
    ) -> Ref {
        if collapse.is_leaf(i) {
            prims.clear();
            collect_prims(bvh2, i, prims);
            let (first, count) = leaf(prims);
            return Ref::leaf(first, count);
        }
        // Open the largest inner children until there are eight.
        let first = bvh2.nodes[i].first_index as usize;
        let mut kids = vec![first, first + 1];
        while kids.len() < WIDTH {
            let area = |k: usize| bvh2.nodes[k].aabb.half_area();
            let Some(pos) = (0..kids.len())
                .filter(|&p| !collapse.is_leaf(kids[p]))
                .max_by(|&a, &b| area(kids[a]).total_cmp(&area(kids[b])))
            else {
                break;
            };
            let k = kids.swap_remove(pos);
            let first = bvh2.nodes[k].first_index as usize;
            kids.extend([first, first + 1]);
        }
        let index = self.nodes.len();
        let empty = Aabb::empty();
        self.nodes.push(Node {
            b: [[Vec4::ZERO; GROUPS]; 6],
            child: [Ref(0); WIDTH],
            len: kids.len() as u32,
        });
        let mut node = self.nodes[index];
        for slot in 0..WIDTH {
            let aabb = kids.get(slot).map_or(empty, |&k| bvh2.nodes[k].aabb);
            for axis in 0..3 {
                node.b[axis][slot / 4][slot % 4] = aabb.min[axis];
                node.b[axis + 3][slot / 4][slot % 4] = aabb.max[axis];
            }
            if let Some(&k) = kids.get(slot) {
                node.child[slot] = self.convert(bvh2, collapse, k, leaf, prims);
            }
        }
        self.nodes[index] = node;
        Ref(index as u32)
    }

    /// Visits the leaves the ray may hit within [0, t_max], nearest first. `leaf` gets a block
    /// range and may lower `t_max`; it returns [`Visit::Stop`] to end the traversal.
    #[inline(always)]
    pub fn closest<const AVX: bool>(
        &self,
        ray: &BoxRay,
        t_max: &mut f32,
        leaf: impl FnMut(u32, u32, &mut f32) -> Visit,
    ) {
        if let Some(root) = self.root {
            self.closest_from::<AVX>(root, ray, t_max, leaf);
        }
    }

    /// [`Bvh8::closest`] in the subtree at `root`.
    #[inline(always)]
    pub(super) fn closest_from<const AVX: bool>(
        &self,
        root: Ref,
        ray: &BoxRay,
        t_max: &mut f32,
        mut leaf: impl FnMut(u32, u32, &mut f32) -> Visit,
    ) {
        // Left uninitialised: zeroing it would cost more than a whole traversal of a small
        // scene.
        let mut stack = [MaybeUninit::<(Ref, f32)>::uninit(); STACK];
        let mut top = 0usize;
        let mut cur = root;
        loop {
            if cur.is_leaf() {
                let (first, count) = cur.blocks();
                if let Visit::Stop = leaf(first, count, t_max) {
                    return;
                }
            } else {
                let node = &self.nodes[cur.0 as usize];
                let (t, mask) = ray.test::<AVX>(node, *t_max);
                if mask != 0 {
                    let a = mask.trailing_zeros() as usize;
                    let rest = mask & (mask - 1);
                    if rest == 0 {
                        cur = node.child[a];
                        continue;
                    }
                    let b = rest.trailing_zeros() as usize;
                    if rest & (rest - 1) == 0 {
                        // Two children (the common case): push the farther, visit the nearer.
                        let (near, far) = if t[a] <= t[b] { (a, b) } else { (b, a) };
                        stack[top].write((node.child[far], t[far]));
                        top += 1;
                        cur = node.child[near];
                        continue;
                    }
                    // Three or more: insert them onto the stack sorted by entry distance,
                    // nearest on top, and take the nearest.
                    let base = top;
                    let mut m = mask;
                    while m != 0 {
                        let slot = m.trailing_zeros() as usize;
                        m &= m - 1;
                        let d = t[slot];
                        let mut j = top;
                        // SAFETY: entries from `base` to `top` were written in this loop.
                        while j > base && unsafe { stack[j - 1].assume_init().1 } < d {
                            stack[j] = stack[j - 1];
                            j -= 1;
                        }
                        stack[j].write((node.child[slot], d));
                        top += 1;
                    }
                    top -= 1;
                    // SAFETY: written just above.
                    cur = unsafe { stack[top].assume_init().0 };
                    continue;
                }
            }
            // Pop the next child still in front of the closest hit.
            loop {
                if top == 0 {
                    return;
                }
                top -= 1;
                // SAFETY: entries below `top` were written above.
                let (c, d) = unsafe { stack[top].assume_init() };
                if d <= *t_max {
                    cur = c;
                    break;
                }
            }
        }
    }

    /// Visits the leaves the ray may hit within [0, t_max], in any order, until `leaf`
    /// returns true.
    #[inline(always)]
    pub fn any<const AVX: bool>(
        &self,
        ray: &BoxRay,
        t_max: f32,
        leaf: impl FnMut(u32, u32) -> bool,
    ) -> bool {
        self.root
            .is_some_and(|root| self.any_from::<AVX>(root, ray, t_max, leaf))
    }

    /// [`Bvh8::any`] in the subtree at `root`.
    #[inline(always)]
    pub(super) fn any_from<const AVX: bool>(
        &self,
        root: Ref,
        ray: &BoxRay,
        t_max: f32,
        mut leaf: impl FnMut(u32, u32) -> bool,
    ) -> bool {
        let mut stack = [MaybeUninit::<Ref>::uninit(); STACK];
        let mut top = 0usize;
        let mut cur = root;
        loop {
            if cur.is_leaf() {
                let (first, count) = cur.blocks();
                if leaf(first, count) {
                    return true;
                }
            } else {
                let node = &self.nodes[cur.0 as usize];
                let (_, mut mask) = ray.test::<AVX>(node, t_max);
                if mask != 0 {
                    let slot = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    cur = node.child[slot];
                    while mask != 0 {
                        stack[top].write(node.child[mask.trailing_zeros() as usize]);
                        top += 1;
                        mask &= mask - 1;
                    }
                    continue;
                }
            }
            if top == 0 {
                return false;
            }
            top -= 1;
            // SAFETY: entries below `top` were written above.
            cur = unsafe { stack[top].assume_init() };
        }
    }
}
