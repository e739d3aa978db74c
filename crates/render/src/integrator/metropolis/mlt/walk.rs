//! Tracing path vertices for the mutations and the bootstrap: sampled and specular
//! continuations, retraced specular chains.

use super::*;

/// Samples a direction at `path[at]` (arrived at from `path[at − 1]`) by its BSDF, marking
/// the vertex specular or not; the ray leaving along it.
pub(super) fn extend(
    ctx: &Ctx,
    path: &mut [Vertex],
    at: usize,
    mode: TransportMode,
    rng: &mut Rng,
) -> Option<Ray> {
    let wo = dir(&path[at], &path[at - 1]);
    let si = path[at].si?;
    let si = &si;
    let material = ctx.scene.material(si.material);
    if material.is_black() {
        return None;
    }
    let fr = material.frame(si, wo);
    let wo_l = fr.to_local(wo);
    let u = (rng.uniform(), Vec2::new(rng.uniform(), rng.uniform()));
    let bs = material.bsdf_at(si).sample(wo_l, u.0, u.1, mode)?;
    let wi = fr.to_world(bs.wi);
    if bs.pdf <= 0.0 || !consistent(si, wo, wi, wo_l, bs.wi) {
        return None;
    }
    path[at].delta = bs.specular;
    Some(si.spawn(wi))
}

/// Continues `path[at]` through the specular lobe that reflects (or, `transmission`,
/// refracts) the direction it arrived from: a perturbation's retraced chain.
pub(super) fn specular(
    ctx: &Ctx,
    path: &mut [Vertex],
    at: usize,
    mode: TransportMode,
    transmission: bool,
) -> Option<Ray> {
    let wo = dir(&path[at], &path[at - 1]);
    let si = path[at].si?;
    let si = &si;
    let material = ctx.scene.material(si.material);
    let fr = material.frame(si, wo);
    let wo_l = fr.to_local(wo);
    for u in [0.0, 0.5, 0.999_999] {
        let Some(bs) = material.bsdf_at(si).sample(wo_l, u, Vec2::splat(0.5), mode) else {
            continue;
        };
        let wi = fr.to_world(bs.wi);
        if bs.specular
            && (wo.dot(si.ng) * wi.dot(si.ng) < 0.0) == transmission
            && consistent(si, wo, wi, wo_l, bs.wi)
        {
            path[at].delta = true;
            return Some(si.spawn(wi));
        }
    }
    None
}

/// A perturbation's retraced chain: follows `ray` through specular vertices that scatter as
/// `lobes` says (true: refract), pushing each onto `path`, then the first vertex after them
/// (to be joined, so not specular). `None` where a hit is missing or cannot scatter so.
pub(super) fn retrace(
    ctx: &Ctx,
    path: &mut Vec<Vertex>,
    mut ray: Ray,
    lobes: impl Iterator<Item = bool>,
    mode: TransportMode,
    stats: &mut RayStats,
) -> Option<()> {
    for transmission in lobes {
        path.push(trace(ctx, &ray, stats)?);
        let at = path.len() - 1;
        ray = specular(ctx, path, at, mode, transmission)?;
    }
    let mut v = trace(ctx, &ray, stats)?;
    v.delta = false;
    path.push(v);
    Some(())
}

/// The surface `ray` hits, as a path vertex.
pub(super) fn trace(ctx: &Ctx, ray: &Ray, stats: &mut RayStats) -> Option<Vertex> {
    stats.rays += 1;
    ctx.scene
        .intersect(ray)
        .map(|si| Vertex::surface(si, -ray.d))
}

/// [`Rng`] as a sampler.
pub(super) struct RngSampler<'a>(pub(super) &'a mut Rng);

impl Sampler for RngSampler<'_> {
    fn start_pixel_sample(&mut self, _: glam::UVec2, _: u32) {}
    fn get_1d(&mut self) -> f32 {
        self.0.uniform()
    }
    fn get_2d(&mut self) -> Vec2 {
        Vec2::new(self.0.uniform(), self.0.uniform())
    }
    fn get_3d(&mut self) -> Vec3A {
        Vec3A::new(self.0.uniform(), self.0.uniform(), self.0.uniform())
    }
    fn get_4d(&mut self) -> glam::Vec4 {
        glam::Vec4::new(
            self.0.uniform(),
            self.0.uniform(),
            self.0.uniform(),
            self.0.uniform(),
        )
    }
}
