//! A balanced kd-tree of points (photons, radiance photons) in one array (Jensen 2001, §6.3):
//! each subarray's median on its widest axis is its root, the halves on either side are the
//! subtrees. Built once from the points in index order, so the tree — and every search — is a
//! pure function of its input.
//!
//! Our own rather than kiddo: the search is flattened toward a disc along the query's surface
//! normal (the distance is |Δ|² + f·(Δ·n)², so photons on a wall around a corner do not leak
//! into the floor's estimate), a metric that depends on the query, which kiddo's fixed
//! per-type distance metrics cannot express. Leaves of up to [`LEAF`] points are scanned in
//! index order, four at a time, and the positions sit in their own arrays, one per axis (12
//! bytes read per point), which keeps it faster than kiddo's immutable tree on plain
//! Euclidean queries
//! (`cargo bench -p tessera-render --bench knn` compares them; figures in docs/src/benchmarks/rays.md).

use glam::{Vec3, Vec3A, Vec4};

/// Most photons one search may return (the candidates live on the stack).
pub const MAX_K: usize = 1024;

/// A photon at rest on a surface.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[repr(C)]
pub struct Photon {
    pub p: Vec3,
    /// Power, W (RGB).
    pub power: Vec3,
    /// Unit direction toward where the photon came from.
    pub wi: Vec3,
    /// Unit surface normal at `p`, on the side the photon arrived from.
    pub n: Vec3,
    /// Material of the surface it rests on.
    pub material: u32,
}

/// Something with a position, for the tree.
pub trait Positioned {
    fn position(&self) -> Vec3;
}

impl Positioned for Photon {
    #[inline]
    fn position(&self) -> Vec3 {
        self.p
    }
}

/// Ranges of at most this many points are leaves: scanned in index order, not split.
const LEAF: usize = 32;

#[derive(Debug, Clone, PartialEq)]
pub struct KdTree<T = Photon> {
    photons: Vec<T>,
    /// Split axis of the subtree rooted at each index (0 within leaves).
    axes: Vec<u8>,
    /// The points' positions apart from the photons, so that a search reads only those: x,
    /// y and z in arrays of their own, so that a leaf's distances are computed four points
    /// at a time.
    xyz: [Vec<f32>; 3],
}

impl<T> Default for KdTree<T> {
    fn default() -> Self {
        KdTree {
            photons: Vec::new(),
            axes: Vec::new(),
            xyz: [Vec::new(), Vec::new(), Vec::new()],
        }
    }
}

impl<T: Positioned + Send> KdTree<T> {
    pub fn build(mut photons: Vec<T>) -> KdTree<T> {
        let mut axes = vec![0u8; photons.len()];
        balance(&mut photons, &mut axes);
        Self::with_points(photons, axes)
    }

    fn with_points(photons: Vec<T>, axes: Vec<u8>) -> KdTree<T> {
        let xyz = [0, 1, 2].map(|a| photons.iter().map(|p| p.position()[a]).collect());
        KdTree { photons, axes, xyz }
    }

    /// A tree from the arrays of [`Self::photons`] and [`Self::axes`] (as stored in an
    /// artifact); checked for shape, not balance.
    pub fn from_parts(photons: Vec<T>, axes: Vec<u8>) -> Result<KdTree<T>, String> {
        if photons.len() != axes.len() || axes.iter().any(|&a| a > 2) {
            return Err(format!(
                "a photon tree needs one split axis (0–2) per photon: {} photons, {} axes",
                photons.len(),
                axes.len()
            ));
        }
        Ok(Self::with_points(photons, axes))
    }

    pub fn axes(&self) -> &[u8] {
        &self.axes
    }

    pub fn len(&self) -> usize {
        self.photons.len()
    }

    pub fn is_empty(&self) -> bool {
        self.photons.is_empty()
    }

    pub fn photons(&self) -> &[T] {
        &self.photons
    }

    pub fn get(&self, i: u32) -> &T {
        &self.photons[i as usize]
    }

    /// Collects into `knn` the nearest photons to `p` under the distance
    /// |Δ|² + `flatten`·(Δ·`n`)² (Δ = photon − p; `n` unit), within `knn`'s radius.
    pub fn nearest<const N: usize>(&self, p: Vec3A, n: Vec3A, flatten: f32, knn: &mut Knn<N>) {
        self.visit(0, self.photons.len(), p, n, flatten, knn);
    }

    /// Calls `f(index, squared distance)` for every point within squared radius `r2` of `p`
    /// under the distance of [`KdTree::nearest`] (`flatten` 0: a ball), in a fixed (tree)
    /// order.
    pub fn within(&self, p: Vec3A, n: Vec3A, flatten: f32, r2: f32, f: &mut impl FnMut(u32, f32)) {
        self.visit(0, self.photons.len(), p, n, flatten, &mut Within { r2, f });
    }

    /// Offers `v` every point of [lo, hi) it accepts, nearest subtree first. The flattened
    /// distance is at least the Euclidean one, so a subtree beyond what `v` accepts along one
    /// axis cannot hold a point it would.
    fn visit(&self, lo: usize, hi: usize, q: Vec3A, n: Vec3A, flatten: f32, v: &mut impl Visit) {
        if hi - lo <= LEAF {
            self.scan(lo, hi, q, n, flatten, v);
            return;
        }
        let mid = (lo + hi) / 2;
        let p = self.point(mid);
        let axis = self.axes[mid] as usize;
        let delta = q[axis] - p[axis];
        let (near, far) = if delta < 0.0 {
            ((lo, mid), (mid + 1, hi))
        } else {
            ((mid + 1, hi), (lo, mid))
        };
        self.visit(near.0, near.1, q, n, flatten, v);
        let d2 = flattened_d2(p - q, n, flatten);
        if v.accepts(d2) {
            v.take(mid as u32, d2);
        }
        if v.accepts(delta * delta) {
            self.visit(far.0, far.1, q, n, flatten, v);
        }
    }
}

impl<T> KdTree<T> {
    fn point(&self, i: usize) -> Vec3A {
        Vec3A::new(self.xyz[0][i], self.xyz[1][i], self.xyz[2][i])
    }

    /// Offers `v` the points of the leaf [lo, hi) it accepts, in index order: distances four
    /// at a time (as [`flattened_d2`] computes them, operation for operation), those beyond
    /// what `v` accepts at the start of the four skipped (its radius only shrinks).
    fn scan(&self, lo: usize, hi: usize, q: Vec3A, n: Vec3A, flatten: f32, v: &mut impl Visit) {
        let [xs, ys, zs] = &self.xyz;
        let (qx, qy, qz) = (Vec4::splat(q.x), Vec4::splat(q.y), Vec4::splat(q.z));
        let (nx, ny, nz) = (Vec4::splat(n.x), Vec4::splat(n.y), Vec4::splat(n.z));
        let f = Vec4::splat(flatten);
        let mut i = lo;
        while i + 4 <= hi {
            let dx = Vec4::from_slice(&xs[i..i + 4]) - qx;
            let dy = Vec4::from_slice(&ys[i..i + 4]) - qy;
            let dz = Vec4::from_slice(&zs[i..i + 4]) - qz;
            let dn = dx * nx + dy * ny + dz * nz;
            let d2 = (dx * dx + dy * dy + dz * dz) + f * dn * dn;
            let mut near = d2.cmple(Vec4::splat(v.limit())).bitmask();
            if near != 0 {
                let d2 = d2.to_array();
                while near != 0 {
                    let lane = near.trailing_zeros() as usize;
                    near &= near - 1;
                    if v.accepts(d2[lane]) {
                        v.take((i + lane) as u32, d2[lane]);
                    }
                }
            }
            i += 4;
        }
        for j in i..hi {
            let d2 = flattened_d2(self.point(j) - q, n, flatten);
            if v.accepts(d2) {
                v.take(j as u32, d2);
            }
        }
    }
}

/// What a tree search does with the points it meets.
trait Visit {
    /// Whether a point at squared distance `d2` is wanted (the radius may shrink as points
    /// are taken).
    fn accepts(&self, d2: f32) -> bool;
    /// A squared distance at or beyond every one it accepts now.
    fn limit(&self) -> f32;
    fn take(&mut self, i: u32, d2: f32);
}

/// Every point within a fixed squared radius.
struct Within<'a, F> {
    r2: f32,
    f: &'a mut F,
}

impl<F: FnMut(u32, f32)> Visit for Within<'_, F> {
    fn accepts(&self, d2: f32) -> bool {
        d2 <= self.r2
    }

    fn limit(&self) -> f32 {
        self.r2
    }

    fn take(&mut self, i: u32, d2: f32) {
        (self.f)(i, d2)
    }
}

impl<const N: usize> Visit for Knn<N> {
    fn accepts(&self, d2: f32) -> bool {
        d2 < self.max_d2
    }

    fn limit(&self) -> f32 {
        self.max_d2
    }

    fn take(&mut self, i: u32, d2: f32) {
        self.insert(d2, i)
    }
}

/// Puts the median of `photons` on its widest axis at the middle, smaller ones before and
/// larger after, recursively, down to leaves of at most [`LEAF`] points.
fn balance<T: Positioned + Send>(photons: &mut [T], axes: &mut [u8]) {
    if photons.len() <= LEAF {
        return;
    }
    let (lo, hi) = photons.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), ph| (lo.min(ph.position()), hi.max(ph.position())),
    );
    let extent = hi - lo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = photons.len() / 2;
    photons.select_nth_unstable_by(mid, |a, b| {
        a.position()[axis].total_cmp(&b.position()[axis])
    });
    axes[mid] = axis as u8;
    let (left, rest) = photons.split_at_mut(mid);
    let (left_axes, rest_axes) = axes.split_at_mut(mid);
    let (right, right_axes) = (&mut rest[1..], &mut rest_axes[1..]);
    if left.len() >= PARALLEL {
        rayon::join(|| balance(left, left_axes), || balance(right, right_axes));
    } else {
        balance(left, left_axes);
        balance(right, right_axes);
    }
}

/// Subarrays of at least this many points balance their halves on the rayon pool (the tree
/// is the same: each half's order depends on that half alone).
const PARALLEL: usize = 8192;

/// The k nearest photons found so far: a max-heap on distance once full, its top the radius.
/// Its capacity `N` is the most `k` it serves, kept on the stack (and cleared per search, so
/// small searches use a small `N`).
pub struct Knn<const N: usize = MAX_K> {
    items: [(f32, u32); N],
    len: usize,
    k: usize,
    /// Squared search radius: the initial limit until k are found, then the k-th distance —
    /// the disc a density estimate divides by.
    pub max_d2: f32,
}

impl<const N: usize> Knn<N> {
    /// A search for the `k` (≤ `N`) nearest within squared radius `max_d2`.
    pub fn new(k: usize, max_d2: f32) -> Self {
        Knn {
            items: [(0.0, 0); N],
            len: 0,
            k: k.clamp(1, N),
            max_d2,
        }
    }

    /// (squared distance, photon index) of what was found, in a deterministic order.
    pub fn found(&self) -> &[(f32, u32)] {
        &self.items[..self.len]
    }

    /// Whether k photons were found (the radius is the k-th distance).
    pub fn is_full(&self) -> bool {
        self.len == self.k
    }

    fn insert(&mut self, d2: f32, i: u32) {
        if self.len < self.k {
            self.items[self.len] = (d2, i);
            self.len += 1;
            if self.len == self.k {
                for j in (0..self.k / 2).rev() {
                    self.sift_down(j);
                }
                self.max_d2 = self.items[0].0;
            }
        } else {
            self.items[0] = (d2, i);
            self.sift_down(0);
            self.max_d2 = self.items[0].0;
        }
    }

    /// Moves the item at `j` down to where both its children are no farther: the larger
    /// child rises into the hole while it is farther than the item (the same heap as
    /// swapping level by level, with one write a level).
    fn sift_down(&mut self, mut j: usize) {
        let n = self.len;
        let item = self.items[j];
        loop {
            let l = 2 * j + 1;
            if l >= n {
                break;
            }
            let r = l + 1;
            let c = if r < n && self.items[r].0 > self.items[l].0 {
                r
            } else {
                l
            };
            if self.items[c].0 <= item.0 {
                break;
            }
            self.items[j] = self.items[c];
            j = c;
        }
        self.items[j] = item;
    }
}

/// |d|² + `flatten`·(d·`n`)²: the squared distance of a photon `d` away, the sphere squeezed
/// into a disc along the surface of normal `n` (Jensen 2001 §7.1).
#[inline]
fn flattened_d2(d: Vec3A, n: Vec3A, flatten: f32) -> f32 {
    let dn = d.dot(n);
    d.length_squared() + flatten * dn * dn
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::hash::{hash, u32_to_unit};

    fn random_photons(n: usize) -> Vec<Photon> {
        (0..n)
            .map(|i| {
                let h = hash(&[i as u64, 7]);
                let c = |s: u32| u32_to_unit((h >> s) as u32);
                Photon {
                    p: Vec3::new(c(0), c(21), c(42) * 0.2),
                    power: Vec3::ONE,
                    wi: Vec3::Z,
                    n: Vec3::Z,
                    material: 0,
                }
            })
            .collect()
    }

    /// Every split point has the points of its subarray's first half at or below it on its
    /// axis and those of the second half at or above.
    fn assert_balanced(tree: &KdTree, lo: usize, hi: usize) {
        if hi - lo <= LEAF {
            return;
        }
        let mid = (lo + hi) / 2;
        let axis = tree.axes[mid] as usize;
        let split = tree.point(mid)[axis];
        assert!((lo..mid).all(|i| tree.point(i)[axis] <= split));
        assert!((mid + 1..hi).all(|i| tree.point(i)[axis] >= split));
        assert_balanced(tree, lo, mid);
        assert_balanced(tree, mid + 1, hi);
    }

    #[test]
    fn nearest_matches_brute_force_with_and_without_flattening() {
        // Enough points that the build balances subarrays on the rayon pool.
        let photons = random_photons(5 * PARALLEL);
        let tree = KdTree::build(photons.clone());
        assert_balanced(&tree, 0, photons.len());
        for (qi, flatten) in [(0u64, 0.0f32), (1, 0.0), (2, 24.0), (3, 24.0), (4, 3.0)] {
            let h = hash(&[qi, 99]);
            let q = Vec3A::new(u32_to_unit(h as u32), u32_to_unit((h >> 32) as u32), 0.1);
            let n = Vec3A::new(0.3, -0.2, 1.0).normalize();
            let dist = |ph: &Photon| {
                let d = Vec3A::from(ph.p) - q;
                d.length_squared() + flatten * d.dot(n) * d.dot(n)
            };
            for (k, r2) in [(1usize, 1.0f32), (50, 1.0), (50, 0.001), (700, 0.05)] {
                let mut knn = Knn::<MAX_K>::new(k, r2);
                tree.nearest(q, n, flatten, &mut knn);
                let mut got: Vec<f32> = knn
                    .found()
                    .iter()
                    .map(|&(d2, i)| {
                        assert_eq!(d2, dist(tree.get(i)));
                        d2
                    })
                    .collect();
                got.sort_by(f32::total_cmp);
                let mut want: Vec<f32> = photons.iter().map(dist).filter(|&d| d < r2).collect();
                want.sort_by(f32::total_cmp);
                want.truncate(k);
                assert_eq!(got, want, "k {k} r² {r2} flatten {flatten}");
                assert_eq!(knn.is_full(), want.len() == k);
            }
        }
    }

    #[test]
    fn within_finds_exactly_the_points_in_the_ball() {
        let photons = random_photons(3000);
        let tree = KdTree::build(photons.clone());
        let q = Vec3A::new(0.4, 0.6, 0.1);
        for r2 in [0.0001f32, 0.01, 0.2] {
            let mut got = Vec::new();
            tree.within(q, Vec3A::Z, 0.0, r2, &mut |i, d2| {
                got.push((d2, tree.get(i).p.to_array()))
            });
            let mut want: Vec<f32> = photons
                .iter()
                .map(|p| (Vec3A::from(p.p) - q).length_squared())
                .filter(|&d| d <= r2)
                .collect();
            let mut got_d: Vec<f32> = got.iter().map(|g| g.0).collect();
            got_d.sort_by(f32::total_cmp);
            want.sort_by(f32::total_cmp);
            assert_eq!(got_d, want);
        }
    }

    #[test]
    fn an_empty_tree_finds_nothing() {
        let tree: KdTree = KdTree::build(Vec::new());
        let mut knn = Knn::<16>::new(10, 1.0);
        tree.nearest(Vec3A::ZERO, Vec3A::Z, 0.0, &mut knn);
        assert!(knn.found().is_empty());
    }
}
