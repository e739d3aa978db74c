//! Owen-scrambled Sobol points, padded per dimension pair (the construction of Burley,
//! "Practical Hash-based Owen Scrambling", JCGT 9(4), 2020; pbrt-v4's PaddedSobolSampler).
//!
//! Each 1D or 2D request uses the first two Sobol dimensions, with the sample index shuffled
//! and the coordinates Owen-scrambled by hashes of (seed, pixel, request number). So every
//! pixel's first 2^k samples form a (0, k, 2)-net in each pair of dimensions, and every value
//! depends only on (seed, pixel, sample index, dimension).

use glam::{UVec2, Vec2};

use super::Sampler;
use super::hash::{hash, mix64, u32_to_unit};

/// The second Sobol dimension of point `index`, bit-reversed. Its generator matrix (primitive
/// polynomial x + 1, direction numbers vₖ = vₖ₋₁ ⊕ (vₖ₋₁ >> 1)) is Pascal's triangle mod 2, so
/// by Lucas' theorem bit j of the reversed result is the XOR of the index bits k ⊇ j: a
/// superset-sum transform over GF(2), five shift-mask-xor steps instead of a loop over bits.
#[inline]
fn sobol1_reversed(index: u32) -> u32 {
    let mut y = index;
    y ^= (y >> 1) & 0x5555_5555;
    y ^= (y >> 2) & 0x3333_3333;
    y ^= (y >> 4) & 0x0f0f_0f0f;
    y ^= (y >> 8) & 0x00ff_00ff;
    y ^= (y >> 16) & 0x0000_ffff;
    y
}

/// Owen scrambling of a bit-reversed integer: a Laine–Karras style hash in which each output
/// bit depends only on the same and lower input bits. Constants from N. Vegdahl, "Building a
/// Better LK Hash" (2021), which behaves much closer to true Owen scrambling than the original.
#[inline]
fn lk_owen_reversed(mut x: u32, seed: u32) -> u32 {
    x ^= x.wrapping_mul(0x3d20_adea);
    x = x.wrapping_add(seed);
    x = x.wrapping_mul((seed >> 16) | 1);
    x ^= x.wrapping_mul(0x0552_6c56);
    x ^= x.wrapping_mul(0x53a2_2864);
    x
}

/// Owen-scrambled first (van der Corput: the reversed index) and second Sobol dimensions of a
/// point, working in reversed-bit space throughout.
#[inline]
fn scrambled_pair(index: u32, s0: u32, s1: u32) -> (u32, u32) {
    (
        lk_owen_reversed(index, s0).reverse_bits(),
        lk_owen_reversed(sobol1_reversed(index), s1).reverse_bits(),
    )
}

#[derive(Debug, Clone)]
pub struct SobolSampler {
    seed: u64,
    pixel_key: u64,
    /// The sample index, bit-reversed once per pixel sample (x86 has no bit-reverse
    /// instruction, and every request needs it).
    index_reversed: u32,
    dimension: u32,
}

impl SobolSampler {
    pub fn new(seed: u64) -> Self {
        SobolSampler {
            seed,
            pixel_key: 0,
            index_reversed: 0,
            dimension: 0,
        }
    }

    /// Shuffled index and the two coordinate seeds for the current request.
    #[inline]
    fn request(&mut self) -> (u32, u32, u32) {
        let h = mix64(self.pixel_key ^ (self.dimension as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
        self.dimension += 1;
        // Owen-scrambling the index (shuffling the padded dimensions independently).
        let index = lk_owen_reversed(self.index_reversed, h as u32).reverse_bits();
        (
            index,
            (h >> 32) as u32,
            (h.rotate_left(17) as u32) ^ 0x5bd1_e995,
        )
    }
}

impl Sampler for SobolSampler {
    fn start_pixel_sample(&mut self, pixel: UVec2, index: u32) {
        self.pixel_key = hash(&[self.seed, pixel.x as u64, pixel.y as u64]);
        self.index_reversed = index.reverse_bits();
        self.dimension = 0;
    }

    #[inline]
    fn get_1d(&mut self) -> f32 {
        let (index, s0, _) = self.request();
        // The first Sobol dimension is the bit reversal of the index (van der Corput).
        u32_to_unit(lk_owen_reversed(index, s0).reverse_bits())
    }

    #[inline]
    fn get_2d(&mut self) -> Vec2 {
        let (index, s0, s1) = self.request();
        let (x, y) = scrambled_pair(index, s0, s1);
        Vec2::new(u32_to_unit(x), u32_to_unit(y))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Nested uniform (Owen) scramble of a 32-bit fraction.
    fn owen_scramble(x: u32, seed: u32) -> u32 {
        lk_owen_reversed(x.reverse_bits(), seed).reverse_bits()
    }

    #[test]
    fn unscrambled_second_dimension_matches_known_sobol_values() {
        // Sobol dimension 2 for indices 0..8 in direct (not Gray-code) order: the XOR of the
        // direction numbers 1/2, 3/4, 5/8 selected by the index bits.
        let expect = [0.0, 0.5, 0.75, 0.25, 0.625, 0.125, 0.375, 0.875];
        for (i, e) in expect.iter().enumerate() {
            assert_eq!(
                sobol1_reversed(i as u32).reverse_bits() as f64 / 4294967296.0,
                *e
            );
        }
        // And against the direction numbers for every single bit.
        let mut v = 1u32 << 31;
        for k in 0..32 {
            assert_eq!(sobol1_reversed(1 << k).reverse_bits(), v, "bit {k}");
            v ^= v >> 1;
        }
    }

    #[test]
    fn owen_scramble_is_a_bijection_preserving_prefix_blocks() {
        // The low bits of the output depend only on the low bits of the input (in fraction
        // order: the leading bits), so aligned blocks map to aligned blocks.
        let seed = 0xdead_beef;
        let mut seen = std::collections::HashSet::new();
        for i in 0..1024u32 {
            let x = i << 22; // 10 leading bits vary
            let y = owen_scramble(x, seed);
            seen.insert(y >> 22);
        }
        assert_eq!(seen.len(), 1024);
    }

    #[test]
    fn every_power_of_two_prefix_is_a_0m2_net() {
        // The first 2^m points of each pixel and dimension pair have exactly one point in each
        // elementary interval of area 2^-m, for every shape of interval.
        let mut s = SobolSampler::new(7);
        for m in [4u32, 6, 8] {
            let n = 1u32 << m;
            for dim_skip in 0..3 {
                let pts: Vec<Vec2> = (0..n)
                    .map(|i| {
                        s.start_pixel_sample(UVec2::new(3, 5), i);
                        for _ in 0..dim_skip {
                            s.get_2d();
                        }
                        s.get_2d()
                    })
                    .collect();
                for kx in 0..=m {
                    let (nx, ny) = (1usize << kx, 1usize << (m - kx));
                    let mut cells = vec![0u32; nx * ny];
                    for p in &pts {
                        let cx = (p.x * nx as f32) as usize;
                        let cy = (p.y * ny as f32) as usize;
                        cells[cy * nx + cx] += 1;
                    }
                    assert!(
                        cells.iter().all(|&c| c == 1),
                        "m={m} kx={kx} dim={dim_skip}"
                    );
                }
            }
        }
    }

    #[test]
    fn values_depend_only_on_seed_pixel_index_and_dimension() {
        let mut a = SobolSampler::new(1);
        let mut b = SobolSampler::new(1);
        b.start_pixel_sample(UVec2::new(9, 9), 3);
        b.get_2d();
        a.start_pixel_sample(UVec2::new(2, 7), 5);
        b.start_pixel_sample(UVec2::new(2, 7), 5);
        assert_eq!(a.get_2d(), b.get_2d());
        assert_eq!(a.get_1d(), b.get_1d());
        let mut c = SobolSampler::new(2);
        c.start_pixel_sample(UVec2::new(2, 7), 5);
        assert_ne!(c.get_2d(), {
            a.start_pixel_sample(UVec2::new(2, 7), 5);
            a.get_2d()
        });
    }
}
