//! Bidirectional path tracing (Veach's thesis ch. 10; pbrt-v3 §16.3).
//!
//! Each pixel sample traces a camera subpath and a light subpath and connects every prefix
//! pair (s light vertices, t camera vertices): s = 0 is a camera path that hits an emitter,
//! s = 1 samples a point on a light for the camera path's end (next-event estimation), t = 1
//! connects a light subpath vertex to the lens (light tracing: the contribution lands on
//! whatever pixel it projects to, a *splat*), and the rest join the two ends with a shadow ray.
//! Every strategy is weighted by the power heuristic over all strategies that could have made
//! the same path, from the densities of each vertex sampled forward (`pdf_fwd`) and reverse
//! (`pdf_rev`), in area measure.
//!
//! Light tracing splats anywhere on the film, so BDPT renders whole frames: samples of every
//! pixel, with the splats accumulated in fixed point (integer addition is associative, so the
//! image does not depend on the order the threads add in).

use std::sync::atomic::{AtomicI64, Ordering::Relaxed};

use glam::{Vec2, Vec3A};
use rayon::prelude::*;

use super::vcm::FIRST_MERGE;
use super::{RayStats, consistent};
use crate::bsdf::TransportMode;
use crate::camera::Camera;
use crate::film::{Image, TileSums, tiles};
use crate::light::{Aim, Light, ShadowTarget, Target};
use crate::render::camera_ray;
use crate::sampler::{PixelSampler, Sampler};
use crate::scene::{NO_LIGHT, Scene, SurfaceInteraction};
use crate::spectrum::{Spectrum, is_black};
use crate::{SampleRange, Tile};

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Kind {
    Camera,
    /// A point on a light (the first vertex of a light subpath, or one sampled for s = 1).
    Light(u32),
    Surface,
}

/// A subpath vertex.
#[derive(Debug, Clone, Copy)]
pub(super) struct Vertex {
    pub(super) kind: Kind,
    pub(super) p: Vec3A,
    pub(super) p_error: Vec3A,
    /// Geometric normal; zero for a point in space (a pinhole, a point light).
    pub(super) ng: Vec3A,
    /// Shading normal (the geometric one where there is no surface to shade).
    pub(super) ns: Vec3A,
    /// For surfaces: the hit, and the direction toward the previous vertex of the subpath.
    pub(super) si: Option<SurfaceInteraction>,
    pub(super) wo: Vec3A,
    pub(super) beta: Spectrum,
    /// Sampled by a specular lobe: no other strategy can make it.
    pub(super) delta: bool,
    /// Density of this vertex sampled from the previous one of its subpath, per unit area.
    pub(super) pdf_fwd: f32,
    /// Density of this vertex sampled from the next one (the other direction), per unit area.
    pub(super) pdf_rev: f32,
    /// A light at infinity (environment, directional): `p` stands one unit from its
    /// neighbour along the direction to the light, so directions to it are exact; its own
    /// densities are per unit solid angle, and the neighbour's from it per unit area of the
    /// disk it emits from, projected.
    pub(super) infinite: bool,
    /// On a light subpath's emitter vertex: [`Ctx::nee_ratio`] toward the path's next vertex
    /// (1 elsewhere): how much likelier light sampling (s = 1) makes this point than the
    /// light subpath's start did.
    pub(super) nee: f32,
}

impl Vertex {
    pub(super) fn point(
        kind: Kind,
        p: Vec3A,
        p_error: Vec3A,
        n: Vec3A,
        beta: Spectrum,
        pdf: f32,
    ) -> Self {
        Vertex {
            kind,
            p,
            p_error,
            ng: n,
            ns: n,
            si: None,
            wo: Vec3A::ZERO,
            beta,
            delta: false,
            pdf_fwd: pdf,
            pdf_rev: 0.0,
            infinite: false,
            nee: 1.0,
        }
    }

    /// A light at infinity seen from `from` in direction `wi`.
    fn at_infinity(light: u32, from: Vec3A, wi: Vec3A, beta: Spectrum) -> Self {
        let mut v = Vertex::point(
            Kind::Light(light),
            from + wi,
            Vec3A::ZERO,
            Vec3A::ZERO,
            beta,
            0.0,
        );
        v.infinite = true;
        v
    }

    /// The vertex of a ray's hit, arrived at from direction `wo`.
    pub(super) fn surface(si: SurfaceInteraction, wo: Vec3A) -> Self {
        let mut v = Vertex::point(Kind::Surface, si.p, si.p_error, si.ng, Spectrum::ONE, 0.0);
        v.ns = si.ns;
        v.si = Some(si);
        v.wo = wo;
        v
    }

    pub(super) fn on_surface(&self) -> bool {
        self.ng != Vec3A::ZERO
    }

    pub(super) fn end(&self) -> (Vec3A, Vec3A, Vec3A) {
        (self.p, self.p_error, self.ng)
    }

    /// A per-solid-angle density `pdf` of sampling `next` from here, per unit area at `next`.
    /// Toward a light at infinity the density stays per solid angle; from one, `pdf` is per
    /// unit area of its disk, projected onto `next`.
    pub(super) fn convert_density(&self, pdf: f32, next: &Vertex) -> f32 {
        if next.infinite {
            return pdf;
        }
        if self.infinite {
            let w = (next.p - self.p).normalize_or_zero();
            return if next.on_surface() {
                pdf * next.ng.dot(w).abs()
            } else {
                pdf
            };
        }
        let w = next.p - self.p;
        let d2 = w.length_squared();
        if d2 == 0.0 {
            return 0.0;
        }
        let mut pdf = pdf / d2;
        if next.on_surface() {
            pdf *= next.ng.dot(w).abs() / d2.sqrt();
        }
        pdf
    }
}

/// The settings BDPT runs with.
#[derive(Debug, Clone, Copy)]
pub struct Bdpt {
    /// Most scattering vertices on a path (the path tracer's `max_depth`).
    pub max_depth: u32,
    /// Fewest scattering vertices on a path: shorter ones are left out (0 for the image).
    pub min_depth: u32,
    /// Russian roulette ends subpaths after this many scattering events, with survival
    /// probability the throughput relative to the subpath's start. The densities MIS weighs
    /// by leave it out: the weights still sum to one over the strategies of a path, so the
    /// estimate stays unbiased (only the weights are less than optimal).
    pub rr_depth: u32,
}

/// Longest subpaths: the camera's has the lens and `max_depth` + 1 more vertices.
const MAX_VERTICES: usize = 66;

pub(super) struct Ctx<'a> {
    pub(super) scene: &'a Scene,
    pub(super) camera: &'a Camera,
    pub(super) rr_depth: u32,
    /// The sphere the lights' bidirectional densities are defined over (infinite lights).
    pub(super) bounds: Target,
}

impl<'a> Ctx<'a> {
    /// The context of `integrator` (named in the error) over `scene` seen by `camera`;
    /// without `at_infinity`, refuses lights at infinity (path-space MLT's mutations do not
    /// handle them).
    pub(super) fn new(
        integrator: &str,
        scene: &'a Scene,
        camera: &'a Camera,
        rr_depth: u32,
        at_infinity: bool,
    ) -> Result<Self, String> {
        if !at_infinity
            && (0..scene.lights.len() as u32).any(|i| scene.lights.get(i).bounds().is_none())
        {
            return Err(format!(
                "{integrator}: lights at infinity (environment, directional) are not supported yet; use the path integrator"
            ));
        }
        Ok(Ctx {
            scene,
            camera,
            rr_depth,
            bounds: Target {
                center: scene.center,
                radius: scene.radius,
            },
        })
    }

    pub(super) fn light_of(&self, v: &Vertex) -> Option<(u32, &Light)> {
        let i = match v.kind {
            Kind::Light(i) => i,
            Kind::Surface => v.si.map_or(NO_LIGHT, |si| si.light),
            Kind::Camera => NO_LIGHT,
        };
        (i != NO_LIGHT).then(|| (i, self.scene.lights.get(i)))
    }

    /// f at a surface vertex for light leaving toward `wo` (the vertex's own) and arriving
    /// from `next`, with the shading-normal correction of importance transport (Veach §5.3);
    /// and the densities (solid angle, as [`Self::pdf`] takes them) of sampling the direction
    /// to `next` from `wo` and of sampling `wo` from the direction to `next`, from one frame.
    /// (Where f is not zero both directions lie on one side of the shading normal, so the
    /// frame is the one `pdf` would turn to either.)
    pub(super) fn f_and_pdfs(
        &self,
        v: &Vertex,
        next: &Vertex,
        mode: TransportMode,
    ) -> (Spectrum, f32, f32) {
        let Some(si) = &v.si else {
            return (Spectrum::ZERO, 0.0, 0.0);
        };
        let wi = (next.p - v.p).normalize_or_zero();
        let material = self.scene.material(si.material);
        let frame = material.frame(si, v.wo);
        let (wo_l, wi_l) = (frame.to_local(v.wo), frame.to_local(wi));
        if !consistent(si, v.wo, wi, wo_l, wi_l) {
            return (Spectrum::ZERO, 0.0, 0.0);
        }
        let f = material.bsdf.eval(wo_l, wi_l, mode) * shading_correction(si, v.wo, wi, mode);
        if is_black(f) {
            return (f, 0.0, 0.0);
        }
        (
            f,
            material.bsdf.pdf(wo_l, wi_l, TransportMode::Radiance),
            material.bsdf.pdf(wi_l, wo_l, TransportMode::Radiance),
        )
    }

    /// Density per unit area at `next` of sampling it from `v` (whose subpath came from
    /// `prev`): BSDF sampling at surfaces, emission at lights, importance at the camera.
    pub(super) fn pdf(&self, v: &Vertex, prev: Option<&Vertex>, next: &Vertex) -> f32 {
        let wn = (next.p - v.p).normalize_or_zero();
        let pdf = match v.kind {
            Kind::Light(_) => return self.pdf_le(v, next).1,
            Kind::Camera => self.camera.pdf_we(v.p, wn).1,
            Kind::Surface => {
                let (Some(si), Some(prev)) = (&v.si, prev) else {
                    return 0.0;
                };
                let wp = (prev.p - v.p).normalize_or_zero();
                let material = self.scene.material(si.material);
                let frame = material.frame(si, wp);
                material.bsdf.pdf(
                    frame.to_local(wp),
                    frame.to_local(wn),
                    TransportMode::Radiance,
                )
            }
        };
        v.convert_density(pdf, next)
    }

    /// The specular lobe at `si` between `wn` (toward the eye side) and `wp` (toward the
    /// light side), seen from both ends. One delta convention serves every strategy's
    /// density (BDPT's and VCM's weights, MLT's C_s = f / p_s): a specular vertex sampled from
    /// the eye side has its radiance lobe's probability; from the light side, its importance
    /// lobe's probability times c_rad |ω_n·n_g| / (c_imp |ω_p·n_g|), c the lobe's coefficient
    /// f|cos θ_i| in each mode — the Jacobian between the two directions' delta measures
    /// (η² across a refraction, shading normals). With it the ratios of densities along a
    /// specular chain are the true ones, which merging needs (a caustic seen through glass
    /// is merged or hit, never connected). `None` where no specular lobe turns one into the
    /// other.
    pub(super) fn delta_lobe(
        &self,
        si: &SurfaceInteraction,
        wn: Vec3A,
        wp: Vec3A,
    ) -> Option<DeltaLobe> {
        let (w_rad, p_rad) = self.lobe_between(si, wn, wp, TransportMode::Radiance)?;
        let (w_imp, p_imp) = self.lobe_between(si, wp, wn, TransportMode::Importance)?;
        let (c_rad, c_imp) = (w_rad * p_rad, w_imp * p_imp);
        let (m_rad, m_imp) = (c_rad.max_element(), c_imp.max_element());
        let cos_p = wp.dot(si.ng).abs();
        if m_rad <= 0.0 || m_imp <= 0.0 || cos_p == 0.0 {
            return None;
        }
        Some(DeltaLobe {
            c_rad,
            p_rad,
            p_imp,
            pdf_imp: p_imp * m_rad * wn.dot(si.ng).abs() / (m_imp * cos_p),
        })
    }

    /// The specular lobe at `si` that turns `wo` into `wi` in `mode`: its sampling weight
    /// (with the shading correction of importance transport) and probability.
    fn lobe_between(
        &self,
        si: &SurfaceInteraction,
        wo: Vec3A,
        wi: Vec3A,
        mode: TransportMode,
    ) -> Option<(Spectrum, f32)> {
        let material = self.scene.material(si.material);
        let fr = material.frame(si, wo);
        let wo_l = fr.to_local(wo);
        for u in [0.0, 0.5, 0.999_999] {
            let Some(bs) = material.bsdf.sample(wo_l, u, Vec2::splat(0.5), mode) else {
                continue;
            };
            if !bs.specular || fr.to_world(bs.wi).dot(wi) < 1.0 - 1e-4 {
                continue;
            }
            if !consistent(si, wo, wi, wo_l, bs.wi) {
                return None;
            }
            return Some((bs.weight() * shading_correction(si, wo, wi, mode), bs.pdf));
        }
        None
    }

    /// Densities of the light at `v` emitting from `v` toward `to`: of choosing the light
    /// and the point `v` on it (per unit area), and of the direction, per unit area at `to`.
    /// For a light at infinity: of choosing it and the direction (per solid angle; an
    /// environment as every environment light together, as a path escaping sees them), and
    /// of the point on its disk, per unit area at `to`.
    fn pdf_le(&self, v: &Vertex, to: &Vertex) -> (f32, f32) {
        let Some((i, light)) = self.light_of(v) else {
            return (0.0, 0.0);
        };
        let w = (to.p - v.p).normalize_or_zero();
        if v.infinite {
            let (disk, _) = light.pdf_le(w, w, self.bounds);
            let origin = match light {
                Light::Environment(_) => self
                    .scene
                    .lights
                    .environment()
                    .map(|(j, l)| self.scene.lights.pmf(j) * l.pdf_li_direction(-w))
                    .sum(),
                // A delta in direction.
                _ => 0.0,
            };
            return (origin, v.convert_density(disk, to));
        }
        let (pdf_pos, pdf_dir) = light.pdf_le(v.ng, w, self.bounds);
        (
            self.scene.lights.pmf(i) * pdf_pos,
            v.convert_density(pdf_dir, to),
        )
    }

    /// How much likelier light sampling (strategy s = 1) makes emitter vertex `v` from `from`
    /// than a light subpath starting there, whose density of `v` per unit area (with the
    /// light's choice) is `start` — a light subpath's `pdf_fwd`, `pdf_le`'s first. A sphere is sampled by the cone
    /// it subtends (from 30 radii away the ratio is ≈ 4 cos θ at the light); a triangle by
    /// area (1); delta lights and lights at infinity start light subpaths as light sampling
    /// picks them (1). MIS weighs s = 1 by this density, as SmallVCM does; pbrt's BDPT takes
    /// the subpath's start for it, which undervalues a sphere's light sampling against light
    /// tracing and merging.
    pub(super) fn nee_ratio(&self, v: &Vertex, from: &Vertex, start: f32) -> f32 {
        if v.infinite {
            return 1.0;
        }
        let Some((i, light)) = self.light_of(v) else {
            return 1.0;
        };
        let nee = from.convert_density(light.pdf_li_surface(from.p, v.p, v.ng), v);
        nee_over_start(nee * self.scene.lights.pmf(i), start)
    }

    /// Radiance an emitter vertex sends toward `to` (from a light at infinity: every
    /// environment light's along that direction).
    fn le(&self, v: &Vertex, to: &Vertex) -> Spectrum {
        let Some((_, light)) = self.light_of(v) else {
            return Spectrum::ZERO;
        };
        let w = (to.p - v.p).normalize_or_zero();
        if v.infinite {
            return self
                .scene
                .lights
                .environment()
                .map(|(_, l)| l.le_direction(-w))
                .sum();
        }
        light.le_surface(v.ng, w)
    }

    /// Whether a light vertex is a delta in position (a point light) or direction (a
    /// directional light): no path can hit it.
    pub(super) fn is_delta_light(&self, v: &Vertex) -> bool {
        matches!(
            self.light_of(v),
            Some((_, Light::Point(_) | Light::Spot(_) | Light::Directional(_)))
        )
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
            let Some(bs) = material.bsdf.sample(wo_l, u.x, Vec2::new(u.y, u.z), mode) else {
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
                material.bsdf.pdf(bs.wi, wo_l, mode)
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
    pub(super) fn camera_subpath(
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
    pub(super) fn light_start(
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
    pub(super) fn light_subpath(
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

    /// The power-heuristic weight of the strategy (s, t), with the connection's endpoints
    /// replaced by `sampled` where it made them (s = 1: a light point; t = 1: the lens), and
    /// vertex merging among the strategies when `merge` > 0 (see [`Self::mis_sums`]).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn mis_weight(
        &self,
        light: &[Vertex],
        camera: &[Vertex],
        sampled: Option<&Vertex>,
        s: usize,
        t: usize,
        merge: f32,
        joined: Option<&Joined>,
    ) -> f32 {
        if s + t == 2 {
            return 1.0;
        }
        1.0 / (1.0 + self.mis_sums(light, camera, sampled, s, t, merge, joined))
    }

    /// Σ over the other strategies j of the path made by (s, t) of (p_j / p_{s,t})²: the
    /// connections, and with `merge` = η π r² > 0 (light paths per iteration × the merging
    /// disc) also vertex merging at each non-specular vertex from the light's second on
    /// ([`FIRST_MERGE`]; Georgiev et al. 2012; p_merge at z = p of the connection that samples
    /// z from one side × the density of z from the other × η π r²). (A merge's own weight is
    /// VCM's, from sums kept along the subpaths.)
    #[allow(clippy::too_many_arguments)]
    fn mis_sums(
        &self,
        light: &[Vertex],
        camera: &[Vertex],
        sampled: Option<&Vertex>,
        s: usize,
        t: usize,
        merge: f32,
        joined: Option<&Joined>,
    ) -> f32 {
        // The four vertices whose reverse densities the connection changes, and the two
        // endpoints, which a connection never treats as specular.
        let qs = match (s, sampled) {
            (0, _) => None,
            (1, Some(v)) => Some(v),
            _ => Some(&light[s - 1]),
        };
        let pt = match (t, sampled) {
            (1, Some(v)) => v,
            _ => &camera[t - 1],
        };
        let qs_minus = (s >= 2).then(|| &light[s - 2]);
        let pt_minus = (t >= 2).then(|| &camera[t - 2]);
        // s = 0: pt is an emitter the camera path hit; as a light subpath would have made it.
        let emitted = match (qs, pt_minus) {
            (None, Some(m)) => self.pdf_le(pt, m),
            _ => (0.0, 0.0),
        };
        let (pt_rev, pt_minus_rev, qs_rev, qs_minus_rev) = match joined {
            Some(j) => (
                j.pt_rev,
                Some(j.pt_minus_rev),
                Some(j.qs_rev),
                Some(j.qs_minus_rev),
            ),
            None => (
                match qs {
                    Some(q) => self.pdf(q, qs_minus, pt),
                    None => emitted.0,
                },
                pt_minus.map(|m| match qs {
                    Some(q) => self.pdf(pt, Some(q), m),
                    None => emitted.1,
                }),
                qs.map(|q| self.pdf(pt, pt_minus, q)),
                match (qs, qs_minus) {
                    (Some(q), Some(m)) => Some(self.pdf(q, Some(pt), m)),
                    _ => None,
                },
            ),
        };
        let remap = |p: f32| if p != 0.0 { p * p } else { 1.0 };
        // Merging at a vertex whose density from the other side is `rev` (ratio `before`
        // while the vertex is still its own side's) or from its own side `fwd` (`after`).
        let merged = |before: f32, after: f32, rev: f32, fwd: f32| {
            if rev != 0.0 {
                before * remap(rev * merge)
            } else if fwd != 0.0 {
                after * remap(fwd * merge)
            } else {
                after
            }
        };
        let mut sum = 0.0f32;

        // Camera side: strategies with fewer camera vertices.
        let cam = |i: usize| -> (f32, f32, bool) {
            let v = if i == t - 1 { pt } else { &camera[i] };
            let rev = if i == t - 1 {
                pt_rev
            } else if i + 2 == t {
                pt_minus_rev.unwrap_or(v.pdf_rev)
            } else {
                v.pdf_rev
            };
            let delta = if i == t - 1 { false } else { v.delta };
            (rev, v.pdf_fwd, delta)
        };
        // Strategy s = 1 samples the light point by light sampling, not as a light subpath
        // starts ([`Self::nee_ratio`]): its term, and with s = 1 the own density, take k².
        let k2 = |v: &Vertex| v.nee * v.nee;
        // (s = 0: the emitter the camera path hit; its s = 1 term is the first below.)
        let hit_k2 = match (s, pt_minus) {
            (0, Some(m)) => self.nee_ratio(pt, m, emitted.0).powi(2),
            _ => 1.0,
        };
        let mut ri = 1.0f32;
        for i in (1..t).rev() {
            let (rev, fwd, delta) = cam(i);
            let before = ri;
            ri *= remap(rev) / remap(fwd);
            if !delta && !cam(i - 1).2 {
                sum += if i == t - 1 { ri * hit_k2 } else { ri };
            }
            // Merges from the light's second vertex on (never at the emitter a camera path
            // hit, nor where the light subpath's first hit would be).
            if merge > 0.0 && !delta && s + t - 1 - i >= FIRST_MERGE {
                sum += merged(before, ri, rev, fwd);
            }
        }

        // Light side: strategies with fewer light vertices.
        let lig = |i: usize| -> (f32, f32, bool) {
            let v = match (&qs, i + 1 == s) {
                (Some(q), true) => q,
                _ => &light[i],
            };
            let rev = if i + 1 == s {
                qs_rev.unwrap_or(v.pdf_rev)
            } else if i + 2 == s {
                qs_minus_rev.unwrap_or(v.pdf_rev)
            } else {
                v.pdf_rev
            };
            let delta = if i + 1 == s { false } else { v.delta };
            (rev, v.pdf_fwd, delta)
        };
        let mut ri = 1.0f32;
        for i in (0..s).rev() {
            let (rev, fwd, delta) = lig(i);
            let before = ri;
            ri *= remap(rev) / remap(fwd);
            if merge > 0.0 && i >= FIRST_MERGE && !delta {
                sum += merged(before, ri, rev, fwd);
            }
            let delta_light = if i > 0 {
                lig(i - 1).2
            } else {
                let first = match (&qs, s) {
                    (Some(q), 1) => q,
                    _ => &light[0],
                };
                self.is_delta_light(first)
            };
            if !delta && !delta_light {
                sum += if i == 1 { ri * k2(&light[0]) } else { ri };
            }
        }
        match (s, qs) {
            (1, Some(v)) => sum / k2(v),
            _ => sum,
        }
    }

    /// The contribution of strategy (s, t), MIS-weighted; for t = 1 also where it lands.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn connect(
        &self,
        light: &[Vertex],
        camera: &[Vertex],
        s: usize,
        t: usize,
        merge: f32,
        sampler: &mut impl Sampler,
        stats: &mut RayStats,
    ) -> (Spectrum, Option<Vec2>) {
        let (l, w, raster) = self.connect_unweighted(light, camera, s, t, merge, sampler, stats);
        (l * w, raster)
    }

    /// [`Self::connect`] with the contribution and its MIS weight apart.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn connect_unweighted(
        &self,
        light: &[Vertex],
        camera: &[Vertex],
        s: usize,
        t: usize,
        merge: f32,
        sampler: &mut impl Sampler,
        stats: &mut RayStats,
    ) -> (Spectrum, f32, Option<Vec2>) {
        let pt = &camera[t - 1];
        let mut raster = None;
        let mut sampled = None;
        let mut joined = None;
        let l = if s == 0 {
            // The camera subpath hit an emitter.
            if t < 2 || self.light_of(pt).is_none() {
                return (Spectrum::ZERO, 0.0, None);
            }
            pt.beta * self.le(pt, &camera[t - 2])
        } else if t == 1 {
            // Light tracing: the light subpath's vertex seen through the lens.
            let qs = &light[s - 1];
            if !self.connectible(qs) {
                return (Spectrum::ZERO, 0.0, None);
            }
            let u = sampler.get_2d();
            let Some(is) = self.camera.sample_wi(qs.p, u) else {
                return (Spectrum::ZERO, 0.0, None);
            };
            if is.pdf <= 0.0 || is.we <= 0.0 {
                return (Spectrum::ZERO, 0.0, None);
            }
            let cam = Vertex::point(
                Kind::Camera,
                is.p_lens,
                Vec3A::ZERO,
                Vec3A::ZERO,
                Spectrum::splat(is.we / is.pdf),
                0.0,
            );
            let (f, to_cam, to_q_minus) = self.f_and_pdfs(qs, &cam, TransportMode::Importance);
            let mut l = qs.beta * f * cam.beta;
            if qs.on_surface() {
                l *= is.wi.dot(qs.ns).abs();
            }
            // (s = 1: f is zero at the light point, no weight needed.)
            if s >= 2 {
                joined = Some(Joined {
                    pt_rev: qs.convert_density(to_cam, &cam),
                    pt_minus_rev: 0.0,
                    qs_rev: self.pdf(&cam, None, qs),
                    qs_minus_rev: qs.convert_density(to_q_minus, &light[s - 2]),
                });
            }
            if is_black(l) {
                return (Spectrum::ZERO, 0.0, None);
            }
            stats.rays += 1;
            if !self.scene.unoccluded_between(qs.end(), cam.end()) {
                return (Spectrum::ZERO, 0.0, None);
            }
            raster = Some(is.raster);
            sampled = Some(cam);
            l
        } else if s == 1 {
            // Next-event estimation: a fresh point on a light for the camera path's end.
            if !self.connectible(pt) {
                return (Spectrum::ZERO, 0.0, None);
            }
            let u = sampler.get_3d();
            let Some((li, pmf)) = self.scene.lights.choose(u.x) else {
                return (Spectrum::ZERO, 0.0, None);
            };
            let light = self.scene.lights.get(li);
            let Some(ls) = light.sample_li(pt.p, Vec2::new(u.y, u.z)) else {
                return (Spectrum::ZERO, 0.0, None);
            };
            if ls.pdf <= 0.0 {
                return (Spectrum::ZERO, 0.0, None);
            }
            let beta = ls.li / (ls.pdf * pmf);
            let mut v = match ls.target {
                ShadowTarget::Point { p, p_error, n } => {
                    Vertex::point(Kind::Light(li), p, p_error, n, beta, 0.0)
                }
                ShadowTarget::Infinite => Vertex::at_infinity(li, pt.p, ls.wi, beta),
            };
            // Densities of v as a light subpath's start and of pt as its next vertex.
            let (start, emit_to_pt) = self.pdf_le(&v, pt);
            v.pdf_fwd = start;
            // [`Self::nee_ratio`] from the densities at hand (both with the light's choice).
            v.nee = if v.infinite {
                1.0
            } else {
                nee_over_start(pt.convert_density(ls.pdf * pmf, &v), v.pdf_fwd)
            };
            let (f, to_v, to_p_minus) = self.f_and_pdfs(pt, &v, TransportMode::Radiance);
            let mut l = pt.beta * f * v.beta;
            if pt.on_surface() {
                l *= ls.wi.dot(pt.ns).abs();
            }
            joined = Some(Joined {
                pt_rev: emit_to_pt,
                pt_minus_rev: pt.convert_density(to_p_minus, &camera[t - 2]),
                qs_rev: pt.convert_density(to_v, &v),
                qs_minus_rev: 0.0,
            });
            if is_black(l) {
                return (Spectrum::ZERO, 0.0, None);
            }
            stats.rays += 1;
            // Toward a light at infinity by direction (`pt` is a surface: t ≥ 2 here).
            let visible = if v.infinite {
                pt.si.is_some_and(|si| self.scene.unoccluded(&si, &ls))
            } else {
                self.scene.unoccluded_between(pt.end(), v.end())
            };
            if !visible {
                return (Spectrum::ZERO, 0.0, None);
            }
            sampled = Some(v);
            l
        } else {
            // Both subpaths joined by a shadow ray; the densities the join changes come with
            // the two f's.
            let qs = &light[s - 1];
            if !self.connectible(qs) || !self.connectible(pt) {
                return (Spectrum::ZERO, 0.0, None);
            }
            let (f_q, to_pt, to_q_minus) = self.f_and_pdfs(qs, pt, TransportMode::Importance);
            let (f_p, to_q, to_p_minus) = self.f_and_pdfs(pt, qs, TransportMode::Radiance);
            let l = qs.beta * f_q * f_p * pt.beta;
            if is_black(l) {
                return (Spectrum::ZERO, 0.0, None);
            }
            joined = Some(Joined {
                pt_rev: qs.convert_density(to_pt, pt),
                pt_minus_rev: pt.convert_density(to_p_minus, &camera[t - 2]),
                qs_rev: pt.convert_density(to_q, qs),
                qs_minus_rev: qs.convert_density(to_q_minus, &light[s - 2]),
            });
            let w = pt.p - qs.p;
            let d2 = w.length_squared();
            if d2 == 0.0 {
                return (Spectrum::ZERO, 0.0, None);
            }
            let wn = w / d2.sqrt();
            let g = qs.ns.dot(wn).abs() * pt.ns.dot(wn).abs() / d2;
            stats.rays += 1;
            if !self.scene.unoccluded_between(qs.end(), pt.end()) {
                return (Spectrum::ZERO, 0.0, None);
            }
            l * g
        };
        if is_black(l) {
            return (Spectrum::ZERO, 0.0, None);
        }
        let w = self.mis_weight(
            light,
            camera,
            sampled.as_ref(),
            s,
            t,
            merge,
            joined.as_ref(),
        );
        (l, w, raster)
    }

    /// Whether a vertex can be joined to another: a surface with a smooth lobe, any light
    /// (area or point) not at infinity, the lens.
    pub(super) fn connectible(&self, v: &Vertex) -> bool {
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

/// [`Ctx::nee_ratio`] from light sampling's and a light subpath start's densities of one
/// emitter point (per unit area); 1 where either is not a density (a delta light's point).
fn nee_over_start(nee: f32, start: f32) -> f32 {
    let k = nee / start;
    if k > 0.0 && k.is_finite() { k } else { 1.0 }
}

/// The densities per unit area that joining light vertex q_s to camera vertex p_t gives their
/// neighbours (each sampled from the other side): p_t and q_s sampled across the join, p_{t−1}
/// from p_t and q_{s−1} from q_s — from the f's frames, not evaluated again. (Light sampling
/// has no q_{s−1}, light tracing no p_{t−1}: 0 there, never read.)
pub(super) struct Joined {
    pt_rev: f32,
    pt_minus_rev: f32,
    qs_rev: f32,
    qs_minus_rev: f32,
}

/// A specular vertex's lobe seen from both ends ([`Ctx::delta_lobe`]).
pub(super) struct DeltaLobe {
    /// The radiance lobe's coefficient f |cos θ| toward the light side.
    pub(super) c_rad: Spectrum,
    /// Lobe probabilities sampled from the eye side (radiance) and the light side.
    pub(super) p_rad: f32,
    pub(super) p_imp: f32,
    /// The density, in the eye side's delta measure, of the light side's choice.
    pub(super) pdf_imp: f32,
}

/// Veach's correction for shading normals in importance transport (thesis §5.3, eq. 5.19):
/// |ωo·ns| |ωi·ng| / (|ωo·ng| |ωi·ns|); 1 for radiance.
pub(super) fn shading_correction(
    si: &SurfaceInteraction,
    wo: Vec3A,
    wi: Vec3A,
    mode: TransportMode,
) -> f32 {
    if mode == TransportMode::Radiance {
        return 1.0;
    }
    let den = wo.dot(si.ng).abs() * wi.dot(si.ns).abs();
    if den == 0.0 {
        return 0.0;
    }
    wo.dot(si.ns).abs() * wi.dot(si.ng).abs() / den
}

/// Splats in fixed point, 2⁻³² units (integer sums: the same whatever order they arrive in).
pub(super) struct Splats {
    pub(super) rgb: Vec<[AtomicI64; 3]>,
    width: u32,
    height: u32,
}

const SPLAT_SCALE: f64 = 4_294_967_296.0;

impl Splats {
    pub(super) fn new(width: u32, height: u32) -> Self {
        Splats {
            rgb: (0..width as usize * height as usize)
                .map(|_| [AtomicI64::new(0), AtomicI64::new(0), AtomicI64::new(0)])
                .collect(),
            width,
            height,
        }
    }

    /// Each pixel's sums, in 2⁻³² units.
    pub(super) fn totals(&self) -> Vec<[i64; 3]> {
        self.rgb
            .iter()
            .map(|s| s.each_ref().map(|a| a.load(Relaxed)))
            .collect()
    }

    /// Adds `l` to one pixel, unfiltered.
    fn add_pixel(&self, pixel: glam::UVec2, l: Spectrum) {
        if !l.is_finite() {
            return;
        }
        let px = &self.rgb[(pixel.y * self.width + pixel.x) as usize];
        for (a, v) in px.iter().zip(l.to_array()) {
            a.fetch_add(fixed_splat(v as f64), Relaxed);
        }
    }

    /// Adds `l` arriving at raster position `at`, shared among the pixels under the filter.
    pub(super) fn add(&self, scene: &Scene, at: Vec2, l: Spectrum) {
        Self::footprint(scene, self.width, self.height, at, l, |i, v| {
            for (a, v) in self.rgb[i].iter().zip(v) {
                a.fetch_add(v, Relaxed);
            }
        });
    }

    /// [`Self::add`] with exclusive access: plain adds, no atomic operations.
    pub(super) fn add_mut(&mut self, scene: &Scene, at: Vec2, l: Spectrum) {
        let (width, height) = (self.width, self.height);
        let rgb = &mut self.rgb;
        Self::footprint(scene, width, height, at, l, |i, v| {
            for (a, v) in rgb[i].iter_mut().zip(v) {
                let a = a.get_mut();
                *a = a.wrapping_add(v);
            }
        });
    }

    /// Calls `add(pixel index, fixed-point share)` for each pixel under the filter centred at
    /// `at`. The filter is separable: one factor per column and per row.
    fn footprint(
        scene: &Scene,
        width: u32,
        height: u32,
        at: Vec2,
        l: Spectrum,
        mut add: impl FnMut(usize, [i64; 3]),
    ) {
        if !l.is_finite() {
            return;
        }
        let r = scene.filter.radius();
        let x0 = ((at.x - r - 0.5).ceil() as i64).max(0);
        let x1 = ((at.x + r - 0.5).floor() as i64).min(width as i64 - 1);
        let y0 = ((at.y - r - 0.5).ceil() as i64).max(0);
        let y1 = ((at.y + r - 0.5).floor() as i64).min(height as i64 - 1);
        // Column factors, computed once (a wide filter's extra columns computed per row).
        let mut wx = [0.0f32; 8];
        for (k, x) in (x0..=x1).take(wx.len()).enumerate() {
            wx[k] = scene.filter.splat_weight_1d(at.x - (x as f32 + 0.5));
        }
        for y in y0..=y1 {
            let wy = scene.filter.splat_weight_1d(at.y - (y as f32 + 0.5));
            if wy == 0.0 {
                continue;
            }
            for (k, x) in (x0..=x1).enumerate() {
                let fx = match wx.get(k) {
                    Some(&f) => f,
                    None => scene.filter.splat_weight_1d(at.x - (x as f32 + 0.5)),
                };
                let w = fx * wy;
                if w == 0.0 {
                    continue;
                }
                let v = [0, 1, 2].map(|c| fixed_splat(l[c] as f64 * w as f64));
                add((y * width as i64 + x) as usize, v);
            }
        }
    }
}

/// Adds fixed-point sums pixel by pixel.
fn add_fixed(to: &mut [[i64; 3]], from: &[[i64; 3]]) {
    for (a, b) in to.iter_mut().zip(from) {
        for c in 0..3 {
            a[c] = a[c].wrapping_add(b[c]);
        }
    }
}

/// A brightness sample in the sums' fixed point (i128: no overflow however many).
pub(super) fn fixed_brightness(v: f64) -> i128 {
    (v * SPLAT_SCALE) as i128
}

/// `v` in the splats' fixed point (clamped far from overflow).
fn fixed_splat(v: f64) -> i64 {
    (v * SPLAT_SCALE).clamp(-(i64::MAX as f64) / 4.0, i64::MAX as f64 / 4.0) as i64
}

/// Adds fixed-point splat sums times `scale` to an image's pixels.
pub(super) fn add_splats(image: &mut Image, splats: &[[i64; 3]], scale: f64) {
    let scale = scale / SPLAT_SCALE;
    for (px, s) in image.pixels.iter_mut().zip(splats) {
        for (v, &t) in px.rgb.iter_mut().zip(s) {
            *v += (t as f64 * scale) as f32;
        }
    }
}

/// One strategy's images (see [`Bdpt::render_strategies`]).
pub struct StrategyImage {
    pub s: u32,
    pub t: u32,
    pub weighted: Image,
    pub unweighted: Image,
}

/// Where [`Bdpt::render_strategies`] collects each strategy's contributions.
struct Recorder<'a> {
    strategies: &'a [(usize, usize)],
    /// (weighted, unweighted) per strategy.
    films: &'a [(Splats, Splats)],
}

impl Recorder<'_> {
    #[allow(clippy::too_many_arguments)]
    fn record(
        &self,
        scene: &Scene,
        s: usize,
        t: usize,
        pixel: glam::UVec2,
        raster: Option<Vec2>,
        weighted: Spectrum,
        unweighted: Spectrum,
    ) {
        let Some(i) = self.strategies.iter().position(|&x| x == (s, t)) else {
            return;
        };
        let (a, b) = &self.films[i];
        let at = raster.unwrap_or(pixel.as_vec2() + Vec2::splat(0.5));
        for (film, l) in [(a, weighted), (b, unweighted)] {
            match raster {
                Some(_) => film.add(scene, at, l),
                None => film.add_pixel(pixel, l),
            }
        }
    }
}

/// A frame's BDPT sums over sample ranges: the camera-side estimates in the film's fixed-point
/// sums (the whole frame as one tile) and the light-tracing splats in fixed point (2⁻³²
/// units). Both are integer sums, so any split of the samples into ranges, merged in any
/// order, gives the same bits as rendering them at once.
#[derive(Debug, Clone, PartialEq)]
pub struct BdptSums {
    pub sums: TileSums,
    /// Σ of the splatted radiance per pixel, row-major, in units of 2⁻³².
    pub splats: Vec<[i64; 3]>,
    /// Samples per pixel summed so far (the merged ranges' total).
    pub samples: u32,
    /// The Metropolis renderers' chain splats (Σ f / f* × acceptance per pixel, 2⁻³² units),
    /// scaled by b per sample in [`Self::image`]; empty for BDPT and VCM.
    pub chain: Vec<[i64; 3]>,
    /// The Metropolis renderers' brightness samples: their sum (2⁻³² units) and count, b
    /// their mean.
    pub brightness: (i128, u64),
}

impl BdptSums {
    /// No samples yet, for a `width` × `height` film.
    pub fn new(width: u32, height: u32) -> Self {
        let tile = Tile {
            x0: 0,
            y0: 0,
            x1: width,
            y1: height,
        };
        BdptSums {
            sums: TileSums::new(tile, SampleRange { start: 0, end: 0 }),
            splats: vec![[0; 3]; tile.pixel_count()],
            samples: 0,
            chain: Vec::new(),
            brightness: (0, 0),
        }
    }

    /// Samples `range` of a `width` × `height` film from its tiles' sums and the splats.
    pub(super) fn gather<'t>(
        width: u32,
        height: u32,
        range: SampleRange,
        tiles: impl IntoIterator<Item = &'t TileSums>,
        splats: &Splats,
    ) -> Self {
        let mut out = BdptSums::new(width, height);
        out.sums.samples = range;
        out.samples = range.end.saturating_sub(range.start);
        for tile in tiles {
            for (p, s) in tile.tile.pixels().zip(&tile.pixels) {
                out.sums.pixels[(p.y * width + p.x) as usize] = *s;
            }
        }
        out.splats = splats.totals();
        out
    }

    /// Adds the sums of another sample range of the same film.
    pub fn merge(&mut self, other: &BdptSums) {
        if self.samples == 0 {
            self.sums.samples = other.sums.samples;
        }
        self.sums.merge(&other.sums);
        add_fixed(&mut self.splats, &other.splats);
        if self.chain.len() < other.chain.len() {
            self.chain.resize(other.chain.len(), [0; 3]);
        }
        add_fixed(&mut self.chain, &other.chain);
        self.brightness.0 += other.brightness.0;
        self.brightness.1 += other.brightness.1;
        self.samples += other.samples;
    }

    /// b, the mean of the brightness samples (0 without any).
    pub fn b(&self) -> f64 {
        self.brightness.0 as f64 / SPLAT_SCALE / self.brightness.1.max(1) as f64
    }

    /// The frame: each pixel's filtered camera-side estimate plus its splats, which estimate
    /// the film's measurement per sample, divided by the samples per pixel.
    pub fn image(&self, exposure: f32) -> Image {
        let t = self.sums.tile;
        let mut image = Image::from_tiles(t.x1, t.y1, std::slice::from_ref(&self.sums));
        let per_sample = exposure as f64 / self.samples.max(1) as f64;
        add_splats(&mut image, &self.splats, per_sample);
        // A chain's splats are f / f* per mutation: b per mutation (of the film) makes them
        // radiance.
        add_splats(&mut image, &self.chain, self.b() * per_sample);
        image
    }
}

impl Bdpt {
    /// The settings of a scene's integrator block.
    pub fn new(desc: &tessera_scene::SceneDesc) -> Self {
        Bdpt {
            max_depth: desc.integrator.max_depth,
            min_depth: 0,
            rr_depth: desc.integrator.rr_depth,
        }
    }

    /// Renders samples `range` of every pixel of the frame seen by `camera` on the rayon
    /// pool: the camera-side estimates in the film's sums plus the light-tracing splats.
    pub fn render_range(
        &self,
        scene: &Scene,
        camera: &Camera,
        range: SampleRange,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<(BdptSums, RayStats), String> {
        let ctx = Ctx::new("bdpt", scene, camera, self.rr_depth, true)?;
        let (w, h) = (scene.film.width, scene.film.height);
        let splats = Splats::new(w, h);
        let results: Vec<(TileSums, RayStats)> = tiles(w, h, 16)
            .into_par_iter()
            .map(|tile| {
                let r = self.render_tile(&ctx, tile, range, &splats, None);
                progress(tile.pixel_count() as u64);
                r
            })
            .collect();
        let mut stats = RayStats::default();
        for (_, st) in &results {
            stats.add(st);
        }
        let tiles = results.iter().map(|(t, _)| t);
        Ok((BdptSums::gather(w, h, range, tiles, &splats), stats))
    }

    /// Renders samples `range` of the frame: [`Self::render_range`]'s sums as an image.
    pub fn render(
        &self,
        scene: &Scene,
        camera: &Camera,
        range: SampleRange,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<(Image, RayStats), String> {
        let (sums, stats) = self.render_range(scene, camera, range, progress)?;
        Ok((sums.image(camera.exposure), stats))
    }

    /// Per-strategy images for debugging (Veach's figure 10.3; pbrt's `visualizeStrategies`):
    /// for every (s, t) of depth s + t − 2 ≤ `depth`, what the strategy contributes to the
    /// image with its MIS weight, and without (the strategy's own estimate of all light of
    /// that depth, wherever it can sample it). Camera-side contributions land on their pixel,
    /// light tracing through the film filter; each is exposed and divided by the samples.
    pub fn render_strategies(
        &self,
        scene: &Scene,
        camera: &Camera,
        range: SampleRange,
        depth: u32,
    ) -> Result<Vec<StrategyImage>, String> {
        let ctx = Ctx::new("bdpt", scene, camera, self.rr_depth, true)?;
        let (w, h) = (scene.film.width, scene.film.height);
        let depth = depth.min(self.max_depth) as usize;
        let strategies: Vec<(usize, usize)> = (0..=depth)
            .flat_map(|d| (0..=d + 1).map(move |s| (s, d + 2 - s)))
            .filter(|&st| st != (1, 1))
            .collect();
        let films: Vec<(Splats, Splats)> = strategies
            .iter()
            .map(|_| (Splats::new(w, h), Splats::new(w, h)))
            .collect();
        let recorder = Recorder {
            strategies: &strategies,
            films: &films,
        };
        let splats = Splats::new(w, h);
        tiles(w, h, 16).into_par_iter().for_each(|tile| {
            self.render_tile(&ctx, tile, range, &splats, Some(&recorder));
        });
        let scale = camera.exposure as f64 / range.end.saturating_sub(range.start).max(1) as f64;
        let image = |f: &Splats| {
            let mut image = Image::new(w, h);
            add_splats(&mut image, &f.totals(), scale);
            image
        };
        Ok(strategies
            .iter()
            .zip(&films)
            .map(|(&(s, t), (weighted, unweighted))| StrategyImage {
                s: s as u32,
                t: t as u32,
                weighted: image(weighted),
                unweighted: image(unweighted),
            })
            .collect())
    }

    fn render_tile(
        &self,
        ctx: &Ctx,
        tile: Tile,
        range: SampleRange,
        splats: &Splats,
        recorder: Option<&Recorder>,
    ) -> (TileSums, RayStats) {
        let scene = ctx.scene;
        let mut sums = TileSums::new(tile, range);
        let mut stats = RayStats::default();
        let mut sampler = PixelSampler::new(scene.integrator.sampler, scene.integrator.seed);
        let (mut cam, mut lig) = (Vec::with_capacity(16), Vec::with_capacity(16));
        for (pixel, acc) in tile.pixels().zip(sums.pixels.iter_mut()) {
            for index in range.start..range.end {
                sampler.start_pixel_sample(pixel, index);
                let (ray, fw) = camera_ray(scene, ctx.camera, pixel, &mut sampler);
                let d = self.max_depth as usize;
                ctx.camera_subpath(ray, d + 2, &mut sampler, &mut stats, &mut cam);
                ctx.light_subpath(d + 1, &mut sampler, &mut stats, &mut lig);
                let mut l = Spectrum::ZERO;
                for t in 1..=cam.len() {
                    // s = 1 samples its own light point: it runs even when the light subpath
                    // could not start (a spot light's emission outside its cone).
                    for s in 0..=lig.len().max(1) {
                        let depth = s as i64 + t as i64 - 2;
                        if (s == 1 && t == 1)
                            || depth < self.min_depth as i64
                            || depth > self.max_depth as i64
                        {
                            continue;
                        }
                        let (u, w, raster) =
                            ctx.connect_unweighted(&lig, &cam, s, t, 0.0, &mut sampler, &mut stats);
                        let c = u * w;
                        if let Some(r) = recorder {
                            r.record(scene, s, t, pixel, raster, c, u);
                        }
                        match raster {
                            Some(at) => splats.add(scene, at, c),
                            None => l += c,
                        }
                    }
                }
                stats.samples += 1;
                let mut l = l * ctx.camera.exposure;
                if !l.is_finite() {
                    stats.nonfinite += 1;
                    l = Spectrum::ZERO;
                }
                acc.add(fw, l, None);
            }
        }
        (sums, stats)
    }
}
