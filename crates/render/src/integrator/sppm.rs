//! Stochastic progressive photon mapping (Hachisuka & Jensen, "Stochastic Progressive Photon
//! Mapping", SIGGRAPH Asia 2009): photon mapping made consistent.
//!
//! Each iteration t:
//! 1. camera pass — every pixel traces one camera path (its sample t) through specular
//!    surfaces to its first surface with a density (the visible point), adding emission and
//!    direct light there by light sampling;
//! 2. photon pass — photons `t·M .. (t+1)·M` are shot (each a function of its index alone),
//!    and those that arrive after at least one bounce are gathered at every visible point
//!    within its radius, in a disc along its surface: Φ += β f(ωo, ωp) Φp, M += 1;
//! 3. per pixel (f64): N' = N + αM, r' = r √(N'/(N + M)), τ' = (τ + Φ) r'²/r², N = N'.
//!
//! The radiance is L_direct/T + τ / (T π r²) after T iterations; r shrinks so bias and
//! variance both vanish as T grows. The variance AOV treats the iterations' own estimates as
//! independent samples: it covers the noise, not the kernel's bias.
//!
//! An iteration's photons are gathered in chunks of [`PHOTONS_PER_CHUNK`] (each chunk its own
//! tree, each pixel's Φ summed in tree order), and the chunks' sums are added in chunk order
//! ([`SppmState::add_iteration`]). A chunk is what a farm task does, so `render` here and the
//! farm add the same numbers in the same order: the image is a pure function of (scene,
//! camera, settings), however the work is split.

use std::ops::Range;

use glam::{DVec3, UVec2, Vec3A};
use rayon::prelude::*;

use super::{RayStats, direct_light, scatter};
use crate::analysis::Analysis;
use crate::bsdf::TransportMode;
use crate::camera::Camera;
use crate::film::{Image, Pixel};
use crate::photon::{DEFAULT_PHOTONS, FLATTEN, KdTree, MapKind, Photon, PhotonSettings, Shooter};
use crate::sampler::{PixelSampler, Sampler};
use crate::scene::{NO_LIGHT, Scene, SurfaceInteraction};
use crate::spectrum::{Spectrum, is_black};
use tessera_scene::SceneDesc;

/// Where a pixel's camera path met its first surface with a density, this iteration.
struct VisiblePoint {
    si: SurfaceInteraction,
    wo: Vec3A,
    /// Throughput from the camera.
    beta: Spectrum,
}

/// Photons per gathering chunk (and per farm task).
pub const PHOTONS_PER_CHUNK: u32 = 25_000;

/// What an iteration's camera paths add by themselves, per pixel (row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct CameraPass {
    /// Emitted and direct light, times the filter weight.
    pub ld: Vec<Spectrum>,
    /// The camera paths' rays; one sample per pixel.
    pub stats: RayStats,
}

/// Every pixel's camera path of one iteration.
pub struct VisiblePoints {
    pub camera: CameraPass,
    points: Vec<Option<VisiblePoint>>,
}

/// What one chunk of photons left at one pixel's visible point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelSum {
    /// Row-major pixel index.
    pub pixel: u32,
    /// Photons within the pixel's radius (M).
    pub m: u32,
    /// Σ β f Φp over them (Φ).
    pub phi: [f64; 3],
}

/// Every pixel's statistics across iterations, row-major (f64: they accumulate over
/// thousands of iterations). This is what a farm coordinator keeps between iterations.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SppmState {
    pub width: u32,
    pub height: u32,
    /// Iterations folded in.
    pub iterations: u32,
    /// Emitted and direct light summed over iterations (filter-weighted).
    pub ld: Vec<DVec3>,
    /// The film filter's mean weight E[w] ([`crate::filter::Filter::mean_weight`]): T
    /// iterations' filter-weighted sums divide by T·E[w].
    pub mean_w: f64,
    pub tau: Vec<DVec3>,
    pub n: Vec<f64>,
    pub r: Vec<f64>,
    /// Σ and Σ² over iterations of each pixel's estimate from that iteration alone,
    /// (L_d,t + Φ_t/(π r_t²))/E[w]: the variance AOV, with iterations taken as independent
    /// samples (the kernel's bias is not in it).
    pub l1: Vec<DVec3>,
    pub l2: Vec<DVec3>,
}

impl SppmState {
    /// A frame of `width` × `height` pixels whose gathering starts at `initial_radius`, its
    /// film filter's samples weighing `mean_w` on average.
    pub fn new(width: u32, height: u32, initial_radius: f32, mean_w: f64) -> Self {
        let len = width as usize * height as usize;
        SppmState {
            width,
            height,
            iterations: 0,
            ld: vec![DVec3::ZERO; len],
            mean_w,
            tau: vec![DVec3::ZERO; len],
            n: vec![0.0; len],
            r: vec![initial_radius as f64; len],
            l1: vec![DVec3::ZERO; len],
            l2: vec![DVec3::ZERO; len],
        }
    }

    /// Squared gathering radius per pixel for the next iteration, as the gather uses it.
    pub fn radii2(&self) -> Vec<f32> {
        self.r.iter().map(|&r| radius2(r)).collect()
    }

    /// Folds one iteration in: each pixel's direct light from `camera`,
    /// then the sums of the iteration's chunks, added in the order given (chunk order), then
    /// Hachisuka & Jensen's update N' = N + αM, r' = r √(N'/(N + M)), τ' = (τ + Φ) r'²/r².
    pub fn add_iteration<'a>(
        &mut self,
        camera: &CameraPass,
        chunks: impl IntoIterator<Item = &'a [PixelSum]>,
        alpha: f32,
    ) {
        let len = self.r.len();
        let (mut phi, mut m) = (vec![[0.0f64; 3]; len], vec![0u64; len]);
        for chunk in chunks {
            for s in chunk {
                let i = s.pixel as usize;
                if i < len {
                    for (p, v) in phi[i].iter_mut().zip(s.phi) {
                        *p += v;
                    }
                    m[i] += s.m as u64;
                }
            }
        }
        let ld: Vec<[f32; 3]> = camera.ld.iter().map(|l| l.to_array()).collect();
        self.add_sums(&ld, &phi, &m, alpha);
    }

    /// Folds one iteration in from its per-pixel totals: emitted and direct light `ld` of the
    /// camera paths, and Φ and M summed over the iteration's chunks;
    /// then Hachisuka & Jensen's update (see [`Self::add_iteration`]).
    pub fn add_sums(&mut self, ld: &[[f32; 3]], phi: &[[f64; 3]], m: &[u64], alpha: f32) {
        let alpha = alpha as f64;
        for i in 0..self.r.len() {
            let l = ld
                .get(i)
                .filter(|l| l.iter().all(|v| v.is_finite()))
                .map_or(DVec3::ZERO, |l| {
                    DVec3::new(l[0] as f64, l[1] as f64, l[2] as f64)
                });
            self.ld[i] += l;
            // This iteration's own estimate, at the radius its photons were gathered with.
            let p = phi.get(i).map_or(DVec3::ZERO, |p| DVec3::from_array(*p));
            let r = self.r[i];
            let estimate = (l + p / (std::f64::consts::PI * r * r)) / self.mean_w;
            self.l1[i] += estimate;
            self.l2[i] += estimate * estimate;
            let mi = m.get(i).copied().unwrap_or(0);
            if mi > 0 {
                let (n, r, mf) = (self.n[i], self.r[i], mi as f64);
                let n_new = n + alpha * mf;
                let r_new = r * (n_new / (n + mf)).sqrt();
                let p = phi.get(i).map_or(DVec3::ZERO, |p| DVec3::from_array(*p));
                self.tau[i] = (self.tau[i] + p) * (r_new * r_new) / (r * r);
                self.n[i] = n_new;
                self.r[i] = r_new;
            }
        }
        self.iterations += 1;
    }

    /// The estimate after the iterations so far: (L_d + τ/(π r²)) / (T E[w]), times
    /// `exposure`: the film filter's weighted mean, as the path tracer's Σ w·L / Σ w is in
    /// expectation, without its ratio (T for a box filter either way), which a filter's
    /// negative lobes bring near 0 while a pixel has few iterations.
    pub fn image(&self, exposure: f32) -> Image {
        let exposure = exposure as f64;
        let mut image = Image::new(self.width, self.height);
        let k = self.iterations as f64;
        let w = k * self.mean_w;
        for (i, px) in image.pixels.iter_mut().enumerate() {
            let r = self.r[i];
            let l = if w != 0.0 {
                (self.ld[i] + self.tau[i] / (std::f64::consts::PI * r * r)) * (exposure / w)
            } else {
                DVec3::ZERO
            };
            // The variance of the mean of the k iterations' estimates, none below two.
            let variance = if k >= 2.0 {
                (self.l2[i] - self.l1[i] * self.l1[i] / k).max(DVec3::ZERO)
                    * (exposure * exposure / (k * (k - 1.0)))
            } else {
                DVec3::ZERO
            };
            *px = Pixel {
                rgb: [l.x as f32, l.y as f32, l.z as f32],
                alpha: 1.0,
                variance: [variance.x as f32, variance.y as f32, variance.z as f32],
                ..Pixel::default()
            };
        }
        image
    }
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

/// The squared radius a pixel at radius `r` gathers within.
#[inline]
pub fn radius2(r: f64) -> f32 {
    (r * r) as f32
}

/// Hachisuka & Jensen's suggested α.
pub const DEFAULT_ALPHA: f32 = 2.0 / 3.0;

/// SPPM's initial radius as a share of the photon map's default search radius (twice the
/// radius that would hold k photons spread evenly, [`crate::photon::PhotonSettings`]): √½, a
/// disc that would hold 2k. The photon map's radius only caps a k-nearest search, which
/// shrinks where photons are dense; SPPM gathers everything within its radius, so that cap's
/// margin would be kernel bias in its first iterations, which α shrinks away slowly. A smaller
/// share trades it for the noise of fewer photons per pixel.
pub const DEFAULT_RADIUS_SHARE: f32 = std::f32::consts::FRAC_1_SQRT_2;

impl SppmSettings {
    pub fn from_photon_settings(p: &PhotonSettings, iterations: u32, alpha: f32) -> Self {
        SppmSettings {
            iterations,
            photons: p.photons,
            initial_radius: p.radius,
            alpha,
        }
    }

    /// The settings of `desc`: its `integrator.spp` iterations of `photon_map.photons`
    /// photons, `photon_map.alpha`, and `photon_map.radius` as the initial radius where the
    /// scene sets it, else [`DEFAULT_RADIUS_SHARE`] of the photon map's default radius.
    pub fn resolve(desc: &SceneDesc, analysis: &Analysis) -> (PhotonSettings, SppmSettings) {
        let (photon, _) = PhotonSettings::resolve(desc, analysis);
        let alpha = desc.integrator.photon.alpha.unwrap_or(DEFAULT_ALPHA);
        let mut s = Self::from_photon_settings(&photon, desc.integrator.spp, alpha);
        if desc.integrator.photon.radius.is_none() {
            s.initial_radius *= DEFAULT_RADIUS_SHARE;
        }
        (photon, s)
    }

    /// How they read in a report and in the image's metadata.
    pub fn describe(&self) -> String {
        format!(
            "sppm: {} iterations of {} photons, initial radius {:.4}, α {}",
            self.iterations, self.photons, self.initial_radius, self.alpha
        )
    }
}

/// Photons per iteration `desc` asks for.
pub fn photons_per_iteration(desc: &SceneDesc) -> u32 {
    desc.integrator.photon.photons.unwrap_or(DEFAULT_PHOTONS)
}

/// The name under which chunk `chunk` of iteration `t`'s photons for frame `frame` is handed
/// from `auto`'s pilot to the render ([`crate::method::TaskCtx::reuse`]): everything the
/// photons depend on besides the scene.
pub fn photons_key(
    photon: &PhotonSettings,
    settings: &SppmSettings,
    frame: u32,
    t: u32,
    chunk: &Range<u32>,
) -> String {
    format!(
        "sppm photons: frame {frame}, iteration {t}, photons {}..{} of {}, max depth {}, {:?} sampler, seed {}",
        chunk.start, chunk.end, settings.photons, photon.max_depth, photon.sampler, photon.seed
    )
}

/// An iteration of `photons` photons in gathering chunks: photon offsets within the
/// iteration, in order.
pub fn chunks(photons: u32) -> Vec<Range<u32>> {
    (0..photons)
        .step_by(PHOTONS_PER_CHUNK as usize)
        .map(|s| s..s.saturating_add(PHOTONS_PER_CHUNK).min(photons))
        .collect()
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
    // The film filter as the path tracer samples it: the weight rides on β.
    let (mut ray, w) = crate::camera::camera_ray(scene, camera, pixel, sampler);
    let mut beta = Spectrum::splat(w);
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
            l += beta * scene.lights.get(si.light).le_surface(si.ng, wo, si.p);
        }
        let material = scene.material(si.material);
        if material.is_black() {
            break;
        }
        if material.flags.smooth {
            let frame = material.frame(&si, wo);
            l += beta * direct_light(scene, &si, material, &frame, wo, sampler, stats);
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

/// One frame's SPPM: its settings and photon shooter. Iteration t's camera paths are pixel
/// samples t; its photons are indices t·M + chunk.
pub struct Sppm<'a> {
    scene: &'a Scene,
    pub settings: SppmSettings,
    max_depth: u32,
    shooter: Shooter<'a>,
    sampler: PixelSampler,
}

impl<'a> Sppm<'a> {
    pub fn new(scene: &'a Scene, photon: &PhotonSettings, settings: SppmSettings) -> Self {
        let shooter = Shooter::new(
            scene,
            &PhotonSettings {
                photons: settings.photons,
                ..*photon
            },
            MapKind::Indirect,
        );
        Sppm {
            scene,
            settings,
            max_depth: photon.max_depth,
            shooter,
            sampler: PixelSampler::new(photon.sampler, photon.seed),
        }
    }

    /// Camera paths of iteration `t` for the row-major pixels `pixels` (one thread).
    pub fn visible_points(&self, camera: &Camera, t: u32, pixels: Range<u32>) -> VisiblePoints {
        let w = self.scene.film.width;
        self.visible_points_of(camera, t, pixels.map(|i| UVec2::new(i % w, i / w)))
    }

    /// Camera paths of iteration `t` for `pixels` of `camera`'s film, in their order (one
    /// thread).
    pub fn visible_points_of(
        &self,
        camera: &Camera,
        t: u32,
        pixels: impl IntoIterator<Item = UVec2>,
    ) -> VisiblePoints {
        let mut sampler = self.sampler.clone();
        let mut stats = RayStats::default();
        let (mut ld, mut points) = (Vec::new(), Vec::new());
        for pixel in pixels {
            let (l, vp) = visible_point(
                self.scene,
                camera,
                pixel,
                t,
                self.max_depth,
                &mut sampler,
                &mut stats,
            );
            stats.samples += 1;
            ld.push(l);
            points.push(vp);
        }
        VisiblePoints {
            camera: CameraPass { ld, stats },
            points,
        }
    }

    /// [`Self::visible_points`] of the whole frame on the rayon pool; the same result.
    pub fn visible_points_parallel(&self, camera: &Camera, t: u32) -> VisiblePoints {
        let (w, h) = (self.scene.film.width, self.scene.film.height);
        let rows: Vec<VisiblePoints> = (0..h)
            .into_par_iter()
            .map(|y| self.visible_points(camera, t, y * w..(y + 1) * w))
            .collect();
        let n = (w * h) as usize;
        let mut all = VisiblePoints {
            camera: CameraPass {
                ld: Vec::with_capacity(n),
                stats: RayStats::default(),
            },
            points: Vec::with_capacity(n),
        };
        for r in rows {
            all.camera.ld.extend(r.camera.ld);
            all.camera.stats.add(&r.camera.stats);
            all.points.extend(r.points);
        }
        all
    }

    /// The photons of chunk `chunk` of iteration `t`, in a tree; `parallel` shoots on the
    /// rayon pool (the same photons).
    pub fn shoot(&self, t: u32, chunk: Range<u32>, parallel: bool) -> KdTree<Photon> {
        let base = t as u64 * self.settings.photons as u64;
        let at = |o: u32| (base + o as u64).min(u32::MAX as u64) as u32;
        let range = at(chunk.start)..at(chunk.end);
        KdTree::build(if parallel {
            self.shooter.shoot_parallel(range)
        } else {
            self.shooter.shoot(range)
        })
    }

    /// Gathers `photons` at the visible points of `pixels` (indices into `vps`, which holds
    /// the whole frame) within each pixel's squared radius `r2`: the pixels that received
    /// any, in pixel order.
    pub fn gather(
        &self,
        vps: &VisiblePoints,
        r2: &[f32],
        photons: &KdTree<Photon>,
        pixels: Range<u32>,
    ) -> Vec<PixelSum> {
        let mut out = Vec::new();
        for i in pixels {
            let Some(Some(vp)) = vps.points.get(i as usize) else {
                continue;
            };
            let material = self.scene.material(vp.si.material);
            let frame = material.frame(&vp.si, vp.wo);
            let wo_local = frame.to_local(vp.wo);
            let bsdf = material.bsdf_at(&vp.si);
            let (mut phi, mut m) = (DVec3::ZERO, 0u32);
            let r2 = r2.get(i as usize).copied().unwrap_or(0.0);
            // The sphere flattened into a disc along the surface, as the photon map gathers:
            // photons on a nearby surface of another orientation — the far side of a thin
            // wall — are not this surface's light.
            photons.within(vp.si.p, vp.si.ns, FLATTEN, r2, &mut |j, _| {
                let ph = photons.get(j);
                let wi = Vec3A::from(ph.wi);
                let f = bsdf.eval(wo_local, frame.to_local(wi), TransportMode::Radiance);
                let c = vp.beta * f * Vec3A::from(ph.power);
                if c.is_finite() {
                    phi += DVec3::new(c.x as f64, c.y as f64, c.z as f64);
                }
                m += 1;
            });
            if m > 0 {
                out.push(PixelSum {
                    pixel: i,
                    m,
                    phi: phi.to_array(),
                });
            }
        }
        out
    }

    /// Runs the next iteration (`state.iterations`) on the rayon pool and folds it into
    /// `state`; returns the camera paths' counters.
    pub fn iterate(&self, camera: &Camera, state: &mut SppmState) -> RayStats {
        let t = state.iterations;
        let vps = self.visible_points_parallel(camera, t);
        let r2 = state.radii2();
        let sums: Vec<Vec<PixelSum>> = chunks(self.settings.photons)
            .into_iter()
            .map(|c| self.gather_parallel(&vps, &r2, &self.shoot(t, c, true)))
            .collect();
        state.add_iteration(
            &vps.camera,
            sums.iter().map(Vec::as_slice),
            self.settings.alpha,
        );
        vps.camera.stats
    }

    /// [`Self::gather`] over the whole frame on the rayon pool; the same result.
    pub fn gather_parallel(
        &self,
        vps: &VisiblePoints,
        r2: &[f32],
        photons: &KdTree<Photon>,
    ) -> Vec<PixelSum> {
        let (w, h) = (self.scene.film.width, self.scene.film.height);
        let rows: Vec<Vec<PixelSum>> = (0..h)
            .into_par_iter()
            .map(|y| self.gather(vps, r2, photons, y * w..(y + 1) * w))
            .collect();
        rows.concat()
    }
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
    let sppm = Sppm::new(scene, photon, *s);
    let mut state = SppmState::new(
        scene.film.width,
        scene.film.height,
        s.initial_radius,
        scene.filter.mean_weight(),
    );
    let mut stats = RayStats::default();
    for t in 0..s.iterations {
        stats.add(&sppm.iterate(camera, &mut state));
        progress(t);
    }
    (state.image(camera.exposure), stats)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Hachisuka & Jensen's update on numbers worked by hand: chunks add before the update,
    /// a pixel without photons keeps N, r and τ, and the estimate is L_d/T + τ/(Tπr²) with
    /// unit filter weights.
    #[test]
    fn an_iteration_updates_n_r_and_tau_as_the_paper_does() {
        let mut s = SppmState::new(2, 1, 1.0, 1.0);
        let sum = |pixel, m, phi| PixelSum {
            pixel,
            m,
            phi: [phi; 3],
        };
        let chunk_a = [sum(0, 1, 1.0)];
        let chunk_b = [sum(0, 3, 2.0)];
        let camera = CameraPass {
            ld: vec![Spectrum::splat(0.5), Spectrum::splat(f32::NAN)],
            stats: RayStats::default(),
        };
        s.add_iteration(&camera, [&chunk_a[..], &chunk_b[..]], 0.5);
        // M = 4, Φ = 3: N' = 0 + 0.5·4 = 2, r'² = 1·2/4, τ' = 3·r'²/r² = 1.5.
        assert_eq!(s.n[0], 2.0);
        assert!((s.r[0] * s.r[0] - 0.5).abs() < 1e-15);
        assert!((s.tau[0].x - 1.5).abs() < 1e-15);
        assert_eq!((s.n[1], s.r[1], s.tau[1]), (0.0, 1.0, DVec3::ZERO));
        assert_eq!(s.ld[1], DVec3::ZERO, "a non-finite direct term is dropped");
        let l = s.image(1.0).pixels[0].rgb[0] as f64;
        let expect = 0.5 + 1.5 / (std::f64::consts::PI * 0.5);
        assert!((l - expect).abs() < 1e-6, "{l} vs {expect}");
        // A second iteration with M = 2, Φ = 1: N'' = 2 + 1 = 3, r''² = 0.5·3/4.
        s.add_iteration(&camera, [&[sum(0, 2, 1.0)][..]], 0.5);
        assert!((s.r[0] * s.r[0] - 0.375).abs() < 1e-15);
        assert!((s.tau[0].x - 2.5 * 0.75).abs() < 1e-15);
        assert_eq!(s.iterations, 2);
    }

    /// The pixel divides by T·E[w], not by its weights' sum: a filter's negative lobe gives
    /// one sample w = −0.999 beside another of w = 1, whose sum 0.001 would make the ratio
    /// (1·1 − 0.999·0) / 0.001 = 1000 of a pixel whose samples saw 1 and 0.
    #[test]
    fn weights_that_nearly_cancel_do_not_blow_a_pixel_up() {
        let mut s = SppmState::new(1, 1, 1.0, 1.0);
        for ld in [1.0, 0.0] {
            let camera = CameraPass {
                ld: vec![Spectrum::splat(ld)],
                stats: RayStats::default(),
            };
            s.add_iteration(&camera, std::iter::empty::<&[PixelSum]>(), 0.7);
        }
        let p = s.image(1.0).pixels[0];
        assert!((p.rgb[0] - 0.5).abs() < 1e-6, "{}", p.rgb[0]);
    }

    /// The variance AOV is that of the mean of the iterations' own estimates: 1, 3, 1, 3
    /// (direct light alone) have sample variance 4/3, so their mean's is 1/3.
    #[test]
    fn the_variance_is_that_of_the_mean_of_the_iterations_estimates() {
        let mut s = SppmState::new(1, 1, 1.0, 1.0);
        for t in 0..4 {
            let camera = CameraPass {
                ld: vec![Spectrum::splat(if t % 2 == 0 { 1.0 } else { 3.0 })],
                stats: RayStats::default(),
            };
            s.add_iteration(&camera, std::iter::empty::<&[PixelSum]>(), 0.7);
        }
        let p = s.image(1.0).pixels[0];
        assert!((p.rgb[0] - 2.0).abs() < 1e-6);
        assert!(
            (p.variance[0] - 1.0 / 3.0).abs() < 1e-6,
            "{}",
            p.variance[0]
        );
        // One iteration says nothing of the variance.
        let mut one = SppmState::new(1, 1, 1.0, 1.0);
        let camera = CameraPass {
            ld: vec![Spectrum::splat(1.0)],
            stats: RayStats::default(),
        };
        one.add_iteration(&camera, std::iter::empty::<&[PixelSum]>(), 0.7);
        assert_eq!(one.image(1.0).pixels[0].variance, [0.0; 3]);
    }
}
