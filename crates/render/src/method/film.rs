//! What camera-side tasks hand over, and what a frame accumulates them into.
//!
//! A task renders in the core's fixed-point sums ([`crate::film::TileSums`]: exact, the same
//! whatever order its threads add in) and hands over only what the fold needs, per pixel:
//! Σ w·L and Σ w in f32 and the centred second moment of w·L in bf16 (a statistic: 8 bits of
//! precision are plenty) — 22 bytes, where the fixed-point sums are 128. Whole-film methods
//! add their light-tracing or chain splats (12 bytes) and leave out the second moment (their
//! variance comes from batches, see [`Batches`]). The AOVs come from tasks of their own
//! ([`super::aov`]), 24 bytes a pixel, once per frame.
//!
//! The frame folds in the plan's order, in f64 where sums grow (Chan et al.'s pairwise update
//! for the second moment), so a frame is the same bits however its tasks were spread.

use std::mem::size_of;

use half::f16;
use serde::{Deserialize, Serialize};

pub use crate::film::{FilmSums, Rect, splats_from_fixed};
use crate::film::{Image, Pixel};
use crate::spectrum::Spectrum;

/// Checks that `rect` lies on a `width`×`height` film and that `len` values cover it.
fn check_rect(rect: Rect, len: usize, width: u32, height: u32, what: &str) -> Result<(), String> {
    let [x0, y0, x1, y1] = rect;
    let pixels = (x1.saturating_sub(x0) as usize) * (y1.saturating_sub(y0) as usize);
    if x0 > x1 || y0 > y1 || x1 > width || y1 > height || len != pixels {
        return Err(format!(
            "{what} over {rect:?} with {len} values does not fit a {width}×{height} film"
        ));
    }
    Ok(())
}

/// Checks a task's film sums: over `rect`, of `samples` samples a pixel, on a
/// `width`×`height` film, every column as long as the rectangle has pixels.
pub fn check_sums(
    s: &FilmSums,
    rect: Rect,
    samples: u32,
    width: u32,
    height: u32,
) -> Result<(), String> {
    if s.rect != rect || s.samples != samples {
        return Err(format!(
            "film sums over {:?} of {} samples, the task is {rect:?} of {samples}",
            s.rect, s.samples
        ));
    }
    check_rect(s.rect, s.sum.len(), width, height, "film sums")?;
    if s.weight.len() != s.sum.len() || (!s.m2.is_empty() && s.m2.len() != s.sum.len()) {
        return Err("film sums with columns of different lengths".into());
    }
    Ok(())
}

/// Checks a task's AOVs: over `rect` on a `width`×`height` film, every column as long as the
/// rectangle has pixels.
pub fn check_aov(a: &AovSums, rect: Rect, width: u32, height: u32) -> Result<(), String> {
    if a.rect != rect {
        return Err(format!("AOVs over {:?}, the task is {rect:?}", a.rect));
    }
    let len = a.weight.len();
    check_rect(a.rect, len, width, height, "AOVs")?;
    if [a.hit.len(), a.albedo.len(), a.normal.len(), a.depth.len()]
        .iter()
        .any(|&l| l != len)
    {
        return Err("AOVs with columns of different lengths".into());
    }
    Ok(())
}

/// Checks splats for a film of `pixels` pixels.
pub fn check_splats(splats: &[[f32; 3]], pixels: usize) -> Result<(), String> {
    if splats.len() != pixels {
        return Err(format!(
            "splats for {} pixels on a film of {pixels}",
            splats.len()
        ));
    }
    Ok(())
}

/// Row-major film indices of the pixels of `rect`, in the rectangle's own row-major order.
fn indices(rect: Rect, width: u32) -> impl Iterator<Item = usize> {
    let [x0, y0, x1, y1] = rect;
    (y0..y1).flat_map(move |y| (x0..x1).map(move |x| (y * width + x) as usize))
}

/// A frame's camera-side sums over the whole film.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FilmAcc {
    pub width: u32,
    pub height: u32,
    /// Samples per pixel folded in.
    pub samples: Vec<u32>,
    sum: Vec<[f64; 3]>,
    weight: Vec<f64>,
    m2: Vec<[f32; 3]>,
}

impl FilmAcc {
    /// Bytes it holds per pixel.
    pub const PIXEL_BYTES: u64 =
        (size_of::<u32>() + size_of::<[f64; 3]>() + size_of::<f64>() + size_of::<[f32; 3]>())
            as u64;

    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        FilmAcc {
            width,
            height,
            samples: vec![0; n],
            sum: vec![[0.0; 3]; n],
            weight: vec![0.0; n],
            m2: vec![[0.0; 3]; n],
        }
    }

    /// Folds a task's sums in: sums added, second moments merged by Chan et al.'s update
    /// M₂ = M₂ₐ + M₂ᵦ + δ² nₐ nᵦ / (nₐ + nᵦ), δ the difference of the two means of w·L.
    pub fn fold(&mut self, s: &FilmSums) -> Result<(), String> {
        check_sums(s, s.rect, s.samples, self.width, self.height)?;
        let variance = !s.m2.is_empty();
        let nb = s.samples as f64;
        for (k, i) in indices(s.rect, self.width).enumerate() {
            let na = self.samples[i] as f64;
            let n = na + nb;
            if variance && n > 0.0 {
                for c in 0..3 {
                    let a = if na > 0.0 { self.sum[i][c] / na } else { 0.0 };
                    let b = if nb > 0.0 {
                        s.sum[k][c] as f64 / nb
                    } else {
                        0.0
                    };
                    let d = b - a;
                    let merged = self.m2[i][c] as f64 + s.m2[k][c].to_f64() + d * d * na * nb / n;
                    self.m2[i][c] = merged as f32;
                }
            }
            for c in 0..3 {
                self.sum[i][c] += s.sum[k][c] as f64;
            }
            self.weight[i] += s.weight[k] as f64;
            self.samples[i] += s.samples;
        }
        Ok(())
    }

    /// Pixel `i`'s estimate Σ w·L / Σ w (0 without weight).
    pub fn mean(&self, i: usize) -> [f64; 3] {
        let w = self.weight[i];
        if w == 0.0 {
            return [0.0; 3];
        }
        self.sum[i].map(|s| s / w)
    }

    /// The variance of pixel `i`'s estimate: Var(w·L) / (n w̄²) with the unbiased sample
    /// variance M₂ / (n − 1) (0 below two samples).
    pub fn variance(&self, i: usize) -> [f32; 3] {
        let n = self.samples[i] as f64;
        let w = self.weight[i];
        if n < 2.0 || w == 0.0 {
            return [0.0; 3];
        }
        let mean_w = w / n;
        self.m2[i].map(|m| ((m as f64 / (n - 1.0)) / (n * mean_w * mean_w)) as f32)
    }

    pub fn len(&self) -> usize {
        self.samples.len()
    }

    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }
}

/// A task's AOVs over a rectangle: what the first surface seen through each pixel looks like.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AovSums {
    pub rect: Rect,
    /// Σ w over the pixel's AOV samples, and over those whose ray hit a surface.
    pub weight: Vec<f32>,
    pub hit: Vec<f32>,
    /// Means over the hits: albedo, world shading normal, depth along the camera axis.
    pub albedo: Vec<[f16; 3]>,
    pub normal: Vec<[f16; 3]>,
    pub depth: Vec<f32>,
}

/// A frame's AOVs, final per pixel (each pixel has one AOV task).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AovAcc {
    pub width: u32,
    pub height: u32,
    alpha: Vec<f32>,
    albedo: Vec<[f32; 3]>,
    normal: Vec<[f32; 3]>,
    depth: Vec<f32>,
}

impl AovAcc {
    /// Bytes it holds per pixel.
    pub const PIXEL_BYTES: u64 = (2 * size_of::<f32>() + 2 * size_of::<[f32; 3]>()) as u64;

    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        AovAcc {
            width,
            height,
            alpha: vec![0.0; n],
            albedo: vec![[0.0; 3]; n],
            normal: vec![[0.0; 3]; n],
            depth: vec![0.0; n],
        }
    }

    pub fn fold(&mut self, a: &AovSums) -> Result<(), String> {
        check_aov(a, a.rect, self.width, self.height)?;
        for (k, i) in indices(a.rect, self.width).enumerate() {
            self.alpha[i] = if a.weight[k] != 0.0 {
                a.hit[k] / a.weight[k]
            } else {
                0.0
            };
            self.albedo[i] = a.albedo[k].map(f16::to_f32);
            self.normal[i] = a.normal[k].map(f16::to_f32);
            self.depth[i] = a.depth[k];
        }
        Ok(())
    }

    /// An image with these AOVs and each pixel's colour and variance from `pixel`.
    pub fn image(&self, pixel: impl Fn(usize) -> ([f32; 3], [f32; 3])) -> Image {
        let mut image = Image::new(self.width, self.height);
        for (i, p) in image.pixels.iter_mut().enumerate() {
            let (rgb, variance) = pixel(i);
            *p = Pixel {
                rgb,
                alpha: self.alpha[i],
                albedo: self.albedo[i],
                normal: self.normal[i],
                depth: self.depth[i],
                variance,
            };
        }
        image
    }
}

/// Whole-film splats (light tracing, Markov chains): Σ per pixel over a task's samples, not
/// exposed, row-major over the film.
pub type Splats = Vec<[f32; 3]>;

/// Adds a task's splats to a frame's.
pub fn add_splats(to: &mut [[f32; 3]], from: &[[f32; 3]]) -> Result<(), String> {
    check_splats(from, to.len())?;
    for (a, b) in to.iter_mut().zip(from) {
        for c in 0..3 {
            a[c] += b[c];
        }
    }
    Ok(())
}

/// The variance of a whole-film method's pixels from its tasks as independent batches.
///
/// A pixel's estimate is a ratio, S / W: the camera side's Σ w·L over its Σ w (filter weights
/// f/pdf, of either sign for a filter with negative lobes), and the splats' Σ l over the
/// samples per pixel N. A batch's own ratio s_b / w_b is no estimate to take the spread of:
/// where a task's weights nearly cancel it is unbounded. The ratio estimator's variance by
/// linearisation is (Cochran, *Sampling Techniques*, §6.4)
///
/// Var(S / W) ≈ T / (T − 1) · Σ_b (s_b − R w_b)² / W², R = S / W, over T batches,
///
/// which needs no division by a batch's weight. The sum of squares is kept about the current
/// R (shifting it when R moves: A ← A − 2δB + δ²C, B ← B − δC with B = Σ w_b (s_b − R w_b),
/// C = Σ w_b²), so it stays on the residuals' scale. The camera side and the splats come from
/// different paths, so their variances add; both are 0 with one batch (unknown).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Batches {
    camera: Ratios,
    splats: Ratios,
}

/// Per pixel, a ratio S / W = Σ_b s_b / Σ_b w_b over independent batches, and the moments of
/// its residuals about it (see [`Batches`]); with w_b = 1 the mean of T batch estimates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Ratios {
    pub batches: u32,
    sum: Vec<[f32; 3]>,
    weight: Vec<f32>,
    /// Σ_b (s_b − R w_b)², Σ_b w_b (s_b − R w_b), Σ_b w_b².
    a: Vec<[f32; 3]>,
    b: Vec<[f32; 3]>,
    c: Vec<f32>,
}

impl Ratios {
    /// Bytes it holds per pixel.
    pub const PIXEL_BYTES: u64 = (3 * size_of::<[f32; 3]>() + 2 * size_of::<f32>()) as u64;

    pub fn new(pixels: usize) -> Self {
        Ratios {
            batches: 0,
            sum: vec![[0.0; 3]; pixels],
            weight: vec![0.0; pixels],
            a: vec![[0.0; 3]; pixels],
            b: vec![[0.0; 3]; pixels],
            c: vec![0.0; pixels],
        }
    }

    /// Folds a batch: pixel i's (s_b, w_b) from `batch(i)`.
    pub fn fold(&mut self, batch: impl Fn(usize) -> ([f64; 3], f64)) {
        for i in 0..self.c.len() {
            let (s, w) = batch(i);
            self.add(i, s, w);
        }
        self.batches += 1;
    }

    fn add(&mut self, i: usize, s: [f64; 3], w: f64) {
        let w0 = self.weight[i] as f64;
        let w1 = w0 + w;
        let c = self.c[i] as f64;
        for (ch, &sb) in s.iter().enumerate() {
            let s0 = self.sum[i][ch] as f64;
            let s1 = s0 + sb;
            let r0 = if w0 != 0.0 { s0 / w0 } else { 0.0 };
            let r1 = if w1 != 0.0 { s1 / w1 } else { 0.0 };
            let d = r1 - r0;
            let (a, b) = (self.a[i][ch] as f64, self.b[i][ch] as f64);
            let e = sb - r1 * w;
            self.a[i][ch] = (a - 2.0 * d * b + d * d * c + e * e).max(0.0) as f32;
            self.b[i][ch] = (b - d * c + w * e) as f32;
            self.sum[i][ch] = s1 as f32;
        }
        self.c[i] = (c + w * w) as f32;
        self.weight[i] = w1 as f32;
    }

    /// The variance of pixel `i`'s ratio, T / (T − 1) · Σ_b (s_b − R w_b)² / W² (0 below two
    /// batches or without weight).
    pub fn variance(&self, i: usize) -> [f64; 3] {
        let (t, w) = (self.batches as f64, self.weight[i] as f64);
        if self.batches < 2 || w == 0.0 {
            return [0.0; 3];
        }
        self.a[i].map(|a| t / (t - 1.0) * a as f64 / (w * w))
    }
}

impl Batches {
    /// Bytes it holds per pixel.
    pub const PIXEL_BYTES: u64 = 2 * Ratios::PIXEL_BYTES;

    pub fn new(pixels: usize) -> Self {
        Batches {
            camera: Ratios::new(pixels),
            splats: Ratios::new(pixels),
        }
    }

    /// Batches folded in.
    pub fn batches(&self) -> u32 {
        self.camera.batches
    }

    /// Folds a batch of `n` samples per pixel: pixel i's camera-side Σ w·L and Σ w, and its
    /// splats' sum (exposed), from `batch(i)`.
    pub fn fold(&mut self, n: u32, batch: impl Fn(usize) -> ([f64; 3], f64, [f64; 3])) {
        if n == 0 {
            return;
        }
        for i in 0..self.camera.c.len() {
            let (s, w, l) = batch(i);
            self.camera.add(i, s, w);
            self.splats.add(i, l, n as f64);
        }
        self.camera.batches += 1;
        self.splats.batches += 1;
    }

    /// The variance of pixel `i`'s estimate over every batch.
    pub fn variance(&self, i: usize) -> [f32; 3] {
        let (a, b) = (self.camera.variance(i), self.splats.variance(i));
        std::array::from_fn(|c| (a[c] + b[c]) as f32)
    }
}

/// A spectrum as three f32.
pub fn rgb(s: Spectrum) -> [f32; 3] {
    [s.x, s.y, s.z]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::{SampleRange, Tile, TileSums};

    fn sums(tile: Tile, range: SampleRange, seed: u32) -> TileSums {
        let mut t = TileSums::new(tile, range);
        for (k, p) in t.pixels.iter_mut().enumerate() {
            for s in range.start..range.end {
                let x = ((s * 7919 + k as u32 * 104_729 + seed) % 1000) as f32 / 250.0;
                p.add(0.75 + (s % 3) as f32 * 0.25, Spectrum::new(x, 2.0 * x, 0.1));
            }
        }
        t
    }

    /// Folding sample ranges one by one gives the moments of all the samples at once, to f32's
    /// precision: the sum, the weight and (Chan's update) the second moment.
    #[test]
    fn folding_ranges_matches_one_range() {
        let tile = Tile {
            x0: 1,
            y0: 2,
            x1: 4,
            y1: 4,
        };
        let mut acc = FilmAcc::new(5, 5);
        for (a, b) in [(0, 3), (3, 4), (4, 10)] {
            let r = SampleRange { start: a, end: b };
            acc.fold(&FilmSums::from_tile(&sums(tile, r, 0), true))
                .expect("fits");
        }
        let whole = FilmSums::from_tile(&sums(tile, SampleRange { start: 0, end: 10 }, 0), true);
        let mut one = FilmAcc::new(5, 5);
        one.fold(&whole).expect("fits");
        for i in indices(whole.rect, 5) {
            assert_eq!(acc.samples[i], 10);
            for c in 0..3 {
                let (m, m1) = (acc.mean(i)[c], one.mean(i)[c]);
                assert!((m - m1).abs() <= 1e-6 * m1.abs().max(1.0), "{m} {m1}");
                let (v, v1) = (acc.variance(i)[c], one.variance(i)[c]);
                assert!((v - v1).abs() <= 0.02 * v1.abs() + 1e-9, "{v} {v1}");
            }
        }
        assert_eq!(acc.variance(0), [0.0; 3], "a pixel without samples");
        let off = FilmSums {
            rect: [3, 3, 6, 4],
            ..whole.clone()
        };
        assert!(acc.fold(&off).is_err());
    }

    #[test]
    fn batches_estimate_the_variance_of_the_mean() {
        // Batches whose estimates are 1 ± 0.5: variance per sample n·0.25 for batches of n.
        let mut b = Batches::new(1);
        for k in 0..400u32 {
            let e = if k % 2 == 0 { 1.5 } else { 0.5 };
            b.fold(4, |_| ([4.0 * e; 3], 4.0, [0.0; 3]));
        }
        let v = b.variance(0)[0] as f64;
        let expect = 4.0 * 0.25 / 1600.0;
        assert!((v / expect - 1.0).abs() < 0.01, "{v} {expect}");
        assert_eq!(Batches::new(1).variance(0), [0.0; 3]);
    }

    /// Filter weights of either sign: a batch whose weights nearly cancel has a huge ratio of
    /// its own, but the estimate's variance stays that of the linearised ratio, which the
    /// spread of independent frames confirms.
    #[test]
    fn batches_of_signed_weights_estimate_the_ratios_variance() {
        use crate::sampler::IndependentSampler;
        use crate::sampler::Sampler;
        let mut rng = IndependentSampler::new(7);
        let mut index = 0;
        // Each sample: weight +1 with probability 0.9, else −1 (a negative lobe); value 2 + noise.
        let mut batch = |rng: &mut IndependentSampler| {
            let (mut s, mut w) = (0.0, 0.0);
            for _ in 0..3 {
                rng.start_pixel_sample(glam::UVec2::ZERO, index);
                index += 1;
                let wi: f64 = if rng.get_1d() < 0.9 { 1.0 } else { -1.0 };
                let li = 2.0 + rng.get_1d() as f64 - 0.5;
                s += wi * li;
                w += wi;
            }
            (s, w)
        };
        let (frames, per) = (2000, 8);
        let (mut estimates, mut predicted) = (Vec::new(), 0.0);
        for _ in 0..frames {
            let mut b = Batches::new(1);
            let (mut s, mut w) = (0.0, 0.0);
            for _ in 0..per {
                let (bs, bw) = batch(&mut rng);
                b.fold(3, |_| ([bs; 3], bw, [0.0; 3]));
                s += bs;
                w += bw;
            }
            if w != 0.0 {
                estimates.push(s / w);
                predicted += b.variance(0)[0] as f64;
            }
        }
        let n = estimates.len() as f64;
        let mean = estimates.iter().sum::<f64>() / n;
        let measured = estimates.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1.0);
        let predicted = predicted / n;
        // Both are means of 2000 nearly independent terms: each within a few per cent (about
        // √(2/2000) relative) of its expectation, so 15 % is several standard errors.
        assert!(
            (predicted / measured - 1.0).abs() < 0.15,
            "predicted {predicted:.3e}, measured {measured:.3e}"
        );
    }
}
