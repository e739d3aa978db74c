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

use rayon::prelude::*;

use super::RayStats;
use crate::camera::Camera;
use crate::camera::camera_ray;
use crate::film::{FilmSums, Image, TileSums, tiles};
use crate::sampler::{PixelSampler, Sampler};
use crate::scene::Scene;
use crate::spectrum::Spectrum;
use crate::{SampleRange, Tile};

mod density;
mod mis;
mod splats;
mod strategies;
mod subpath;
mod vertex;

pub(in crate::integrator) use mis::FIRST_MERGE;
use splats::{SPLAT_SCALE, add_fixed};
pub(in crate::integrator) use splats::{Splats, add_splats, fixed_brightness};
use strategies::Recorder;
pub use strategies::StrategyImage;
pub(in crate::integrator) use subpath::Ctx;
pub(in crate::integrator) use vertex::{Kind, Vertex};

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

/// A frame's BDPT sums over a sample range: the camera-side estimates as compact sums over
/// the whole film (each 16×16 tile's fixed-point sums rounded to f32 once the tile is done)
/// and the light-tracing splats in fixed point (2⁻³² units). Within a range neither depends
/// on how the threads shared the work; ranges merge in f32.
#[derive(Debug, Clone, PartialEq)]
pub struct BdptSums {
    pub sums: FilmSums,
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
            sums: FilmSums::empty(tile, false),
            splats: vec![[0; 3]; tile.pixel_count()],
            samples: 0,
            chain: Vec::new(),
            brightness: (0, 0),
        }
    }

    /// Samples `range` of a `width` × `height` film from its tiles' compact sums and the
    /// splats.
    pub(in crate::integrator) fn gather<'t>(
        width: u32,
        height: u32,
        range: SampleRange,
        tiles: impl IntoIterator<Item = &'t FilmSums>,
        splats: &Splats,
    ) -> Self {
        let mut out = BdptSums::new(width, height);
        out.samples = range.len();
        out.sums.samples = range.len();
        for tile in tiles {
            out.sums.put(tile);
        }
        out.splats = splats.totals();
        out
    }

    /// Adds the sums of another sample range of the same film.
    pub fn merge(&mut self, other: &BdptSums) {
        self.sums.add(&other.sums);
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
        let t = self.sums.tile();
        let mut image = Image::new(t.width(), t.height());
        for (k, px) in image.pixels.iter_mut().enumerate() {
            px.rgb = self.sums.mean(k);
            px.alpha = 1.0;
        }
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
        let ctx = Ctx::new(scene, camera, self.rr_depth);
        let (w, h) = (scene.film.width, scene.film.height);
        let splats = Splats::new(w, h);
        // Each tile's fixed-point sums become compact as soon as it is done.
        let results: Vec<(FilmSums, RayStats)> = tiles(w, h, 16)
            .into_par_iter()
            .map(|tile| {
                let (sums, stats) = self.render_tile(&ctx, tile, range, &splats, None);
                progress(tile.pixel_count() as u64);
                (FilmSums::from_tile(&sums, false), stats)
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
                acc.add(fw, l);
            }
        }
        (sums, stats)
    }
}
