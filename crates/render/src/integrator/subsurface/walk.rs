//! The brute-force reference for translucent objects: a volumetric random walk inside the
//! object itself (issue 7, "Reference"). Free paths are exponential in σt of one channel (the
//! hero, chosen once per walk); every collision scatters by the Henyey–Greenstein phase
//! function with weight σs/σt; at the surface the walk reflects with the exact Fresnel
//! probability or leaves, refracted. The three channels share one walk: its weight divides
//! each channel's f by the mean of the three channels' densities of the whole walk (one-sample
//! MIS over channels, the balance heuristic: "spectral MIS", pbrt-v4 §14.2.2), which keeps
//! chromatic media such as skin from growing fireflies the way a per-step ratio would.
//!
//! Light inside the object is not sampled toward the lights (it cannot be, through a smooth
//! interface): walks find light only after leaving. That is what makes this the slow method.

use glam::{Vec2, Vec3A};

use crate::bsdf::fresnel;
use crate::bssrdf::Subsurface;
use crate::math::reflect;
use crate::phase::sample_hg;
use crate::ray::Ray;
use crate::sampler::{PixelSampler, Sampler};
use crate::scene::{Scene, SurfaceInteraction};
use crate::spectrum::Spectrum;
use crate::stats::RayStats;

/// Collisions after which a walk is given up (counted as absorbed). Marble's albedo is
/// 0.999: a walk across a 10 cm object takes some ten thousand.
pub const MAX_EVENTS: u32 = 1 << 20;

/// Walks from `si`, where the path refracted into the object along `d` (pointing inside),
/// until it leaves: the surface point where it leaves, the direction it leaves along and the
/// weight it carries (the refractions' η² factors cancel between entry and exit and are left
/// out at both). `None` if the walk was absorbed by the cap, escaped an open mesh or met a
/// surface of another material inside.
pub fn walk(
    scene: &Scene,
    si: &SurfaceInteraction,
    d: Vec3A,
    sub: &Subsurface,
    sampler: &mut PixelSampler,
    stats: &mut RayStats,
) -> Option<(SurfaceInteraction, Vec3A, Spectrum)> {
    let sigma_t = (sub.sigma_s + sub.sigma_a).to_array().map(f64::from);
    let sigma_s = sub.sigma_s.to_array().map(f64::from);
    let hero = ((sampler.get_1d() * 3.0) as usize).min(2);
    // f_c / p_hero and p_c / p_hero of the walk so far.
    let (mut f, mut ratio) = ([1.0f64; 3], [1.0f64; 3]);
    let mut ray = si.spawn(d);
    for _ in 0..MAX_EVENTS {
        stats.rays += 1;
        let hit = scene.intersect(&ray)?;
        let u = sampler.get_3d();
        let t = -(1.0 - u.x as f64).ln() / sigma_t[hero];
        if t < hit.t as f64 {
            // A collision: density σt e^(−σt t) per channel, f = σs e^(−σt t).
            let p_hero = sigma_t[hero] * (-sigma_t[hero] * t).exp();
            for c in 0..3 {
                let tr = (-sigma_t[c] * t).exp();
                f[c] *= sigma_s[c] * tr / p_hero;
                ratio[c] *= sigma_t[c] * tr / p_hero;
            }
            let p = ray.at(t as f32);
            ray = Ray::new(p, sample_hg(ray.d, sub.g, Vec2::new(u.y, u.z)));
            continue;
        }
        // The surface: passed with probability e^(−σt T), which is also f.
        let t = hit.t as f64;
        let p_hero = (-sigma_t[hero] * t).exp();
        for c in 0..3 {
            let tr = (-sigma_t[c] * t).exp() / p_hero;
            f[c] *= tr;
            ratio[c] *= tr;
        }
        if hit.material != si.material {
            return None;
        }
        // The normal on the outside; a walk meeting a surface from its outside has left an
        // open mesh.
        let n = hit.ns;
        let cos = ray.d.dot(n);
        if cos <= 0.0 {
            return None;
        }
        if u.y < fresnel::dielectric(-cos, sub.eta) {
            ray = hit.spawn(reflect(-ray.d, n));
            continue;
        }
        let out = fresnel::refract(-ray.d, -n, 1.0 / sub.eta)?;
        let mean = (ratio[0] + ratio[1] + ratio[2]) / 3.0;
        let w = f.map(|v| (v / mean) as f32);
        return Some((hit, out, Spectrum::new(w[0], w[1], w[2])));
    }
    None
}
