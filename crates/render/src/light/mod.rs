//! Light sources, one per file, behind one enum; the set of a scene's lights is sampled in
//! proportion to (an estimate of) each light's power.

mod area;
mod directional;
mod environment;
mod point;
pub mod projection;
mod spot;

use glam::{Vec2, Vec3A};

use crate::math::{Frame, offset_ray_origin};
use crate::ray::Ray;
use crate::sampling::{Distribution1D, square_to_cosine_hemisphere, square_to_disk};
use crate::spectrum::{Spectrum, luminance};

pub use area::{SphereLight, TriangleLight};
pub use directional::DirectionalLight;
pub use environment::EnvironmentLight;
pub use point::PointLight;
pub use projection::{ProjectionMap, Target};
pub use spot::SpotLight;

/// Where photons leaving a light are aimed; the photon pass chooses, per light and map.
#[derive(Debug, Clone, Copy)]
pub enum Aim<'a> {
    /// Everywhere the light emits: area lights cosine-weighted over their emitting side,
    /// point lights uniformly over the sphere.
    Everywhere,
    /// Through the marked cells of a projection map only (the light's power scaled by the
    /// covered fraction).
    Projection(&'a ProjectionMap),
    /// Lights at infinity: from the disk that covers this sphere, perpendicular to the
    /// direction of travel.
    Disk(Target),
}

/// A photon (or a light subpath's first vertex) leaving a light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Emission {
    /// Origin on (or just off) the light, unit direction of travel.
    pub ray: Ray,
    /// Power carried by this one sample, W: Le·|cos θ| / (pdf_pos · pdf_dir); divided
    /// by the light's choice probability and the photon count by the caller.
    pub flux: Spectrum,
    /// What leaves along the ray: radiance for area and infinite lights, intensity for point
    /// lights, irradiance for directional ones.
    pub le: Spectrum,
    /// The emitting surface's front normal; zero for point lights; the direction of travel
    /// for lights at infinity (their "surface" is the disk across it).
    pub n: Vec3A,
    /// Density of the origin: per unit area (1 for a point light, a delta in position).
    pub pdf_pos: f32,
    /// Density of the direction: per unit solid angle (1 for a directional light, a delta).
    pub pdf_dir: f32,
}

/// An emission from surface point `p` (error `p_error`, front normal `n`) of an area light of
/// area `area` with radiance `radiance`, aimed by `aim`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn emit_from_surface(
    aim: &Aim,
    p: Vec3A,
    p_error: Vec3A,
    n: Vec3A,
    area: f32,
    radiance: Spectrum,
    two_sided: bool,
    u_dir: Vec2,
    u_extra: f32,
) -> Option<Emission> {
    let (d, pdf_dir) = match aim {
        Aim::Projection(map) => {
            let (d, pdf) = map.sample(u_extra, u_dir)?;
            let cos = n.dot(d);
            if cos <= 0.0 && !two_sided {
                return None;
            }
            (d, pdf)
        }
        _ => {
            // Cosine-weighted about the emitting side: Le cos / (1/A · cos/π) = Le π A.
            let (side, sides) = match (two_sided, u_extra < 0.5) {
                (false, _) => (n, 1.0),
                (true, true) => (n, 2.0),
                (true, false) => (-n, 2.0),
            };
            let local = square_to_cosine_hemisphere(u_dir);
            if local.z <= 0.0 {
                return None;
            }
            let d = Frame::from_normal(side).to_world(local);
            (d, local.z / (crate::math::PI * sides))
        }
    };
    let (pdf_pos, cos) = (1.0 / area, n.dot(d).abs());
    Some(Emission {
        ray: Ray::new(offset_ray_origin(p, p_error, n, d), d),
        flux: radiance * (cos / (pdf_pos * pdf_dir)),
        le: radiance,
        n,
        pdf_pos,
        pdf_dir,
    })
}

/// Densities (per area, per solid angle) with which an area light of area `area` and front
/// normal `n` emits toward `w` when aimed everywhere (cosine-weighted about the emitting side).
fn pdf_le_surface(n: Vec3A, w: Vec3A, area: f32, two_sided: bool) -> (f32, f32) {
    let cos = n.dot(w);
    let pdf_dir = match two_sided {
        true => cos.abs() / (2.0 * crate::math::PI),
        false => cos.max(0.0) / crate::math::PI,
    };
    (if area > 0.0 { 1.0 / area } else { 0.0 }, pdf_dir)
}

/// An emission of a light at infinity travelling along `d` with radiance `le` (per unit
/// solid-angle density `pdf_dir`, 1 for a delta direction), from the disk covering `target`.
pub(crate) fn emit_from_disk(
    target: Target,
    d: Vec3A,
    le: Spectrum,
    pdf_dir: f32,
    u_pos: Vec2,
) -> Emission {
    let r = target.radius.max(f32::MIN_POSITIVE);
    let disk = square_to_disk(u_pos) * r;
    let frame = Frame::from_normal(d);
    let o = target.center + frame.to_world(Vec3A::new(disk.x, disk.y, 0.0)) - d * r;
    let pdf_pos = 1.0 / (crate::math::PI * r * r);
    Emission {
        ray: Ray::new(o, d),
        flux: le / (pdf_pos * pdf_dir),
        le,
        n: d,
        pdf_pos,
        pdf_dir,
    }
}

/// Where a shadow ray toward a light sample must reach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ShadowTarget {
    /// A point on a surface (with its error bound and normal) or in space (zero error).
    Point { p: Vec3A, p_error: Vec3A, n: Vec3A },
    /// A direction to infinity.
    Infinite,
}

/// Incident radiance from a sampled point on a light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightSample {
    /// Radiance arriving along −wi (for delta lights: intensity / d², or irradiance).
    pub li: Spectrum,
    /// Unit direction from the receiving point toward the light.
    pub wi: Vec3A,
    /// Density with respect to solid angle at the receiver; 1 for delta lights.
    pub pdf: f32,
    pub delta: bool,
    pub target: ShadowTarget,
}

#[derive(Debug, Clone)]
pub enum Light {
    Triangle(TriangleLight),
    Sphere(SphereLight),
    Point(PointLight),
    Spot(SpotLight),
    Directional(DirectionalLight),
    Environment(EnvironmentLight),
}

impl Light {
    /// Samples incident light at the point `p`.
    pub fn sample_li(&self, p: Vec3A, u: Vec2) -> Option<LightSample> {
        match self {
            Light::Triangle(l) => l.sample_li(p, u),
            Light::Sphere(l) => l.sample_li(p, u),
            Light::Point(l) => l.sample_li(p),
            Light::Spot(l) => l.sample_li(p),
            Light::Directional(l) => l.sample_li(),
            Light::Environment(l) => l.sample_li(u),
        }
    }

    /// Solid-angle density with which `sample_li` at `p` picks the point `p_light` (normal
    /// `n_light`) of an area light.
    pub fn pdf_li_surface(&self, p: Vec3A, p_light: Vec3A, n_light: Vec3A) -> f32 {
        match self {
            Light::Triangle(l) => l.pdf_li(p, p_light, n_light),
            Light::Sphere(l) => l.pdf_li(p, p_light, n_light),
            _ => 0.0,
        }
    }

    /// Solid-angle density with which `sample_li` picks direction `wi` of an infinite light.
    pub fn pdf_li_direction(&self, wi: Vec3A) -> f32 {
        match self {
            Light::Environment(l) => l.pdf_li(wi),
            _ => 0.0,
        }
    }

    /// Radiance of an infinite light arriving along −`wi` (seen in direction `wi`).
    pub fn le_direction(&self, wi: Vec3A) -> Spectrum {
        match self {
            Light::Environment(l) => l.le(wi),
            _ => Spectrum::ZERO,
        }
    }

    /// Radiant intensity of a point or spot light toward unit direction `w`.
    pub fn intensity(&self, w: Vec3A) -> Spectrum {
        match self {
            Light::Point(l) => l.intensity(),
            Light::Spot(l) => l.intensity(w),
            _ => Spectrum::ZERO,
        }
    }

    /// Radiance leaving point `p` of an area light's surface (front normal `n`) in
    /// direction `w`.
    pub fn le_surface(&self, n: Vec3A, w: Vec3A, p: Vec3A) -> Spectrum {
        match self {
            Light::Triangle(l) => l.le(n, w, p),
            Light::Sphere(l) => l.le(n, w),
            _ => Spectrum::ZERO,
        }
    }

    /// A photon leaving the light, aimed by `aim` (`u_pos` picks the point, `u_dir` the
    /// direction, `u_extra` the side of a two-sided emitter or a projection-map cell).
    pub fn sample_le(&self, aim: &Aim, u_pos: Vec2, u_dir: Vec2, u_extra: f32) -> Option<Emission> {
        let e = match self {
            Light::Triangle(l) => l.sample_le(aim, u_pos, u_dir, u_extra),
            Light::Sphere(l) => l.sample_le(aim, u_pos, u_dir, u_extra),
            Light::Point(l) => l.sample_le(aim, u_dir, u_extra),
            Light::Spot(l) => l.sample_le(aim, u_dir, u_extra),
            Light::Directional(l) => l.sample_le(aim, u_pos),
            Light::Environment(l) => l.sample_le(aim, u_pos, u_dir),
        }?;
        (e.flux.is_finite() && e.flux.max_element() > 0.0).then_some(e)
    }

    /// Densities (per area, per solid angle) with which [`Self::sample_le`] emits from a point
    /// with normal `n` (as in [`Emission::n`]) along `w`, aimed everywhere (for lights at
    /// infinity: from the disk covering `scene`). Zero for a delta: a point light's position,
    /// a directional light's direction.
    pub fn pdf_le(&self, n: Vec3A, w: Vec3A, scene: Target) -> (f32, f32) {
        let disk = 1.0 / (crate::math::PI * scene.radius.max(f32::MIN_POSITIVE).powi(2));
        match self {
            Light::Triangle(l) => pdf_le_surface(n, w, l.area(), l.two_sided()),
            Light::Sphere(l) => pdf_le_surface(n, w, l.area(), l.two_sided()),
            Light::Point(_) | Light::Spot(_) => (0.0, crate::sampling::UNIFORM_SPHERE_PDF),
            Light::Directional(_) => (disk, 0.0),
            Light::Environment(l) => (disk, l.pdf_li(-w)),
        }
    }

    /// The sphere that contains the light's emitting points; `None` at infinity.
    pub fn bounds(&self) -> Option<Target> {
        match self {
            Light::Triangle(l) => Some(l.bounds()),
            Light::Sphere(l) => Some(l.bounds()),
            Light::Point(l) => Some(l.bounds()),
            Light::Spot(l) => Some(l.bounds()),
            Light::Directional(_) | Light::Environment(_) => None,
        }
    }

    /// A spot light's emission cone: axis and half-angle.
    pub fn cone(&self) -> Option<(Vec3A, f32)> {
        match self {
            Light::Spot(l) => Some(l.cone()),
            _ => None,
        }
    }

    /// Emitted power (luminance-weighted watts) used to choose among lights; `scene_radius`
    /// bounds the scene for lights at infinity.
    pub fn power(&self, scene_radius: f32) -> f32 {
        let p = match self {
            Light::Triangle(l) => l.power(),
            Light::Sphere(l) => l.power(),
            Light::Point(l) => l.power(),
            Light::Spot(l) => l.power(),
            Light::Directional(l) => l.power(scene_radius),
            Light::Environment(l) => l.power(scene_radius),
        };
        if p.is_finite() { p.max(0.0) } else { 0.0 }
    }
}

/// All lights of a scene and the distribution for choosing one.
#[derive(Debug, Clone)]
pub struct LightSet {
    lights: Vec<Light>,
    choice: Option<Distribution1D>,
    /// Lights that rays escaping the scene see.
    environment: Vec<u32>,
}

impl LightSet {
    pub fn new(lights: Vec<Light>, scene_radius: f32) -> Self {
        let powers: Vec<f32> = lights.iter().map(|l| l.power(scene_radius)).collect();
        let choice = powers
            .iter()
            .any(|&p| p > 0.0)
            .then(|| Distribution1D::new(&powers));
        let environment = (0..lights.len() as u32)
            .filter(|&i| matches!(lights[i as usize], Light::Environment(_)))
            .collect();
        LightSet {
            lights,
            choice,
            environment,
        }
    }

    pub fn get(&self, i: u32) -> &Light {
        &self.lights[i as usize]
    }

    /// Chooses a light: its index and probability; `None` without emitting lights.
    #[inline]
    pub fn choose(&self, u: f32) -> Option<(u32, f32)> {
        let (i, p, _) = self.choice.as_ref()?.sample_discrete(u);
        (p > 0.0).then_some((i as u32, p))
    }

    pub fn len(&self) -> usize {
        self.lights.len()
    }

    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }

    /// Probability that [`Self::choose`] picks light `i`.
    #[inline]
    pub fn pmf(&self, i: u32) -> f32 {
        self.choice.as_ref().map_or(0.0, |d| d.pmf(i as usize))
    }

    /// The environment lights.
    pub fn environment(&self) -> impl Iterator<Item = (u32, &Light)> {
        self.environment
            .iter()
            .map(|&i| (i, &self.lights[i as usize]))
    }
}

/// Scalar brightness used in power estimates.
#[inline]
fn lum(s: Spectrum) -> f32 {
    luminance(s).max(s.max_element() * 1e-3)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::square_to_uniform_sphere;

    fn lights() -> Vec<Light> {
        let tri = [
            Vec3A::new(-1.0, 2.0, -1.0),
            Vec3A::new(1.0, 2.0, -1.0),
            Vec3A::new(0.0, 2.0, 1.0),
        ];
        vec![
            Light::Triangle(TriangleLight::new(tri, Spectrum::new(1.0, 2.0, 3.0), false)),
            Light::Triangle(TriangleLight::new(tri, Spectrum::ONE, true)),
            Light::Sphere(SphereLight::new(Vec3A::Y, 0.5, Spectrum::ONE, false)),
            Light::Point(PointLight::new(Vec3A::ZERO, Spectrum::splat(2.0))),
            Light::Spot(SpotLight::new(
                Vec3A::ZERO,
                Vec3A::Z,
                Spectrum::ONE,
                0.5,
                0.3,
            )),
            Light::Directional(DirectionalLight::new(-Vec3A::Y, Spectrum::ONE)),
            Light::Environment(EnvironmentLight::new(
                None,
                Spectrum::ONE,
                glam::Mat3A::IDENTITY,
            )),
        ]
    }

    const SCENE: Target = Target {
        center: Vec3A::ZERO,
        radius: 3.0,
    };

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() <= 1e-4 * a.abs().max(b.abs())
    }

    /// What bidirectional methods need of an emission: its densities are those `pdf_le`
    /// gives for the ray it returned (`pdf_le` says 0 for a delta), and its flux is
    /// Le·|cos| / (pdf_pos · pdf_dir).
    #[test]
    fn emission_densities_agree_with_pdf_le_and_the_flux() {
        for light in lights() {
            let aim = match light.bounds() {
                Some(_) => Aim::Everywhere,
                None => Aim::Disk(SCENE),
            };
            let mut sampled = 0;
            for i in 0..64u32 {
                let u = |k: u32| ((i * 37 + k * 11) % 64) as f32 / 64.0 + 0.007;
                let (u_pos, u_dir) = (Vec2::new(u(1), u(2)), Vec2::new(u(3), u(4)));
                let Some(e) = light.sample_le(&aim, u_pos, u_dir, u(5)) else {
                    continue;
                };
                sampled += 1;
                let (pdf_pos, pdf_dir) = light.pdf_le(e.n, e.ray.d, SCENE);
                if pdf_pos != 0.0 {
                    assert!(close(pdf_pos, e.pdf_pos), "{light:?}: {pdf_pos} vs {e:?}");
                } else {
                    assert_eq!(e.pdf_pos, 1.0, "a delta position: {light:?}");
                }
                if pdf_dir != 0.0 {
                    assert!(close(pdf_dir, e.pdf_dir), "{light:?}: {pdf_dir} vs {e:?}");
                } else {
                    assert_eq!(e.pdf_dir, 1.0, "a delta direction: {light:?}");
                }
                let cos = if e.n == Vec3A::ZERO {
                    1.0
                } else {
                    e.n.dot(e.ray.d).abs()
                };
                let flux = e.le * (cos / (e.pdf_pos * e.pdf_dir));
                for c in 0..3 {
                    assert!(close(flux[c], e.flux[c]), "{light:?}: {flux} vs {e:?}");
                }
            }
            assert!(sampled >= 8, "{light:?}: {sampled} of 64 samples emitted");
        }
    }

    /// The direction densities of area lights integrate to 1 over the sphere (a Fibonacci
    /// lattice of 20 000 directions: quadrature error well under the 1 % allowed).
    #[test]
    fn area_light_direction_densities_integrate_to_one() {
        let n = 20_000;
        for light in lights().iter().take(3) {
            let normal = match light {
                Light::Sphere(_) => Vec3A::Y,
                _ => Vec3A::NEG_Y,
            };
            let golden = (1.0 + 5f32.sqrt()) / 2.0;
            let sum: f64 = (0..n)
                .map(|i| {
                    let u = Vec2::new((i as f32 + 0.5) / n as f32, (i as f32 / golden).fract());
                    light.pdf_le(normal, square_to_uniform_sphere(u), SCENE).1 as f64
                })
                .sum();
            let integral = sum * 4.0 * std::f64::consts::PI / n as f64;
            assert!((integral - 1.0).abs() < 0.01, "{light:?}: {integral}");
        }
    }
}
