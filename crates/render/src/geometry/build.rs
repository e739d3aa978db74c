//! The binary BVH the eight-wide one is collapsed from: top-down, one primitive per leaf,
//! each node split where the surface area heuristic over binned centroids puts it (Wald,
//! "On fast Construction of SAH-based Bounding Volume Hierarchies", 2007; 16 bins on each
//! axis).
//!
//! Its cost is bounded for any input: a level touches each primitive once, splits deeper
//! than [`SAH_LEVELS`] are object medians, and primitives whose centres coincide (copies,
//! shells nested around one point) are split at the median of their areas, so the build is
//! O(n log n) however the primitives lie. (A bottom-up builder merging nearest neighbours
//! degenerates on such input: with every centre alike, a pass merges a pair or two.)

use glam::Vec3A;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;

/// Bins per axis.
const BINS: usize = 16;
/// Nodes of at most this many primitives are split by a full sweep over their sorted
/// centres instead of bins (exact SAH where coarse bins cost most, near the leaves).
const SWEEP: usize = 256;
/// Levels split by the surface area heuristic; deeper ones split at the object median,
/// which bounds the depth (and the work) by this plus ⌈log₂ n⌉.
pub const SAH_LEVELS: u32 = 32;

/// A binary BVH over `bounds`, one primitive per leaf (`primitive_indices` maps leaves to
/// the input's indices).
pub fn build(bounds: &[Aabb]) -> Bvh2 {
    let mut bvh2 = Bvh2::default();
    if bounds.is_empty() {
        return bvh2;
    }
    let centres: Vec<Vec3A> = bounds.iter().map(Aabb::center).collect();
    let mut prims: Vec<u32> = (0..bounds.len() as u32).collect();
    let mut nodes = vec![Bvh2Node::new(Aabb::empty(), 0, 0)];
    // (node, range of `prims`, depth)
    let mut work = vec![(0usize, 0usize, prims.len(), 0u32)];
    while let Some((node, start, end, depth)) = work.pop() {
        let range = &mut prims[start..end];
        if let [p] = range {
            nodes[node] = Bvh2Node::new(bounds[*p as usize], 1, start as u32);
            continue;
        }
        let mut aabb = Aabb::empty();
        let mut spread = Aabb::empty();
        for &p in range.iter() {
            aabb = aabb.union(&bounds[p as usize]);
            spread.extend(centres[p as usize]);
        }
        let mid = split(range, bounds, &centres, &spread, depth);
        let pair = nodes.len();
        nodes.push(Bvh2Node::new(Aabb::empty(), 0, 0));
        nodes.push(Bvh2Node::new(Aabb::empty(), 0, 0));
        nodes[node] = Bvh2Node::new(aabb, 0, pair as u32);
        work.push((pair, start, start + mid, depth + 1));
        work.push((pair + 1, start + mid, end, depth + 1));
    }
    bvh2.nodes = nodes;
    bvh2.primitive_indices = prims;
    bvh2
}

/// Reorders `range` (at least two primitives) into two non-empty halves and returns where
/// the second begins: by binned SAH near the root, else at the object median of the widest
/// axis of the centres, or of the areas where the centres coincide.
fn split(
    range: &mut [u32],
    bounds: &[Aabb],
    centres: &[Vec3A],
    spread: &Aabb,
    depth: u32,
) -> usize {
    let extent = spread.max - spread.min;
    let axis = spread.largest_axis();
    let half = range.len() / 2;
    if extent[axis] <= 0.0 || !extent[axis].is_finite() {
        range.select_nth_unstable_by(half, |&a, &b| {
            bounds[a as usize]
                .half_area()
                .total_cmp(&bounds[b as usize].half_area())
        });
        return half;
    }
    if depth < SAH_LEVELS && range.len() <= SWEEP {
        return sweep(range, bounds, centres);
    }
    if depth < SAH_LEVELS
        && let Some((axis, plane)) = best_plane(range, bounds, centres, spread)
    {
        let bin = |p: u32| bin_of(centres[p as usize], spread, axis);
        let mut i = 0;
        for j in 0..range.len() {
            if bin(range[j]) < plane {
                range.swap(i, j);
                i += 1;
            }
        }
        if i > 0 && i < range.len() {
            return i;
        }
    }
    range.select_nth_unstable_by(half, |&a, &b| {
        centres[a as usize][axis].total_cmp(&centres[b as usize][axis])
    });
    half
}

/// The split of least SAH cost A_L·N_L + A_R·N_R over every position of the centres sorted
/// along each axis; reorders `range` along the best axis and returns the position.
fn sweep(range: &mut [u32], bounds: &[Aabb], centres: &[Vec3A]) -> usize {
    let n = range.len();
    let mut best = (f32::INFINITY, 0usize, n / 2);
    let mut order = range.to_vec();
    let mut right = vec![0f32; n];
    #[allow(clippy::needless_range_loop)] // `axis` picks a coordinate of each centre
    for axis in 0..3 {
        order.sort_by(|&a, &b| {
            centres[a as usize][axis]
                .total_cmp(&centres[b as usize][axis])
                .then(a.cmp(&b))
        });
        let mut acc = Aabb::empty();
        for i in (1..n).rev() {
            acc = acc.union(&bounds[order[i] as usize]);
            right[i] = acc.half_area() * (n - i) as f32;
        }
        let mut acc = Aabb::empty();
        for i in 1..n {
            acc = acc.union(&bounds[order[i - 1] as usize]);
            let cost = acc.half_area() * i as f32 + right[i];
            if cost < best.0 {
                best = (cost, axis, i);
            }
        }
    }
    let (_, axis, at) = best;
    range.sort_by(|&a, &b| {
        centres[a as usize][axis]
            .total_cmp(&centres[b as usize][axis])
            .then(a.cmp(&b))
    });
    at
}

/// The bin of a centre along `axis`, 0..BINS.
fn bin_of(c: Vec3A, spread: &Aabb, axis: usize) -> usize {
    let lo = spread.min[axis];
    let width = spread.max[axis] - lo;
    if width <= 0.0 {
        return 0;
    }
    (((c[axis] - lo) / width * BINS as f32) as usize).min(BINS - 1)
}

/// The axis and bin boundary (1..BINS, bins below it go left) of least SAH cost
/// A_L·N_L + A_R·N_R, over the axes the centres spread along.
fn best_plane(
    range: &[u32],
    bounds: &[Aabb],
    centres: &[Vec3A],
    spread: &Aabb,
) -> Option<(usize, usize)> {
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        if spread.max[axis] - spread.min[axis] <= 0.0 {
            continue;
        }
        let mut count = [0u32; BINS];
        let mut boxes = [Aabb::empty(); BINS];
        for &p in range {
            let b = bin_of(centres[p as usize], spread, axis);
            count[b] += 1;
            boxes[b] = boxes[b].union(&bounds[p as usize]);
        }
        // Right-to-left sweep: the cost of everything from bin k up.
        let mut right = [0f32; BINS];
        let (mut acc, mut n) = (Aabb::empty(), 0u32);
        for k in (1..BINS).rev() {
            acc = acc.union(&boxes[k]);
            n += count[k];
            right[k] = if n > 0 {
                acc.half_area() * n as f32
            } else {
                0.0
            };
        }
        let (mut acc, mut n) = (Aabb::empty(), 0u32);
        for k in 1..BINS {
            acc = acc.union(&boxes[k - 1]);
            n += count[k - 1];
            if n == 0 || n as usize == range.len() {
                continue;
            }
            let cost = acc.half_area() * n as f32 + right[k];
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, k));
            }
        }
    }
    best.map(|(_, axis, plane)| (axis, plane))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leaves(bvh2: &Bvh2) -> Vec<u32> {
        let mut out = Vec::new();
        let mut stack = vec![0usize];
        while let Some(k) = stack.pop() {
            let node = bvh2.nodes[k];
            if node.prim_count > 0 {
                assert_eq!(node.prim_count, 1);
                out.push(bvh2.primitive_indices[node.first_index as usize]);
            } else {
                for c in [node.first_index as usize, node.first_index as usize + 1] {
                    let child = bvh2.nodes[c].aabb;
                    assert!(
                        node.aabb.min.cmple(child.min).all()
                            && node.aabb.max.cmpge(child.max).all(),
                        "a child's box inside its parent's"
                    );
                }
                stack.extend([node.first_index as usize, node.first_index as usize + 1]);
            }
        }
        out.sort_unstable();
        out
    }

    #[test]
    fn every_primitive_is_one_leaf_whatever_the_input() {
        let unit = |x: f32| Aabb::new(Vec3A::new(x, 0.0, 0.0), Vec3A::new(x + 1.0, 1.0, 1.0));
        let cases: Vec<Vec<Aabb>> = vec![
            vec![unit(0.0)],
            (0..1000).map(|i| unit(i as f32)).collect(),
            vec![unit(0.0); 1000],
            (0..1000)
                .map(|i| {
                    let s = 1.0 + i as f32;
                    Aabb::new(Vec3A::splat(-s), Vec3A::splat(s))
                })
                .collect(),
            (0..1000).map(|i| unit(2f32.powi(i % 100))).collect(),
        ];
        for bounds in cases {
            let bvh2 = build(&bounds);
            assert_eq!(leaves(&bvh2), (0..bounds.len() as u32).collect::<Vec<_>>());
        }
    }
}
