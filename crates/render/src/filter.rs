//! Pixel reconstruction filters, applied by filter importance sampling (Ernst et al., "Filter
//! Importance Sampling", 2006; pbrt-v4 §8.8): each sample belongs to one pixel, its position
//! is drawn from |f| around the pixel centre and it carries the weight f/pdf. A pixel therefore
//! depends only on its own samples: tiles need no shared borders and the image does not depend
//! on how it was cut into tiles.

use glam::Vec2;
use tessera_scene::FilterDesc;

use crate::sampling::Distribution1D;

/// Bins of the tabulated |f| along one axis.
const TABLE: usize = 256;

#[derive(Debug, Clone)]
pub struct Filter {
    desc: FilterDesc,
    radius: f32,
    /// |f| along one axis for separable, non-box filters, tabulated.
    table: Option<Distribution1D>,
    /// A sample's weight factor along one axis, by the table's bin it falls in: ∫ |f| over
    /// the table, negative in the filter's negative lobes.
    bin_weights: Vec<f32>,
    /// ∫ f along one axis over the table: the mean of a weight's factor along it.
    table_integral: f32,
    /// ∫ f along one axis.
    integral: f32,
}

/// Mitchell–Netravali cubic on t = |2x/r| ∈ [0, 2] (Mitchell & Netravali 1988).
fn mitchell(t: f32, b: f32, c: f32) -> f32 {
    let t = t.abs();
    if t < 1.0 {
        ((12.0 - 9.0 * b - 6.0 * c) * t * t * t
            + (-18.0 + 12.0 * b + 6.0 * c) * t * t
            + (6.0 - 2.0 * b))
            / 6.0
    } else if t < 2.0 {
        ((-b - 6.0 * c) * t * t * t
            + (6.0 * b + 30.0 * c) * t * t
            + (-12.0 * b - 48.0 * c) * t
            + (8.0 * b + 24.0 * c))
            / 6.0
    } else {
        0.0
    }
}

impl Filter {
    pub fn new(desc: FilterDesc) -> Self {
        let radius = match desc {
            FilterDesc::Box { radius }
            | FilterDesc::Gaussian { radius, .. }
            | FilterDesc::Mitchell { radius, .. } => radius,
        };
        let mut f = Filter {
            desc,
            radius,
            table: None,
            bin_weights: Vec::new(),
            table_integral: 1.0,
            integral: 1.0,
        };
        f.integral = f.integral_1d();
        if !matches!(desc, FilterDesc::Box { .. }) {
            let values: Vec<f32> = (0..TABLE)
                .map(|i| f.eval_1d(((i as f32 + 0.5) / TABLE as f32 * 2.0 - 1.0) * radius))
                .collect();
            let h = 2.0 * radius as f64 / TABLE as f64;
            f.table_integral = (values.iter().map(|&v| v as f64).sum::<f64>() * h) as f32;
            let table = Distribution1D::new(&values);
            let abs_integral = table.integral() * 2.0 * radius;
            f.bin_weights = values
                .iter()
                .map(|&v| if v < 0.0 { -abs_integral } else { abs_integral })
                .collect();
            f.table = Some(table);
        }
        f
    }

    /// E[w] of [`Self::sample`]'s weights: ∫∫ f over the table = (∫ f along one axis)², and 1
    /// for the box, whose samples all weigh 1. Σ w·L / (n E[w]) over n samples is the pixel's
    /// filtered value without the ratio Σ w·L / Σ w, whose denominator a filter's negative
    /// lobes bring to 0 when a pixel's few samples fall as many in them as out.
    pub fn mean_weight(&self) -> f64 {
        match self.table {
            None => 1.0,
            Some(_) => (self.table_integral as f64).powi(2),
        }
    }

    /// Half-width of the filter's support, pixels.
    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// The filter at offset `d` pixels from a pixel centre, divided by its integral: the
    /// share of a splat at `d` that the pixel receives. A pixel's camera samples estimate
    /// ∫ f(x − c) L(x) dx / ∫ f (see [`Self::sample`]), so a splat shared this way estimates
    /// the same; the shares sum to 1 on average over where a splat lands, not at every point
    /// (a narrow Gaussian is no partition of unity).
    pub fn splat_weight(&self, d: Vec2) -> f32 {
        self.splat_weight_1d(d.x) * self.splat_weight_1d(d.y)
    }

    /// [`Self::splat_weight`] along one axis (the filter is separable): the weight of pixel
    /// (x, y) is the product of the factors at its column's and its row's offsets.
    pub fn splat_weight_1d(&self, d: f32) -> f32 {
        self.eval_1d(d) / self.integral
    }

    /// ∫ f along one axis (midpoint rule, 1024 steps; exact for the box).
    fn integral_1d(&self) -> f32 {
        match self.desc {
            FilterDesc::Box { radius } => 2.0 * radius,
            _ => {
                let n = 1024;
                let h = 2.0 * self.radius / n as f32;
                (0..n)
                    .map(|i| self.eval_1d(-self.radius + (i as f32 + 0.5) * h))
                    .sum::<f32>()
                    * h
            }
        }
    }

    /// The filter along one axis at offset `x` pixels.
    pub fn eval_1d(&self, x: f32) -> f32 {
        match self.desc {
            FilterDesc::Box { radius } => (x.abs() <= radius) as u8 as f32,
            FilterDesc::Gaussian { radius, sigma } => {
                let g = |x: f32| (-x * x / (2.0 * sigma * sigma)).exp();
                (g(x) - g(radius)).max(0.0)
            }
            FilterDesc::Mitchell { radius, b, c } => mitchell(2.0 * x / radius, b, c),
        }
    }

    /// An offset from the pixel centre and the sample's weight f/pdf, f the tabulated filter
    /// (constant over each of its bins, as pbrt-v4's `FilterSampler`): along each axis ±∫ |f|,
    /// so every weight has the same magnitude and a pixel's Σ w is a multiple of it, never
    /// near 0 but at 0 (a sample's own f at a bin that straddles a zero of the filter, over
    /// the bin's mean, could be any small number, and one such sample beside one of the other
    /// sign left Σ w·L / Σ w unbounded).
    #[inline]
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let r = self.radius;
        match &self.table {
            None => ((u - Vec2::splat(0.5)) * (2.0 * r), 1.0),
            Some(table) => {
                let axis = |u: f32| {
                    let (x01, _, bin) = table.sample_continuous(u);
                    ((x01 * 2.0 - 1.0) * r, self.bin_weights[bin])
                };
                let (x, wx) = axis(u.x);
                let (y, wy) = axis(u.y);
                (Vec2::new(x, y), wx * wy)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GAUSSIAN: FilterDesc = FilterDesc::Gaussian {
        radius: 1.5,
        sigma: 0.5,
    };
    const MITCHELL: FilterDesc = FilterDesc::Mitchell {
        radius: 2.0,
        b: 1.0 / 3.0,
        c: 1.0 / 3.0,
    };

    /// A splat's shares over the pixels around it sum to 1 on average over where in a pixel
    /// it lands (a 32×32 grid of positions; exact for the box at every position).
    #[test]
    fn splat_weights_sum_to_one_on_average() {
        for desc in [FilterDesc::Box { radius: 0.5 }, GAUSSIAN, MITCHELL] {
            let f = Filter::new(desc);
            let n = 32;
            let mut mean = 0.0f64;
            for j in 0..n * n {
                let at = Vec2::new(
                    ((j % n) as f32 + 0.5) / n as f32,
                    ((j / n) as f32 + 0.5) / n as f32,
                );
                let mut sum = 0.0;
                for y in -4..=4 {
                    for x in -4..=4 {
                        let centre = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                        sum += f.splat_weight(at - centre);
                    }
                }
                if matches!(desc, FilterDesc::Box { .. }) {
                    assert!((sum - 1.0).abs() < 1e-6, "box at {at}: {sum}");
                }
                mean += sum as f64 / (n * n) as f64;
            }
            assert!((mean - 1.0).abs() < 2e-3, "{desc:?}: {mean}");
        }
    }

    #[test]
    fn box_offsets_cover_the_pixel_with_unit_weight() {
        let f = Filter::new(FilterDesc::Box { radius: 0.5 });
        assert_eq!(f.sample(Vec2::ZERO), (Vec2::splat(-0.5), 1.0));
        assert_eq!(f.sample(Vec2::splat(0.5)), (Vec2::ZERO, 1.0));
    }

    #[test]
    fn weighted_mean_reproduces_the_filter_average() {
        // For a linear function g(x) = x + 1 the filtered value at the centre is 1 (symmetric
        // filters), whatever the filter: Σ w g / Σ w must converge to 1.
        for desc in [GAUSSIAN, MITCHELL] {
            let f = Filter::new(desc);
            let (mut swg, mut sw) = (0.0f64, 0.0f64);
            let n = 256;
            for i in 0..n {
                for j in 0..n {
                    let (o, w) = f.sample(Vec2::new(
                        (i as f32 + 0.5) / n as f32,
                        (j as f32 + 0.5) / n as f32,
                    ));
                    assert!(o.abs().max_element() <= f.radius);
                    swg += (w * (o.x + 1.0)) as f64;
                    sw += w as f64;
                }
            }
            assert!((swg / sw - 1.0).abs() < 1e-3, "{desc:?}: {}", swg / sw);
        }
    }

    /// Every weight of a filter has one magnitude, and their mean is `mean_weight`; so a
    /// pixel of two samples with radiance 1 and 2 is their mean where their signs agree and
    /// has no weight (Σ w exactly 0) where they do not. A sample's own f over its bin's
    /// mean gave weights near 0 at the Mitchell's zero crossings, and such a pair's
    /// Σ w·L / Σ w anywhere.
    #[test]
    fn weights_have_one_magnitude_so_a_pixel_is_never_extrapolated() {
        for desc in [GAUSSIAN, MITCHELL] {
            let f = Filter::new(desc);
            let n = 128;
            let ws: Vec<f32> = (0..n * n)
                .map(|j| {
                    let u = Vec2::new(
                        ((j % n) as f32 + 0.5) / n as f32,
                        ((j / n) as f32 + 0.5) / n as f32,
                    );
                    f.sample(u).1
                })
                .collect();
            let c = ws[0].abs();
            assert!(ws.iter().all(|w| w.abs() == c), "{desc:?}");
            let mean = ws.iter().map(|&w| w as f64).sum::<f64>() / ws.len() as f64;
            assert!(
                (mean / f.mean_weight() - 1.0).abs() < 1e-2,
                "{desc:?}: {mean} against {}",
                f.mean_weight()
            );
            if matches!(desc, FilterDesc::Mitchell { .. }) {
                assert!(ws.iter().any(|&w| w < 0.0), "the Mitchell's lobes");
            }
            for (i, &a) in ws.iter().enumerate().step_by(7) {
                for &b in ws.iter().skip(i % 5).step_by(11) {
                    let (sw, swl) = (a + b, a * 1.0 + b * 2.0);
                    assert!(
                        sw == 0.0 || (1.0..=2.0).contains(&(swl / sw)),
                        "{desc:?}: weights {a}, {b}"
                    );
                }
            }
        }
    }

    #[test]
    fn mitchell_has_negative_lobes_and_unit_partition() {
        assert!(mitchell(1.5, 1.0 / 3.0, 1.0 / 3.0) < 0.0);
        // The cubic's integer translates sum to one (B + 2C = 1 family).
        let s: f32 = [-2.0f32, -1.0, 0.0, 1.0]
            .iter()
            .map(|&k| mitchell(0.3 + k, 1.0 / 3.0, 1.0 / 3.0))
            .sum();
        assert!((s - 1.0).abs() < 1e-5, "{s}");
    }
}
