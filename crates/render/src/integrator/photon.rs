//! Photon mapping with final gathering (Jensen 2001, ch. 9 "A Practical Two-Pass Algorithm"),
//! and Ward's irradiance cache for the gathered term.
//!
//! The camera path is traced like a path tracer through specular and glossy surfaces (light
//! sampling with MIS where a lobe has a density). At the first surface with a diffuse
//! component, radiance is split (Jensen 2001 eq. 9.4):
//!
//! - direct light: a light sample and a BSDF sample combined by MIS, exact;
//! - caustics: the caustic map's radiance estimate (cone or Gaussian filter);
//! - indirect diffuse: from the irradiance cache (Lambertian surfaces, where a record serves)
//!   or by final gathering: rays sampled from the BSDF, followed through specular bounces, that
//!   read the global map's radiance estimate where they first meet a non-specular surface.
//!   Emitters a gather ray meets count nothing: that light is direct (or a caustic) here.

use std::sync::Arc;

use glam::{Vec2, Vec3, Vec3A};
use rayon::prelude::*;
use tessera_scene::SceneDesc;

use crate::analysis::Analysis;

use super::{Integrator, PathIntegrator, RayStats, consistent, direct_light, scatter};
use crate::bsdf::TransportMode;
use crate::camera::Camera;
use crate::film::Tile;
use crate::irradiance::{self, IrradianceCache, Record};
use crate::math::{Frame, PI};
use crate::photon::{PhotonMaps, PhotonSettings};
use crate::ray::Ray;
use crate::sampler::hash::hash;
use crate::sampler::{PixelSampler, Sampler};
use crate::scene::{Material, Scene, SurfaceInteraction};
use crate::spectrum::{Spectrum, is_black};

/// Specular bounces a gather ray follows before giving up.
const GATHER_SPECULAR_DEPTH: u32 = 8;

/// Record candidates per side of a record-pass tile, at least.
pub const RECORD_TILE: u32 = 8;
/// Most record-pass tiles per keyframe: larger films get larger tiles.
const MAX_RECORD_TILES: usize = 256;

/// The record pass's tiles: the grid of record candidates of a `width`×`height` film (one per
/// `spacing` pixels) in tiles of 8×8 candidates, doubled until a keyframe has at most 256
/// tiles; none without an irradiance cache. (A tile makes its records without seeing other
/// tiles', so the tiling is part of what determines the cache: a function of the film size.)
pub fn record_tiles(settings: &PhotonSettings, width: u32, height: u32) -> Vec<Tile> {
    let Some(ic) = settings.irradiance_cache else {
        return Vec::new();
    };
    let s = ic.spacing.max(1);
    let (w, h) = (width.div_ceil(s), height.div_ceil(s));
    let mut side = RECORD_TILE;
    while (w.div_ceil(side) as usize) * (h.div_ceil(side) as usize) > MAX_RECORD_TILES {
        side *= 2;
    }
    crate::film::tiles(w, h, side)
}

/// The frames whose cameras make the irradiance records of a job rendering `frames`: every
/// `step`-th frame from the first, and the last (V-Ray's "use camera path", Mental Ray's
/// frozen final-gather maps). One cache, built once, serves every frame of the job.
pub fn keyframes(frames: std::ops::RangeInclusive<u32>, step: u32) -> Vec<u32> {
    let last = *frames.end();
    let mut out: Vec<u32> = frames.step_by(step.max(1) as usize).collect();
    if out.last() != Some(&last) {
        out.push(last);
    }
    out
}

pub struct PhotonIntegrator {
    settings: PhotonSettings,
    /// The camera paths' tracer, up to their first diffuse vertex.
    path: PathIntegrator,
    maps: Arc<PhotonMaps>,
    cache: Option<Arc<IrradianceCache>>,
}

/// Where a camera path meets its first diffuse surface (for the record pass).
struct GatherPoint {
    si: SurfaceInteraction,
    /// Shading normal turned toward the viewer.
    n: Vec3A,
}

impl PhotonIntegrator {
    pub fn new(
        settings: PhotonSettings,
        rr_depth: u32,
        maps: Arc<PhotonMaps>,
        cache: Option<Arc<IrradianceCache>>,
    ) -> Self {
        PhotonIntegrator {
            path: PathIntegrator::new(settings.max_depth, rr_depth),
            settings,
            maps,
            cache,
        }
    }

    /// The integrator for `desc` with its passes run in-process: both maps shot in chunks on
    /// the rayon pool, the record pass over every keyframe's pre-render tiles, each merged in
    /// order — the same artifacts a farm's pass tasks make. Returns what was decided.
    pub fn prepare(
        desc: &SceneDesc,
        scene: &Scene,
        analysis: &Analysis,
        frames: std::ops::RangeInclusive<u32>,
    ) -> (Self, Vec<String>) {
        let (settings, mut why) = PhotonSettings::resolve(desc, analysis);
        let maps = Arc::new(PhotonMaps::shoot(scene, &settings));
        why.push(format!(
            "photon maps: {} global photons stored of {} shot, {} caustic of {}",
            maps.global.tree.len(),
            settings.photons,
            maps.caustic.tree.len(),
            settings.caustic_photons
        ));
        let mut integrator = PhotonIntegrator::new(settings, desc.integrator.rr_depth, maps, None);
        if let Some(ic) = settings.irradiance_cache {
            let keyframes = keyframes(frames, ic.keyframe_step);
            let tiles = record_tiles(&settings, desc.film.width, desc.film.height);
            let mut records = Vec::new();
            for &frame in &keyframes {
                let camera = Camera::new(&desc.camera_at(frame), &desc.film);
                let parts: Vec<Vec<Record>> = tiles
                    .par_iter()
                    .map(|&t| {
                        integrator.record_pass(scene, &camera, t, frame, &mut RayStats::default())
                    })
                    .collect();
                records.extend(parts.into_iter().flatten());
            }
            why.push(format!(
                "irradiance cache: {} records (a = {}) from {} keyframe{}",
                records.len(),
                ic.accuracy,
                keyframes.len(),
                if keyframes.len() == 1 { "" } else { "s" }
            ));
            integrator.cache = Some(Arc::new(IrradianceCache::build(records, ic.accuracy)));
        } else {
            why.push("irradiance cache: off — final gathering at every camera sample".into());
        }
        (integrator, why)
    }

    pub fn settings(&self) -> &PhotonSettings {
        &self.settings
    }

    pub fn maps(&self) -> &PhotonMaps {
        &self.maps
    }

    pub fn cache(&self) -> Option<&IrradianceCache> {
        self.cache.as_deref()
    }

    /// Radiance arriving along `ray` from the global map at the first non-specular surface it
    /// meets (through at most a few specular bounces), and the distance to the first surface
    /// (infinite if none).
    fn gather_ray(
        &self,
        scene: &Scene,
        mut ray: Ray,
        sampler: &mut PixelSampler,
        stats: &mut RayStats,
    ) -> (Spectrum, f32) {
        let mut beta = Spectrum::ONE;
        let mut first_t = f32::INFINITY;
        for bounce in 0..GATHER_SPECULAR_DEPTH {
            stats.rays += 1;
            let Some(si) = scene.intersect(&ray) else {
                break;
            };
            if bounce == 0 {
                first_t = si.t;
            }
            let material = scene.material(si.material);
            let wo = -ray.d;
            if material.flags.smooth {
                let l = self.maps.gather_radiance(&si, material, wo, &self.settings);
                return (beta * l, first_t);
            }
            if material.is_black() {
                break;
            }
            // Delta-only surface: follow it.
            let Some((weight, next)) = scatter(&si, material, wo, sampler) else {
                break;
            };
            beta *= weight;
            if is_black(beta) {
                break;
            }
            ray = next;
        }
        (Spectrum::ZERO, first_t)
    }

    /// Indirect radiance toward `wo` at a diffuse vertex by final gathering: `gather_rays`
    /// directions sampled from the BSDF, each reading the global map where it lands.
    #[allow(clippy::too_many_arguments)]
    fn final_gather(
        &self,
        scene: &Scene,
        si: &SurfaceInteraction,
        material: &Material,
        frame: &Frame,
        wo: Vec3A,
        sampler: &mut PixelSampler,
        stats: &mut RayStats,
    ) -> Spectrum {
        let n = self.settings.gather_rays;
        let wo_local = frame.to_local(wo);
        let bsdf = material.bsdf_at(si);
        let mut sum = Spectrum::ZERO;
        for _ in 0..n {
            let u = sampler.get_3d();
            let Some(bs) = bsdf.sample(wo_local, u.x, Vec2::new(u.y, u.z), TransportMode::Radiance)
            else {
                continue;
            };
            let wi = frame.to_world(bs.wi);
            if !consistent(si, wo, wi, wo_local, bs.wi) {
                continue;
            }
            let (l, _) = self.gather_ray(scene, si.spawn(wi), sampler, stats);
            sum += bs.weight() * l;
        }
        sum / n as f32
    }

    /// Indirect irradiance at `gp` by Ward's stratified hemisphere: M × N cosine-weighted
    /// strata (N ≈ πM) over the gather rays, E = π/(MN) Σ L; R the harmonic mean distance,
    /// clamped to [r_min, r_max].
    fn record(
        &self,
        scene: &Scene,
        gp: &GatherPoint,
        rays: u32,
        (r_min, r_max): (f32, f32),
        sampler: &mut PixelSampler,
        stats: &mut RayStats,
    ) -> Record {
        let m = ((rays as f32 / PI).sqrt().round() as u32).max(1);
        let n = ((rays / m).max(1)).max(1);
        let frame = Frame::from_normal(gp.n);
        let mut sum = Spectrum::ZERO;
        let mut inv_dist = 0.0f32;
        for j in 0..m {
            for k in 0..n {
                let u = sampler.get_2d();
                let sin2 = (j as f32 + u.x) / m as f32;
                let (sin, cos) = (sin2.sqrt(), (1.0 - sin2).max(0.0).sqrt());
                let phi = 2.0 * PI * (k as f32 + u.y) / n as f32;
                let local = Vec3A::new(sin * phi.cos(), sin * phi.sin(), cos);
                let wi = frame.to_world(local);
                if wi.dot(gp.si.ng) * gp.n.dot(gp.si.ng) <= 0.0 {
                    continue;
                }
                let (l, t) = self.gather_ray(scene, gp.si.spawn(wi), sampler, stats);
                sum += l;
                if t.is_finite() && t > 0.0 {
                    inv_dist += 1.0 / t;
                }
            }
        }
        let count = (m * n) as f32;
        let r = if inv_dist > 0.0 {
            count / inv_dist
        } else {
            r_max
        };
        Record {
            p: Vec3::from(gp.si.p),
            n: Vec3::from(gp.n),
            e: Vec3::from(sum * (PI / count)),
            r: r.clamp(r_min, r_max.max(r_min)),
        }
    }

    /// Follows a ray through specular surfaces to the first surface with a diffuse component.
    fn first_diffuse(
        &self,
        scene: &Scene,
        mut ray: Ray,
        sampler: &mut PixelSampler,
        stats: &mut RayStats,
    ) -> Option<GatherPoint> {
        for _ in 0..GATHER_SPECULAR_DEPTH {
            stats.rays += 1;
            let si = scene.intersect(&ray)?;
            let material = scene.material(si.material);
            let wo = -ray.d;
            if material.flags.diffuse {
                let n = si.ns_toward(wo);
                return Some(GatherPoint { si, n });
            }
            if !material.flags.specular {
                return None;
            }
            ray = scatter(&si, material, wo, sampler)?.1;
        }
        None
    }

    /// The record pass over one tile of the pre-render: one candidate every `spacing` pixels
    /// of the film seen by `camera`; in the tile's own order, a record is made at each
    /// Lambertian candidate that the records made so far (by this tile) do not serve.
    /// A pure function of (scene, maps, camera, tile, key): `key` (the frame) seeds it.
    pub fn record_pass(
        &self,
        scene: &Scene,
        camera: &Camera,
        tile: Tile,
        key: u32,
        stats: &mut RayStats,
    ) -> Vec<Record> {
        let Some(ic) = self.settings.irradiance_cache else {
            return Vec::new();
        };
        let s = ic.spacing.max(1);
        let mut sampler = PixelSampler::new(
            self.settings.sampler,
            hash(&[self.settings.seed, 0x1cac_4e00, key as u64]),
        );
        let mut records: Vec<Record> = Vec::new();
        let r_max = scene.radius;
        // The camera's film, not the scene's: an `auto` pilot renders a smaller film from the
        // records of the render's.
        let size = camera.film_size() + Vec2::splat(s as f32);
        for pixel in tile.pixels() {
            sampler.start_pixel_sample(pixel, 0);
            let film = Vec2::new(
                (pixel.x * s) as f32 + 0.5 * s as f32,
                (pixel.y * s) as f32 + 0.5 * s as f32,
            );
            if film.x >= size.x || film.y >= size.y {
                continue;
            }
            let ray = camera.generate_ray(film, Vec2::splat(0.5));
            let Some(gp) = self.first_diffuse(scene, ray, &mut sampler, stats) else {
                continue;
            };
            if scene.material(gp.si.material).bsdf.lambertian().is_none() {
                continue;
            }
            if irradiance::served(&records, gp.si.p, gp.n, ic.accuracy) {
                continue;
            }
            // Records must reach at least 1.5 candidate spacings: the validity radius a·R is
            // held above that footprint, so every pixel near a candidate is served.
            let r_min = 1.5 * s as f32 * camera.pixel_footprint(gp.si.p) / ic.accuracy;
            records.push(self.record(
                scene,
                &gp,
                ic.gather_rays,
                (r_min, r_max),
                &mut sampler,
                stats,
            ));
        }
        records
    }

    /// Indirect diffuse radiance toward `wo` at a gather vertex.
    #[allow(clippy::too_many_arguments)]
    fn indirect(
        &self,
        scene: &Scene,
        si: &SurfaceInteraction,
        material: &Material,
        frame: &Frame,
        wo: Vec3A,
        sampler: &mut PixelSampler,
        stats: &mut RayStats,
    ) -> Spectrum {
        if let (Some(cache), Some(rho)) = (&self.cache, material.bsdf.lambertian()) {
            let n = si.ns_toward(wo);
            if let Some(e) = cache.lookup(si.p, n) {
                return rho * e * crate::math::INV_PI;
            }
        }
        self.final_gather(scene, si, material, frame, wo, sampler, stats)
    }
}

impl Integrator for PhotonIntegrator {
    /// Path tracing through specular and glossy surfaces, ended at the first diffuse one by
    /// direct light (a light and a BSDF sample: the path stops there, so only that BSDF sample
    /// finds emitters), caustics and indirect light.
    fn li(
        &self,
        scene: &Scene,
        ray: Ray,
        sampler: &mut PixelSampler,
        stats: &mut RayStats,
    ) -> Spectrum {
        let s = &self.settings;
        let gather = |si: &SurfaceInteraction,
                      material: &Material,
                      frame: &Frame,
                      wo: Vec3A,
                      sampler: &mut PixelSampler,
                      stats: &mut RayStats| {
            let direct = direct_light(scene, si, material, frame, wo, sampler, stats);
            let caustic = self.maps.caustic.radiance(
                si,
                material,
                wo,
                s.caustic_k,
                s.caustic_radius,
                s.caustic_filter,
            );
            direct + caustic + self.indirect(scene, si, material, frame, wo, sampler, stats)
        };
        self.path.trace(scene, ray, sampler, stats, Some(&gather))
    }
}
