//! Geometry: primitive intersection and the acceleration structure.

pub mod accel;
pub mod build;
pub mod bvh8;
pub mod depth;
#[cfg(target_arch = "x86_64")]
mod packet;
pub mod sphere;
pub mod triangle;

pub use accel::{Accel, LANES, Prim, PrimHit};
