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

/// A photon leaving a light.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Emission {
    /// Origin on (or just off) the light, unit direction of travel.
    pub ray: Ray,
    /// Power carried by this one sample, W: Le·|cos θ| / (pdf_area · pdf_direction); divided
    /// by the light's choice probability and the photon count by the caller.
    pub flux: Spectrum,
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
    let (d, flux) = match aim {
        Aim::Projection(map) => {
            let (d, pdf) = map.sample(u_extra, u_dir)?;
            let cos = n.dot(d);
            if cos <= 0.0 && !two_sided {
                return None;
            }
            (d, radiance * (cos.abs() * area / pdf))
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
            (d, radiance * (crate::math::PI * area * sides))
        }
    };
    Some(Emission {
        ray: Ray::new(offset_ray_origin(p, p_error, n, d), d),
        flux,
    })
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
    Emission {
        ray: Ray::new(o, d),
        flux: le * (crate::math::PI * r * r / pdf_dir),
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

    /// Radiance leaving an area light's surface with front normal `n` in direction `w`.
    pub fn le_surface(&self, n: Vec3A, w: Vec3A) -> Spectrum {
        match self {
            Light::Triangle(l) => l.le(n, w),
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
