//! Tiles and their accumulated samples.
//!
//! A tile is a rectangle of pixels and a range of sample indices. It accumulates, per pixel,
//! weighted sums (Σw·L, Σw, Σ(w·L)²) — never normalised colour — in fixed point
//! (i128). Integer addition is associative, so sums merged from any split of the sample range,
//! in any order, on any machine, are bit-identical; the image is divided out once, at the end
//! (docs/src/design/overview.md: tiles carry Σw·L and Σw).

use glam::UVec2;
use half::bf16;
use serde::{Deserialize, Serialize};

use crate::spectrum::Spectrum;

/// A rectangle of pixels [x0, x1) × [y0, y1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Tile {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

impl Tile {
    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }
    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }
    pub fn pixel_count(&self) -> usize {
        (self.width() * self.height()) as usize
    }
    /// Pixels in row-major order.
    pub fn pixels(&self) -> impl Iterator<Item = UVec2> + '_ {
        (self.y0..self.y1).flat_map(move |y| (self.x0..self.x1).map(move |x| UVec2::new(x, y)))
    }
}

/// Cuts a `width` × `height` film into tiles of `size` × `size` pixels, row-major.
pub fn tiles(width: u32, height: u32, size: u32) -> Vec<Tile> {
    let size = size.max(1);
    let mut out = Vec::new();
    for y0 in (0..height).step_by(size as usize) {
        for x0 in (0..width).step_by(size as usize) {
            out.push(Tile {
                x0,
                y0,
                x1: (x0 + size).min(width),
                y1: (y0 + size).min(height),
            });
        }
    }
    out
}

/// Sample indices [start, end) of every pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SampleRange {
    pub start: u32,
    pub end: u32,
}

impl SampleRange {
    pub fn len(&self) -> u32 {
        self.end.saturating_sub(self.start)
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Most samples one pixel may take: the fixed-point sums are sized for 2²⁴.
pub const MAX_SPP: u32 = 1 << 24;

/// Fractional bits of first moments and of second moments. Per-sample first moments are
/// clamped to ±2³² (`LIMIT`, a guard far above any sane radiance) and squares are taken of
/// the clamped value, so at most 2⁶⁴ (`LIMIT_SQ`): 2²⁴ samples of (2³²·2⁶⁴) fit in an i128,
/// as do 2²⁴ squares of (2⁶⁴·2³⁸).
const FRAC: i32 = 64;
const FRAC_SQ: i32 = 38;
const LIMIT: f32 = 4_294_967_296.0;
const LIMIT_SQ: f32 = LIMIT * LIMIT;

/// v·2^frac as an integer, from the bits of `v` clamped to ±`limit`: the 24-bit significand
/// shifted by the exponent (exact where the result is an integer, truncated toward zero below
/// 2^−frac).
#[inline]
fn fixed(v: f32, frac: i32, limit: f32) -> i128 {
    let v = v.clamp(-limit, limit);
    let bits = v.to_bits();
    let exponent = ((bits >> 23) & 0xff) as i32;
    if exponent == 0 {
        return 0; // zero and subnormals: far below the resolution
    }
    let significand = ((bits & 0x7f_ffff) | 0x80_0000) as i128;
    let shift = exponent - 150 + frac;
    let magnitude = if shift >= 0 {
        significand << shift
    } else if shift > -32 {
        significand >> -shift
    } else {
        0
    };
    if bits >> 31 != 0 {
        -magnitude
    } else {
        magnitude
    }
}

#[inline]
fn unfixed(v: i128, frac: i32) -> f64 {
    v as f64 * f64::from_bits(((1023 - frac) as u64) << 52)
}

/// Fixed-point sums of one pixel.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PixelSums {
    pub samples: u64,
    pub w: i128,
    pub wl: [i128; 3],
    pub wl2: [i128; 3],
}

impl PixelSums {
    /// Adds a sample of radiance `l` (already finite) with filter weight `w`.
    #[inline]
    pub fn add(&mut self, w: f32, l: Spectrum) {
        let first = |v: f32| fixed(v, FRAC, LIMIT);
        let wl = l * w;
        self.samples += 1;
        self.w += first(w);
        for c in 0..3 {
            let v = wl[c].clamp(-LIMIT, LIMIT);
            self.wl[c] += first(v);
            self.wl2[c] += fixed(v * v, FRAC_SQ, LIMIT_SQ);
        }
    }

    pub fn merge(&mut self, o: &PixelSums) {
        self.samples += o.samples;
        self.w += o.w;
        for c in 0..3 {
            self.wl[c] += o.wl[c];
            self.wl2[c] += o.wl2[c];
        }
    }

    /// Σ w·L, Σ w and the centred second moment Σ (w·L − mean)² of the pixel's samples, from
    /// the exact sums.
    pub fn moments(&self) -> ([f64; 3], f64, [f64; 3]) {
        let n = self.samples as f64;
        let s = self.wl.map(|v| unfixed(v, FRAC));
        let mut m2 = [0.0; 3];
        if n > 0.0 {
            for c in 0..3 {
                m2[c] = (unfixed(self.wl2[c], FRAC_SQ) - s[c] * s[c] / n).max(0.0);
            }
        }
        (s, unfixed(self.w, FRAC), m2)
    }

    /// The pixel's colour and its variance (its AOVs come from the camera rays alone,
    /// [`crate::render::first_hits`]).
    pub fn resolve(&self) -> Pixel {
        let w = unfixed(self.w, FRAC);
        let n = self.samples as f64;
        if w == 0.0 || n == 0.0 {
            return Pixel::default();
        }
        let mut p = Pixel::default();
        let mean_w = w / n;
        for c in 0..3 {
            let s1 = unfixed(self.wl[c], FRAC);
            p.rgb[c] = (s1 / w) as f32;
            // Variance of the pixel estimate Σw·L/Σw ≈ Var(w·L) / (n w̄²) with the unbiased
            // sample variance of w·L (w is constant up to sign under filter importance sampling).
            if n > 1.0 {
                let s2 = unfixed(self.wl2[c], FRAC_SQ);
                let var = ((s2 - s1 * s1 / n) / (n - 1.0)).max(0.0);
                p.variance[c] = (var / (n * mean_w * mean_w)) as f32;
            }
        }
        p
    }
}

/// The final values of a pixel.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Pixel {
    pub rgb: [f32; 3],
    /// Fraction of the filter weight whose rays hit geometry.
    pub alpha: f32,
    pub albedo: [f32; 3],
    pub normal: [f32; 3],
    /// Mean depth along the camera axis over the samples that hit (0 where none did).
    pub depth: f32,
    /// Estimated variance of `rgb` (of the mean, not of one sample).
    pub variance: [f32; 3],
}

/// The sums of every pixel of a tile over a sample range.
#[derive(Debug, Clone, PartialEq)]
pub struct TileSums {
    pub tile: Tile,
    pub samples: SampleRange,
    pub pixels: Vec<PixelSums>,
}

impl TileSums {
    pub fn new(tile: Tile, samples: SampleRange) -> Self {
        TileSums {
            tile,
            samples,
            pixels: vec![PixelSums::default(); tile.pixel_count()],
        }
    }

    /// Adds the sums of another sample range of the same tile.
    pub fn merge(&mut self, other: &TileSums) {
        assert_eq!(self.tile, other.tile, "merging sums of different tiles");
        for (a, b) in self.pixels.iter_mut().zip(&other.pixels) {
            a.merge(b);
        }
        self.samples = SampleRange {
            start: self.samples.start.min(other.samples.start),
            end: self.samples.end.max(other.samples.end),
        };
    }
}

/// A finished frame: every pixel's final values, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Pixel>,
}

impl Image {
    pub fn new(width: u32, height: u32) -> Self {
        Image {
            width,
            height,
            pixels: vec![Pixel::default(); (width * height) as usize],
        }
    }

    /// A frame from the sums of tiles that cover it.
    pub fn from_tiles(width: u32, height: u32, tiles: &[TileSums]) -> Self {
        let mut image = Image::new(width, height);
        for t in tiles {
            image.put(t);
        }
        image
    }

    /// Writes a tile's resolved pixels into place.
    pub fn put(&mut self, sums: &TileSums) {
        for (p, s) in sums.tile.pixels().zip(&sums.pixels) {
            self.pixels[(p.y * self.width + p.x) as usize] = s.resolve();
        }
    }
}

/// A rectangle of pixels [x0, x1) × [y0, y1), as compact sums carry it.
pub type Rect = [u32; 4];

fn rect_of(t: &Tile) -> Rect {
    [t.x0, t.y0, t.x1, t.y1]
}

/// A task's camera-side sums over a rectangle of pixels, row-major.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FilmSums {
    pub rect: Rect,
    /// Samples per pixel (every pixel of the rectangle took as many).
    pub samples: u32,
    /// Σ w·L: exposed radiance times the film filter's weight f/pdf.
    pub sum: Vec<[f32; 3]>,
    /// Σ w.
    pub weight: Vec<f32>,
    /// Σ (w·L − mean)²; empty where the camera side is not the whole estimate.
    pub m2: Vec<[bf16; 3]>,
}

impl FilmSums {
    /// From a tile's fixed-point sums; with the second moment if `variance`.
    pub fn from_tile(t: &TileSums, variance: bool) -> Self {
        let mut out = FilmSums {
            rect: rect_of(&t.tile),
            samples: t.samples.len(),
            sum: Vec::with_capacity(t.pixels.len()),
            weight: Vec::with_capacity(t.pixels.len()),
            m2: Vec::with_capacity(if variance { t.pixels.len() } else { 0 }),
        };
        for p in &t.pixels {
            let (s, w, m2) = p.moments();
            out.sum.push(s.map(|v| v as f32));
            out.weight.push(w as f32);
            if variance {
                out.m2.push(m2.map(bf16::from_f64));
            }
        }
        out
    }
}

impl FilmSums {
    /// No samples yet over `rect`.
    pub fn empty(rect: Tile, variance: bool) -> Self {
        let n = rect.pixel_count();
        FilmSums {
            rect: rect_of(&rect),
            samples: 0,
            sum: vec![[0.0; 3]; n],
            weight: vec![0.0; n],
            m2: if variance {
                vec![[bf16::ZERO; 3]; n]
            } else {
                Vec::new()
            },
        }
    }

    /// The rectangle.
    pub fn tile(&self) -> Tile {
        let [x0, y0, x1, y1] = self.rect;
        Tile { x0, y0, x1, y1 }
    }

    /// Copies the sums of `part`, a rectangle inside this one, into place (its samples must
    /// be this one's).
    pub fn put(&mut self, part: &FilmSums) {
        let (t, p) = (self.tile(), part.tile());
        let w = t.width() as usize;
        for (k, px) in p.pixels().enumerate() {
            let i = (px.y - t.y0) as usize * w + (px.x - t.x0) as usize;
            self.sum[i] = part.sum[k];
            self.weight[i] = part.weight[k];
            if !self.m2.is_empty() && !part.m2.is_empty() {
                self.m2[i] = part.m2[k];
            }
        }
    }

    /// Adds another range of samples of the same rectangle (in f32; the second moment is not
    /// kept).
    pub fn add(&mut self, other: &FilmSums) {
        for (a, b) in self.sum.iter_mut().zip(&other.sum) {
            for c in 0..3 {
                a[c] += b[c];
            }
        }
        for (a, b) in self.weight.iter_mut().zip(&other.weight) {
            *a += b;
        }
        self.m2.clear();
        self.samples += other.samples;
    }

    /// Pixel `k`'s estimate Σ w·L / Σ w (0 without weight).
    pub fn mean(&self, k: usize) -> [f32; 3] {
        let w = self.weight[k] as f64;
        if w == 0.0 {
            return [0.0; 3];
        }
        self.sum[k].map(|s| (s as f64 / w) as f32)
    }
}

/// Per pixel Σ w·L and Σ w in f64 over a rectangle, for sums a task keeps across many passes
/// of its own (VCM's iterations): 32 bytes a pixel, deterministic where each pixel's samples
/// are added by one thread in a fixed order.
#[derive(Debug, Clone, PartialEq)]
pub struct TileF64 {
    pub tile: Tile,
    pub samples: u32,
    pub sum: Vec<[f64; 3]>,
    pub weight: Vec<f64>,
}

impl TileF64 {
    pub fn new(tile: Tile) -> Self {
        let n = tile.pixel_count();
        TileF64 {
            tile,
            samples: 0,
            sum: vec![[0.0; 3]; n],
            weight: vec![0.0; n],
        }
    }

    /// Adds pixel `k`'s sample of radiance `l` (already finite) and filter weight `w`.
    #[inline]
    pub fn add(&mut self, k: usize, w: f32, l: Spectrum) {
        let w = w as f64;
        for c in 0..3 {
            self.sum[k][c] += w * l[c] as f64;
        }
        self.weight[k] += w;
    }

    /// As compact sums.
    pub fn to_sums(&self) -> FilmSums {
        FilmSums {
            rect: rect_of(&self.tile),
            samples: self.samples,
            sum: self.sum.iter().map(|s| s.map(|v| v as f32)).collect(),
            weight: self.weight.iter().map(|&w| w as f32).collect(),
            m2: Vec::new(),
        }
    }
}

/// Splats from the core's fixed-point sums (units of 2⁻³²).
pub fn splats_from_fixed(fixed: &[[i64; 3]]) -> Vec<[f32; 3]> {
    let scale = 1.0 / 4_294_967_296.0;
    fixed
        .iter()
        .map(|s| s.map(|v| (v as f64 * scale) as f32))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_point_is_exact_for_representable_values() {
        for v in [0.0f32, 1.0, -1.0, 0.375, 3.0e5, -7.25e-3, 1.0e-12, 4.0e9] {
            let expect = (v as f64 * (FRAC as f64).exp2()).trunc();
            assert_eq!(fixed(v, FRAC, LIMIT) as f64, expect, "{v}");
            let back = unfixed(fixed(v, FRAC, LIMIT), FRAC);
            assert!((back - v as f64).abs() <= 1e-18 + 1e-7 * v.abs() as f64);
        }
        assert_eq!(fixed(f32::INFINITY, FRAC, LIMIT), fixed(LIMIT, FRAC, LIMIT));
        assert_eq!(fixed(1.0e-30, FRAC_SQ, LIMIT_SQ), 0);
        // Squares keep their own, larger range: 1e15 is not cut to 2³².
        let sq = unfixed(fixed(1.0e15, FRAC_SQ, LIMIT_SQ), FRAC_SQ);
        assert!((sq / 1.0e15 - 1.0).abs() < 1e-7, "{sq}");
        // The worst case fits: 2²⁴ samples at the limits do not overflow an i128.
        let top = fixed(LIMIT_SQ, FRAC_SQ, LIMIT_SQ);
        assert!(top.checked_mul(1 << 24).is_some());
        assert!(fixed(LIMIT, FRAC, LIMIT).checked_mul(1 << 24).is_some());
    }

    #[test]
    fn tiles_cover_the_film_exactly_once() {
        let t = tiles(70, 33, 16);
        let mut covered = vec![0u8; 70 * 33];
        for tile in &t {
            for p in tile.pixels() {
                covered[(p.y * 70 + p.x) as usize] += 1;
            }
        }
        assert!(covered.iter().all(|&c| c == 1));
        assert_eq!(t.len(), 5 * 3);
    }

    #[test]
    fn sums_are_independent_of_how_samples_are_split_and_ordered() {
        let values: Vec<(f32, Spectrum)> = (0..100)
            .map(|i| {
                (
                    1.0 + (i % 3) as f32 * 0.25,
                    glam::Vec3A::new(i as f32 * 0.37, 1e-3 / (i + 1) as f32, 1e4 * (i % 7) as f32),
                )
            })
            .collect();
        let mut whole = PixelSums::default();
        for (w, l) in &values {
            whole.add(*w, *l);
        }
        let (mut a, mut b) = (PixelSums::default(), PixelSums::default());
        for (i, (w, l)) in values.iter().enumerate().rev() {
            if i % 2 == 0 {
                a.add(*w, *l)
            } else {
                b.add(*w, *l)
            }
        }
        b.merge(&a);
        assert_eq!(whole, b);
    }

    #[test]
    fn resolve_gives_weighted_mean_and_variance_of_the_mean() {
        let mut s = PixelSums::default();
        let ls = [1.0f32, 2.0, 3.0, 6.0];
        for l in ls {
            s.add(1.0, Spectrum::splat(l));
        }
        let p = s.resolve();
        assert!((p.rgb[0] - 3.0).abs() < 1e-6);
        // Sample variance 14/3, variance of the mean 14/12.
        assert!((p.variance[1] - 14.0 / 12.0).abs() < 1e-5);
    }
}
