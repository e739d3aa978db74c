//! Path tracing with next-event estimation and MIS (Veach's thesis ch. 9; pbrt-v4 §13.4).

use glam::{Vec2, Vec3A};

use super::{Integrator, RadianceSample, RayStats, consistent, sample_direct};
use crate::bsdf::TransportMode;
use crate::integrator::FirstHit;
use crate::math::Frame;
use crate::ray::Ray;
use crate::sampler::{PixelSampler, Sampler};
use crate::sampling::power_heuristic;
use crate::scene::{Material, NO_LIGHT, Scene, SurfaceInteraction};
use crate::spectrum::{Spectrum, is_black};

#[derive(Debug, Clone)]
pub struct PathIntegrator {
    /// Most scattering events on a path.
    max_depth: u32,
    /// Russian roulette starts after this many scattering events.
    rr_depth: u32,
    /// Most diffuse or glossy scattering events (1 for direct lighting).
    max_nonspecular: u32,
}

impl PathIntegrator {
    pub fn new(max_depth: u32, rr_depth: u32) -> Self {
        PathIntegrator {
            max_depth,
            rr_depth,
            max_nonspecular: u32::MAX,
        }
    }

    /// Emitted and directly reflected light only; specular chains are followed.
    pub fn direct_lighting(max_depth: u32) -> Self {
        PathIntegrator {
            max_depth,
            rr_depth: u32::MAX,
            max_nonspecular: 1,
        }
    }
}

/// What a path does at a surface with a diffuse component, if not continue: the radiance
/// leaving it toward `wo` (all of it, emission aside), after which the path ends. Photon mapping
/// gathers here.
pub(crate) type Gather<'a> = &'a dyn Fn(
    &SurfaceInteraction,
    &Material,
    &Frame,
    Vec3A,
    &mut PixelSampler,
    &mut RayStats,
) -> Spectrum;

impl Integrator for PathIntegrator {
    fn li(
        &self,
        scene: &Scene,
        ray: Ray,
        sampler: &mut PixelSampler,
        stats: &mut RayStats,
    ) -> RadianceSample {
        self.trace(scene, ray, sampler, stats, None)
    }
}

impl PathIntegrator {
    /// The path tracer, with `gather` ending paths at their first diffuse vertex if given.
    pub(crate) fn trace(
        &self,
        scene: &Scene,
        mut ray: Ray,
        sampler: &mut PixelSampler,
        stats: &mut RayStats,
        gather: Option<Gather>,
    ) -> RadianceSample {
        let mode = TransportMode::Radiance;
        let mut l = Spectrum::ZERO;
        let mut beta = Spectrum::ONE;
        let mut eta_scale = 1.0f32;
        // The last scattering was specular (or there was none yet): emitters hit now could
        // not have been found by light sampling, so they count fully.
        let mut specular = true;
        let mut prev_p = ray.o;
        let mut prev_pdf = 0.0f32;
        let mut first_hit = None;
        let mut depth = 0u32;
        let mut nonspecular = 0u32;

        loop {
            stats.rays += 1;
            let Some(si) = scene.intersect(&ray) else {
                for (i, light) in scene.lights.environment() {
                    let le = light.le_direction(ray.d);
                    let w = if specular {
                        1.0
                    } else {
                        power_heuristic(
                            prev_pdf,
                            scene.lights.pmf(i) * light.pdf_li_direction(ray.d),
                        )
                    };
                    l += beta * le * w;
                }
                break;
            };
            let material = scene.material(si.material);
            if depth == 0 {
                first_hit = Some(FirstHit {
                    albedo: material.bsdf.albedo(),
                    normal: si.ns,
                    p: si.p,
                });
            }
            let wo = -ray.d;
            if si.light != NO_LIGHT {
                let light = scene.lights.get(si.light);
                let le = light.le_surface(si.ng, wo);
                if !is_black(le) {
                    let w = if specular {
                        1.0
                    } else {
                        power_heuristic(
                            prev_pdf,
                            scene.lights.pmf(si.light) * light.pdf_li_surface(prev_p, si.p, si.ng),
                        )
                    };
                    l += beta * le * w;
                }
            }
            if depth >= self.max_depth || material.is_black() || nonspecular >= self.max_nonspecular
            {
                break;
            }
            depth += 1;
            let frame = material.frame(&si, wo);
            if let Some(gather) = gather
                && material.flags.diffuse
            {
                l += beta * gather(&si, material, &frame, wo, sampler, stats);
                break;
            }
            let wo_local = frame.to_local(wo);

            // Next-event estimation: one light chosen by power, one point on it.
            if material.flags.smooth {
                let u = sampler.get_3d();
                l += beta * sample_direct(scene, &si, material, &frame, wo, u, true, stats);
            }

            // Continue the path by sampling the BSDF; the fourth value decides Russian roulette.
            let u = sampler.get_4d();
            let Some(bs) = material
                .bsdf
                .sample(wo_local, u.x, Vec2::new(u.y, u.z), mode)
            else {
                break;
            };
            let wi = frame.to_world(bs.wi);
            if !consistent(&si, wo, wi, wo_local, bs.wi) {
                break;
            }
            beta *= bs.weight();
            if bs.transmission {
                eta_scale *= bs.eta * bs.eta;
            }
            specular = bs.specular;
            if !bs.specular {
                nonspecular += 1;
            }
            prev_pdf = bs.pdf;
            prev_p = si.p;
            ray = si.spawn(wi);
            if is_black(beta) {
                break;
            }
            // Russian roulette on the throughput (undoing the η² of refraction, which is not
            // a loss of energy).
            if depth >= self.rr_depth {
                let survive = (beta * eta_scale).max_element();
                if survive < 1.0 {
                    if u.w >= survive {
                        break;
                    }
                    beta /= survive;
                }
            }
        }
        RadianceSample { l, first_hit }
    }
}
