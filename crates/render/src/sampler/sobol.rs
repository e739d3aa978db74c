//! Owen-scrambled Sobol points, padded per request (the construction of Burley, "Practical
//! Hash-based Owen Scrambling", JCGT 9(4), 2020; pbrt-v4's PaddedSobolSampler).
//!
//! Each request of one to four dimensions uses the first four Sobol dimensions, with the
//! sample index shuffled and the coordinates Owen-scrambled by hashes of (seed, pixel, request
//! number). So every pixel's first 2^k samples form a (0, k, 2)-net in the first two dimensions
//! of each request and are stratified in each dimension, and every value depends only on
//! (seed, pixel, sample index, dimension).

use glam::{UVec2, Vec2, Vec3A, Vec4};

use super::Sampler;
use super::hash::{hash, mix64};

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

/// Direction numbers of Sobol dimension `d` (0-based; Joe & Kuo, new-joe-kuo-6.21201) for
/// d = 2 (polynomial x² + x + 1, m = 1, 3) and d = 3 (x³ + x + 1, m = 1, 3, 1).
const fn direction_numbers(d: usize) -> [u32; 32] {
    let (s, a, m): (usize, u32, [u32; 3]) = if d == 2 {
        (2, 1, [1, 3, 0])
    } else {
        (3, 1, [1, 3, 1])
    };
    let mut v = [0u32; 32];
    let mut k = 0;
    while k < 32 {
        if k < s {
            v[k] = m[k] << (31 - k);
        } else {
            // vₖ = vₖ₋ₛ ⊕ (vₖ₋ₛ >> s) ⊕ ⊕ⱼ aⱼ vₖ₋ⱼ, with a's bits a₁ … aₛ₋₁ from the top.
            let mut x = v[k - s] ^ (v[k - s] >> s);
            let mut j = 1;
            while j < s {
                if (a >> (s - 1 - j)) & 1 == 1 {
                    x ^= v[k - j];
                }
                j += 1;
            }
            v[k] = x;
        }
        k += 1;
    }
    v
}

/// Byte tables of the bit-reversed Sobol dimension `d`: entry [b][x] is the XOR of the
/// reversed direction numbers of the set bits of byte b = x.
const fn reversed_tables(d: usize) -> [[u32; 256]; 4] {
    let v = direction_numbers(d);
    let mut t = [[0u32; 256]; 4];
    let mut b = 0;
    while b < 4 {
        let mut x = 0;
        while x < 256 {
            let mut acc = 0u32;
            let mut bit = 0;
            while bit < 8 {
                if (x >> bit) & 1 == 1 {
                    acc ^= v[8 * b + bit].reverse_bits();
                }
                bit += 1;
            }
            t[b][x] = acc;
            x += 1;
        }
        b += 1;
    }
    t
}

static SOBOL2: [[u32; 256]; 4] = reversed_tables(2);
static SOBOL3: [[u32; 256]; 4] = reversed_tables(3);

/// A bit-reversed Sobol coordinate from its byte tables.
#[inline]
fn sobol_reversed(t: &[[u32; 256]; 4], i: u32) -> u32 {
    t[0][(i & 0xff) as usize]
        ^ t[1][((i >> 8) & 0xff) as usize]
        ^ t[2][((i >> 16) & 0xff) as usize]
        ^ t[3][(i >> 24) as usize]
}

/// 12-bit bit reversal, for turning reversed-domain values into floats without a full
/// 32-bit `reverse_bits` (x86 has no instruction for it).
static REVERSE12: [u16; 4096] = {
    let mut t = [0u16; 4096];
    let mut i = 0;
    while i < 4096 {
        t[i] = ((i as u32).reverse_bits() >> 20) as u16;
        i += 1;
    }
    t
};

/// The float in [0, 1) whose binary fraction is the bit reversal of `y`: equal to
/// `u32_to_unit(y.reverse_bits())` (its top 24 bits are y's low 24 reversed).
#[inline]
fn reversed_to_unit(y: u32) -> f32 {
    let top = (REVERSE12[(y & 0xfff) as usize] as u32) << 12
        | REVERSE12[((y >> 12) & 0xfff) as usize] as u32;
    top as f32 * (1.0 / (1u32 << 24) as f32)
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

    /// The shuffled index and the coordinate seeds for the current request.
    #[inline]
    fn request(&mut self) -> (u32, u64) {
        let h = mix64(self.pixel_key ^ (self.dimension as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
        self.dimension += 1;
        // Owen-scrambling the index (shuffling the padded requests independently).
        let index = lk_owen_reversed(self.index_reversed, h as u32).reverse_bits();
        (index, h)
    }

    /// Up to four scrambled coordinates of one request (`N` of them computed).
    #[inline]
    fn coordinates<const N: usize>(&mut self) -> [f32; N] {
        let (index, h) = self.request();
        let g = mix64(h ^ 0x2545_f491_4f6c_dd1d);
        let seeds = [
            (h >> 32) as u32,
            g as u32,
            (g >> 32) as u32,
            mix64(g) as u32,
        ];
        let mut out = [0.0f32; N];
        for (d, value) in out.iter_mut().enumerate() {
            // Reversed Sobol coordinate d of the point: the first is the index itself.
            let r = match d {
                0 => index,
                1 => sobol1_reversed(index),
                2 => sobol_reversed(&SOBOL2, index),
                _ => sobol_reversed(&SOBOL3, index),
            };
            *value = reversed_to_unit(lk_owen_reversed(r, seeds[d]));
        }
        out
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
        self.coordinates::<1>()[0]
    }

    #[inline]
    fn get_2d(&mut self) -> Vec2 {
        Vec2::from(self.coordinates::<2>())
    }

    #[inline]
    fn get_3d(&mut self) -> Vec3A {
        Vec3A::from(self.coordinates::<3>())
    }

    #[inline]
    fn get_4d(&mut self) -> Vec4 {
        Vec4::from(self.coordinates::<4>())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampler::hash::u32_to_unit;

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
    fn reversed_to_unit_equals_reversing_then_converting() {
        for i in 0..200_000u64 {
            let y = crate::sampler::hash::mix64(i) as u32;
            assert_eq!(reversed_to_unit(y), u32_to_unit(y.reverse_bits()));
        }
    }

    #[test]
    fn third_and_fourth_dimensions_match_the_direction_numbers() {
        // Joe & Kuo dimension 3 (x² + x + 1, m = 1, 3): v = 1/2, 3/4, then v₃ = v₁ ⊕ (v₁ >> 2) ⊕ v₂.
        let v = direction_numbers(2);
        assert_eq!((v[0], v[1]), (1 << 31, 3 << 30));
        assert_eq!(v[2], v[0] ^ (v[0] >> 2) ^ v[1]);
        let w = direction_numbers(3);
        assert_eq!((w[0], w[1], w[2]), (1 << 31, 3 << 30, 1 << 29));
        // Tables reproduce the XOR over the set bits of any index.
        for i in [1u32, 5, 255, 256, 0x1234_5678, u32::MAX] {
            let direct = (0..32)
                .filter(|k| i >> k & 1 == 1)
                .fold(0u32, |a, k| a ^ v[k]);
            assert_eq!(sobol_reversed(&SOBOL2, i).reverse_bits(), direct);
        }
    }

    #[test]
    fn every_dimension_of_a_request_is_stratified() {
        // The first 2^m samples put exactly one value in each interval [k/2^m, (k+1)/2^m) of
        // every dimension of a 4D request.
        let mut s = SobolSampler::new(11);
        let m = 7;
        let n = 1u32 << m;
        for skip in 0..3 {
            let pts: Vec<Vec4> = (0..n)
                .map(|i| {
                    s.start_pixel_sample(UVec2::new(8, 1), i);
                    for _ in 0..skip {
                        s.get_4d();
                    }
                    s.get_4d()
                })
                .collect();
            for d in 0..4 {
                let mut cells = vec![0u32; n as usize];
                for p in &pts {
                    cells[(p[d] * n as f32) as usize] += 1;
                }
                assert!(
                    cells.iter().all(|&c| c == 1),
                    "dimension {d} of request {skip}"
                );
            }
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
