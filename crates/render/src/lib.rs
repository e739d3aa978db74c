//! Tessera's rendering core.

pub mod bsdf;
pub mod geometry;
pub mod math;
pub mod ray;
pub mod sampler;
pub mod sampling;
pub mod spectrum;
