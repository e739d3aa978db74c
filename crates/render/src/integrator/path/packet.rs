//! The path tracer over up to [`LANES`] paths at once: each bounce casts the rays of the paths
//! still alive as one packet ([`Scene::intersect8`]), takes every path one vertex further
//! ([`PathIntegrator::step`]), and tests their light samples' shadow rays as one packet
//! ([`Scene::occluded8`]). The paths of one pixel's samples start together, so their camera
//! rays, and their first shadow rays toward a light, stay together through the BVH.
//!
//! Each path draws its sample values in the order the one-path tracer draws them, and its
//! light sample counts before the next vertex's light as there: the estimates are the same.

use super::{PathIntegrator, PathStart, PathState};
use crate::geometry::LANES;
use crate::integrator::RayStats;
use crate::ray::Ray;
use crate::sampler::PixelSampler;
use crate::scene::{Scene, SurfaceInteraction};
use crate::spectrum::Spectrum;

impl PathIntegrator {
    /// Radiance along `rays` (at most [`LANES`]), path i with `samplers[i]`, into `out`.
    pub(super) fn trace8(
        &self,
        scene: &Scene,
        rays: &[Ray],
        samplers: &mut [PixelSampler],
        stats: &mut RayStats,
        out: &mut [Spectrum],
    ) {
        let start = PathStart {
            specular: true,
            prev_pdf: 0.0,
            depth: 0,
        };
        let mut paths = [PathState::new(glam::Vec3A::ZERO, start); LANES];
        let mut next = [Ray::new(glam::Vec3A::ZERO, glam::Vec3A::Z); LANES];
        for (i, r) in rays.iter().enumerate() {
            paths[i] = PathState::new(r.o, start);
            next[i] = *r;
        }
        // The paths still alive, and their rays in that order.
        let mut alive = [0usize; LANES];
        let mut alive_len = rays.len();
        for (i, a) in alive.iter_mut().enumerate().take(alive_len) {
            *a = i;
        }
        let mut cast = [Ray::new(glam::Vec3A::ZERO, glam::Vec3A::Z); LANES];
        let mut hits: [Option<SurfaceInteraction>; LANES] = [None; LANES];
        let mut shadow = [Ray::new(glam::Vec3A::ZERO, glam::Vec3A::Z); LANES];
        let mut shadow_t = [0.0f32; LANES];
        let mut pending = [(0usize, Spectrum::ZERO); LANES];
        while alive_len > 0 {
            let n = alive_len;
            for k in 0..n {
                cast[k] = next[alive[k]];
            }
            stats.rays += n as u64;
            scene.intersect8(&cast[..n], &mut hits[..n]);
            // One vertex of each path; light samples to test, paths that go on.
            let (mut shadows, mut kept) = (0, 0);
            for k in 0..n {
                let i = alive[k];
                let (ray, direct) = self.step(
                    scene,
                    &cast[k],
                    hits[k].take(),
                    &mut paths[i],
                    &mut samplers[i],
                    stats,
                    None,
                );
                if let Some(d) = direct {
                    match d.shadow {
                        Some((r, t)) => {
                            shadow[shadows] = r;
                            shadow_t[shadows] = t;
                            pending[shadows] = (i, d.l);
                            shadows += 1;
                        }
                        None => paths[i].l += d.l,
                    }
                }
                if let Some(r) = ray {
                    next[i] = r;
                    alive[kept] = i;
                    kept += 1;
                }
            }
            if shadows > 0 {
                let occluded = scene.occluded8(&shadow[..shadows], &shadow_t[..shadows]);
                for (k, &(i, l)) in pending[..shadows].iter().enumerate() {
                    if occluded >> k & 1 == 0 {
                        paths[i].l += l;
                    }
                }
            }
            alive_len = kept;
        }
        for (l, path) in out.iter_mut().zip(&paths) {
            *l = path.l;
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::UVec2;

    use super::*;
    use crate::camera::{Camera, camera_ray};
    use crate::integrator::Integrator;
    use crate::sampler::Sampler;

    /// The packets' estimates are the one-path tracer's, bit for bit, for every sample of a
    /// patch of pixels (camera rays of one pixel together, as `render_tile` casts them), and
    /// for packets of fewer than eight: on the Cornell box (diffuse, an area light) and on the
    /// glass scene (specular chains, a sphere light, spheres in the BVH).
    #[test]
    fn packets_estimate_what_one_path_at_a_time_does() {
        for name in ["cornell-box", "cornell-glass"] {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../scenes")
                .join(name)
                .join("scene.json");
            let mut desc = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
            (desc.film.width, desc.film.height) = (32, 32);
            let scene = Scene::build(&desc);
            let camera = Camera::new(&desc.camera, &desc.film);
            let integrator = PathIntegrator::new(64, desc.integrator.rr_depth);
            let new_sampler = || PixelSampler::new(scene.integrator.sampler, scene.integrator.seed);
            let (mut nonzero, mut packets) = (0, 0);
            for y in 8..24 {
                for x in 8..24 {
                    let pixel = UVec2::new(x, y);
                    let n = [LANES, 3, 1][(x + y) as usize % 3];
                    let mut samplers: Vec<PixelSampler> = (0..n).map(|_| new_sampler()).collect();
                    let mut rays = Vec::new();
                    for (k, s) in samplers.iter_mut().enumerate() {
                        s.start_pixel_sample(pixel, 5 + k as u32);
                        rays.push(camera_ray(&scene, &camera, pixel, s).0);
                    }
                    let mut got = vec![Spectrum::ZERO; n];
                    let mut stats8 = RayStats::default();
                    integrator.li8(&scene, &rays, &mut samplers, &mut stats8, &mut got);
                    let mut stats1 = RayStats::default();
                    for (k, ray) in rays.iter().enumerate() {
                        let mut s = new_sampler();
                        s.start_pixel_sample(pixel, 5 + k as u32);
                        camera_ray(&scene, &camera, pixel, &mut s);
                        let want = integrator.li(&scene, *ray, &mut s, &mut stats1);
                        assert_eq!(
                            got[k].to_array().map(f32::to_bits),
                            want.to_array().map(f32::to_bits),
                            "{name}: pixel {pixel}, sample {k} of {n}: {:?} vs {want:?}",
                            got[k]
                        );
                        nonzero += (want.max_element() > 0.0) as u32;
                    }
                    assert_eq!(stats8.rays, stats1.rays, "{name}: rays cast at {pixel}");
                    packets += 1;
                }
            }
            assert!(nonzero > packets, "{name}: {nonzero} lit samples");
        }
    }
}
