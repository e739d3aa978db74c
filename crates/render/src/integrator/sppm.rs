//! Stochastic progressive photon mapping (Hachisuka & Jensen, "Stochastic Progressive Photon
//! Mapping", SIGGRAPH Asia 2009): photon mapping made consistent.
//!
//! Each iteration t:
//! 1. camera pass — every pixel traces one camera path (its sample t) through specular
//!    surfaces to its first surface with a density (the visible point), adding emission and
//!    direct light there by light sampling;
//! 2. photon pass — photons `t·M .. (t+1)·M` are shot (each a function of its index alone),
//!    and those that arrive after at least one bounce are gathered at every visible point
//!    within its radius: Φ += β f(ωo, ωp) Φp, M += 1;
//! 3. per pixel (f64): N' = N + αM, r' = r √(N'/(N + M)), τ' = (τ + Φ) r'²/r², N = N'.
//!
//! The radiance is L_direct/T + τ / (T π r²) after T iterations; r shrinks so bias and
//! variance both vanish as T grows. Everything is per pixel, and the photon sums run in tree
//! order, so the image is a pure function of (scene, camera, settings).

use glam::{DVec3, UVec2, Vec2, Vec3A};
use rayon::prelude::*;

use super::{RayStats, sample_direct, scatter};
use crate::bsdf::TransportMode;
use crate::camera::Camera;
use crate::film::{Image, Pixel};
use crate::photon::{KdTree, MapKind, Photon, PhotonSettings, Shooter};
use crate::sampler::{PixelSampler, Sampler};
use crate::scene::{NO_LIGHT, Scene, SurfaceInteraction};
use crate::spectrum::{Spectrum, is_black};

/// Where a pixel's camera path met its first surface with a density, this iteration.
struct VisiblePoint {
    si: SurfaceInteraction,
    wo: Vec3A,
    /// Throughput from the camera.
    beta: Spectrum,
}

/// A pixel's statistics across iterations (f64: they accumulate for thousands of them).
#[derive(Debug, Clone, Copy)]
struct PixelState {
    /// Emitted and direct light summed over iterations.
    ld: DVec3,
    tau: DVec3,
    n: f64,
    r: f64,
}

/// SPPM's own settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SppmSettings {
    pub iterations: u32,
    /// Photons per iteration.
    pub photons: u32,
    pub initial_radius: f32,
    /// Fraction of new photons kept per iteration (Hachisuka & Jensen's α).
    pub alpha: f32,
}

impl SppmSettings {
    pub fn from_photon_settings(p: &PhotonSettings, iterations: u32, alpha: f32) -> Self {
        SppmSettings {
            iterations,
            photons: p.photons,
            initial_radius: p.radius,
            alpha,
        }
    }
}

fn visible_point(
    scene: &Scene,
    camera: &Camera,
    pixel: UVec2,
    iteration: u32,
    max_depth: u32,
    sampler: &mut PixelSampler,
    stats: &mut RayStats,
) -> (Spectrum, Option<VisiblePoint>) {
    sampler.start_pixel_sample(pixel, iteration);
    let film = pixel.as_vec2() + sampler.get_2d();
    let u_lens = if camera.has_aperture() {
        sampler.get_2d()
    } else {
        Vec2::ZERO
    };
    let mut ray = camera.generate_ray(film, u_lens);
    let mut beta = Spectrum::ONE;
    let mut l = Spectrum::ZERO;
    for _ in 0..max_depth.max(1) {
        stats.rays += 1;
        let Some(si) = scene.intersect(&ray) else {
            // Seen directly or through specular surfaces only: light sampling cannot find it.
            for (_, light) in scene.lights.environment() {
                l += beta * light.le_direction(ray.d);
            }
            break;
        };
        let wo = -ray.d;
        if si.light != NO_LIGHT {
            l += beta * scene.lights.get(si.light).le_surface(si.ng, wo);
        }
        let material = scene.material(si.material);
        if material.is_black() {
            break;
        }
        if material.flags.smooth {
            let frame = material.frame(&si, wo);
            let u = sampler.get_3d();
            l += beta * sample_direct(scene, &si, material, &frame, wo, u, false, stats);
            return (l, Some(VisiblePoint { si, wo, beta }));
        }
        let Some((weight, next)) = scatter(&si, material, wo, sampler) else {
            break;
        };
        beta *= weight;
        if is_black(beta) {
            break;
        }
        ray = next;
    }
    (l, None)
}

/// Renders the frame seen by `camera` with `s.iterations` SPPM iterations on the rayon pool;
/// `progress(t)` is called after iteration t.
pub fn render(
    scene: &Scene,
    camera: &Camera,
    photon: &PhotonSettings,
    s: &SppmSettings,
    progress: &(dyn Fn(u32) + Sync),
) -> (Image, RayStats) {
    let (w, h) = (scene.film.width, scene.film.height);
    let r0 = s.initial_radius as f64;
    let mut states = vec![
        PixelState {
            ld: DVec3::ZERO,
            tau: DVec3::ZERO,
            n: 0.0,
            r: r0,
        };
        (w * h) as usize
    ];
    let base = PixelSampler::new(photon.sampler, photon.seed);
    let shooter = Shooter::new(
        scene,
        &PhotonSettings {
            photons: s.photons,
            ..*photon
        },
        MapKind::Indirect,
    );
    let mut stats = RayStats::default();
    for t in 0..s.iterations {
        // 1. Camera pass.
        let points: Vec<(Spectrum, Option<VisiblePoint>, RayStats)> = (0..w * h)
            .into_par_iter()
            .map_init(
                || base.clone(),
                |sampler, i| {
                    let mut st = RayStats::default();
                    let (l, vp) = visible_point(
                        scene,
                        camera,
                        UVec2::new(i % w, i / w),
                        t,
                        photon.max_depth,
                        sampler,
                        &mut st,
                    );
                    st.samples = 1;
                    (l, vp, st)
                },
            )
            .collect();
        // 2. Photon pass: this iteration's index range, in a tree.
        let start = (t as u64 * s.photons as u64).min(u32::MAX as u64) as u32;
        let end = start.saturating_add(s.photons);
        let photons: KdTree<Photon> = KdTree::build(shooter.shoot_parallel(start..end));
        // 3. Gather at each visible point and update its pixel.
        let alpha = s.alpha as f64;
        states
            .par_iter_mut()
            .zip(points.par_iter())
            .for_each(|(st, (l, vp, _))| {
                if l.is_finite() {
                    st.ld += DVec3::new(l.x as f64, l.y as f64, l.z as f64);
                }
                let Some(vp) = vp else {
                    return;
                };
                let material = scene.material(vp.si.material);
                let frame = material.frame(&vp.si, vp.wo);
                let wo_local = frame.to_local(vp.wo);
                let (mut phi, mut m) = (DVec3::ZERO, 0u64);
                photons.within(vp.si.p, (st.r * st.r) as f32, &mut |i, _| {
                    let ph = photons.get(i);
                    let wi = Vec3A::from(ph.wi);
                    let f =
                        material
                            .bsdf
                            .eval(wo_local, frame.to_local(wi), TransportMode::Radiance);
                    let c = vp.beta * f * Vec3A::from(ph.power);
                    if c.is_finite() {
                        phi += DVec3::new(c.x as f64, c.y as f64, c.z as f64);
                    }
                    m += 1;
                });
                if m > 0 {
                    let m = m as f64;
                    let n_new = st.n + alpha * m;
                    let r_new = st.r * (n_new / (st.n + m)).sqrt();
                    st.tau = (st.tau + phi) * (r_new * r_new) / (st.r * st.r);
                    st.n = n_new;
                    st.r = r_new;
                }
            });
        for (_, _, st) in &points {
            stats.add(st);
        }
        progress(t);
    }
    let iters = s.iterations.max(1) as f64;
    let exposure = camera.exposure as f64;
    let mut image = Image::new(w, h);
    for (px, st) in image.pixels.iter_mut().zip(&states) {
        let l = (st.ld / iters + st.tau / (iters * std::f64::consts::PI * st.r * st.r)) * exposure;
        *px = Pixel {
            rgb: [l.x as f32, l.y as f32, l.z as f32],
            alpha: 1.0,
            ..Pixel::default()
        };
    }
    (image, stats)
}
