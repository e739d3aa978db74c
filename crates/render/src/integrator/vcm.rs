//! Vertex connection and merging (Georgiev, Křivánek, Davidovič & Slusallek 2012; the same
//! estimator as Hachisuka, Pantaleoni & Jensen's unified path sampling, 2012).
//!
//! Each iteration traces one light subpath per pixel first and keeps their vertices in a
//! kd-tree; then each pixel's camera subpath is joined to its own light subpath by every BDPT
//! connection (vertex connection), and at each of its non-specular vertices it *merges* with
//! the light vertices of every light subpath within radius r, as photon mapping would: a light
//! vertex y near the camera vertex x stands for a path through x, with contribution
//! β_camera(x) f(x) β_light(y) / (η π r²), η the light subpaths of the iteration. Merging is
//! how specular–diffuse–specular paths (a caustic seen through glass) are found, which no
//! connection can make. One power-heuristic MIS weighs connections and merges: a merge at
//! vertex z has density p(connection sampling z from one side) × p(z from the other side) ×
//! η π r² (`Ctx::mis_sums` for connections, [`merge_weight`] for merges). The radius shrinks as r_k = r₀ k^((α−1)/2) over iterations k, so
//! the merging bias vanishes (α = 0.75, as the paper).
//!
//! Light tracing (t = 1) splats during the light pass; the camera pass fills each pixel's
//! film sums. The output is BDPT's ([`BdptSums`], iterations as samples), and an iteration
//! depends only on its index, so ranges of iterations merge exactly like BDPT's sample
//! ranges — in any order, on any number of threads or workers.

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use super::RayStats;
use super::bdpt::{BdptSums, Ctx, Kind, Splats, Vertex};
use crate::SampleRange;
use crate::bsdf::TransportMode;
use crate::camera::Camera;
use crate::film::{TileSums, tiles};
use crate::photon::kdtree::{KdTree, Positioned};
use crate::render::camera_ray;
use crate::sampler::hash::hash;
use crate::sampler::{PixelSampler, Sampler};
use crate::scene::Scene;
use crate::spectrum::{Spectrum, is_black};

/// The settings VCM runs with.
#[derive(Debug, Clone, Copy)]
pub struct Vcm {
    pub max_depth: u32,
    pub rr_depth: u32,
    /// Merging radius of the first iteration, scene units.
    pub radius: f32,
    /// Radius reduction: r_k = r₀ k^((α−1)/2).
    pub alpha: f32,
}

impl Vcm {
    /// The scene's settings; r₀ is SmallVCM's 0.003 × the scene's bounding radius at 512²
    /// light paths per iteration, scaled by √(512² / pixels) so that a merge finds as many
    /// light vertices on a smaller film.
    pub fn new(desc: &tessera_scene::SceneDesc, scene: &Scene) -> Self {
        let pixels = (desc.film.width as f32 * desc.film.height as f32).max(1.0);
        Vcm {
            max_depth: desc.integrator.max_depth,
            rr_depth: desc.integrator.rr_depth,
            radius: 0.003 * scene.radius * (512.0 * 512.0 / pixels).sqrt(),
            alpha: 0.75,
        }
    }

    /// The merging radius of iteration `k` (counted from 0).
    pub fn radius_at(&self, k: u32) -> f32 {
        self.radius * ((k + 1) as f32).powf((self.alpha - 1.0) / 2.0)
    }

    /// Renders iterations `range` of the frame on the rayon pool.
    pub fn render_range(
        &self,
        scene: &Scene,
        camera: &Camera,
        range: SampleRange,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<(BdptSums, RayStats), String> {
        let ctx = Ctx::new("vcm", scene, camera, self.rr_depth, true)?;
        let (w, h) = (scene.film.width, scene.film.height);
        let splats = Splats::new(w, h);
        let mut film: Vec<TileSums> = tiles(w, h, 16)
            .into_iter()
            .map(|t| TileSums::new(t, range))
            .collect();
        let mut stats = RayStats::default();
        for k in range.start..range.end {
            stats.add(&self.iteration(&ctx, k, &mut film, &splats));
            progress(w as u64 * h as u64);
        }
        Ok((BdptSums::gather(w, h, range, &film, &splats), stats))
    }

    /// Iteration `k`: the light pass (subpaths, light tracing, the merge tree), then the
    /// camera pass into `film`.
    fn iteration(&self, ctx: &Ctx, k: u32, film: &mut [TileSums], splats: &Splats) -> RayStats {
        let scene = ctx.scene;
        let (w, h) = (scene.film.width, scene.film.height);
        let r = self.radius_at(k);
        let merge = w as f32 * h as f32 * std::f32::consts::PI * r * r;
        let d = self.max_depth as usize;
        let seed = hash(&[scene.integrator.seed, 0x76636d]);
        // The lens stands in for the camera subpath of light tracing (t = 1 samples its own).
        let lens = [Vertex::point(
            Kind::Camera,
            Vec3A::ZERO,
            Vec3A::ZERO,
            Vec3A::ZERO,
            Spectrum::ONE,
            0.0,
        )];
        let light: Vec<(Vec<Vertex>, RayStats)> = (0..w * h)
            .into_par_iter()
            .map_init(
                || PixelSampler::new(scene.integrator.sampler, seed),
                |sampler, j| {
                    let mut stats = RayStats::default();
                    let mut path = Vec::new();
                    sampler.start_pixel_sample(glam::UVec2::new(j % w, j / w), k);
                    ctx.light_subpath(d + 1, sampler, &mut stats, &mut path);
                    for s in 2..=path.len() {
                        let (c, raster) =
                            ctx.connect(&path, &lens, s, 1, merge, sampler, &mut stats);
                        if let Some(at) = raster {
                            splats.add(scene, at, c);
                        }
                    }
                    (path, stats)
                },
            )
            .collect();
        let mut stats = RayStats::default();
        let mut refs = Vec::new();
        for (j, (path, st)) in light.iter().enumerate() {
            stats.add(st);
            for (i, v) in path.iter().enumerate().skip(1) {
                if !v.delta && ctx.connectible(v) {
                    refs.push(LightRef {
                        p: Vec3::from(v.p),
                        path: j as u32,
                        index: i as u32,
                    });
                }
            }
        }
        let tree = KdTree::build(refs);
        let paths: Vec<&[Vertex]> = light.iter().map(|(p, _)| p.as_slice()).collect();
        let pass = CameraPass {
            ctx,
            vcm: self,
            k,
            r2: r * r,
            merge,
            tree: &tree,
            paths: &paths,
            splats,
        };
        let per_tile: Vec<RayStats> = film.par_iter_mut().map(|t| pass.tile(t)).collect();
        for st in &per_tile {
            stats.add(st);
        }
        stats
    }
}

/// A light vertex in the merge tree: light subpath `path` (its pixel), vertex `index`.
#[derive(Debug, Clone, Copy)]
struct LightRef {
    p: Vec3,
    path: u32,
    index: u32,
}

impl Positioned for LightRef {
    fn position(&self) -> Vec3 {
        self.p
    }
}

/// What an iteration's camera pass reads.
struct CameraPass<'a> {
    ctx: &'a Ctx<'a>,
    vcm: &'a Vcm,
    k: u32,
    r2: f32,
    merge: f32,
    tree: &'a KdTree<LightRef>,
    paths: &'a [&'a [Vertex]],
    splats: &'a Splats,
}

impl CameraPass<'_> {
    fn tile(&self, sums: &mut TileSums) -> RayStats {
        let ctx = self.ctx;
        let scene = ctx.scene;
        let w = scene.film.width;
        let d = self.vcm.max_depth as usize;
        let mut stats = RayStats::default();
        let mut sampler = PixelSampler::new(scene.integrator.sampler, scene.integrator.seed);
        let mut cam = Vec::with_capacity(16);
        let tile = sums.tile;
        for (pixel, acc) in tile.pixels().zip(sums.pixels.iter_mut()) {
            sampler.start_pixel_sample(pixel, self.k);
            let (ray, fw) = camera_ray(scene, ctx.camera, pixel, &mut sampler);
            ctx.camera_subpath(ray, d + 2, &mut sampler, &mut stats, &mut cam);
            let lig = self.paths[(pixel.y * w + pixel.x) as usize];
            let mut l = Spectrum::ZERO;
            for t in 2..=cam.len() {
                // Connections to this pixel's light subpath (light tracing was the light pass's;
                // s = 1 samples its own light point, whether or not the subpath started).
                for s in 0..=lig.len().max(1) {
                    if s + t - 2 > d {
                        continue;
                    }
                    let (c, raster) =
                        ctx.connect(lig, &cam, s, t, self.merge, &mut sampler, &mut stats);
                    match raster {
                        Some(at) => self.splats.add(scene, at, c),
                        None => l += c,
                    }
                }
                l += self.merge_at(&cam, t);
            }
            stats.samples += 1;
            let l = l * ctx.camera.exposure;
            if !l.is_finite() {
                stats.nonfinite += 1;
                continue;
            }
            acc.add(fw, l, None);
        }
        stats
    }

    /// Merges at camera vertex t − 1 with every light vertex within r, MIS-weighted.
    fn merge_at(&self, cam: &[Vertex], t: usize) -> Spectrum {
        let ctx = self.ctx;
        let x = &cam[t - 1];
        if x.delta || !ctx.connectible(x) {
            return Spectrum::ZERO;
        }
        let d = self.vcm.max_depth as usize;
        let mut l = Spectrum::ZERO;
        self.tree.within(x.p, self.r2, &mut |i, _| {
            let y = self.tree.get(i);
            let i = y.index as usize;
            if i + t - 2 > d {
                return;
            }
            let light = &self.paths[y.path as usize][..=i];
            let v = &light[i];
            // (f is zero for light arriving on the other side of x's surface.)
            let f = ctx.f_dir(x, v.wo, TransportMode::Radiance);
            if is_black(f) {
                return;
            }
            let w = merge_weight(ctx, light, &cam[..t], self.merge);
            l += x.beta * f * v.beta * (w / self.merge);
        });
        l
    }
}

/// The power-heuristic weight of merging camera vertex x = `cam[t − 1]` with light vertex
/// y = `light[i]` (i ≥ 1), over every connection and merge that makes the path z =
/// `light[..i]`, y, `cam[t − 2]` … `cam[0]` (y standing in for x). Each z_j has its density
/// sampled from the light side (p→) and from the eye side (p←), as its subpath stored them;
/// those the join changes are evaluated at y — except what a specular `cam[t − 2]` samples,
/// which can only be x: those stay the camera subpath's. Connection s (light vertices z_0 …
/// z_{s−1}) has density P_s = Π_{j<s} p→(z_j) Π_{s≤j<n} p←(z_j), z_n the lens; merging at
/// z_j, P_{j+1} p←(z_j) η π r². Specular vertices carry the delta convention of
/// [`Ctx::delta_lobe`], so the chain S D S of a caustic seen through glass weighs right.
fn merge_weight(ctx: &Ctx, light: &[Vertex], cam: &[Vertex], merge: f32) -> f32 {
    let (i, t) = (light.len() - 1, cam.len());
    let n = i + t - 1;
    let (x, y, c) = (&cam[t - 1], &light[i], &cam[t - 2]);
    let before = (t >= 3).then(|| &cam[t - 3]);
    // y's neighbours sampled from y, and y and c's predecessor sampled from c.
    let to_light = ctx.pdf(y, Some(c), &light[i - 1]);
    let to_eye = before.map_or(0.0, |_| ctx.pdf(y, Some(&light[i - 1]), c));
    let (at_y, past_c) = if c.delta {
        (x.pdf_fwd, before.map_or(0.0, |b| b.pdf_rev))
    } else {
        (
            ctx.pdf(c, before, y),
            before.map_or(0.0, |b| ctx.pdf(c, Some(y), b)),
        )
    };
    // (p→, p←, specular) of z_j; a zero density (a film edge, a neighbour behind y's
    // surface) counts as 1, as in BDPT's weights (pbrt's remap), so that connections and
    // merges weigh each path alike.
    let z_raw = |j: usize| -> (f32, f32, bool) {
        if j < i {
            let v = &light[j];
            let rev = if j + 1 == i { to_light } else { v.pdf_rev };
            (v.pdf_fwd, rev, v.delta)
        } else if j == i {
            (y.pdf_fwd, at_y, false)
        } else {
            let v = &cam[n - j];
            let fwd = match j - i {
                1 => to_eye,
                2 => past_c,
                _ => v.pdf_rev,
            };
            (fwd, v.pdf_fwd, v.delta)
        }
    };
    let one = |p: f32| if p == 0.0 { 1.0 } else { p };
    let z = |j: usize| -> (f32, f32, bool) {
        let (fwd, rev, delta) = z_raw(j);
        (one(fwd), one(rev), delta)
    };
    let delta_light = ctx.is_delta_light(&light[0]);
    // Connection s needs non-specular ends (and s = 0, a camera path hitting the light, an
    // area light).
    let joins = |s: usize| {
        let light_end = if s == 0 { !delta_light } else { !z(s - 1).2 };
        light_end && (s == n || !z(s).2)
    };
    let (own_fwd, own_rev, _) = z(i);
    if own_fwd <= 0.0 || own_rev <= 0.0 {
        return 0.0;
    }
    let sq = |v: f32| v * v;
    let mut sum = 1.0f32;
    // Toward the eye: connections s = i + 1 … n and merges at z_{i+1} … z_{n−1}, as ratios
    // to this merge's density.
    let mut r = 1.0 / (own_rev * merge);
    for s in i + 1..=n {
        if joins(s) {
            sum += sq(r);
        }
        if s == n {
            break;
        }
        let (fwd, rev, delta) = z(s);
        if !delta {
            sum += sq(r * fwd * merge);
        }
        r *= fwd / rev;
    }
    // Toward the light: connections s = i … 0 and merges at z_{i−1} … z_1.
    let mut r = 1.0 / (own_fwd * merge);
    for s in (0..=i).rev() {
        if joins(s) {
            sum += sq(r);
        }
        if s == 0 {
            break;
        }
        let (fwd, rev, delta) = z(s - 1);
        if s >= 2 && !delta {
            sum += sq(r * rev * merge);
        }
        r *= rev / fwd;
    }
    if sum.is_finite() { 1.0 / sum } else { 0.0 }
}
