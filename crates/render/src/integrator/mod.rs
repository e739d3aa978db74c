//! Integrators: given a camera ray, estimate the radiance arriving along it. All share one
//! interface and are deterministic functions of the ray and the sampler's values.
//!
//! - `path`: unidirectional path tracing with next-event estimation, multiple importance
//!   sampling (power heuristic) and Russian roulette (pbrt-v4 §13.4).
//! - `direct`: the same estimator stopped after the first diffuse or glossy vertex (specular
//!   chains before it are followed): emitted plus directly reflected light.

pub mod bdpt;
pub mod metropolis;
mod path;
mod photon;
pub mod sppm;
pub mod subsurface;
pub mod vcm;

use glam::{Vec2, Vec3A};
use tessera_scene::{SceneDesc, SubsurfaceMethod};

use crate::bsdf::TransportMode;
use crate::math::Frame;
use crate::ray::Ray;
use crate::sampler::PixelSampler;
use crate::sampling::power_heuristic;
use crate::scene::{Material, Scene, SurfaceInteraction};
use crate::spectrum::{Spectrum, is_black};
use subsurface::hierarchical::{Placement, PointClouds};

pub use crate::stats::RayStats;
pub use path::PathIntegrator;
pub use photon::{PhotonIntegrator, keyframes, record_tiles};

/// Whether a pair of directions is reflection (same side) both for the geometric normal and
/// for the BSDF's local frame. Where shading normals disagree with the geometry, light would
/// leak through the surface; such pairs contribute nothing (Veach's thesis §5.3).
#[inline]
pub(crate) fn consistent(
    si: &SurfaceInteraction,
    wo: Vec3A,
    wi: Vec3A,
    wo_local: Vec3A,
    wi_local: Vec3A,
) -> bool {
    (wo.dot(si.ng) * wi.dot(si.ng) > 0.0) == (wo_local.z * wi_local.z > 0.0)
}

/// Continues a path at `si` by sampling `material`'s BSDF toward the camera side `wo` (three
/// sample values): the throughput weight f|cos θ|/p and the ray leaving along the sampled
/// direction; `None` where sampling fails. For the specular chains photon mapping follows.
#[inline]
pub(crate) fn scatter(
    si: &SurfaceInteraction,
    material: &Material,
    wo: Vec3A,
    sampler: &mut PixelSampler,
) -> Option<(Spectrum, Ray)> {
    use crate::sampler::Sampler;
    let frame = material.frame(si, wo);
    let u = sampler.get_3d();
    let bs = material.bsdf_at(si).sample(
        frame.to_local(wo),
        u.x,
        Vec2::new(u.y, u.z),
        TransportMode::Radiance,
    )?;
    Some((bs.weight(), si.spawn(frame.to_world(bs.wi))))
}

/// Next-event estimation at `si`: one light chosen by power (`u.x`), one point on it
/// (`u.y`, `u.z`), f·Li·|cos θi| / p toward `wo`, weighted by the power heuristic against BSDF
/// sampling (the caller also counts the emitters its BSDF samples hit, as [`direct_light`]
/// does).
#[inline]
pub(crate) fn sample_direct(
    scene: &Scene,
    si: &SurfaceInteraction,
    material: &Material,
    frame: &Frame,
    wo: Vec3A,
    u: Vec3A,
    stats: &mut RayStats,
) -> Spectrum {
    let mode = TransportMode::Radiance;
    let Some((li, pmf)) = scene.lights.choose(u.x) else {
        return Spectrum::ZERO;
    };
    let Some(ls) = scene.lights.get(li).sample_li(si.p, Vec2::new(u.y, u.z)) else {
        return Spectrum::ZERO;
    };
    let wo_local = frame.to_local(wo);
    let wi_local = frame.to_local(ls.wi);
    let bsdf = material.bsdf_at(si);
    let f = bsdf.eval(wo_local, wi_local, mode) * wi_local.z.abs();
    if is_black(f) || !consistent(si, wo, ls.wi, wo_local, wi_local) {
        return Spectrum::ZERO;
    }
    stats.rays += 1;
    if !scene.unoccluded(si, &ls) {
        return Spectrum::ZERO;
    }
    let p_light = pmf * ls.pdf;
    let w = if ls.delta {
        1.0
    } else {
        power_heuristic(p_light, bsdf.pdf(wo_local, wi_local, mode))
    };
    f * ls.li * (w / p_light)
}

/// Direct light toward `wo` at `si`, for estimators that end the camera path there (photon
/// mapping's gather point, SPPM's visible point): a light sample and a BSDF sample, combined
/// by the power heuristic (Veach 1997, ch. 9). The BSDF sample counts only an emitter it
/// meets first. Light sampling alone cannot see an emitter through a narrow glossy lobe (a
/// polished or nearly smooth transmitting surface), which the BSDF sample finds.
pub(crate) fn direct_light(
    scene: &Scene,
    si: &SurfaceInteraction,
    material: &Material,
    frame: &Frame,
    wo: Vec3A,
    sampler: &mut PixelSampler,
    stats: &mut RayStats,
) -> Spectrum {
    use crate::sampler::Sampler;
    let mut l = sample_direct(scene, si, material, frame, wo, sampler.get_3d(), stats);
    let u = sampler.get_3d();
    let wo_local = frame.to_local(wo);
    let Some(bs) =
        material
            .bsdf_at(si)
            .sample(wo_local, u.x, Vec2::new(u.y, u.z), TransportMode::Radiance)
    else {
        return l;
    };
    let wi = frame.to_world(bs.wi);
    if !consistent(si, wo, wi, wo_local, bs.wi) {
        return l;
    }
    stats.rays += 1;
    // Weighted against light sampling's density of the same direction (a delta lobe only
    // this sample can follow).
    let weight = |p_light: f32| {
        if bs.specular {
            1.0
        } else {
            power_heuristic(bs.pdf, p_light)
        }
    };
    let ray = si.spawn(wi);
    let le = match scene.intersect(&ray) {
        None => scene
            .lights
            .environment()
            .map(|(i, light)| {
                light.le_direction(ray.d)
                    * weight(scene.lights.pmf(i) * light.pdf_li_direction(ray.d))
            })
            .fold(Spectrum::ZERO, |a, b| a + b),
        Some(hit) if hit.light != crate::scene::NO_LIGHT => {
            let light = scene.lights.get(hit.light);
            light.le_surface(hit.ng, -wi, hit.p)
                * weight(scene.lights.pmf(hit.light) * light.pdf_li_surface(si.p, hit.p, hit.ng))
        }
        Some(_) => Spectrum::ZERO,
    };
    if !is_black(le) {
        l += bs.weight() * le;
    }
    l
}

pub trait Integrator: Send + Sync {
    fn li(
        &self,
        scene: &Scene,
        ray: Ray,
        sampler: &mut PixelSampler,
        stats: &mut RayStats,
    ) -> Spectrum;
}

/// Whether rendering `desc` takes the hierarchical method's point-cloud pass: translucent
/// materials rendered by `hierarchical`.
pub fn needs_point_clouds(desc: &SceneDesc) -> bool {
    desc.integrator.subsurface == SubsurfaceMethod::Hierarchical
        && !desc.translucent_materials().is_empty()
}

/// The hierarchical method's pass: point clouds on the translucent surfaces, their irradiance
/// path traced (translucent surfaces those paths meet sampled by the dipole). Empty without
/// translucent materials.
pub fn subsurface_pass(desc: &SceneDesc, scene: &Scene) -> PointClouds {
    let placement = Placement::new(desc);
    let e = subsurface_irradiance(desc, scene, &placement, 0..placement.len());
    placement
        .with_irradiance(desc, &e)
        .expect("one value per point")
}

/// The irradiance of the points of `placement` with indices in `range`, as the pass computes
/// them (the same values whichever process and range: a farm task's share of the pass).
pub fn subsurface_irradiance(
    desc: &SceneDesc,
    scene: &Scene,
    placement: &Placement,
    range: std::ops::Range<usize>,
) -> Vec<Spectrum> {
    let tracer = PathIntegrator::new(desc.integrator.max_depth, desc.integrator.rr_depth);
    placement.irradiance(desc, scene, range, &|si, sub, sampler, stats| {
        tracer.exit_irradiance(scene, si, sub, sampler, stats)
    })
}
