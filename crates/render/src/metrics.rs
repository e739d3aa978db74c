//! Error of an image against a reference.

use glam::Vec3A;

/// Errors of `image` against `reference` (same size, linear RGB).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageError {
    /// Relative MSE: mean over pixels and channels of (x − r)² / (r² + 0.01).
    pub rel_mse: f64,
    pub rmse: f64,
    /// Mean of the image over mean of the reference (all channels).
    pub mean_ratio: f64,
}

pub fn compare(image: &[Vec3A], reference: &[Vec3A]) -> ImageError {
    assert_eq!(image.len(), reference.len(), "images differ in size");
    let (mut rel, mut sq, mut sum_x, mut sum_r) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (x, r) in image.iter().zip(reference) {
        for c in 0..3 {
            let (x, r) = (x[c] as f64, r[c] as f64);
            let d = x - r;
            rel += d * d / (r * r + 0.01);
            sq += d * d;
            sum_x += x;
            sum_r += r;
        }
    }
    let n = (image.len() * 3) as f64;
    ImageError {
        rel_mse: rel / n,
        rmse: (sq / n).sqrt(),
        mean_ratio: sum_x / sum_r,
    }
}

/// relMSE predicted by the film's own per-pixel variance of the mean, with no reference:
/// mean over pixels and channels of Var / (x² + 0.01) — the expectation of the measured relMSE
/// for an unbiased render (up to the noise in x² and in the variance estimate itself). Pixels
/// with a single sample have no variance estimate and count as 0.
pub fn estimated_rel_mse(image: &crate::Image) -> f64 {
    let mut sum = 0.0f64;
    for p in &image.pixels {
        for c in 0..3 {
            let x = p.rgb[c] as f64;
            sum += p.variance[c] as f64 / (x * x + 0.01);
        }
    }
    sum / (image.pixels.len() * 3).max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_images_have_zero_error() {
        let a = vec![Vec3A::new(0.1, 0.5, 2.0); 4];
        let e = compare(&a, &a);
        assert_eq!((e.rel_mse, e.rmse, e.mean_ratio), (0.0, 0.0, 1.0));
        let b: Vec<Vec3A> = a.iter().map(|v| *v * 1.1).collect();
        assert!((compare(&b, &a).mean_ratio - 1.1).abs() < 1e-6);
    }
}
