//! Kubelka–Munk layers (Kubelka & Munk 1931; in graphics Haase & Meyer 1992, Dorsey &
//! Hanrahan 1996): two diffuse fluxes, down and up, in a layer that absorbs (K) and scatters
//! (S) per unit length. A layer of thickness d reflects and transmits, per channel,
//!
//! R = sinh(bSd) / (a sinh(bSd) + b cosh(bSd)),  T = b / (a sinh(bSd) + b cosh(bSd)),
//!
//! with a = 1 + K/S and b = √(a² − 1) (R → R∞ = a − b as d grows; at K = 0,
//! R = Sd / (1 + Sd) and T = 1 − R). Layers stack by summing the inter-reflections,
//! R₁₂ = R₁ + T₁² R₂ / (1 − R₁ R₂), T₁₂ = T₁ T₂ / (1 − R₁ R₂). The material is Lambertian
//! with the stack's reflectance over its substrate.

use crate::spectrum::Spectrum;

/// (R, T) of one layer: absorption `k` and scattering `s` per unit length, thickness `d` in the
/// same unit. Written with e^(−2bSd) so that thick layers neither overflow nor lose digits.
pub fn layer(k: f64, s: f64, d: f64) -> (f64, f64) {
    if s <= 0.0 {
        return (0.0, (-k * d).exp());
    }
    let a = 1.0 + k / s;
    let b = (a * a - 1.0).sqrt();
    let x = b * s * d;
    if x < 1e-9 {
        // K = 0 (or a vanishing layer): the limit of the formulas above.
        let r = s * d / (1.0 + s * d);
        return (r, 1.0 - r);
    }
    let e = (-2.0 * x).exp();
    let den = a * (1.0 - e) + b * (1.0 + e);
    ((1.0 - e) / den, 2.0 * b * (-x).exp() / den)
}

/// (R, T) of layer 1 on top of layer 2.
pub fn stack((r1, t1): (f64, f64), (r2, t2): (f64, f64)) -> (f64, f64) {
    let inter = 1.0 / (1.0 - r1 * r2);
    (r1 + t1 * t1 * r2 * inter, t1 * t2 * inter)
}

/// The reflectance of `layers` (top first: absorption, scattering per mm, thickness in mm)
/// over an opaque substrate of reflectance `substrate`.
pub fn reflectance(layers: &[tessera_scene::KmLayer], substrate: Spectrum) -> Spectrum {
    let channel = |c: usize| {
        let below = (substrate[c] as f64, 0.0);
        layers.iter().rev().fold(below, |below, l| {
            let one = layer(
                l.absorption[c] as f64,
                l.scattering[c] as f64,
                l.thickness as f64,
            );
            stack(one, below)
        })
    };
    Spectrum::new(
        channel(0).0 as f32,
        channel(1).0 as f32,
        channel(2).0 as f32,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) {
        assert!((a - b).abs() <= tol, "{a} vs {b}");
    }

    #[test]
    fn a_layer_meets_its_closed_forms_and_limits() {
        // Non-absorbing: R = Sd / (1 + Sd), T = 1 − R.
        let (r, t) = layer(0.0, 3.0, 0.5);
        close(r, 1.5 / 2.5, 1e-12);
        close(t, 1.0 / 2.5, 1e-12);
        // Absorbing: the sinh/cosh forms directly, and R + T < 1.
        let (k, s, d) = (0.4, 2.0, 0.7);
        let a = 1.0 + k / s;
        let b = (a * a - 1.0f64).sqrt();
        let x = b * s * d;
        let den = a * x.sinh() + b * x.cosh();
        let (r, t) = layer(k, s, d);
        close(r, x.sinh() / den, 1e-12);
        close(t, b / den, 1e-12);
        assert!(r + t < 1.0);
        // Thick: R∞ = a − b, no light through; nothing scatters: Beer–Lambert.
        let (r, t) = layer(k, s, 1e4);
        close(r, a - b, 1e-12);
        close(t, 0.0, 1e-300);
        close(layer(0.5, 0.0, 2.0).1, (-1.0f64).exp(), 1e-15);
    }

    #[test]
    fn two_halves_stack_to_the_whole_layer() {
        // The two-flux equations are local: a layer of thickness d is two of d/2 stacked.
        for (k, s, d) in [(0.4, 2.0, 0.7), (0.0, 5.0, 1.0), (3.0, 0.2, 0.3)] {
            let half = layer(k, s, d / 2.0);
            let (r, t) = stack(half, half);
            let (r_d, t_d) = layer(k, s, d);
            close(r, r_d, 1e-12);
            close(t, t_d, 1e-12);
        }
    }

    #[test]
    fn a_stack_over_a_substrate() {
        // A white substrate under a non-absorbing layer reflects everything; a black one
        // leaves the layer's own R; a layer over its own R∞ reflects R∞.
        let clear = tessera_scene::KmLayer {
            absorption: glam::Vec3::ZERO,
            scattering: glam::Vec3::splat(2.0),
            thickness: 0.3,
        };
        let white = reflectance(&[clear], Spectrum::ONE);
        assert!((white - Spectrum::ONE).abs().max_element() < 1e-6);
        let black = reflectance(&[clear], Spectrum::ZERO);
        assert!((black.x as f64 - 0.6 / 1.6).abs() < 1e-6);
        let paint = tessera_scene::KmLayer {
            absorption: glam::Vec3::new(0.1, 1.0, 5.0),
            scattering: glam::Vec3::splat(4.0),
            thickness: 0.05,
        };
        let r_inf = Spectrum::from([0.1f64, 1.0, 5.0].map(|k| {
            let a = 1.0 + k / 4.0;
            (a - (a * a - 1.0).sqrt()) as f32
        }));
        let over = reflectance(&[paint, paint], r_inf);
        assert!(
            (over - r_inf).abs().max_element() < 1e-6,
            "{over} vs {r_inf}"
        );
    }
}
