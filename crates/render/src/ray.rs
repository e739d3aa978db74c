//! Rays.

use glam::Vec3A;

/// A ray with origin `o` and unit direction `d`; the parametric distance `t` is in scene units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    pub o: Vec3A,
    pub d: Vec3A,
}

impl Ray {
    #[inline]
    pub fn new(o: Vec3A, d: Vec3A) -> Ray {
        Ray { o, d }
    }

    #[inline]
    pub fn at(&self, t: f32) -> Vec3A {
        self.o + self.d * t
    }
}
