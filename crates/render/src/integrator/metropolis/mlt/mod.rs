//! Metropolis light transport in path space (Veach & Guibas 1997; Veach's thesis ch. 11).
//!
//! The chain's state is a path x = x₀ … x_k (x₀ on a light, x_k the pinhole), and the chain
//! moves by mutating it: proposals y drawn from T(y|x), accepted with
//! a = min(1, f*(y) T(x|y) / (f*(x) T(y|x))), f* the luminance of the measurement
//! contribution f (area measure, W_e over the filter-extended film). Each mutation splats
//! the proposal with weight a and the current path with 1 − a (Veach's expected values) as
//! f / f*, and the image is the splats × b / (mutations per pixel), b = ∫ f* dμ over the film.
//!
//! Mutations (all exactly reversible, so T's ratio is known):
//! - **bidirectional** (§11.4.2): delete the subpath x_{l+1} … x_{m−1} (k_d = m − l edges,
//!   p_d favouring 1–2), add k_a edges (k_d or one more or fewer), j new vertices traced from
//!   x_l and the rest from x_m, joined by a shadow ray. T(y|x) sums over every split j that
//!   could have made y: with C_s = f / p_s (the BDPT estimate of strategy s, s light
//!   vertices), f*(y) / T(y|x) = 1 / (p_d p_a Σ_j p_j / C_{l+1+j}).
//! - **lens subpath** (§11.4.3.3): the eye end E S* D replaced by one traced from a new
//!   uniform film point until it meets a surface with a diffuse or glossy part.
//! - **lens perturbation** (§11.4.4.1): the film point moved by an offset of radius from
//!   r₁ = 0.1 px to r₂ = 5 % of the film (density ∝ 1/r), the ray retraced through the same
//!   specular lobes to the next non-specular vertex and joined to the kept path.
//! - **caustic perturbation** (§11.4.4.2): for paths ending D S⁺ D E, the direction leaving
//!   the light-side D (or the light) turned by θ from 10⁻⁴ to 0.1 rad (∝ 1/θ), retraced
//!   through the same specular lobes, joined to the lens.
//!
//! The perturbations are symmetric in the film point or direction they perturb, so their
//! ratio is that of f over the density of the retraced vertices given it.
//!
//! Specular vertices: f and every p_s are written with one delta convention (a specular
//! vertex's density sampled from the eye side is its lobe probability, from the light side the
//! lobe probability × c_rad |ω_n·n_g| / (c_imp |ω_p·n_g|), c the lobe's coefficient in each
//! mode), which makes f / p_s equal the sampling weights BDPT multiplies (η² and shading
//! normals included), so the sums over splits are exact.
//!
//! Direct light (depths 0 and 1) is BDPT's, as the paper proposes, and b comes from BDPT
//! samples (shared with PSSMLT, [`super::chains`], which also cuts the frame into groups
//! for the farm). The chains (1000, seeded (seed, chain)) start from paths resampled from a
//! bootstrap of independent BDPT paths (one strategy and depth each, weight f / Σ_s p_s) in
//! proportion to their weight, which removes start-up bias as the bootstrap grows (Veach
//! §11.3.3). Pinhole cameras only; every light: area, point and spot lights (a point light's
//! vertex is a delta in position: density 1 in the discrete measure, intensity for radiance,
//! no cosine, never hit from the eye side), and lights at infinity, whose vertex is a
//! direction: the environment's density per solid angle, the next vertex's per unit area of
//! the disk it emits from (projected), no distance and no cosine at the light in G; a
//! directional light is a delta in direction as a point light is in position (irradiance for
//! radiance). Its stand-in point moves with its neighbour ([`anchor`]); a join to it is a ray
//! to infinity; an eye path that leaves the scene ends on the environment. The caustic
//! perturbation does not turn a light at infinity's direction (the bidirectional mutation
//! changes it).

use glam::{Vec2, Vec3A};
use rayon::prelude::*;

use super::chains::{ChainSettings, Chains, mean_and_error};
use super::primary::{
    MIN_DEPTH, MltSampler, Paths, Rng, brightness, ctx_area, film_ray, on_extended_film,
};
use crate::bsdf::TransportMode;
use crate::camera::Camera;
use crate::integrator::RayStats;
use crate::integrator::bdpt::{Ctx, Splats, Vertex};
use crate::integrator::consistent;
use crate::math::{Frame, offset_ray_origin};
use crate::ray::Ray;
use crate::sampler::Sampler;
use crate::sampler::hash::hash;
use crate::scene::Scene;
use crate::spectrum::{Spectrum, luminance};

mod evaluate;
mod mutations;
#[cfg(test)]
mod tests;
mod walk;

use walk::{RngSampler, extend, retrace, trace};

/// The settings path-space MLT runs with.
#[derive(Debug, Clone, Copy)]
pub struct Mlt {
    /// Most scattering vertices on a path.
    pub max_depth: u32,
    /// Independent BDPT paths the chains' starts are resampled from.
    pub bootstrap: u32,
    /// Independent Markov chains.
    pub chains: u32,
    pub seed: u64,
}

impl Mlt {
    pub fn new(desc: &tessera_scene::SceneDesc) -> Self {
        Mlt {
            max_depth: desc.integrator.max_depth,
            bootstrap: 100_000,
            chains: 1000,
            seed: desc.integrator.seed,
        }
    }
}

/// Weights of the mutations, in this order: bidirectional, lens subpath, lens perturbation,
/// caustic perturbation, among those that apply to the path (see [`mutation_probabilities`]).
const MUTATIONS: [f64; 4] = [0.5, 0.1, 0.2, 0.2];

/// Whether a vertex's surface has a diffuse or glossy part (can be joined to).
fn smooth(scene: &Scene, v: &Vertex) -> bool {
    v.si.is_some_and(|si| scene.material(si.material).flags.smooth)
}

/// The vertex a lens subpath mutation joins to: x_q, the first from the eye with a diffuse
/// or glossy part (those between are purely specular), not itself reached specularly, and
/// x_{q−1} joinable.
fn lens_subpath_start(scene: &Scene, x: &[Vertex]) -> Option<usize> {
    let q = (1..x.len() - 1).rev().find(|&i| smooth(scene, &x[i]))?;
    (!x[q].delta && !x[q - 1].delta).then_some(q)
}

/// The vertex a lens perturbation retraces to: x_q, the first non-specular one from the eye,
/// with x_{q−1} joinable.
fn lens_perturbation_start(x: &[Vertex]) -> Option<usize> {
    let q = (1..x.len() - 1).rev().find(|&i| !x[i].delta)?;
    (!x[q - 1].delta).then_some(q)
}

/// The vertex whose outgoing direction a caustic perturbation turns: x_c of a path ending
/// x_c S⁺ D E (x_c a light not at infinity, or non-specular).
fn caustic_start(x: &[Vertex]) -> Option<usize> {
    let k = x.len() - 1;
    if k < 3 || x[k - 1].delta || !x[k - 2].delta {
        return None;
    }
    let c = (0..k - 2).rev().find(|&i| !x[i].delta).unwrap_or(0);
    (c > 0 || !x[0].infinite).then_some(c)
}

/// The probability of each mutation at path `x`: [`MUTATIONS`] over those that apply. (A
/// mutation chosen by the state needs its probability at both ends in the acceptance.)
fn mutation_probabilities(scene: &Scene, x: &[Vertex]) -> [f64; 4] {
    let applies = [
        true,
        lens_subpath_start(scene, x).is_some(),
        lens_perturbation_start(x).is_some(),
        caustic_start(x).is_some(),
    ];
    let mut p = MUTATIONS;
    for (p, a) in p.iter_mut().zip(applies) {
        if !a {
            *p = 0.0;
        }
    }
    let total: f64 = p.iter().sum();
    p.map(|p| p / total)
}

/// A mean and its standard error.
pub type Estimate = (f64, f64);

/// What [`Mlt::evaluate`] finds of a path (buffers reused from path to path).
#[derive(Debug, Default, Clone)]
struct PathEval {
    /// C_s = f / p_s in luminance for s = 0..=k light vertices; zero where strategy s cannot
    /// make the path (a specular vertex at the join).
    c: Vec<f64>,
    /// f / f* (luminance 1).
    color: Spectrum,
    /// Where the path lands on the film.
    raster: Vec2,
    /// Density with which x_i chose its direction toward x_{i+1} (solid angle; a specular
    /// lobe's probability; the light's emission density at x₀).
    sel_fwd: Vec<f64>,
    /// The same toward x_{i−1}.
    sel_rev: Vec<f64>,
    /// Per-edge geometry term, and the densities per unit area of each vertex sampled from
    /// its neighbour toward the light (`fwd`) or toward the eye (`rev`).
    g: Vec<f64>,
    pa_fwd: Vec<f64>,
    pa_rev: Vec<f64>,
    /// Scratch: per-edge conversions to area at the eye end (`fwd`) and the light end, and
    /// the eye side's suffix products.
    conv_fwd: Vec<f64>,
    conv_rev: Vec<f64>,
    eye_from: Vec<f64>,
}

/// One interior vertex's scattering: the factor f contributes (radiance form, per unit area
/// with geometric cosines in G), the solid-angle densities of sampling toward the eye side
/// (`imp`, light-side walk) and toward the light side (`rad`), and the selection densities.
struct Scatter {
    f: Spectrum,
    pdf_imp: f32,
    pdf_rad: f32,
    sel_imp: f32,
    sel_rad: f32,
}

/// A chain's working space: the current path, a proposal, and scratch.
#[derive(Default)]
pub(super) struct Work {
    x: Vec<Vertex>,
    ex: PathEval,
    y: Vec<Vertex>,
    ey: PathEval,
    eye: Vec<Vertex>,
}

fn dir(from: &Vertex, to: &Vertex) -> Vec3A {
    (to.p - from.p).normalize_or_zero()
}

/// A ray leaving vertex `v` along `d`.
fn spawn(v: &Vertex, d: Vec3A) -> Ray {
    match &v.si {
        Some(si) => si.spawn(d),
        None if v.on_surface() => Ray::new(offset_ray_origin(v.p, v.p_error, v.ng, d), d),
        None => Ray::new(v.p, d),
    }
}

/// Places a light at infinity that starts `path` one unit from its neighbour along the
/// direction it stands for (the vertex is a direction: its stand-in point moves with the
/// neighbour, as mutations move that).
fn anchor(path: &mut [Vertex]) {
    if let [x0, x1, ..] = path
        && x0.infinite
    {
        x0.p = x1.p + x0.wo;
    }
}

/// Whether the join between light-side vertex `a` and eye-side vertex `b` is clear: the
/// segment, or toward a light at infinity the ray from `b` to infinity.
fn visible(ctx: &Ctx, a: &Vertex, b: &Vertex) -> bool {
    if a.infinite {
        ctx.scene.unoccluded_to_infinity(b.end(), a.wo)
    } else {
        ctx.scene.unoccluded_between(a.end(), b.end())
    }
}

/// What a ray leaving the scene ends on: the environment, as a path's light vertex.
fn escape(ctx: &Ctx, ray: &Ray) -> Option<Vertex> {
    ctx.scene
        .lights
        .environment()
        .next()
        .map(|(env, _)| Vertex::at_infinity(env, ray.o, ray.d, Spectrum::ONE))
}

/// Whether a path vertex scatters through a specular lobe (its two directions are reflected
/// or refracted images of each other).
fn transmits(x: &[Vertex], i: usize) -> bool {
    dir(&x[i], &x[i - 1]).dot(x[i].ng) * dir(&x[i], &x[i + 1]).dot(x[i].ng) < 0.0
}

impl Chains for Mlt {
    type Scratch = Work;

    fn settings(&self) -> ChainSettings {
        ChainSettings {
            max_depth: self.max_depth,
            bootstrap: self.bootstrap,
            bootstrap_paths: self.bootstrap as u64,
            chains: self.chains,
            seed: self.seed,
        }
    }

    /// Only pinhole cameras.
    fn ctx<'a>(&self, scene: &'a Scene, camera: &'a Camera) -> Result<Ctx<'a>, String> {
        let ctx = Ctx::new(scene, camera, u32::MAX);
        if camera.has_aperture() {
            return Err("mlt: only pinhole cameras are supported (its lens mutations assume one); use pssmlt or bdpt".into());
        }
        Ok(ctx)
    }

    fn bootstrap_weight(&self, ctx: &Ctx, work: &mut Work, i: u64) -> (f64, RayStats) {
        let mut stats = RayStats::default();
        let w = self.bootstrap_path(ctx, i, work, &mut stats);
        (w, stats)
    }

    fn run_chain(
        &self,
        ctx: &Ctx,
        work: &mut Work,
        chain: (u64, u64, u64),
        splats: &Splats,
    ) -> RayStats {
        let (c, steps, start) = chain;
        self.chain(ctx, c, steps, start, work, splats)
    }
}

impl Mlt {
    /// Two independent estimates of b, the mean luminance of the indirect light over the
    /// extended film, each with its standard error: the bootstrap's (`n` paths weighted by
    /// this module's f / Σ_s p_s) and BDPT's (`n` samples, as the image is scaled by). They
    /// agree only if f and every strategy's density here are right: a check, not a step of
    /// rendering.
    pub fn brightness_check(
        &self,
        scene: &Scene,
        camera: &Camera,
        n: u64,
    ) -> Result<(Estimate, Estimate), String> {
        let ctx = self.ctx(scene, camera)?;
        let rr = Ctx { rr_depth: 3, ..ctx };
        let sums = |(a, b): (f64, f64), (c, d): (f64, f64)| (a + c, b + d);
        let bdpt = (0..n)
            .into_par_iter()
            .map_init(Paths::default, |paths, i| {
                let mut sampler = MltSampler::independent(hash(&[self.seed, 0x636865636b, i]));
                let y = brightness(
                    &rr,
                    self.max_depth,
                    &mut sampler,
                    paths,
                    &mut RayStats::default(),
                );
                (y, y * y)
            })
            .reduce(|| (0.0, 0.0), sums);
        let boot = (0..n)
            .into_par_iter()
            .map_init(Work::default, |work, i| {
                let w = self.bootstrap_path(&ctx, i, work, &mut RayStats::default());
                (w, w * w)
            })
            .reduce(|| (0.0, 0.0), sums);
        Ok((
            mean_and_error(boot.0, boot.1, n),
            mean_and_error(bdpt.0, bdpt.1, n),
        ))
    }

    /// Bootstrap path `i` into `work.x` (evaluated into `work.ex`), and its resampling weight
    /// f / (q Σ_s p_s): a depth in 2..=max_depth and a strategy s drawn uniformly (q), the
    /// subpaths traced, every strategy's density counted (the balance heuristic), so that
    /// over the bootstrap the weights sum to ∫ f and a path drawn ∝ weight is ∝ f.
    fn bootstrap_path(&self, ctx: &Ctx, i: u64, work: &mut Work, stats: &mut RayStats) -> f64 {
        self.bootstrap_strategy(ctx, i, work, stats).0
    }

    /// [`Self::bootstrap_path`] with the strategy that made the path (its light vertices s;
    /// the subpaths stay in `work.y` and `work.eye`), where the weight is not zero.
    fn bootstrap_strategy(
        &self,
        ctx: &Ctx,
        i: u64,
        work: &mut Work,
        stats: &mut RayStats,
    ) -> (f64, usize) {
        let mut sampler = MltSampler::independent(hash(&[self.seed, 0x626f6f74, i]));
        let depths = (self.max_depth + 1 - MIN_DEPTH) as usize;
        let d = MIN_DEPTH as usize + ((sampler.get_1d() * depths as f32) as usize).min(depths - 1);
        let s = ((sampler.get_1d() * (d + 2) as f32) as usize).min(d + 1);
        let t = d + 2 - s;
        let Work { x, ex, y, eye, .. } = work;
        y.clear();
        if s > 0 {
            ctx.light_subpath(s, &mut sampler, stats, y);
            if y.len() != s {
                return (0.0, 0);
            }
        }
        let (ray, _) = film_ray(ctx, &mut sampler);
        ctx.camera_subpath(ray, t, &mut sampler, stats, eye);
        if eye.len() != t {
            return (0.0, 0);
        }
        x.clear();
        x.extend_from_slice(y);
        x.extend(eye.iter().rev());
        anchor(x);
        // The join's ends scatter nowhere yet.
        if s >= 2 {
            x[s - 1].delta = false;
        }
        if t >= 2 {
            x[s].delta = false;
        }
        if s > 0 {
            stats.rays += 1;
            if !visible(ctx, &x[s - 1], &x[s]) {
                return (0.0, 0);
            }
        }
        if !self.evaluate(ctx, x, ex) || ex.c[s] <= 0.0 {
            return (0.0, 0);
        }
        let inv: f64 = ex.c.iter().filter(|&&c| c > 0.0).map(|c| 1.0 / c).sum();
        ((depths * (d + 2)) as f64 / inv, s)
    }

    /// Runs chain `c` for `steps` mutations from bootstrap path `i`.
    fn chain(
        &self,
        ctx: &Ctx,
        c: u64,
        steps: u64,
        i: u64,
        work: &mut Work,
        splats: &Splats,
    ) -> RayStats {
        let mut stats = RayStats::default();
        let mut rng = Rng(hash(&[self.seed, 0x6d6c7463, c]));
        if self.bootstrap_path(ctx, i, work, &mut stats) <= 0.0 {
            return stats;
        }
        let scene = ctx.scene;
        let mut probs = mutation_probabilities(scene, &work.x);
        for _ in 0..steps {
            let mut u = rng.uniform() as f64;
            let kind = (0..3)
                .find(|&i| {
                    u -= probs[i];
                    u < 0.0
                })
                .unwrap_or(3);
            let mut r = match kind {
                0 => self.bidirectional(ctx, work, &mut rng, &mut stats),
                1 => self.lens_subpath(ctx, work, &mut rng, &mut stats),
                2 => self.lens_perturbation(ctx, work, &mut rng, &mut stats),
                _ => self.caustic_perturbation(ctx, work, &mut rng, &mut stats),
            };
            let probs_y = if r > 0.0 {
                mutation_probabilities(scene, &work.y)
            } else {
                probs
            };
            r *= probs_y[kind] / probs[kind];
            stats.samples += 1;
            let a = if r.is_finite() {
                r.clamp(0.0, 1.0)
            } else {
                0.0
            };
            if a > 0.0 {
                splats.add(scene, work.ey.raster, work.ey.color * a as f32);
            }
            if a < 1.0 {
                splats.add(scene, work.ex.raster, work.ex.color * (1.0 - a) as f32);
            }
            if a > 0.0 && (rng.uniform() as f64) < a {
                std::mem::swap(&mut work.x, &mut work.y);
                std::mem::swap(&mut work.ex, &mut work.ey);
                probs = probs_y;
            }
        }
        stats
    }
}
