//! Independent uniform random numbers, each a hash of (seed, pixel, sample index, dimension).

use glam::{UVec2, Vec2, Vec3A, Vec4};

use super::Sampler;
use super::hash::{hash, mix64, u32_to_unit};

#[derive(Debug, Clone)]
pub struct IndependentSampler {
    seed: u64,
    key: u64,
    dimension: u64,
}

impl IndependentSampler {
    pub fn new(seed: u64) -> Self {
        IndependentSampler {
            seed,
            key: 0,
            dimension: 0,
        }
    }

    #[inline]
    fn next(&mut self) -> u64 {
        let v = mix64(self.key ^ self.dimension.wrapping_mul(0xd6e8_feb8_6659_fd93));
        self.dimension += 1;
        v
    }
}

impl Sampler for IndependentSampler {
    fn start_pixel_sample(&mut self, pixel: UVec2, index: u32) {
        self.key = hash(&[self.seed, pixel.x as u64, pixel.y as u64, index as u64]);
        self.dimension = 0;
    }

    #[inline]
    fn get_1d(&mut self) -> f32 {
        u32_to_unit(self.next() as u32)
    }

    #[inline]
    fn get_2d(&mut self) -> Vec2 {
        let v = self.next();
        Vec2::new(u32_to_unit(v as u32), u32_to_unit((v >> 32) as u32))
    }

    #[inline]
    fn get_3d(&mut self) -> Vec3A {
        let (a, b) = (self.get_2d(), self.get_1d());
        Vec3A::new(a.x, a.y, b)
    }

    #[inline]
    fn get_4d(&mut self) -> Vec4 {
        let (a, b) = (self.get_2d(), self.get_2d());
        Vec4::new(a.x, a.y, b.x, b.y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mean_and_variance_are_uniform() {
        let mut s = IndependentSampler::new(3);
        let n = 100_000;
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for i in 0..n {
            s.start_pixel_sample(UVec2::new(i % 17, i / 17), i);
            let x = s.get_1d() as f64;
            sum += x;
            sum2 += x * x;
        }
        let mean = sum / n as f64;
        let var = sum2 / n as f64 - mean * mean;
        // Standard error of the mean is sqrt(1/12/n) ≈ 9e-4: allow 4 of them.
        assert!(
            (mean - 0.5).abs() < 4.0 * (1.0 / 12.0 / n as f64).sqrt(),
            "{mean}"
        );
        assert!((var - 1.0 / 12.0).abs() < 2e-3, "{var}");
    }
}
