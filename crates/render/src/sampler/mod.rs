//! Samplers: every value is a function of (seed, pixel, sample index, dimension) only —
//! never of thread, tile or worker (invariant 1 of docs/src/design/overview.md).

pub mod hash;
mod independent;
mod sobol;

use glam::{UVec2, Vec2, Vec3A, Vec4};
use tessera_scene::SamplerType;

pub use independent::IndependentSampler;
pub use sobol::SobolSampler;

/// A source of sample values for one pixel sample at a time; each call consumes the next
/// dimension.
pub trait Sampler {
    /// Starts sample `index` of `pixel`, at dimension 0.
    fn start_pixel_sample(&mut self, pixel: UVec2, index: u32);
    fn get_1d(&mut self) -> f32;
    fn get_2d(&mut self) -> Vec2;
    /// Three or four values of one request (one dimension of the sequence each), cheaper than
    /// separate requests and stratified together.
    fn get_3d(&mut self) -> Vec3A;
    fn get_4d(&mut self) -> Vec4;
}

/// The samplers a scene may ask for (an enum, so integrators stay object-safe without dynamic
/// dispatch per sample value).
#[derive(Debug, Clone)]
pub enum PixelSampler {
    Sobol(SobolSampler),
    Independent(IndependentSampler),
}

impl PixelSampler {
    pub fn new(kind: SamplerType, seed: u64) -> Self {
        match kind {
            SamplerType::Sobol => PixelSampler::Sobol(SobolSampler::new(seed)),
            SamplerType::Independent => PixelSampler::Independent(IndependentSampler::new(seed)),
        }
    }
}

impl Sampler for PixelSampler {
    #[inline]
    fn start_pixel_sample(&mut self, pixel: UVec2, index: u32) {
        match self {
            PixelSampler::Sobol(s) => s.start_pixel_sample(pixel, index),
            PixelSampler::Independent(s) => s.start_pixel_sample(pixel, index),
        }
    }
    #[inline]
    fn get_1d(&mut self) -> f32 {
        match self {
            PixelSampler::Sobol(s) => s.get_1d(),
            PixelSampler::Independent(s) => s.get_1d(),
        }
    }
    #[inline]
    fn get_2d(&mut self) -> Vec2 {
        match self {
            PixelSampler::Sobol(s) => s.get_2d(),
            PixelSampler::Independent(s) => s.get_2d(),
        }
    }
    #[inline]
    fn get_3d(&mut self) -> Vec3A {
        match self {
            PixelSampler::Sobol(s) => s.get_3d(),
            PixelSampler::Independent(s) => s.get_3d(),
        }
    }
    #[inline]
    fn get_4d(&mut self) -> Vec4 {
        match self {
            PixelSampler::Sobol(s) => s.get_4d(),
            PixelSampler::Independent(s) => s.get_4d(),
        }
    }
}
