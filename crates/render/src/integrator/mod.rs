//! Integrators: given a camera ray, estimate the radiance arriving along it. All share one
//! interface and are deterministic functions of the ray and the sampler's values.
//!
//! - `path`: unidirectional path tracing with next-event estimation, multiple importance
//!   sampling (power heuristic) and Russian roulette (pbrt-v4 §13.4).
//! - `direct`: the same estimator stopped after the first diffuse or glossy vertex (specular
//!   chains before it are followed): emitted plus directly reflected light.

mod path;

use glam::Vec3A;
use tessera_scene::{IntegratorDesc, IntegratorKind};

use crate::ray::Ray;
use crate::sampler::PixelSampler;
use crate::scene::Scene;
use crate::spectrum::Spectrum;

pub use path::PathIntegrator;

/// Counters kept per tile (no shared state in the sample loop).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RayStats {
    /// Rays traced: camera, continuation and shadow rays.
    pub rays: u64,
    pub samples: u64,
    /// Samples whose radiance was NaN or infinite and was dropped before the film.
    pub nonfinite: u64,
}

impl RayStats {
    pub fn add(&mut self, o: &RayStats) {
        self.rays += o.rays;
        self.samples += o.samples;
        self.nonfinite += o.nonfinite;
    }
}

/// The first surface a camera ray hit, for the AOVs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FirstHit {
    pub albedo: Spectrum,
    /// World-space shading normal.
    pub normal: Vec3A,
    /// World-space position (the film turns it into depth along the camera axis).
    pub p: Vec3A,
}

/// Radiance along a camera ray, and what it hit first.
#[derive(Debug, Clone, Copy)]
pub struct RadianceSample {
    pub l: Spectrum,
    pub first_hit: Option<FirstHit>,
}

pub trait Integrator: Send + Sync {
    fn li(
        &self,
        scene: &Scene,
        ray: Ray,
        sampler: &mut PixelSampler,
        stats: &mut RayStats,
    ) -> RadianceSample;
}

/// The integrator a description names; `auto` (which needs the scene, see [`for_scene`])
/// means path tracing here.
pub fn from_desc(desc: &IntegratorDesc) -> Box<dyn Integrator> {
    match desc.kind {
        IntegratorKind::Path | IntegratorKind::Auto => {
            Box::new(PathIntegrator::new(desc.max_depth, desc.rr_depth))
        }
        IntegratorKind::Direct => Box::new(PathIntegrator::direct_lighting(desc.max_depth)),
    }
}

/// The integrator for a scene: its own choice, or the one scene analysis makes for `auto`.
pub fn for_scene(scene: &tessera_scene::SceneDesc) -> Box<dyn Integrator> {
    let kind = crate::analysis::analyze(scene).integrator;
    from_desc(&IntegratorDesc {
        kind,
        ..scene.integrator
    })
}
