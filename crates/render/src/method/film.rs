//! What camera-side tasks hand over, and what a frame accumulates them into.
//!
//! A task renders in the core's fixed-point sums ([`crate::film::TileSums`]: exact, the same
//! whatever order its threads add in) and hands over only what the fold needs, per pixel:
//! Σ w·L and Σ w in f32 and the centred second moment of w·L in bf16 (a statistic: 8 bits of
//! precision are plenty) — 22 bytes, where the fixed-point sums are 248. Whole-film methods
//! add their light-tracing or chain splats (12 bytes) and leave out the second moment (their
//! variance comes from batches, see [`Batches`]). The AOVs come from tasks of their own
//! ([`super::aov`]), 24 bytes a pixel, once per frame.
//!
//! The frame folds in the plan's order, in f64 where sums grow (Chan et al.'s pairwise update
//! for the second moment), so a frame is the same bits however its tasks were spread.

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
        check_rect(s.rect, s.sum.len(), self.width, self.height, "film sums")?;
        let variance = !s.m2.is_empty();
        if s.weight.len() != s.sum.len() || (variance && s.m2.len() != s.sum.len()) {
            return Err("film sums with columns of different lengths".into());
        }
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
        let len = a.weight.len();
        check_rect(a.rect, len, self.width, self.height, "AOVs")?;
        if [a.hit.len(), a.albedo.len(), a.normal.len(), a.depth.len()]
            .iter()
            .any(|&l| l != len)
        {
            return Err("AOVs with columns of different lengths".into());
        }
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
    if to.len() != from.len() {
        return Err(format!(
            "splats for {} pixels on a film of {}",
            from.len(),
            to.len()
        ));
    }
    for (a, b) in to.iter_mut().zip(from) {
        for c in 0..3 {
            a[c] += b[c];
        }
    }
    Ok(())
}

/// The variance of a whole-film method's pixels from its tasks as independent batches: each
/// task's estimate of the pixel, weighted by its samples, merged by Chan et al.'s update. With
/// T batches, M₂ / (T − 1) estimates the variance of one sample, so M₂ / ((T − 1) N) that of
/// the frame's estimate of N samples (0 with one batch: unknown).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Batches {
    pub batches: u32,
    samples: u32,
    mean: Vec<[f32; 3]>,
    m2: Vec<[f32; 3]>,
}

impl Batches {
    pub fn new(pixels: usize) -> Self {
        Batches {
            batches: 0,
            samples: 0,
            mean: vec![[0.0; 3]; pixels],
            m2: vec![[0.0; 3]; pixels],
        }
    }

    /// Folds a batch of `n` samples per pixel whose estimate of pixel i is `estimate(i)`.
    pub fn fold(&mut self, n: u32, estimate: impl Fn(usize) -> [f64; 3]) {
        if n == 0 {
            return;
        }
        let (na, nb) = (self.samples as f64, n as f64);
        let total = na + nb;
        for (i, (mean, m2)) in self.mean.iter_mut().zip(self.m2.iter_mut()).enumerate() {
            let e = estimate(i);
            for c in 0..3 {
                let d = e[c] - mean[c] as f64;
                mean[c] = (mean[c] as f64 + d * nb / total) as f32;
                m2[c] = (m2[c] as f64 + d * d * na * nb / total) as f32;
            }
        }
        self.samples += n;
        self.batches += 1;
    }

    /// The variance of pixel `i`'s estimate over every batch.
    pub fn variance(&self, i: usize) -> [f32; 3] {
        if self.batches < 2 {
            return [0.0; 3];
        }
        let scale = 1.0 / ((self.batches - 1) as f64 * self.samples as f64);
        self.m2[i].map(|m| (m as f64 * scale) as f32)
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
                p.add(
                    0.75 + (s % 3) as f32 * 0.25,
                    Spectrum::new(x, 2.0 * x, 0.1),
                    None,
                );
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
            b.fold(4, |_| [e; 3]);
        }
        let v = b.variance(0)[0] as f64;
        let expect = 4.0 * 0.25 / 1600.0;
        assert!((v / expect - 1.0).abs() < 0.01, "{v} {expect}");
        assert_eq!(Batches::new(1).variance(0), [0.0; 3]);
    }
}
