//! Light sources, one per file, behind one enum; the set of a scene's lights is sampled in
//! proportion to (an estimate of) each light's power.

mod area;
mod directional;
mod environment;
mod point;
mod spot;

use glam::{Vec2, Vec3A};

use crate::sampling::Distribution1D;
use crate::spectrum::{Spectrum, luminance};

pub use area::{SphereLight, TriangleLight};
pub use directional::DirectionalLight;
pub use environment::EnvironmentLight;
pub use point::PointLight;
pub use spot::SpotLight;

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
