//! Projection maps (Jensen, "Realistic Image Synthesis Using Photon Mapping" §5.2.2): the
//! sphere of directions around a light cut into cells of equal solid angle, marking the cells
//! through which some target object can be seen. Photons are shot only through marked cells
//! and carry the light's power scaled by the covered fraction, so none are wasted on empty
//! space, and a caustic map shot toward the specular objects alone is cheap.
//!
//! Cells are uniform in (z, φ), z = cos θ from +Z: equal areas on the sphere (Archimedes). A
//! cell is marked when the cone around its centre direction that contains the cell meets the
//! cone around a target's bounding sphere: conservative, so no direction toward a target is
//! ever left out, and the map stays unbiased.

use glam::{Vec2, Vec3A};

use crate::math::{PI, safe_sqrt};

/// Cells along z and along φ.
const NZ: usize = 64;
const NPHI: usize = 128;
const CELL_SOLID_ANGLE: f32 = 4.0 * PI / (NZ * NPHI) as f32;

/// A sphere that photons should reach: centre and radius in scene units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Target {
    pub center: Vec3A,
    pub radius: f32,
}

#[derive(Debug, Clone)]
pub struct ProjectionMap {
    /// Indices of the marked cells, increasing (so the map is a pure function of its input).
    marked: Vec<u32>,
}

/// Centre direction of cell (iz, iphi).
fn cell_center(iz: usize, iphi: usize) -> Vec3A {
    direction(
        -1.0 + 2.0 * (iz as f32 + 0.5) / NZ as f32,
        2.0 * PI * (iphi as f32 + 0.5) / NPHI as f32,
    )
}

fn direction(z: f32, phi: f32) -> Vec3A {
    let r = safe_sqrt(1.0 - z * z);
    let (s, c) = phi.sin_cos();
    Vec3A::new(r * c, r * s, z)
}

/// Largest angle between a cell's centre direction and any direction in the cell, for cells
/// of row `iz` (the same for every φ): the corners are the farthest points.
fn cell_angular_radius(iz: usize) -> f32 {
    let center = cell_center(iz, 0);
    let mut cos_min = 1.0f32;
    for dz in [0.0, 1.0] {
        for dphi in [0.0, 1.0] {
            let z = -1.0 + 2.0 * (iz as f32 + dz) / NZ as f32;
            let corner = direction(z, 2.0 * PI * dphi / NPHI as f32);
            cos_min = cos_min.min(center.dot(corner));
        }
    }
    // Rounding must not shrink the cell.
    cos_min.clamp(-1.0, 1.0).acos() * 1.001 + 1e-4
}

impl ProjectionMap {
    /// The map for a light at `origin`, extending `spread` around it (an area light's bounding
    /// radius, 0 for a point), toward `targets`; `allowed(dir, angular_radius)` may further
    /// exclude cells the light cannot emit through (a spot light's cone). Directions from any
    /// point within `spread` of `origin` toward a target are inside the marked cells, because
    /// each target is grown by `spread`.
    pub fn new(
        origin: Vec3A,
        spread: f32,
        targets: &[Target],
        allowed: impl Fn(Vec3A, f32) -> bool,
    ) -> Self {
        // Angular centre and radius of every target as seen from the origin.
        let cones: Vec<Option<(Vec3A, f32)>> = targets
            .iter()
            .map(|t| {
                let to = t.center - origin;
                let d = to.length();
                let r = t.radius + spread;
                if d <= r {
                    None // the origin is inside: every direction may reach it
                } else {
                    Some((to / d, (r / d).min(1.0).asin()))
                }
            })
            .collect();
        let mut marked = Vec::new();
        for iz in 0..NZ {
            let radius = cell_angular_radius(iz);
            for iphi in 0..NPHI {
                let c = cell_center(iz, iphi);
                let sees = cones.iter().any(|cone| match cone {
                    None => true,
                    Some((axis, half)) => c.dot(*axis).clamp(-1.0, 1.0).acos() <= half + radius,
                });
                if sees && allowed(c, radius) {
                    marked.push((iz * NPHI + iphi) as u32);
                }
            }
        }
        ProjectionMap { marked }
    }

    /// Fraction of the sphere of directions that is marked.
    pub fn covered_fraction(&self) -> f32 {
        self.marked.len() as f32 / (NZ * NPHI) as f32
    }

    pub fn is_empty(&self) -> bool {
        self.marked.is_empty()
    }

    /// A direction uniform over the marked cells (`u_cell` picks the cell) and its solid-angle
    /// density 1 / (marked cells × cell solid angle).
    pub fn sample(&self, u_cell: f32, u: Vec2) -> Option<(Vec3A, f32)> {
        if self.marked.is_empty() {
            return None;
        }
        let n = self.marked.len();
        let i = ((u_cell * n as f32) as usize).min(n - 1);
        let cell = self.marked[i] as usize;
        let (iz, iphi) = (cell / NPHI, cell % NPHI);
        let z = -1.0 + 2.0 * (iz as f32 + u.x) / NZ as f32;
        let phi = 2.0 * PI * (iphi as f32 + u.y) / NPHI as f32;
        Some((direction(z, phi), 1.0 / (n as f32 * CELL_SOLID_ANGLE)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_light_inside_a_target_marks_every_cell() {
        let t = [Target {
            center: Vec3A::ZERO,
            radius: 10.0,
        }];
        let m = ProjectionMap::new(Vec3A::new(1.0, 0.0, 0.0), 0.0, &t, |_, _| true);
        assert_eq!(m.covered_fraction(), 1.0);
    }

    #[test]
    fn a_small_far_target_marks_a_few_cells_and_every_sample_toward_it_is_covered() {
        let target = Target {
            center: Vec3A::new(0.3, 4.0, -1.0),
            radius: 0.5,
        };
        let m = ProjectionMap::new(Vec3A::ZERO, 0.0, &[target], |_, _| true);
        // The cone's solid angle is 2π(1 − cos θ), θ = asin(0.5 / 4.13): about 0.37 % of
        // the sphere; the marked cells cover it with a margin of one cell.
        let f = m.covered_fraction();
        assert!(f > 0.0037 && f < 0.03, "{f}");
        // Every direction that hits the target lies in a marked cell: sample the target's
        // cone densely and check the cell of each direction.
        let axis = target.center.normalize();
        let frame = crate::math::Frame::from_normal(axis);
        let one_minus_cos =
            crate::sampling::sphere_cone_one_minus_cos(0.25, target.center.length_squared());
        let marked: std::collections::HashSet<u32> = m.marked.iter().copied().collect();
        for i in 0..64 {
            for j in 0..64 {
                let u = Vec2::new((i as f32 + 0.5) / 64.0, (j as f32 + 0.5) / 64.0);
                let w = frame.to_world(crate::sampling::square_to_uniform_cone(u, one_minus_cos));
                let iz = (((w.z + 1.0) * 0.5 * NZ as f32) as usize).min(NZ - 1);
                let phi = w.y.atan2(w.x).rem_euclid(2.0 * PI);
                let iphi = ((phi / (2.0 * PI) * NPHI as f32) as usize).min(NPHI - 1);
                assert!(marked.contains(&((iz * NPHI + iphi) as u32)), "{w:?}");
            }
        }
    }

    #[test]
    fn samples_stay_in_marked_cells_with_a_constant_density() {
        let t = [Target {
            center: Vec3A::new(0.0, 0.0, 3.0),
            radius: 1.0,
        }];
        let m = ProjectionMap::new(Vec3A::ZERO, 0.0, &t, |_, _| true);
        let mut pdf0 = None;
        for i in 0..200 {
            let u = (i as f32 + 0.5) / 200.0;
            let (w, pdf) = m.sample(u, Vec2::new(u, 1.0 - u)).unwrap();
            assert!((w.length() - 1.0).abs() < 1e-5);
            assert!(w.z > 0.8, "{w:?}");
            assert_eq!(*pdf0.get_or_insert(pdf), pdf);
        }
        // Density × covered solid angle = 1.
        let covered = m.covered_fraction() * 4.0 * PI;
        assert!((pdf0.unwrap() * covered - 1.0).abs() < 1e-5);
    }
}
