//! Ward's irradiance cache (Ward, Rubinstein & Clear, "A Ray Tracing Solution for Diffuse
//! Interreflection", SIGGRAPH 1988).
//!
//! A record holds the indirect irradiance E at a point with its normal and R, the harmonic
//! mean distance to the surfaces its hemisphere rays hit. A record serves a point x with
//! normal n when its error weight
//!
//!   w(x, n) = 1 / ( |x − xᵢ| / Rᵢ + √(1 − n·nᵢ) )
//!
//! exceeds 1/a for the user's accuracy a, and the record is not in front of x; the estimate is
//! Σ wᵢEᵢ / Σ wᵢ over the records that serve. Records live in a loose octree: each sits in the
//! deepest node whose half-size is at least its validity radius a·Rᵢ, so a lookup visits only
//! the nodes whose loose bounds contain x.
//!
//! The cache is frozen (docs/src/design/overview.md: artifacts are frozen): it is built once from records made by a
//! pass, and lookups never add to it; a point no record serves is gathered on its own.

use glam::{Vec3, Vec3A};

use crate::spectrum::Spectrum;

/// One irradiance record.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[repr(C)]
pub struct Record {
    pub p: Vec3,
    /// Unit surface normal (the side the hemisphere was gathered on).
    pub n: Vec3,
    /// Indirect irradiance, W/m² (RGB).
    pub e: Vec3,
    /// Harmonic mean distance to the surfaces seen, clamped to the pass's range, scene units.
    pub r: f32,
}

impl Record {
    /// Whether every value is finite and the distance positive: what the octree and the
    /// weights need of a record.
    pub fn is_finite(&self) -> bool {
        self.p.is_finite()
            && self.n.is_finite()
            && self.e.is_finite()
            && self.r.is_finite()
            && self.r > 0.0
    }
}

/// Deepest octree level (a node's half-size is the root's / 2^depth).
const MAX_DEPTH: u32 = 20;

#[derive(Debug, Clone, PartialEq)]
struct Node {
    center: Vec3A,
    half: f32,
    /// Child node indices (0: none; the root is never a child).
    children: [u32; 8],
    records: Vec<u32>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct IrradianceCache {
    records: Vec<Record>,
    nodes: Vec<Node>,
    accuracy: f32,
}

/// Ward's weight of `rec` at (p, n), or `None` where the record must not serve: weight ≤ 1/a,
/// or the record lies in front of p (it cannot see what p sees).
#[inline]
fn weight(rec: &Record, p: Vec3A, n: Vec3A, inv_a: f32) -> Option<f32> {
    let rp = Vec3A::from(rec.p);
    let rn = Vec3A::from(rec.n);
    let d = p - rp;
    let cos = n.dot(rn);
    if cos <= 0.0 {
        return None;
    }
    // In front: the record's point is above the plane halfway between both normals.
    if d.dot(n + rn) * 0.5 < -0.05 * rec.r {
        return None;
    }
    let denom = d.length() / rec.r + (1.0 - cos).max(0.0).sqrt();
    if denom * inv_a >= 1.0 {
        return None;
    }
    Some(1.0 / denom.max(1e-6))
}

impl IrradianceCache {
    /// The cache of `records` (in the order given, which fixes every sum) for accuracy `a`.
    pub fn build(records: Vec<Record>, accuracy: f32) -> Self {
        let (lo, hi) = records.iter().fold(
            (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY)),
            |(lo, hi), r| (lo.min(r.p.into()), hi.max(r.p.into())),
        );
        let (center, half) = if lo.x <= hi.x {
            (
                0.5 * (lo + hi),
                (0.5 * (hi - lo).max_element()).max(1e-6) * 1.001,
            )
        } else {
            (Vec3A::ZERO, 1.0)
        };
        let mut nodes = vec![Node {
            center,
            half,
            children: [0; 8],
            records: Vec::new(),
        }];
        for (i, rec) in records.iter().enumerate() {
            let p = Vec3A::from(rec.p);
            let validity = accuracy * rec.r;
            let mut node = 0usize;
            let mut depth = 0;
            loop {
                let child_half = nodes[node].half * 0.5;
                if depth >= MAX_DEPTH || child_half < validity {
                    break;
                }
                let c = nodes[node].center;
                let octant = (p.x > c.x) as usize
                    | ((p.y > c.y) as usize) << 1
                    | ((p.z > c.z) as usize) << 2;
                if nodes[node].children[octant] == 0 {
                    let offset = Vec3A::new(
                        if octant & 1 != 0 {
                            child_half
                        } else {
                            -child_half
                        },
                        if octant & 2 != 0 {
                            child_half
                        } else {
                            -child_half
                        },
                        if octant & 4 != 0 {
                            child_half
                        } else {
                            -child_half
                        },
                    );
                    nodes.push(Node {
                        center: c + offset,
                        half: child_half,
                        children: [0; 8],
                        records: Vec::new(),
                    });
                    let id = (nodes.len() - 1) as u32;
                    nodes[node].children[octant] = id;
                }
                node = nodes[node].children[octant] as usize;
                depth += 1;
            }
            nodes[node].records.push(i as u32);
        }
        IrradianceCache {
            records,
            nodes,
            accuracy,
        }
    }

    pub fn records(&self) -> &[Record] {
        &self.records
    }

    pub fn accuracy(&self) -> f32 {
        self.accuracy
    }

    pub fn len(&self) -> usize {
        self.records.len()
    }

    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// Interpolated irradiance at `p` with unit normal `n`, if any record serves it.
    pub fn lookup(&self, p: Vec3A, n: Vec3A) -> Option<Spectrum> {
        let inv_a = 1.0 / self.accuracy;
        let mut sum = Spectrum::ZERO;
        let mut wsum = 0.0f32;
        // Explicit stack: at most 7 siblings pending per level.
        let mut stack = [0u32; 8 * MAX_DEPTH as usize + 8];
        let mut top = 1;
        stack[0] = 0;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            // Loose bounds: the node's cube grown by its half-size on every side.
            if ((p - node.center).abs().max_element()) > 2.0 * node.half {
                continue;
            }
            for &ri in &node.records {
                let rec = &self.records[ri as usize];
                if let Some(w) = weight(rec, p, n, inv_a) {
                    sum += Vec3A::from(rec.e) * w;
                    wsum += w;
                }
            }
            for &c in node.children.iter().rev() {
                if c != 0 {
                    stack[top] = c;
                    top += 1;
                }
            }
        }
        (wsum > 0.0).then(|| sum / wsum)
    }
}

/// Whether any of `records` serves (p, n) at accuracy `a` (for a record pass deciding where
/// a new record is needed; linear: a pass's own records are few).
pub fn served(records: &[Record], p: Vec3A, n: Vec3A, accuracy: f32) -> bool {
    let inv_a = 1.0 / accuracy;
    records.iter().any(|r| weight(r, p, n, inv_a).is_some())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::hash::{hash, u32_to_unit};

    fn rec(p: Vec3, n: Vec3, e: f32, r: f32) -> Record {
        Record {
            p,
            n,
            e: Vec3::splat(e),
            r,
        }
    }

    #[test]
    fn lookup_equals_the_brute_force_weighted_average() {
        let records: Vec<Record> = (0..3000u64)
            .map(|i| {
                let h = hash(&[i, 3]);
                let c = |s: u32| u32_to_unit((h >> s) as u32);
                rec(
                    Vec3::new(c(0) * 10.0, c(20) * 10.0, 0.0),
                    Vec3::Z,
                    c(40),
                    0.05 + c(44) * 2.0,
                )
            })
            .collect();
        let a = 0.3;
        let cache = IrradianceCache::build(records.clone(), a);
        for i in 0..500u64 {
            let h = hash(&[i, 4]);
            let p = Vec3A::new(
                u32_to_unit(h as u32) * 10.0,
                u32_to_unit((h >> 32) as u32) * 10.0,
                0.0,
            );
            let n = Vec3A::Z;
            let (mut s, mut ws) = (0.0f64, 0.0f64);
            for r in &records {
                if let Some(w) = weight(r, p, n, 1.0 / a) {
                    s += (w * r.e.x) as f64;
                    ws += w as f64;
                }
            }
            let got = cache.lookup(p, n);
            assert_eq!(got.is_some(), ws > 0.0, "{p:?}");
            if let Some(e) = got {
                assert!((e.x as f64 - s / ws).abs() < 1e-4, "{} vs {}", e.x, s / ws);
            }
            assert_eq!(served(&records, p, n, a), ws > 0.0);
        }
    }

    #[test]
    fn ward_weight_rejects_far_turned_and_in_front_records() {
        let r = rec(Vec3::ZERO, Vec3::Z, 1.0, 1.0);
        let inv_a = 1.0 / 0.2;
        assert!(weight(&r, Vec3A::new(0.1, 0.0, 0.0), Vec3A::Z, inv_a).is_some());
        // Farther than a·R.
        assert!(weight(&r, Vec3A::new(0.25, 0.0, 0.0), Vec3A::Z, inv_a).is_none());
        // Normal turned by 30°: √(1 − cos 30°) = 0.37 > a.
        let n = Vec3A::new(0.5, 0.0, 0.866);
        assert!(weight(&r, Vec3A::ZERO, n, inv_a).is_none());
        // The record above a lower point (in front of it) does not serve it.
        assert!(weight(&r, Vec3A::new(0.0, 0.0, -0.1), Vec3A::Z, inv_a).is_none());
    }
}
