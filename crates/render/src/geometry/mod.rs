//! Geometry: primitive intersection and the acceleration structure.

pub mod accel;
pub mod build;
pub mod bvh8;
pub mod depth;
pub mod sphere;
pub mod triangle;

pub use accel::{Accel, Prim, PrimHit};
