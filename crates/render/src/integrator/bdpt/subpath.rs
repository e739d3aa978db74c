//! The context BDPT and the methods built on it run in, and the random walks that make camera
//! and light subpaths.

use glam::{Vec2, Vec3A};

use super::vertex::{Kind, Vertex, shading_correction};
use crate::bsdf::TransportMode;
use crate::camera::Camera;
use crate::integrator::{RayStats, consistent};
use crate::light::{Aim, Light, Target};
use crate::sampler::Sampler;
use crate::scene::{NO_LIGHT, Scene};
use crate::spectrum::{Spectrum, is_black};

/// Longest subpaths: the camera's has the lens and `max_depth` + 1 more vertices.
const MAX_VERTICES: usize = 66;

pub(in crate::integrator) struct Ctx<'a> {
    pub(in crate::integrator) scene: &'a Scene,
    pub(in crate::integrator) camera: &'a Camera,
    pub(in crate::integrator) rr_depth: u32,
    /// The sphere the lights' bidirectional densities are defined over (infinite lights).
    pub(in crate::integrator) bounds: Target,
}

impl<'a> Ctx<'a> {
    /// The context over `scene` seen by `camera`, Russian roulette from `rr_depth` vertices.
    pub(in crate::integrator) fn new(scene: &'a Scene, camera: &'a Camera, rr_depth: u32) -> Self {
        Ctx {
            scene,
            camera,
            rr_depth,
            bounds: Target {
                center: scene.center,
                radius: scene.radius,
            },
        }
    }

    pub(in crate::integrator) fn light_of(&self, v: &Vertex) -> Option<(u32, &Light)> {
        let i = match v.kind {
            Kind::Light(i) => i,
            Kind::Surface => v.si.map_or(NO_LIGHT, |si| si.light),
            Kind::Camera => NO_LIGHT,
        };
        (i != NO_LIGHT).then(|| (i, self.scene.lights.get(i)))
    }

    /// Extends `path` (whose last vertex is where `ray` left, with solid-angle density `pdf`)
    /// by BSDF sampling until it leaves the scene, is absorbed or has `max` vertices.
    #[allow(clippy::too_many_arguments)]
    fn random_walk(
        &self,
        path: &mut Vec<Vertex>,
        mut ray: crate::ray::Ray,
        mut beta: Spectrum,
        mut pdf_fwd: f32,
        max: usize,
        mode: TransportMode,
        sampler: &mut impl Sampler,
        stats: &mut RayStats,
    ) {
        let start = beta.max_element();
        let first = path.len();
        while path.len() < max && !is_black(beta) {
            stats.rays += 1;
            let Some(si) = self.scene.intersect(&ray) else {
                // A camera path that escapes sees the environment: a light vertex at infinity.
                if mode == TransportMode::Radiance
                    && let Some((env, _)) = self.scene.lights.environment().next()
                {
                    let prev = path.len() - 1;
                    let mut v = Vertex::at_infinity(env, ray.o, ray.d, beta);
                    v.pdf_fwd = path[prev].convert_density(pdf_fwd, &v);
                    path.push(v);
                }
                break;
            };
            let wo = -ray.d;
            let prev = path.len() - 1;
            let mut v = Vertex::surface(si, wo);
            v.beta = beta;
            v.pdf_fwd = path[prev].convert_density(pdf_fwd, &v);
            path.push(v);
            if path.len() >= max {
                break;
            }
            let material = self.scene.material(si.material);
            if material.is_black() {
                break;
            }
            let frame = material.frame(&si, wo);
            let wo_l = frame.to_local(wo);
            let u = sampler.get_4d();
            let bsdf = material.bsdf_at(&si);
            let Some(bs) = bsdf.sample(wo_l, u.x, Vec2::new(u.y, u.z), mode) else {
                break;
            };
            let wi = frame.to_world(bs.wi);
            if !consistent(&si, wo, wi, wo_l, bs.wi) {
                break;
            }
            let cur = path.len() - 1;
            let pdf_rev = if bs.specular {
                // Both directions' densities by the delta convention of `delta_lobe`.
                path[cur].delta = true;
                let (wn, wp) = match mode {
                    TransportMode::Radiance => (wo, wi),
                    TransportMode::Importance => (wi, wo),
                };
                let (from_eye, from_light) = self
                    .delta_lobe(&si, wn, wp)
                    .map_or((0.0, 0.0), |l| (l.p_rad, l.pdf_imp));
                match mode {
                    TransportMode::Radiance => {
                        pdf_fwd = from_eye;
                        from_light
                    }
                    TransportMode::Importance => {
                        pdf_fwd = from_light;
                        from_eye
                    }
                }
            } else {
                pdf_fwd = bs.pdf;
                bsdf.pdf(bs.wi, wo_l, mode)
            };
            beta *= bs.weight() * shading_correction(&si, wo, wi, mode);
            let rev = path[cur].convert_density(pdf_rev, &path[prev]);
            path[prev].pdf_rev = rev;
            ray = si.spawn(wi);
            if path.len() - first >= self.rr_depth as usize && start > 0.0 {
                let survive = beta.max_element() / start;
                if survive < 1.0 {
                    if u.w >= survive {
                        break;
                    }
                    beta /= survive;
                }
            }
        }
    }

    /// The camera subpath of a sample, at most `max` vertices: the lens vertex, then the walk.
    pub(in crate::integrator) fn camera_subpath(
        &self,
        ray: crate::ray::Ray,
        max: usize,
        sampler: &mut impl Sampler,
        stats: &mut RayStats,
        path: &mut Vec<Vertex>,
    ) {
        path.clear();
        let (_, pdf_dir) = self.camera.pdf_we(ray.o, ray.d);
        path.push(Vertex::point(
            Kind::Camera,
            ray.o,
            Vec3A::ZERO,
            Vec3A::ZERO,
            Spectrum::ONE,
            0.0,
        ));
        let max = max.min(MAX_VERTICES);
        self.random_walk(
            path,
            ray,
            Spectrum::ONE,
            pdf_dir,
            max,
            TransportMode::Radiance,
            sampler,
            stats,
        );
    }

    /// A light subpath's first vertex, its emission and the light's choice probability: a
    /// light chosen by power, a point and a direction from it.
    pub(in crate::integrator) fn light_start(
        &self,
        sampler: &mut impl Sampler,
    ) -> Option<(Vertex, crate::light::Emission, f32)> {
        let u = sampler.get_4d();
        let u_dir = sampler.get_2d();
        let (li, pmf) = self.scene.lights.choose(u.x)?;
        let light = self.scene.lights.get(li);
        if light.bounds().is_none() {
            // From the disk across the scene: the vertex is the direction (its density per
            // solid angle), the disk's density the next vertex's.
            let aim = Aim::Disk(self.bounds);
            let e = light.sample_le(&aim, Vec2::new(u.y, u.z), u_dir, u.w)?;
            let mut v = Vertex::at_infinity(li, e.ray.o, -e.ray.d, e.le);
            v.pdf_fwd = pmf * e.pdf_dir;
            return Some((v, e, pmf));
        }
        let e = light.sample_le(&Aim::Everywhere, Vec2::new(u.y, u.z), u_dir, u.w)?;
        let v = Vertex::point(
            Kind::Light(li),
            e.ray.o,
            Vec3A::ZERO,
            e.n,
            e.le,
            pmf * e.pdf_pos,
        );
        Some((v, e, pmf))
    }

    /// The light subpath of a sample, at most `max` vertices: a light chosen by power, an
    /// emission from it, the walk.
    pub(in crate::integrator) fn light_subpath(
        &self,
        max: usize,
        sampler: &mut impl Sampler,
        stats: &mut RayStats,
        path: &mut Vec<Vertex>,
    ) {
        path.clear();
        let Some((v, e, pmf)) = self.light_start(sampler) else {
            return;
        };
        // The first step's density: per solid angle from a point, per unit disk area from
        // infinity.
        let pdf = if v.infinite { e.pdf_pos } else { e.pdf_dir };
        path.push(v);
        let max = max.min(MAX_VERTICES);
        self.random_walk(
            path,
            e.ray,
            e.flux / pmf,
            pdf,
            max,
            TransportMode::Importance,
            sampler,
            stats,
        );
        if let [z0, z1, ..] = &mut path[..] {
            z0.nee = self.nee_ratio(z0, z1, z0.pdf_fwd);
        }
    }

    /// Whether a vertex can be joined to another: a surface with a smooth lobe, any light
    /// (area or point) not at infinity, the lens.
    pub(in crate::integrator) fn connectible(&self, v: &Vertex) -> bool {
        if v.infinite {
            return false;
        }
        match v.kind {
            Kind::Surface => {
                v.si.is_some_and(|si| self.scene.material(si.material).flags.smooth)
            }
            _ => true,
        }
    }
}
