//! Jensen et al. 2001's single-scattering term S⁽¹⁾: light refracted in at one point, scattered
//! once inside, refracted out toward the viewer (the dipole carries the rest).
//!
//! Sampled along the refracted viewing ray: a distance s′o from the exponential of one channel's
//! σt (one-sample MIS over the three channels), then a point on a light. The light is joined by a
//! straight line to where it crosses the surface, x_i; the refracted path there is not traced but
//! its length is taken from Snell's law, s′i = s_i cos θi / cos θ′i (Jensen et al. 2001, §2.3;
//! exact on a flat surface). Radiance at the viewer:
//!
//! L⁽¹⁾ = (1 − Fr(θo)) / η² · ∫ds ∫dωi σs p(ω′i · ω′o) e^(−σt (s′o + s′i)) (1 − Fr(θi)) (cos θi / cos θ′i) Li,
//!
//! where 1/η² and cos θi / cos θ′i are the radiance and solid angle of refraction (étendue:
//! cos θ dω = η² cos θ′ dω′); the first transmittance is the path tracer's probability of
//! refracting in, so it does not appear below.

use glam::{Vec2, Vec3A};

use crate::bsdf::fresnel;
use crate::bssrdf::Subsurface;
use crate::light::ShadowTarget;
use crate::phase::hg;
use crate::ray::Ray;
use crate::sampler::{PixelSampler, Sampler};
use crate::scene::{Scene, SurfaceInteraction};
use crate::spectrum::Spectrum;
use crate::stats::RayStats;

/// S⁽¹⁾'s radiance toward the viewer at `si`, where the path refracted into `sub` along `wo`
/// (pointing inside), less the entry transmittance; one sample.
pub fn single_scatter(
    scene: &Scene,
    si: &SurfaceInteraction,
    wo: Vec3A,
    sub: &Subsurface,
    sampler: &mut PixelSampler,
    stats: &mut RayStats,
) -> Spectrum {
    let u = sampler.get_2d();
    let ul = sampler.get_3d();
    let sigma_t = sub.sigma_s + sub.sigma_a;
    let ray = si.spawn(wo);
    stats.rays += 1;
    let Some(far) = scene.intersect(&ray) else {
        return Spectrum::ZERO;
    };
    let c = ((u.x * 3.0) as usize).min(2);
    let s = -(1.0 - u.y).ln() / sigma_t[c];
    if s >= far.t {
        return Spectrum::ZERO;
    }
    let tr_o = (-sigma_t * s).exp();
    let pdf_s = (sigma_t * tr_o).element_sum() / 3.0;
    let p = ray.at(s);

    let Some((li, pmf)) = scene.lights.choose(ul.x) else {
        return Spectrum::ZERO;
    };
    let Some(ls) = scene.lights.get(li).sample_li(p, Vec2::new(ul.y, ul.z)) else {
        return Spectrum::ZERO;
    };
    // Where the line to the light leaves the object; the light must be outside it.
    stats.rays += 1;
    let Some(xi) = scene.intersect(&Ray::new(p, ls.wi)) else {
        return Spectrum::ZERO;
    };
    let scale = match ls.target {
        ShadowTarget::Infinite => 1.0,
        ShadowTarget::Point { p: y, .. } => {
            let (d_p, d_i) = ((y - p).length_squared(), (y - xi.p).length_squared());
            if d_i >= d_p {
                return Spectrum::ZERO;
            }
            d_p / d_i
        }
    };
    let cos_i = ls.wi.dot(xi.ns);
    if xi.material != si.material || cos_i <= 0.0 {
        return Spectrum::ZERO;
    }
    let Some(t) = fresnel::refract(ls.wi, xi.ns, sub.eta) else {
        return Spectrum::ZERO;
    };
    let cos_t = -t.dot(xi.ns);
    stats.rays += 1;
    if cos_t <= 0.0 || !scene.unoccluded(&xi, &ls) {
        return Spectrum::ZERO;
    }
    let s_i = xi.t * cos_i / cos_t;
    let ft = 1.0 - fresnel::dielectric(cos_i, sub.eta);
    // The light travels along t, then (scattered) back along −wo.
    let phase = hg(t.dot(-wo), sub.g);
    let f = sub.sigma_s
        * tr_o
        * (-sigma_t * s_i).exp()
        * (phase * ft * cos_i / (cos_t * sub.eta * sub.eta));
    f * ls.li * (scale / (pmf * ls.pdf * pdf_s))
}
