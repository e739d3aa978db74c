//! Environment light: radiance arriving from infinitely far away, constant or from a
//! latitude–longitude image interpolated bilinearly between texel centres (wrapping around in
//! φ, clamped at the poles), importance-sampled by a piecewise-constant 2D distribution
//! proportional to each texel's mean interpolated brightness × sin θ (pbrt-v4 §12.5). That
//! mean is non-zero wherever the interpolation is, so every direction that emits can be
//! sampled.
//!
//! Image coordinates (u, v) ∈ [0, 1)² map to the local direction
//! (−sin θ sin φ, cos θ, sin θ cos φ) with θ = πv from +Y (up) and φ = 2π(u − ½): the centre of
//! the image looks along +Z, and u grows to the right as seen from inside, so the image is not
//! mirrored. `to_world` rotates local into world directions.

use glam::{Mat3A, Vec2, Vec3A};
use tessera_scene::EnvImage;

use super::{Aim, Emission, LightSample, ShadowTarget, emit_from_disk, lum};
use crate::math::{INV_PI, PI};
use crate::sampling::{Distribution2D, UNIFORM_SPHERE_PDF, square_to_uniform_sphere};
use crate::spectrum::Spectrum;

#[derive(Debug, Clone)]
pub struct EnvironmentLight {
    scale: Spectrum,
    image: Option<Image>,
    to_world: Mat3A,
    to_local: Mat3A,
}

#[derive(Debug, Clone)]
struct Image {
    width: u32,
    height: u32,
    texels: Vec<Spectrum>,
    distribution: Distribution2D,
    /// sin θ-weighted mean radiance over the sphere (for the power estimate).
    mean: Spectrum,
}

/// Local direction of image coordinates.
fn direction(uv: Vec2) -> (Vec3A, f32) {
    let theta = PI * uv.y;
    let phi = 2.0 * PI * (uv.x - 0.5);
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    (Vec3A::new(-st * sp, ct, st * cp), st)
}

/// Image coordinates of a local direction. θ by atan2, which unlike acos(y) stays accurate
/// near the poles, where the density's 1/sin θ is most sensitive to it.
fn coordinates(w: Vec3A) -> Vec2 {
    let theta = (w.x * w.x + w.z * w.z).sqrt().atan2(w.y);
    let phi = (-w.x).atan2(w.z);
    Vec2::new((phi * 0.5 * INV_PI + 0.5).rem_euclid(1.0), theta * INV_PI)
}

impl EnvironmentLight {
    pub fn new(image: Option<&EnvImage>, scale: Spectrum, to_world: Mat3A) -> Self {
        let image = image.map(|img| {
            let (w, h) = (img.width as usize, img.height as usize);
            let texels: Vec<Spectrum> = img.texels.iter().map(|&t| Vec3A::from(t)).collect();
            let mut weights = Vec::with_capacity(w * h);
            let mut mean = Spectrum::ZERO;
            let mut total = 0.0;
            let at = |x: isize, y: isize| {
                let x = x.rem_euclid(w as isize) as usize;
                let y = y.clamp(0, h as isize - 1) as usize;
                texels[y * w + x]
            };
            for y in 0..h {
                let sin = (PI * (y as f32 + 0.5) / h as f32).sin();
                for x in 0..w {
                    // The bilinear interpolant's mean over the texel: the texel and its
                    // neighbours weighted (3/4, 1/8, 1/8) along each axis.
                    let (xi, yi) = (x as isize, y as isize);
                    let row =
                        |y: isize| at(xi - 1, y) * 0.125 + at(xi, y) * 0.75 + at(xi + 1, y) * 0.125;
                    let t = row(yi - 1) * 0.125 + row(yi) * 0.75 + row(yi + 1) * 0.125;
                    // Channel average: zero exactly where the interpolant is black.
                    weights.push((t.x + t.y + t.z) / 3.0 * sin);
                    mean += t * sin;
                    total += sin;
                }
            }
            Image {
                width: img.width,
                height: img.height,
                distribution: Distribution2D::new(&weights, w, h),
                texels,
                mean: mean / total,
            }
        });
        EnvironmentLight {
            scale,
            image,
            to_world,
            to_local: to_world.transpose(),
        }
    }

    fn lookup(&self, uv: Vec2) -> Spectrum {
        match &self.image {
            None => self.scale,
            Some(img) => {
                // Texel centres at half integers; φ wraps, θ clamps at the poles.
                let (w, h) = (img.width as i64, img.height as i64);
                let x = uv.x * w as f32 - 0.5;
                let y = uv.y * h as f32 - 0.5;
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = (x - x0, y - y0);
                let (x0, y0) = (x0 as i64, y0 as i64);
                let texel = |dx: i64, dy: i64| {
                    let tx = (x0 + dx).rem_euclid(w);
                    let ty = (y0 + dy).clamp(0, h - 1);
                    img.texels[(ty * w + tx) as usize]
                };
                let top = texel(0, 0) * (1.0 - fx) + texel(1, 0) * fx;
                let bottom = texel(0, 1) * (1.0 - fx) + texel(1, 1) * fx;
                (top * (1.0 - fy) + bottom * fy) * self.scale
            }
        }
    }

    /// Radiance seen looking in world direction `wi`.
    pub fn le(&self, wi: Vec3A) -> Spectrum {
        if self.image.is_none() {
            return self.scale;
        }
        self.lookup(coordinates(self.to_local * wi))
    }

    pub fn sample_li(&self, u: Vec2) -> Option<LightSample> {
        let (wi, li, pdf) = match &self.image {
            None => (square_to_uniform_sphere(u), self.scale, UNIFORM_SPHERE_PDF),
            Some(img) => {
                let (uv, pdf_uv) = img.distribution.sample(u);
                let (local, sin) = direction(uv);
                if sin == 0.0 || pdf_uv == 0.0 {
                    return None;
                }
                (
                    self.to_world * local,
                    self.lookup(uv),
                    pdf_uv / (2.0 * PI * PI * sin),
                )
            }
        };
        (pdf > 0.0 && li.max_element() > 0.0).then_some(LightSample {
            li,
            wi,
            pdf,
            delta: false,
            target: ShadowTarget::Infinite,
        })
    }

    pub fn pdf_li(&self, wi: Vec3A) -> f32 {
        match &self.image {
            None => UNIFORM_SPHERE_PDF,
            Some(img) => {
                let uv = coordinates(self.to_local * wi);
                let sin = (PI * uv.y).sin();
                if sin == 0.0 {
                    0.0
                } else {
                    img.distribution.pdf(uv) / (2.0 * PI * PI * sin)
                }
            }
        }
    }

    /// A photon arriving from a direction importance-sampled like `sample_li`, from the disk
    /// of `aim` (other aims have no disk: no photon).
    pub fn sample_le(&self, aim: &Aim, u_pos: Vec2, u_dir: Vec2) -> Option<Emission> {
        let Aim::Disk(target) = aim else {
            return None;
        };
        let ls = self.sample_li(u_dir)?;
        Some(emit_from_disk(*target, -ls.wi, ls.li, ls.pdf, u_pos))
    }

    pub fn power(&self, scene_radius: f32) -> f32 {
        let mean = self.image.as_ref().map_or(Spectrum::ONE, |i| i.mean) * self.scale;
        4.0 * PI * PI * scene_radius * scene_radius * lum(mean)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coordinates_invert_direction() {
        for (u, v) in [(0.1, 0.2), (0.5, 0.5), (0.93, 0.71), (0.25, 0.9)] {
            let (w, _) = direction(Vec2::new(u, v));
            let uv = coordinates(w);
            assert!(
                (uv - Vec2::new(u, v)).abs().max_element() < 1e-5,
                "{u} {v} -> {uv}"
            );
        }
        // Image centre looks along +Z; up is the top row.
        assert!((direction(Vec2::new(0.5, 0.5)).0 - Vec3A::Z).length() < 1e-6);
        assert!((direction(Vec2::new(0.3, 0.0)).0 - Vec3A::Y).length() < 1e-6);
    }

    #[test]
    fn sampling_density_matches_pdf_and_integrates_to_one() {
        // A 16×8 image with one bright texel: estimate ∫ pdf dω by uniform sphere sampling.
        let mut texels = vec![glam::Vec3::splat(0.1); 128];
        texels[3 * 16 + 5] = glam::Vec3::splat(50.0);
        let img = EnvImage {
            width: 16,
            height: 8,
            texels,
        };
        let env = EnvironmentLight::new(Some(&img), Spectrum::ONE, Mat3A::from_rotation_y(0.7));
        let n = 200_000;
        let mut integral = 0.0f64;
        // ∫ Le dω twice: by uniform directions, and by the light's own samples (Le / pdf),
        // which agree only if every direction the interpolation lights can be sampled.
        let (mut uniform, mut sampled) = (0.0f64, 0.0f64);
        for i in 0..n {
            let h = crate::sampler::hash::mix64(i);
            let u = Vec2::new(
                crate::sampler::hash::u32_to_unit(h as u32),
                crate::sampler::hash::u32_to_unit((h >> 32) as u32),
            );
            let w = square_to_uniform_sphere(u);
            integral += (env.pdf_li(w) / UNIFORM_SPHERE_PDF) as f64;
            uniform += (env.le(w).x / UNIFORM_SPHERE_PDF) as f64;
            // Samples exactly at a pole (sin θ = 0) have no density and are refused.
            if let Some(s) = env.sample_li(u) {
                sampled += (s.li.x / s.pdf) as f64;
                assert!(
                    (s.pdf - env.pdf_li(s.wi)).abs() <= 1e-3 * s.pdf,
                    "{} vs {}",
                    s.pdf,
                    env.pdf_li(s.wi)
                );
                // The same radiance both ways (up to the direction's round trip through
                // the rotation, on the bright texel's steep interpolation).
                let tolerance = 1e-4 * s.li.max_element().max(1.0);
                assert!((s.li - env.le(s.wi)).abs().max_element() < tolerance);
            }
        }
        let (uniform, sampled) = (uniform / n as f64, sampled / n as f64);
        assert!(
            (sampled / uniform - 1.0).abs() < 0.02,
            "∫ Le dω: {uniform} uniformly, {sampled} by the light's samples"
        );
        assert!(
            (integral / n as f64 - 1.0).abs() < 0.02,
            "{}",
            integral / n as f64
        );
    }
}
