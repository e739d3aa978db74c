//! Geometry: primitive intersection and the acceleration structure.

pub mod accel;
pub mod bvh8;
pub mod sphere;
pub mod triangle;

pub use accel::{Accel, Prim, PrimHit};
