//! Diffuse area emitters: triangles (every emissive mesh triangle is one light) and spheres.
//! Radiance is constant over the surface, or over a triangle its radiance times an image
//! texture's colour at the point (glTF's emissiveTexture); emitted on the front side (the
//! side of the geometric normal), or on both.

use glam::{Vec2, Vec3A};

use super::{Aim, Emission, LightSample, ShadowTarget, Target, emit_from_surface, lum};
use crate::geometry::triangle;
use crate::math::{Frame, PI, gamma};
use crate::sampling::{
    sphere_cone_one_minus_cos, square_to_triangle, square_to_uniform_sphere, uniform_cone_pdf,
};
use crate::spectrum::Spectrum;
use crate::texture::MipMap;

#[derive(Debug, Clone)]
pub struct TriangleLight {
    v: [Vec3A; 3],
    /// Front-face unit normal.
    n: Vec3A,
    area: f32,
    radiance: Spectrum,
    two_sided: bool,
    /// An emission texture and the corners' texture coordinates.
    texture: Option<Box<(MipMap, [Vec2; 3])>>,
}

/// Radiance toward `w` from a surface with front normal `n`.
#[inline]
fn emitted(radiance: Spectrum, two_sided: bool, n: Vec3A, w: Vec3A) -> Spectrum {
    if two_sided || n.dot(w) > 0.0 {
        radiance
    } else {
        Spectrum::ZERO
    }
}

/// Converts an area density at `p_light` to solid angle at `p`.
#[inline]
fn area_to_solid_angle(pdf_area: f32, p: Vec3A, p_light: Vec3A, n_light: Vec3A) -> f32 {
    let d = p_light - p;
    let dist2 = d.length_squared();
    let cos = n_light.dot(d).abs() / dist2.sqrt();
    if cos == 0.0 {
        0.0
    } else {
        pdf_area * dist2 / cos
    }
}

impl TriangleLight {
    pub fn area(&self) -> f32 {
        self.area
    }

    pub fn two_sided(&self) -> bool {
        self.two_sided
    }

    /// `v` wound so that its normal is the front face. Degenerate triangles have zero area
    /// and are never chosen.
    pub fn new(v: [Vec3A; 3], radiance: Spectrum, two_sided: bool) -> Self {
        let c = (v[1] - v[0]).cross(v[2] - v[0]);
        let area = 0.5 * c.length();
        TriangleLight {
            v,
            n: c.normalize_or_zero(),
            area,
            radiance,
            two_sided,
            texture: None,
        }
    }

    /// The radiance multiplied by `map` at the texture coordinates interpolated from `uv`.
    pub fn with_texture(mut self, map: MipMap, uv: [Vec2; 3]) -> Self {
        self.texture = Some(Box::new((map, uv)));
        self
    }

    /// Radiance at barycentrics `b` (finest texture level: a light sample is a point).
    #[inline]
    fn radiance_at(&self, b: [f32; 3]) -> Spectrum {
        match &self.texture {
            None => self.radiance,
            Some(t) => {
                let (map, [a, b1, c]) = &**t;
                let uv = *a * b[0] + *b1 * b[1] + *c * b[2];
                self.radiance * Vec3A::from(map.lookup(uv, 0.0).truncate())
            }
        }
    }

    /// Barycentrics of `p` (on the triangle's plane) with respect to its corners.
    fn barycentrics(&self, p: Vec3A) -> [f32; 3] {
        let [a, b, c] = self.v;
        let total = (b - a).cross(c - a).dot(self.n);
        if total == 0.0 {
            return [1.0, 0.0, 0.0];
        }
        let u = (c - b).cross(p - b).dot(self.n) / total;
        let v = (a - c).cross(p - c).dot(self.n) / total;
        [u, v, 1.0 - u - v]
    }

    pub fn sample_li(&self, p: Vec3A, u: Vec2) -> Option<LightSample> {
        if self.area == 0.0 {
            return None;
        }
        let b = square_to_triangle(u);
        let (pl, p_error) = triangle::point_and_error(&self.v, b);
        let to = pl - p;
        let dist2 = to.length_squared();
        if dist2 == 0.0 {
            return None;
        }
        let wi = to / dist2.sqrt();
        let li = emitted(self.radiance_at(b), self.two_sided, self.n, -wi);
        let pdf = area_to_solid_angle(1.0 / self.area, p, pl, self.n);
        (pdf > 0.0 && pdf.is_finite() && li.max_element() > 0.0).then_some(LightSample {
            li,
            wi,
            pdf,
            delta: false,
            target: ShadowTarget::Point {
                p: pl,
                p_error,
                n: self.n,
            },
        })
    }

    pub fn pdf_li(&self, p: Vec3A, p_light: Vec3A, n_light: Vec3A) -> f32 {
        if self.area == 0.0 || (!self.two_sided && n_light.dot(p - p_light) <= 0.0) {
            return 0.0;
        }
        area_to_solid_angle(1.0 / self.area, p, p_light, n_light)
    }

    /// Radiance leaving point `p` of the triangle (front normal `n`) toward `w`.
    pub fn le(&self, n: Vec3A, w: Vec3A, p: Vec3A) -> Spectrum {
        let radiance = if self.texture.is_some() {
            self.radiance_at(self.barycentrics(p))
        } else {
            self.radiance
        };
        emitted(radiance, self.two_sided, n, w)
    }

    /// Emitted power, for choosing among lights: with a texture, its mean over the whole
    /// image stands for its mean over the triangle.
    pub fn power(&self) -> f32 {
        let mean = self
            .texture
            .as_ref()
            .map_or(Spectrum::ONE, |t| Vec3A::from(t.0.mean().truncate()));
        PI * self.area * lum(self.radiance * mean) * if self.two_sided { 2.0 } else { 1.0 }
    }

    pub fn sample_le(&self, aim: &Aim, u_pos: Vec2, u_dir: Vec2, u_extra: f32) -> Option<Emission> {
        if self.area == 0.0 {
            return None;
        }
        let b = square_to_triangle(u_pos);
        let (p, p_error) = triangle::point_and_error(&self.v, b);
        emit_from_surface(
            aim,
            p,
            p_error,
            self.n,
            self.area,
            self.radiance_at(b),
            self.two_sided,
            u_dir,
            u_extra,
        )
    }

    pub fn bounds(&self) -> Target {
        let center = (self.v[0] + self.v[1] + self.v[2]) / 3.0;
        let radius = self
            .v
            .iter()
            .map(|v| (*v - center).length())
            .fold(0.0, f32::max);
        Target { center, radius }
    }
}

/// A spherical emitter, sampled by the cone it subtends (pbrt-v4 §6.2.4) from outside and
/// uniformly by area from inside.
#[derive(Debug, Clone)]
pub struct SphereLight {
    center: Vec3A,
    radius: f32,
    radiance: Spectrum,
    two_sided: bool,
}

impl SphereLight {
    pub fn area(&self) -> f32 {
        4.0 * PI * self.radius * self.radius
    }

    pub fn two_sided(&self) -> bool {
        self.two_sided
    }

    pub fn new(center: Vec3A, radius: f32, radiance: Spectrum, two_sided: bool) -> Self {
        SphereLight {
            center,
            radius,
            radiance,
            two_sided,
        }
    }

    /// 1 − cos of the half-angle of the cone the sphere subtends from a point outside it,
    /// given the vector from that point to the centre (`None` inside).
    #[inline]
    fn cone(&self, to_center: Vec3A) -> Option<f32> {
        let dist2 = to_center.length_squared();
        let r2 = self.radius * self.radius;
        (dist2 > r2 * 1.0001).then(|| sphere_cone_one_minus_cos(r2, dist2))
    }

    pub fn sample_li(&self, p: Vec3A, u: Vec2) -> Option<LightSample> {
        let to_center = self.center - p;
        let (pl, n, wi, pdf) = match self.cone(to_center) {
            Some(cone) => {
                // A direction at angle θ from the axis, uniform in the cone, meets the sphere
                // first at angle α from the axis seen from the centre (pbrt-v4 §6.2.4):
                // cos α = sin²θ / sin θ_max + cos θ √(1 − sin²θ / sin²θ_max). No ray to trace.
                // The direction is the sampled one (opposite azimuth to the point's normal),
                // not the normalised difference of the points: the same up to rounding, and
                // off the chain of square roots and divisions the point needs.
                let dist = to_center.length();
                let frame = Frame::around(to_center / dist);
                let inv_sin_max = dist / self.radius;
                let one_minus_cos = u.x * cone;
                let cos_theta = 1.0 - one_minus_cos;
                let sin2_theta = one_minus_cos * (2.0 - one_minus_cos);
                let k = sin2_theta * inv_sin_max;
                let cos_alpha = k + cos_theta * (1.0 - k * inv_sin_max).max(0.0).sqrt();
                let sin_alpha = (1.0 - cos_alpha * cos_alpha).max(0.0).sqrt();
                let sin_theta = sin2_theta.sqrt();
                let (s, c) = (2.0 * PI * u.y).sin_cos();
                let n = frame.to_world(-Vec3A::new(sin_alpha * c, sin_alpha * s, cos_alpha));
                let wi = frame.to_world(Vec3A::new(-sin_theta * c, -sin_theta * s, cos_theta));
                (self.center + n * self.radius, n, wi, uniform_cone_pdf(cone))
            }
            None => {
                let n = square_to_uniform_sphere(u);
                let pl = self.center + n * self.radius;
                let pdf =
                    area_to_solid_angle(1.0 / (4.0 * PI * self.radius * self.radius), p, pl, n);
                (pl, n, (pl - p).normalize_or_zero(), pdf)
            }
        };
        let p_error = (n * self.radius).abs() * gamma(5) + pl.abs() * gamma(2);
        let li = emitted(self.radiance, self.two_sided, n, -wi);
        (pdf > 0.0 && pdf.is_finite() && li.max_element() > 0.0 && wi != Vec3A::ZERO).then_some(
            LightSample {
                li,
                wi,
                pdf,
                delta: false,
                target: ShadowTarget::Point { p: pl, p_error, n },
            },
        )
    }

    pub fn pdf_li(&self, p: Vec3A, p_light: Vec3A, n_light: Vec3A) -> f32 {
        match self.cone(self.center - p) {
            Some(cone) => uniform_cone_pdf(cone),
            None => area_to_solid_angle(
                1.0 / (4.0 * PI * self.radius * self.radius),
                p,
                p_light,
                n_light,
            ),
        }
    }

    pub fn le(&self, n: Vec3A, w: Vec3A) -> Spectrum {
        emitted(self.radiance, self.two_sided, n, w)
    }

    /// A photon from the sphere. Aimed through a projection map, the direction d comes first
    /// and the point is uniform on the hemisphere facing d (the other half emits nothing
    /// toward d): half the area, no photon wasted.
    pub fn sample_le(&self, aim: &Aim, u_pos: Vec2, u_dir: Vec2, u_extra: f32) -> Option<Emission> {
        let full = 4.0 * PI * self.radius * self.radius;
        let (n, area) = match aim {
            Aim::Projection(map) if !self.two_sided => {
                let (d, _) = map.sample(u_extra, u_dir)?;
                let local = square_to_uniform_sphere(Vec2::new(0.5 * u_pos.x, u_pos.y));
                (Frame::from_normal(d).to_world(local), 0.5 * full)
            }
            _ => (square_to_uniform_sphere(u_pos), full),
        };
        let p = self.center + n * self.radius;
        let p_error = (n * self.radius).abs() * gamma(5) + p.abs() * gamma(2);
        emit_from_surface(
            aim,
            p,
            p_error,
            n,
            area,
            self.radiance,
            self.two_sided,
            u_dir,
            u_extra,
        )
    }

    pub fn bounds(&self) -> Target {
        Target {
            center: self.center,
            radius: self.radius,
        }
    }

    pub fn power(&self) -> f32 {
        PI * 4.0
            * PI
            * self.radius
            * self.radius
            * lum(self.radiance)
            * if self.two_sided { 2.0 } else { 1.0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::sphere;

    /// A sphere light sampled from outside: each point lies on the sphere, is where its
    /// direction meets the sphere first, has density `pdf_li`, and the directions are uniform
    /// in the cone (1 − cos θ over its maximum has mean ½, within 4 standard errors of n
    /// uniform values), from near (1.2 radii) to far (100 radii; 10⁴ for the rest).
    #[test]
    fn sphere_samples_lie_on_the_visible_cap_uniform_in_the_cone() {
        let center = Vec3A::new(1.0, 2.0, -3.0);
        let radius = 0.5;
        let light = SphereLight::new(center, radius, Spectrum::ONE, false);
        let n = 20_000;
        for (k, dist) in [0.6f32, 2.0, 50.0, 5000.0].into_iter().enumerate() {
            let dir = Vec3A::new(0.3, -0.8, 0.52).normalize();
            let p = center + dir * dist;
            let cone = light.cone(center - p).expect("outside");
            let axis = (center - p).normalize();
            let mut mean = 0.0f64;
            for i in 0..n {
                let u = Vec2::new((i as f32 + 0.5) / n as f32, (i as f32 * 0.618_034).fract());
                let ls = light.sample_li(p, u).expect("a sample");
                let ShadowTarget::Point { p: pl, n: nl, .. } = ls.target else {
                    panic!("a point on the sphere");
                };
                let on = ((pl - center).length() - radius).abs();
                assert!(on <= 1e-5 * dist.max(1.0), "{dist}: {on} off the sphere");
                let d = (pl - p).length();
                let t = sphere::intersect(center, radius, p, ls.wi, f32::INFINITY);
                let first = t.map_or(radius * 1e-3, |t| (t - d).abs());
                assert!(
                    first <= 2e-3 * radius + 4e-6 * dist,
                    "{dist}: not the first hit ({first})"
                );
                let pdf = light.pdf_li(p, pl, nl);
                assert!(
                    (ls.pdf - pdf).abs() <= 1e-4 * pdf,
                    "{dist}: {} vs {pdf}",
                    ls.pdf
                );
                mean += ((1.0 - ls.wi.dot(axis)) / cone) as f64;
            }
            mean /= n as f64;
            let se = (1.0 / 12.0 / n as f64).sqrt();
            // (From 10⁴ radii 1 − cos θ is below f32's resolution: no check of θ there.)
            assert!(
                k == 3 || (mean - 0.5).abs() <= 4.0 * se,
                "{dist}: mean {mean}"
            );
        }
    }
}
