//! Light tracing's splats: radiance arriving anywhere on the film, shared among the pixels
//! under the reconstruction filter, summed in fixed point.

use std::sync::atomic::{AtomicI64, Ordering::Relaxed};

use glam::Vec2;

use crate::film::Image;
use crate::scene::Scene;
use crate::spectrum::Spectrum;

/// Splats in fixed point, 2⁻³² units (integer sums: the same whatever order they arrive in).
pub(in crate::integrator) struct Splats {
    pub(in crate::integrator) rgb: Vec<[AtomicI64; 3]>,
    width: u32,
    height: u32,
}

pub(super) const SPLAT_SCALE: f64 = 4_294_967_296.0;

impl Splats {
    pub(in crate::integrator) fn new(width: u32, height: u32) -> Self {
        Splats {
            rgb: (0..width as usize * height as usize)
                .map(|_| [AtomicI64::new(0), AtomicI64::new(0), AtomicI64::new(0)])
                .collect(),
            width,
            height,
        }
    }

    /// Each pixel's sums, in 2⁻³² units.
    pub(in crate::integrator) fn totals(&self) -> Vec<[i64; 3]> {
        self.rgb
            .iter()
            .map(|s| s.each_ref().map(|a| a.load(Relaxed)))
            .collect()
    }

    /// Adds `l` to one pixel, unfiltered.
    pub(super) fn add_pixel(&self, pixel: glam::UVec2, l: Spectrum) {
        if !l.is_finite() {
            return;
        }
        let px = &self.rgb[(pixel.y * self.width + pixel.x) as usize];
        for (a, v) in px.iter().zip(l.to_array()) {
            a.fetch_add(fixed_splat(v as f64), Relaxed);
        }
    }

    /// Adds `l` arriving at raster position `at`, shared among the pixels under the filter.
    pub(in crate::integrator) fn add(&self, scene: &Scene, at: Vec2, l: Spectrum) {
        Self::footprint(scene, self.width, self.height, at, l, |i, v| {
            for (a, v) in self.rgb[i].iter().zip(v) {
                a.fetch_add(v, Relaxed);
            }
        });
    }

    /// [`Self::add`] with exclusive access: plain adds, no atomic operations.
    pub(in crate::integrator) fn add_mut(&mut self, scene: &Scene, at: Vec2, l: Spectrum) {
        let (width, height) = (self.width, self.height);
        let rgb = &mut self.rgb;
        Self::footprint(scene, width, height, at, l, |i, v| {
            for (a, v) in rgb[i].iter_mut().zip(v) {
                let a = a.get_mut();
                *a = a.wrapping_add(v);
            }
        });
    }

    /// Calls `add(pixel index, fixed-point share)` for each pixel under the filter centred at
    /// `at`. The filter is separable: one factor per column and per row.
    fn footprint(
        scene: &Scene,
        width: u32,
        height: u32,
        at: Vec2,
        l: Spectrum,
        mut add: impl FnMut(usize, [i64; 3]),
    ) {
        if !l.is_finite() {
            return;
        }
        let r = scene.filter.radius();
        let x0 = ((at.x - r - 0.5).ceil() as i64).max(0);
        let x1 = ((at.x + r - 0.5).floor() as i64).min(width as i64 - 1);
        let y0 = ((at.y - r - 0.5).ceil() as i64).max(0);
        let y1 = ((at.y + r - 0.5).floor() as i64).min(height as i64 - 1);
        // Column factors, computed once (a wide filter's extra columns computed per row).
        let mut wx = [0.0f32; 8];
        for (k, x) in (x0..=x1).take(wx.len()).enumerate() {
            wx[k] = scene.filter.splat_weight_1d(at.x - (x as f32 + 0.5));
        }
        for y in y0..=y1 {
            let wy = scene.filter.splat_weight_1d(at.y - (y as f32 + 0.5));
            if wy == 0.0 {
                continue;
            }
            for (k, x) in (x0..=x1).enumerate() {
                let fx = match wx.get(k) {
                    Some(&f) => f,
                    None => scene.filter.splat_weight_1d(at.x - (x as f32 + 0.5)),
                };
                let w = fx * wy;
                if w == 0.0 {
                    continue;
                }
                let v = [0, 1, 2].map(|c| fixed_splat(l[c] as f64 * w as f64));
                add((y * width as i64 + x) as usize, v);
            }
        }
    }
}

/// Adds fixed-point sums pixel by pixel.
pub(super) fn add_fixed(to: &mut [[i64; 3]], from: &[[i64; 3]]) {
    for (a, b) in to.iter_mut().zip(from) {
        for c in 0..3 {
            a[c] = a[c].wrapping_add(b[c]);
        }
    }
}

/// A brightness sample in the sums' fixed point (i128: no overflow however many).
pub(in crate::integrator) fn fixed_brightness(v: f64) -> i128 {
    (v * SPLAT_SCALE) as i128
}

/// `v` in the splats' fixed point (clamped far from overflow).
fn fixed_splat(v: f64) -> i64 {
    (v * SPLAT_SCALE).clamp(-(i64::MAX as f64) / 4.0, i64::MAX as f64 / 4.0) as i64
}

/// Adds fixed-point splat sums times `scale` to an image's pixels.
pub(in crate::integrator) fn add_splats(image: &mut Image, splats: &[[i64; 3]], scale: f64) {
    let scale = scale / SPLAT_SCALE;
    for (px, s) in image.pixels.iter_mut().zip(splats) {
        for (v, &t) in px.rgb.iter_mut().zip(s) {
            *v += (t as f64 * scale) as f32;
        }
    }
}
