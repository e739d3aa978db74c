//! Warps from the unit square to directions and points, with their densities, and tabulated
//! piecewise-constant distributions (pbrt-v4 ch. A.5 and A.6).

use glam::{Vec2, Vec3A};

use crate::math::{INV_4PI, INV_PI, PI, safe_sqrt};

/// Concentric map of the square to the unit disk (Shirley & Chiu 1997): area-preserving.
#[inline]
pub fn square_to_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, (PI / 4.0) * (o.y / o.x))
    } else {
        (o.y, PI / 2.0 - (PI / 4.0) * (o.x / o.y))
    };
    let (s, c) = theta.sin_cos();
    Vec2::new(r * c, r * s)
}

/// Cosine-weighted direction on the +z hemisphere (Malley's method); pdf = cos θ / π.
#[inline]
pub fn square_to_cosine_hemisphere(u: Vec2) -> Vec3A {
    let d = square_to_disk(u);
    Vec3A::new(d.x, d.y, safe_sqrt(1.0 - d.length_squared()))
}

#[inline]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * INV_PI
}

/// Uniform direction on the unit sphere; pdf = 1 / 4π.
#[inline]
pub fn square_to_uniform_sphere(u: Vec2) -> Vec3A {
    let z = 1.0 - 2.0 * u.x;
    let r = safe_sqrt(1.0 - z * z);
    let (s, c) = (2.0 * PI * u.y).sin_cos();
    Vec3A::new(r * c, r * s, z)
}

pub const UNIFORM_SPHERE_PDF: f32 = INV_4PI;

/// Uniform direction in the cone around +z with cos θ ≥ 1 − `one_minus_cos_max`;
/// pdf = 1 / (2π · one_minus_cos_max). The cone is given by 1 − cos θ_max, not cos θ_max, so
/// that tiny cones (a 1 mm light 2 m away: 1 − cos θ_max ≈ 1e-7, below f32's resolution near 1)
/// keep their size; sin θ comes from (1 − cos θ)(1 + cos θ) for the same reason.
#[inline]
pub fn square_to_uniform_cone(u: Vec2, one_minus_cos_max: f32) -> Vec3A {
    let one_minus_cos = u.x * one_minus_cos_max;
    let cos_theta = 1.0 - one_minus_cos;
    let sin_theta = safe_sqrt(one_minus_cos * (2.0 - one_minus_cos));
    let (s, c) = (2.0 * PI * u.y).sin_cos();
    Vec3A::new(sin_theta * c, sin_theta * s, cos_theta)
}

#[inline]
pub fn uniform_cone_pdf(one_minus_cos_max: f32) -> f32 {
    1.0 / (2.0 * PI * one_minus_cos_max)
}

/// 1 − cos θ_max of the cone a sphere of radius² `r2` subtends from distance² `d2` (> r2),
/// without cancellation: sin²θ_max / (1 + cos θ_max).
#[inline]
pub fn sphere_cone_one_minus_cos(r2: f32, d2: f32) -> f32 {
    let sin2 = (r2 / d2).min(1.0);
    sin2 / (1.0 + (1.0 - sin2).max(0.0).sqrt())
}

/// Uniform barycentric coordinates (b0, b1, b2) over a triangle (pbrt-v4 SampleUniformTriangle,
/// the square-root-free warp of Heitz 2019).
#[inline]
pub fn square_to_triangle(u: Vec2) -> [f32; 3] {
    let (b0, b1) = if u.x < u.y {
        let b0 = u.x / 2.0;
        (b0, u.y - b0)
    } else {
        let b1 = u.y / 2.0;
        (u.x - b1, b1)
    };
    [b0, b1, 1.0 - b0 - b1]
}

/// Veach's power heuristic (β = 2) weight for a sample of density `f` against `g`.
#[inline]
pub fn power_heuristic(f: f32, g: f32) -> f32 {
    let (f2, g2) = (f * f, g * g);
    if f2.is_infinite() {
        return 1.0;
    }
    if f2 + g2 == 0.0 {
        return 0.0;
    }
    f2 / (f2 + g2)
}

/// A piecewise-constant density on [0, 1) with `n` equal bins.
#[derive(Debug, Clone)]
pub struct Distribution1D {
    func: Vec<f32>,
    cdf: Vec<f32>,
    integral: f32,
}

impl Distribution1D {
    /// Builds from non-negative bin values; all-zero input becomes uniform.
    pub fn new(values: &[f32]) -> Self {
        assert!(!values.is_empty(), "a distribution needs at least one bin");
        let n = values.len();
        let func: Vec<f32> = values.iter().map(|v| v.abs()).collect();
        let mut cdf = vec![0.0f32; n + 1];
        let mut acc = 0.0f64;
        for i in 0..n {
            acc += func[i] as f64 / n as f64;
            cdf[i + 1] = acc as f32;
        }
        let integral = acc as f32;
        if integral > 0.0 {
            for c in cdf.iter_mut() {
                *c /= integral;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f32 / n as f32;
            }
        }
        cdf[n] = 1.0;
        Distribution1D {
            func,
            cdf,
            integral,
        }
    }

    pub fn len(&self) -> usize {
        self.func.len()
    }

    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// ∫ f over [0, 1).
    pub fn integral(&self) -> f32 {
        self.integral
    }

    /// Index of the bin with cdf[i] <= u < cdf[i + 1].
    #[inline]
    fn find(&self, u: f32) -> usize {
        let i = self.cdf.partition_point(|&c| c <= u);
        i.saturating_sub(1).min(self.func.len() - 1)
    }

    /// A continuous sample in [0, 1), its density, and its bin.
    #[inline]
    pub fn sample_continuous(&self, u: f32) -> (f32, f32, usize) {
        let i = self.find(u);
        let (c0, c1) = (self.cdf[i], self.cdf[i + 1]);
        let du = if c1 > c0 { (u - c0) / (c1 - c0) } else { 0.0 };
        let x = ((i as f32 + du) / self.len() as f32).min(1.0 - f32::EPSILON / 2.0);
        (x, self.pdf_bin(i), i)
    }

    /// A discrete sample: the bin, its probability, and `u` remapped to [0, 1) within the bin.
    #[inline]
    pub fn sample_discrete(&self, u: f32) -> (usize, f32, f32) {
        let i = self.find(u);
        let (c0, c1) = (self.cdf[i], self.cdf[i + 1]);
        let p = c1 - c0;
        let remapped = if p > 0.0 {
            ((u - c0) / p).min(1.0 - f32::EPSILON / 2.0)
        } else {
            0.0
        };
        (i, p, remapped)
    }

    /// Probability of bin `i` in discrete sampling.
    #[inline]
    pub fn pmf(&self, i: usize) -> f32 {
        self.cdf[i + 1] - self.cdf[i]
    }

    /// Density of continuous sampling anywhere in bin `i`.
    #[inline]
    pub fn pdf_bin(&self, i: usize) -> f32 {
        if self.integral > 0.0 {
            self.func[i] / self.integral
        } else {
            1.0
        }
    }
}

/// A piecewise-constant density on [0, 1)², sampled as marginal rows then a column.
#[derive(Debug, Clone)]
pub struct Distribution2D {
    conditional: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// `values` in row-major order, `width` columns (u) by `height` rows (v).
    pub fn new(values: &[f32], width: usize, height: usize) -> Self {
        let conditional: Vec<Distribution1D> = values
            .chunks_exact(width)
            .take(height)
            .map(Distribution1D::new)
            .collect();
        let row_integrals: Vec<f32> = conditional.iter().map(|d| d.integral()).collect();
        Distribution2D {
            marginal: Distribution1D::new(&row_integrals),
            conditional,
        }
    }

    /// A point (u, v) and its density with respect to area in [0, 1)².
    #[inline]
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let (v, pdf_v, row) = self.marginal.sample_continuous(u.y);
        let (x, pdf_u, _) = self.conditional[row].sample_continuous(u.x);
        (Vec2::new(x, v), pdf_v * pdf_u)
    }

    #[inline]
    pub fn pdf(&self, p: Vec2) -> f32 {
        let rows = self.conditional.len();
        let cols = self.conditional[0].len();
        let iv = ((p.y * rows as f32) as usize).min(rows - 1);
        let iu = ((p.x * cols as f32) as usize).min(cols - 1);
        if self.marginal.integral() == 0.0 {
            return 1.0;
        }
        self.conditional[iv].func[iu] / self.marginal.integral()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disk_and_hemisphere_warps_stay_in_domain() {
        for i in 0..64 {
            for j in 0..64 {
                let u = Vec2::new(i as f32 / 63.0, j as f32 / 63.0);
                assert!(square_to_disk(u).length() <= 1.0 + 1e-6);
                let w = square_to_cosine_hemisphere(u);
                assert!((w.length() - 1.0).abs() < 1e-5 && w.z >= 0.0);
                let c = square_to_uniform_cone(u, 0.2);
                assert!(c.z >= 0.8 - 1e-6);
                let b = square_to_triangle(u);
                assert!(b.iter().all(|&x| (-1e-7..=1.0).contains(&x)));
            }
        }
    }

    #[test]
    fn distribution_1d_samples_proportionally() {
        let d = Distribution1D::new(&[1.0, 3.0, 0.0, 4.0]);
        assert!((d.integral() - 2.0).abs() < 1e-6);
        assert!((d.pmf(1) - 3.0 / 8.0).abs() < 1e-6);
        assert_eq!(d.pmf(2), 0.0);
        let mut counts = [0usize; 4];
        let n = 80_000;
        for i in 0..n {
            let (x, pdf, bin) = d.sample_continuous((i as f32 + 0.5) / n as f32);
            assert_eq!((x * 4.0) as usize, bin);
            assert!((pdf - d.pdf_bin(bin)).abs() < 1e-6);
            counts[bin] += 1;
        }
        assert_eq!(counts[2], 0);
        assert!((counts[3] as f32 / n as f32 - 0.5).abs() < 1e-3);
    }

    #[test]
    fn distribution_2d_density_matches_sampling() {
        let vals = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
        let d = Distribution2D::new(&vals, 3, 2);
        let total: f32 = vals.iter().sum::<f32>() / 6.0;
        let (p, pdf) = d.sample(Vec2::new(0.99, 0.99));
        assert!((pdf - 5.0 / total).abs() < 1e-4 && (d.pdf(p) - pdf).abs() < 1e-4);
    }
}
