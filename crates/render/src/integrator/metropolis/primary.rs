//! The primary sample space both Metropolis renderers draw from (Kelemen et al. 2002; pbrt-v3
//! §16.4): a counter-based generator, a sampler over a lazily mutated vector of uniform
//! numbers, and the BDPT sample through a uniform point of the filter-extended film that
//! estimates the chains' brightness b.

use glam::{UVec2, Vec2, Vec3A, Vec4};

use crate::integrator::RayStats;
use crate::integrator::bdpt::{Ctx, Vertex};
use crate::sampler::Sampler;
use crate::sampler::hash::{mix64, u32_to_unit};
use crate::spectrum::luminance;

/// The chains' shortest paths: shorter ones (emission and direct light) are BDPT's.
pub(super) const MIN_DEPTH: u32 = 2;

pub(super) const CAMERA_STREAM: u32 = 0;
pub(super) const LIGHT_STREAM: u32 = 1;
pub(super) const CONNECT_STREAM: u32 = 2;
const STREAMS: u32 = 3;

/// A 64-bit counter-based generator (splitmix64 over `mix64`).
pub(super) struct Rng(pub(super) u64);

impl Rng {
    pub(super) fn uniform(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        u32_to_unit((mix64(self.0) >> 32) as u32)
    }

    /// An integer uniform in 0..n (n > 0).
    pub(super) fn below(&mut self, n: usize) -> usize {
        ((self.uniform() * n as f32) as usize).min(n - 1)
    }

    /// A standard normal number (Box–Muller).
    fn normal(&mut self) -> f32 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * (1.0 - a).ln()).sqrt() * (std::f32::consts::TAU * b).cos()
    }
}

/// One number of the primary sample, changed lazily: it catches up on the mutations it missed
/// when it is next read (a large step since its last change redraws it; n missed small steps
/// are one step of σ√n).
#[derive(Debug, Clone, Copy, Default)]
struct PrimarySample {
    value: f32,
    modified: i64,
    backup: f32,
    backup_modified: i64,
}

/// A sampler over a mutating primary sample (pbrt-v3's `MLTSampler`).
pub(super) struct MltSampler {
    rng: Rng,
    sigma: f32,
    p_large: f32,
    x: Vec<PrimarySample>,
    iteration: i64,
    pub(super) large_step: bool,
    last_large: i64,
    stream: u32,
    index: u32,
}

impl MltSampler {
    pub(super) fn new(seed: u64, sigma: f32, p_large: f32) -> Self {
        MltSampler {
            rng: Rng(seed),
            sigma,
            p_large,
            x: Vec::with_capacity(64),
            iteration: 0,
            large_step: true,
            last_large: 0,
            stream: 0,
            index: 0,
        }
    }

    /// Independent uniform numbers (every read a large step) from `seed`.
    pub(super) fn independent(seed: u64) -> Self {
        MltSampler::new(seed, 0.0, 1.0)
    }

    pub(super) fn start_iteration(&mut self) {
        self.iteration += 1;
        self.large_step = self.rng.uniform() < self.p_large;
    }

    pub(super) fn accept(&mut self) {
        if self.large_step {
            self.last_large = self.iteration;
        }
    }

    pub(super) fn reject(&mut self) {
        for x in &mut self.x {
            if x.modified == self.iteration {
                x.value = x.backup;
                x.modified = x.backup_modified;
            }
        }
        self.iteration -= 1;
    }

    pub(super) fn start_stream(&mut self, stream: u32) {
        self.stream = stream;
        self.index = 0;
    }

    fn next(&mut self) -> f32 {
        let i = (self.stream + STREAMS * self.index) as usize;
        self.index += 1;
        if i >= self.x.len() {
            self.x.resize(i + 1, PrimarySample::default());
        }
        let x = &mut self.x[i];
        if x.modified < self.last_large {
            x.value = self.rng.uniform();
            x.modified = self.last_large;
        }
        x.backup = x.value;
        x.backup_modified = x.modified;
        if self.large_step {
            x.value = self.rng.uniform();
        } else {
            let missed = (self.iteration - x.modified) as f32;
            x.value += self.rng.normal() * self.sigma * missed.sqrt();
            x.value -= x.value.floor();
            if x.value >= 1.0 {
                x.value = 0.0;
            }
        }
        x.modified = self.iteration;
        x.value
    }
}

impl Sampler for MltSampler {
    fn start_pixel_sample(&mut self, _pixel: UVec2, _index: u32) {}
    fn get_1d(&mut self) -> f32 {
        self.next()
    }
    fn get_2d(&mut self) -> Vec2 {
        Vec2::new(self.next(), self.next())
    }
    fn get_3d(&mut self) -> Vec3A {
        Vec3A::new(self.next(), self.next(), self.next())
    }
    fn get_4d(&mut self) -> Vec4 {
        Vec4::new(self.next(), self.next(), self.next(), self.next())
    }
}

/// Scratch space for one thread's subpaths.
#[derive(Default)]
pub(super) struct Paths {
    pub(super) camera: Vec<Vertex>,
    pub(super) light: Vec<Vertex>,
}

/// The luminance of every strategy of every depth 2..=`max_depth` of one BDPT sample through
/// a uniform point of the (filter-extended) film: an unbiased sample of the chains' b.
pub(super) fn brightness(
    ctx: &Ctx,
    max_depth: u32,
    sampler: &mut MltSampler,
    paths: &mut Paths,
    stats: &mut RayStats,
) -> f64 {
    let (ray, _) = film_ray(ctx, sampler);
    let d = max_depth as usize;
    ctx.camera_subpath(ray, d + 2, sampler, stats, &mut paths.camera);
    ctx.light_subpath(d + 1, sampler, stats, &mut paths.light);
    let mut y = 0.0f64;
    for t in 1..=paths.camera.len() {
        for s in 0..=paths.light.len().max(1) {
            let depth = s + t;
            if depth < MIN_DEPTH as usize + 2 || depth > d + 2 {
                continue;
            }
            let (l, _) = ctx.connect(&paths.light, &paths.camera, s, t, 0.0, sampler, stats);
            if l.is_finite() {
                y += (luminance(l) * light_tracing_scale(ctx, t)) as f64;
            }
        }
    }
    stats.samples += 1;
    y
}

/// The film extended by the filter's reach beyond the outer pixels' centres (pbrt's sample
/// bounds): paths landing there still reach the edge pixels.
pub(super) fn film_extent(ctx: &Ctx) -> (Vec2, Vec2) {
    let film = &ctx.scene.film;
    let e = (ctx.scene.filter.radius() - 0.5).max(0.0);
    (
        Vec2::splat(-e),
        Vec2::new(film.width as f32 + 2.0 * e, film.height as f32 + 2.0 * e),
    )
}

/// Whether raster point `p` lies on the extended film.
pub(super) fn on_extended_film(ctx: &Ctx, p: Vec2) -> bool {
    let (origin, size) = film_extent(ctx);
    p.cmpge(origin).all() && p.cmplt(origin + size).all()
}

/// A camera ray through a uniform point of the extended film, and the point.
pub(super) fn film_ray(ctx: &Ctx, sampler: &mut impl Sampler) -> (crate::ray::Ray, Vec2) {
    let (origin, size) = film_extent(ctx);
    let p = origin + sampler.get_2d() * size;
    let u_lens = if ctx.camera.has_aperture() {
        sampler.get_2d()
    } else {
        Vec2::ZERO
    };
    (ctx.camera.generate_ray(p, u_lens), p)
}

/// The extended film's area, in pixels.
pub(super) fn ctx_area(ctx: &Ctx) -> f64 {
    let (_, size) = film_extent(ctx);
    size.x as f64 * size.y as f64
}

/// BDPT's light-tracing (t = 1) estimates are per pixel sample of a W × H film; the chains
/// sample the extended film, of larger area: this rescales them to it (1 for other t).
pub(super) fn light_tracing_scale(ctx: &Ctx, t: usize) -> f32 {
    if t != 1 {
        return 1.0;
    }
    let film = &ctx.scene.film;
    (film.width as f64 * film.height as f64 / ctx_area(ctx)) as f32
}
