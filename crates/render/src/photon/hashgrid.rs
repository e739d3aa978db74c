//! A uniform grid hashed into a table, for searches of one fixed radius r (Teschner et al.
//! 2003; the range query of SmallVCM): cells of side 2r, so a ball of radius r touches at most
//! the 2×2×2 cells nearest its centre. Points are sorted by bucket (a counting sort, O(n)),
//! positions in their own array. Built in index order, so every search is a pure function of
//! the input. VCM merges with it: a query finds a few light vertices among ~30 candidates,
//! where the kd-tree ([`super::kdtree`]) scans whole leaves of 32.

use glam::{IVec3, Vec3A};

use super::kdtree::Positioned;

pub struct HashGrid<T> {
    items: Vec<T>,
    points: Vec<Vec3A>,
    /// Bucket b holds `items[starts[b]..starts[b + 1]]`.
    starts: Vec<u32>,
    origin: Vec3A,
    inv_cell: f32,
    mask: u32,
}

impl<T: Positioned + Copy> HashGrid<T> {
    /// The grid of `items` (read twice, in the same order) for searches within `radius` (> 0).
    pub fn build<'a>(items: impl Iterator<Item = &'a T> + Clone, radius: f32) -> Self
    where
        T: 'a,
    {
        let points: Vec<Vec3A> = items.clone().map(|t| t.position().into()).collect();
        let origin = points.iter().fold(Vec3A::INFINITY, |a, &p| a.min(p));
        let n = points.len();
        let buckets = n.next_power_of_two().max(1) as u32;
        let mut grid = HashGrid {
            items: Vec::new(),
            points: vec![Vec3A::ZERO; n],
            starts: vec![0; buckets as usize + 1],
            origin,
            inv_cell: 0.5 / radius,
            mask: buckets - 1,
        };
        let keys: Vec<u32> = points.iter().map(|&p| grid.bucket(grid.cell(p))).collect();
        for &k in &keys {
            grid.starts[k as usize + 1] += 1;
        }
        for b in 0..buckets as usize {
            grid.starts[b + 1] += grid.starts[b];
        }
        // Each item scattered to its place in bucket order.
        let mut next = grid.starts.clone();
        if let Some(&first) = items.clone().next() {
            grid.items = vec![first; n];
        }
        for ((&k, &p), item) in keys.iter().zip(&points).zip(items) {
            let at = next[k as usize] as usize;
            next[k as usize] += 1;
            grid.items[at] = *item;
            grid.points[at] = p;
        }
        grid
    }

    pub fn len(&self) -> usize {
        self.items.len()
    }

    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    fn cell(&self, p: Vec3A) -> IVec3 {
        ((p - self.origin) * self.inv_cell).floor().as_ivec3()
    }

    fn bucket(&self, c: IVec3) -> u32 {
        let h = (c.x as u32).wrapping_mul(73_856_093)
            ^ (c.y as u32).wrapping_mul(19_349_663)
            ^ (c.z as u32).wrapping_mul(83_492_791);
        h & self.mask
    }

    /// Calls `f` with every item within distance² `r2` of `q` (r2 at most the radius the grid
    /// was built for, squared), each once, in a fixed order.
    pub fn within(&self, q: Vec3A, r2: f32, f: &mut impl FnMut(&T)) {
        if self.items.is_empty() {
            return;
        }
        let c = (q - self.origin) * self.inv_cell;
        let lo = (c - 0.5).floor().as_ivec3();
        let mut seen = [u32::MAX; 8];
        for n in 0..8 {
            let cell = lo + IVec3::new(n as i32 & 1, (n as i32 >> 1) & 1, n as i32 >> 2);
            let b = self.bucket(cell);
            // Two cells may share a bucket: visit it once.
            if seen[..n].contains(&b) {
                continue;
            }
            seen[n] = b;
            let (a, e) = (self.starts[b as usize], self.starts[b as usize + 1]);
            for i in a as usize..e as usize {
                if (self.points[i] - q).length_squared() <= r2 {
                    f(&self.items[i]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[derive(Debug, Clone, Copy, PartialEq)]
    struct P(Vec3, u32);

    impl Positioned for P {
        fn position(&self) -> Vec3 {
            self.0
        }
    }

    #[test]
    fn within_finds_exactly_the_points_in_the_ball_once() {
        // A hashed lattice (deterministic), clustered on a plane and spread in a box.
        let mut s = 0x9e37_79b9_u32;
        let mut u = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as f32 / u32::MAX as f32
        };
        let pts: Vec<P> = (0..4000)
            .map(|i| {
                let y = if i % 2 == 0 { 0.25 } else { u() };
                P(Vec3::new(u() * 3.0 - 1.0, y, u()), i)
            })
            .collect();
        for r in [0.01f32, 0.05, 0.2] {
            let grid = HashGrid::build(pts.iter(), r);
            assert_eq!(grid.len(), pts.len());
            for q in 0..200 {
                let q = Vec3A::new(u() * 3.0 - 1.0, if q % 2 == 0 { 0.25 } else { u() }, u());
                let mut got = Vec::new();
                grid.within(q, r * r, &mut |p| got.push(p.1));
                got.sort_unstable();
                let want: Vec<u32> = pts
                    .iter()
                    .filter(|p| (Vec3A::from(p.0) - q).length_squared() <= r * r)
                    .map(|p| p.1)
                    .collect();
                assert_eq!(got, want, "r = {r}, q = {q}");
            }
        }
    }

    #[test]
    fn an_empty_grid_finds_nothing() {
        let grid = HashGrid::<P>::build([].iter(), 0.1);
        assert!(grid.is_empty());
        grid.within(Vec3A::ZERO, 1.0, &mut |_| panic!("nothing to find"));
    }
}
