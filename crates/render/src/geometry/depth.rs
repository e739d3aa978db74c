//! A binary BVH's depth, bounded for any input. Traversal keeps its pending children on a
//! fixed stack (no allocation per ray), which holds a bounded number of levels; a builder
//! given many coincident, degenerate or nested primitives can make chains far deeper than a
//! balanced tree. Subtrees that make the tree too deep are rebuilt balanced (object median
//! on the widest axis of their leaves' centres), deep enough in the tree that a good build
//! elsewhere is kept, high enough that the rebuilt subtree fits: at a node at depth d, a
//! balanced subtree of n leaves takes ⌈log₂ n⌉ levels, and the root's n < 2³² always fits.

use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;

/// Deepest binary BVH the eight-wide traversal stacks are sized for: each eight-wide level
/// takes at least one binary level and pushes at most seven children.
pub const MAX_DEPTH: u32 = 64;

/// Levels of a balanced binary tree over `n` leaves.
fn balanced_height(n: u32) -> u32 {
    n.max(1).next_power_of_two().trailing_zeros()
}

/// Rebuilds as few subtrees of `bvh2` as it takes for its depth (edges from the root to the
/// deepest leaf) to be at most `max_depth` (≥ 32). Returns how many subtrees were rebuilt.
pub fn bound_depth(bvh2: &mut Bvh2, max_depth: u32) -> usize {
    assert!(
        max_depth >= 32,
        "a depth bound below 32 cannot hold 2³² leaves"
    );
    if bvh2.nodes.is_empty() {
        return 0;
    }
    let (height, leaves) = heights(bvh2);
    if height[0] <= max_depth {
        return 0;
    }
    let mut rebuilt = 0;
    let mut stack = vec![(0usize, 0u32)];
    while let Some((i, d)) = stack.pop() {
        let first = bvh2.nodes[i].first_index as usize;
        let deep: Vec<usize> = [first, first + 1]
            .into_iter()
            .filter(|&c| d + 1 + height[c] > max_depth)
            .collect();
        // Descend only where each too-deep child could still be rebuilt in place.
        if deep
            .iter()
            .all(|&c| d + 1 + balanced_height(leaves[c]) <= max_depth)
        {
            stack.extend(deep.into_iter().map(|c| (c, d + 1)));
        } else {
            rebuild(bvh2, i);
            rebuilt += 1;
        }
    }
    // The optional maps obvhs keeps no longer describe the tree.
    bvh2.parents.clear();
    bvh2.primitives_to_nodes.clear();
    bvh2.children_are_ordered_after_parents = false;
    rebuilt
}

/// Each node's height (0 for a leaf) and leaf count, for the nodes reached from the root.
fn heights(bvh2: &Bvh2) -> (Vec<u32>, Vec<u32>) {
    let n = bvh2.nodes.len();
    let (mut height, mut leaves) = (vec![0u32; n], vec![0u32; n]);
    let mut stack = vec![(0usize, false)];
    while let Some((i, children_done)) = stack.pop() {
        let node = &bvh2.nodes[i];
        if node.prim_count > 0 {
            leaves[i] = 1;
            continue;
        }
        let (l, r) = (node.first_index as usize, node.first_index as usize + 1);
        if !children_done {
            stack.extend([(i, true), (l, false), (r, false)]);
            continue;
        }
        height[i] = 1 + height[l].max(height[r]);
        leaves[i] = leaves[l].saturating_add(leaves[r]);
    }
    (height, leaves)
}

/// Replaces the subtree at inner node `i` by a balanced one over the same leaves. The old
/// nodes stay in the array, unreachable; the new ones are appended in sibling pairs.
fn rebuild(bvh2: &mut Bvh2, i: usize) {
    let mut leaves = Vec::new();
    let mut stack = vec![i];
    while let Some(k) = stack.pop() {
        let node = bvh2.nodes[k];
        if node.prim_count > 0 {
            leaves.push(node);
        } else {
            stack.extend([node.first_index as usize, node.first_index as usize + 1]);
        }
    }
    bvh2.nodes[i] = balanced(&mut leaves, &mut bvh2.nodes);
}

/// A balanced tree over `leaves` (at least one), its nodes appended to `nodes`; returns its
/// root. Recursion depth is the tree's height, ⌈log₂ n⌉.
fn balanced(leaves: &mut [Bvh2Node], nodes: &mut Vec<Bvh2Node>) -> Bvh2Node {
    if let [leaf] = leaves {
        return *leaf;
    }
    let mut centres = Aabb::empty();
    for l in leaves.iter() {
        centres.extend(l.aabb.center());
    }
    let axis = centres.largest_axis();
    let mid = leaves.len() / 2;
    leaves.select_nth_unstable_by(mid, |a, b| {
        a.aabb
            .center_axis(axis)
            .total_cmp(&b.aabb.center_axis(axis))
    });
    let pair = nodes.len();
    nodes.extend([leaves[0], leaves[0]]);
    let (lo, hi) = leaves.split_at_mut(mid);
    let (left, right) = (balanced(lo, nodes), balanced(hi, nodes));
    nodes[pair] = left;
    nodes[pair + 1] = right;
    Bvh2Node::new(left.aabb.union(&right.aabb), 0, pair as u32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

    /// A chain: each inner node has one leaf and one inner child, `n` leaves in all.
    fn chain(n: u32) -> Bvh2 {
        let mut bvh2 = Bvh2::default();
        let unit = Aabb::new(Vec3A::ZERO, Vec3A::ONE);
        bvh2.nodes.push(Bvh2Node::new(unit, 0, 1));
        for k in 0..n - 1 {
            let pair = bvh2.nodes.len() as u32;
            bvh2.nodes.push(Bvh2Node::new(unit, 1, k));
            if k + 2 == n {
                bvh2.nodes.push(Bvh2Node::new(unit, 1, k + 1));
            } else {
                bvh2.nodes.push(Bvh2Node::new(unit, 0, pair + 2));
            }
        }
        bvh2.primitive_indices = (0..n).collect();
        bvh2
    }

    fn leaf_prims(bvh2: &Bvh2) -> Vec<u32> {
        let mut out = Vec::new();
        let mut stack = vec![0usize];
        while let Some(k) = stack.pop() {
            let node = bvh2.nodes[k];
            if node.prim_count > 0 {
                out.push(bvh2.primitive_indices[node.first_index as usize]);
            } else {
                stack.extend([node.first_index as usize, node.first_index as usize + 1]);
            }
        }
        out.sort_unstable();
        out
    }

    #[test]
    fn a_chain_is_rebuilt_within_the_bound_keeping_every_leaf() {
        for n in [2u32, 65, 66, 2000, 100_000] {
            let mut bvh2 = chain(n);
            assert_eq!(heights(&bvh2).0[0], n - 1);
            let rebuilt = bound_depth(&mut bvh2, MAX_DEPTH);
            assert_eq!(rebuilt > 0, n - 1 > MAX_DEPTH, "n = {n}");
            assert!(heights(&bvh2).0[0] <= MAX_DEPTH, "n = {n}");
            assert_eq!(leaf_prims(&bvh2), (0..n).collect::<Vec<_>>(), "n = {n}");
        }
    }

    #[test]
    fn a_deep_chain_under_a_good_tree_is_rebuilt_where_it_hangs() {
        // Root: a leaf and the chain; the chain is rebuilt one level down, the leaf kept.
        let mut bvh2 = chain(3000);
        let unit = Aabb::new(Vec3A::ZERO, Vec3A::ONE);
        let root = bvh2.nodes[0];
        let pair = bvh2.nodes.len() as u32;
        bvh2.nodes.push(Bvh2Node::new(unit, 1, 3000));
        bvh2.nodes.push(root);
        bvh2.primitive_indices.push(3000);
        bvh2.nodes[0] = Bvh2Node::new(unit, 0, pair);
        assert_eq!(bound_depth(&mut bvh2, MAX_DEPTH), 1);
        assert_eq!(bvh2.nodes[0].first_index, pair, "the root is kept");
        assert!(heights(&bvh2).0[0] <= MAX_DEPTH);
        assert_eq!(leaf_prims(&bvh2), (0..3001).collect::<Vec<_>>());
    }
}
