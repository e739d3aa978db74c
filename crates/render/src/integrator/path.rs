//! Path tracing with next-event estimation and MIS (Veach's thesis ch. 9; pbrt-v4 §13.4).

use std::sync::Arc;

use glam::{Vec2, Vec3A};
use tessera_scene::SubsurfaceMethod;

use super::subsurface::hierarchical::{self, PointClouds};
use super::subsurface::{probe, single, walk};
use super::{Integrator, RayStats, consistent, sample_direct};
use crate::bsdf::TransportMode;
use crate::math::Frame;
use crate::ray::Ray;
use crate::sampler::{PixelSampler, Sampler};
use crate::sampling::power_heuristic;
use crate::scene::{Material, NO_LIGHT, Scene, SurfaceInteraction, Translucent};
use crate::spectrum::{Spectrum, is_black};

/// The throughput below which Russian roulette plays, and which its survivors carry: a path
/// whose throughput t (largest channel, η² of refraction undone) is below the floor survives
/// with probability t / floor and is reweighted by floor / t, an unbiased weight window with a
/// fixed lower bound (Vorba & Křivánek 2016 centre theirs on the pixel's estimate). pbrt-v4's
/// roulette is this with a floor of 1: each survivor returns to the weight of a primary
/// sample, so a long path that then reaches a small emitter through glass, or by the rare
/// BSDF sample, adds a sample as bright as direct light. A floor of one half lets paths run
/// longer but halves those outliers; of the floors measured it gave the lowest time × relMSE
/// on the Cornell glass and was within noise of the lowest on the box
/// (docs/src/benchmarks/profile.md).
pub const ROULETTE_FLOOR: f32 = 0.5;

#[derive(Debug, Clone)]
pub struct PathIntegrator {
    /// Most scattering events on a path.
    max_depth: u32,
    /// Russian roulette starts after this many scattering events.
    rr_depth: u32,
    /// Most diffuse or glossy scattering events (1 for direct lighting).
    max_nonspecular: u32,
    /// How light beneath translucent surfaces is carried.
    subsurface: SubsurfaceMethod,
    /// The hierarchical method's point clouds (its pass), when that is the method.
    clouds: Option<Arc<PointClouds>>,
}

impl PathIntegrator {
    pub fn new(max_depth: u32, rr_depth: u32) -> Self {
        PathIntegrator {
            max_depth,
            rr_depth,
            max_nonspecular: u32::MAX,
            subsurface: SubsurfaceMethod::Dipole,
            clouds: None,
        }
    }

    /// Emitted and directly reflected light only; specular chains are followed.
    pub fn direct_lighting(max_depth: u32) -> Self {
        PathIntegrator {
            max_depth,
            rr_depth: u32::MAX,
            max_nonspecular: 1,
            subsurface: SubsurfaceMethod::Dipole,
            clouds: None,
        }
    }

    /// The same integrator summing translucent materials' light over `clouds`.
    pub fn with_clouds(self, clouds: Arc<PointClouds>) -> Self {
        PathIntegrator {
            clouds: Some(clouds),
            ..self
        }
    }

    /// The same integrator with translucent materials rendered by `method`.
    pub fn with_subsurface(self, method: SubsurfaceMethod) -> Self {
        PathIntegrator {
            subsurface: method,
            ..self
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
    ) -> Spectrum {
        self.trace(scene, ray, sampler, stats, None)
    }
}

impl PathIntegrator {
    /// The path tracer, with `gather` ending paths at their first diffuse vertex if given.
    pub(crate) fn trace(
        &self,
        scene: &Scene,
        ray: Ray,
        sampler: &mut PixelSampler,
        stats: &mut RayStats,
        gather: Option<Gather>,
    ) -> Spectrum {
        let start = PathStart {
            specular: true,
            prev_pdf: 0.0,
            depth: 0,
        };
        self.trace_from(scene, ray, sampler, stats, gather, start)
    }

    /// The path tracer continuing a path whose last vertex sampled `ray` (`start`).
    fn trace_from(
        &self,
        scene: &Scene,
        mut ray: Ray,
        sampler: &mut PixelSampler,
        stats: &mut RayStats,
        gather: Option<Gather>,
        start: PathStart,
    ) -> Spectrum {
        let mode = TransportMode::Radiance;
        let mut l = Spectrum::ZERO;
        let mut beta = Spectrum::ONE;
        let mut eta_scale = 1.0f32;
        // The last scattering was specular (or there was none yet): emitters hit now could
        // not have been found by light sampling, so they count fully.
        let mut specular = start.specular;
        let mut prev_p = ray.o;
        let mut prev_pdf = start.prev_pdf;
        let mut depth = start.depth;
        let mut nonspecular = start.depth;

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
            let wo = -ray.d;
            if si.light != NO_LIGHT {
                let light = scene.lights.get(si.light);
                let le = light.le_surface(si.ng, wo, si.p);
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
                l += beta * sample_direct(scene, &si, material, &frame, wo, u, stats);
            }

            // Continue the path by sampling the BSDF; the fourth value decides Russian roulette.
            let u = sampler.get_4d();
            let Some(bs) = material
                .bsdf_at(&si)
                .sample(wo_local, u.x, Vec2::new(u.y, u.z), mode)
            else {
                break;
            };
            let wi = frame.to_world(bs.wi);
            if !consistent(&si, wo, wi, wo_local, bs.wi) {
                break;
            }
            let u_rr = if let Some(sub) = &material.subsurface
                && bs.transmission
                && wo_local.z > 0.0
            {
                // Light enters a translucent object (the Fresnel transmittance was the
                // probability of this branch) and leaves elsewhere.
                let Some(exit) = self.subsurface(scene, &si, wi, sub, sampler, stats, &mut l, beta)
                else {
                    break;
                };
                beta *= exit.weight;
                specular = exit.specular;
                nonspecular += 1;
                prev_pdf = exit.pdf;
                prev_p = exit.ray.o;
                ray = exit.ray;
                exit.u_rr
            } else {
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
                u.w
            };
            if is_black(beta) {
                break;
            }
            // Russian roulette on the throughput (undoing the η² of refraction, which is not
            // a loss of energy).
            if depth >= self.rr_depth {
                let survive = (beta * eta_scale).max_element() / ROULETTE_FLOOR;
                if survive < 1.0 {
                    if u_rr >= survive {
                        break;
                    }
                    beta /= survive;
                }
            }
        }
        l
    }

    /// Subsurface transport from `si`, where the path refracted into a translucent object
    /// along `wi`: for both dipole methods, single scattering added to `l` with the path's
    /// throughput `beta`; then the sampled dipole (an exit point by probe rays, direct light
    /// there added to `l`, then a direction from the exit lobe), the hierarchical sum (the
    /// path ends), or the random walk (the point and refracted direction it leaves by).
    /// `None` ends the path.
    #[allow(clippy::too_many_arguments)]
    fn subsurface(
        &self,
        scene: &Scene,
        si: &SurfaceInteraction,
        wi: Vec3A,
        sub: &Translucent,
        sampler: &mut PixelSampler,
        stats: &mut RayStats,
        l: &mut Spectrum,
        beta: Spectrum,
    ) -> Option<Exit> {
        if self.subsurface != SubsurfaceMethod::RandomWalk {
            // Jensen et al. 2001's BSSRDF: single scattering plus the dipole's diffusion.
            *l += beta * single::single_scatter(scene, si, wi, &sub.bssrdf, sampler, stats);
        }
        match self.subsurface {
            SubsurfaceMethod::Hierarchical => {
                // The path ends here: the cloud's irradiance holds all the light that enters.
                if let Some(tree) = self.clouds.as_ref().and_then(|c| c.get(si.material)) {
                    *l += beta * tree.exitance(si.p, &sub.bssrdf, hierarchical::EPSILON);
                }
                None
            }
            SubsurfaceMethod::Dipole => {
                let (pi, w) = probe::sample_exit(scene, si, &sub.bssrdf, sampler.get_4d(), stats)?;
                let (direct, exit) = leave(scene, &pi, &sub.exit, sampler, stats);
                *l += beta * w * direct;
                exit.map(|e| Exit {
                    weight: w * e.weight,
                    ..e
                })
            }
            SubsurfaceMethod::RandomWalk => {
                let (exit, d, w) = walk::walk(scene, si, wi, &sub.bssrdf, sampler, stats)?;
                Some(Exit {
                    weight: w,
                    specular: true,
                    pdf: 0.0,
                    ray: exit.spawn(d),
                    u_rr: sampler.get_1d(),
                })
            }
        }
    }
}

/// Where a path starts: whether its last scattering was specular, that scattering's density
/// (for MIS against light sampling), and the scattering events so far (none of them
/// specular: they count toward both the depth and the diffuse/glossy limit).
#[derive(Debug, Clone, Copy)]
struct PathStart {
    specular: bool,
    prev_pdf: f32,
    depth: u32,
}

impl PathIntegrator {
    /// The light leaving translucent surface point `si` through the exit lobe of `sub`,
    /// E = ∫ Sw(ω) L(ω) cos θ dω: light sampling and one path from the lobe, weighted by
    /// MIS (the irradiance of the hierarchical method's points).
    pub fn exit_irradiance(
        &self,
        scene: &Scene,
        si: &SurfaceInteraction,
        sub: &Translucent,
        sampler: &mut PixelSampler,
        stats: &mut RayStats,
    ) -> Spectrum {
        let (direct, exit) = leave(scene, si, &sub.exit, sampler, stats);
        let Some(exit) = exit else {
            return direct;
        };
        let start = PathStart {
            specular: false,
            prev_pdf: exit.pdf,
            depth: 1,
        };
        let rest = self.trace_from(scene, exit.ray, sampler, stats, None, start);
        direct + exit.weight * rest
    }
}

/// At exit point `pi` of a translucent object (its frame facing out): the light arriving there
/// as its exit lobe `exit_lobe` weighs it, by light sampling (MIS-weighted), and the lobe's sampled
/// direction to continue along (`None` if it fails or points into the surface).
fn leave(
    scene: &Scene,
    pi: &SurfaceInteraction,
    exit_lobe: &Material,
    sampler: &mut PixelSampler,
    stats: &mut RayStats,
) -> (Spectrum, Option<Exit>) {
    let frame = Frame::from_normal(pi.ns);
    let u = sampler.get_3d();
    let direct = sample_direct(scene, pi, exit_lobe, &frame, pi.ns, u, stats);
    let u = sampler.get_4d();
    let exit = exit_lobe
        .bsdf
        .sample(Vec3A::Z, u.x, Vec2::new(u.y, u.z), TransportMode::Radiance)
        .and_then(|bs| {
            let wi = frame.to_world(bs.wi);
            (wi.dot(pi.ng) > 0.0).then(|| Exit {
                weight: bs.weight(),
                specular: false,
                pdf: bs.pdf,
                ray: pi.spawn(wi),
                u_rr: u.w,
            })
        });
    (direct, exit)
}

/// How a path leaves a translucent object: the throughput factor, whether the direction was
/// a delta event (emitters then count without MIS), its density, the ray, and the sample value
/// for Russian roulette.
struct Exit {
    weight: Spectrum,
    specular: bool,
    pdf: f32,
    ray: Ray,
    u_rr: f32,
}
