//! Vertex connection and merging (Georgiev, Křivánek, Davidovič & Slusallek 2012; the same
//! estimator as Hachisuka, Pantaleoni & Jensen's unified path sampling, 2012).
//!
//! Each iteration traces one light subpath per pixel first and keeps their vertices in a
//! hash grid; then each pixel's camera subpath is joined to its own light subpath by every BDPT
//! connection (vertex connection), and at each of its non-specular vertices it *merges* with
//! the light vertices of every light subpath within radius r, as photon mapping would: a light
//! vertex y near the camera vertex x stands for a path through x, with contribution
//! β_camera(x) f(x) β_light(y) / (η π r²), η the light subpaths of the iteration. Merging is
//! how specular–diffuse–specular paths (a caustic seen through glass) are found, which no
//! connection can make. Merging starts at the light subpath's second vertex after the
//! emitter ([`FIRST_MERGE`]), and only with light vertices on surfaces facing like x's
//! ([`MERGE_COS`]). One power-heuristic MIS weighs connections and merges: a merge at
//! vertex z has density p(connection sampling z from one side) × p(z from the other side) ×
//! η π r² (`Ctx::mis_sums` for connections; for merges, sums kept along each subpath, see
//! [`push_light_refs`]). The radius shrinks as r_k = r₀ k^((α−1)/2) over iterations k, so the
//! merging bias vanishes (α = 0.75, as the paper).
//!
//! Light tracing (t = 1) is done in the light pass, its splats added to the film (without
//! atomics) while the camera pass fills each pixel's film sums. The output is BDPT's
//! ([`BdptSums`], iterations as samples), and an iteration depends only on its index, so
//! ranges of iterations merge exactly like BDPT's sample ranges — in any order, on any number
//! of threads or workers.

use glam::{Vec2, Vec3, Vec3A};
use rayon::prelude::*;

use super::bdpt::{BdptSums, Ctx, FIRST_MERGE, Kind, Splats, Vertex};
use super::{RayStats, consistent};
use crate::SampleRange;
use crate::bsdf::TransportMode;
use crate::camera::Camera;
use crate::camera::camera_ray;
use crate::film::{FilmSums, TileF64, tiles};
use crate::photon::hashgrid::HashGrid;
use crate::photon::kdtree::Positioned;
use crate::sampler::hash::hash;
use crate::sampler::{PixelSampler, Sampler};
use crate::scene::Scene;
use crate::spectrum::{Spectrum, is_black};

/// Merging takes only light vertices whose surface is within 60° of the camera vertex's
/// (|cos| of the geometric normals at least this): the merging disc lies in x's tangent plane,
/// and without the test a disc near a corner takes light arriving on the other wall, a bias
/// seen as a brighter room lit around corners (docs/src/benchmarks/speed-vs-error.md). As r → 0 a disc meets
/// another surface only ever closer to an edge, a vanishing area, so the estimate stays
/// consistent.
const MERGE_COS: f32 = 0.5;

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
        let ctx = Ctx::new(scene, camera, self.rr_depth);
        let (w, h) = (scene.film.width, scene.film.height);
        let mut splats = Splats::new(w, h);
        // Each pixel's samples are added by one thread in iteration order: f64 sums are as
        // deterministic as fixed point here, at 32 bytes a pixel.
        let mut film: Vec<TileF64> = tiles(w, h, 16).into_iter().map(TileF64::new).collect();
        let mut stats = RayStats::default();
        let mut light = LightPaths::new(w * h);
        for k in range.start..range.end {
            stats.add(&self.iteration(&ctx, k, &mut light, &mut film, &mut splats));
            progress(w as u64 * h as u64);
        }
        let sums: Vec<FilmSums> = film.iter().map(TileF64::to_sums).collect();
        Ok((BdptSums::gather(w, h, range, &sums, &splats), stats))
    }

    /// Iteration `k`: the light pass (subpaths, light tracing, the merge grid), then the
    /// camera pass into `film`.
    fn iteration(
        &self,
        ctx: &Ctx,
        k: u32,
        light: &mut LightPaths,
        film: &mut [TileF64],
        splats: &mut Splats,
    ) -> RayStats {
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
        light.chunks.par_iter_mut().enumerate().for_each_init(
            || {
                (
                    PixelSampler::new(scene.integrator.sampler, seed),
                    Vec::new(),
                )
            },
            |(sampler, path), (c, chunk)| {
                chunk.clear();
                let first = c as u32 * CHUNK;
                for j in first..(first + CHUNK).min(w * h) {
                    sampler.start_pixel_sample(glam::UVec2::new(j % w, j / w), k);
                    ctx.light_subpath(d + 1, sampler, &mut chunk.stats, path);
                    for s in 2..=path.len() {
                        let (c, raster) =
                            ctx.connect(path, &lens, s, 1, merge, sampler, &mut chunk.stats);
                        if let Some(at) = raster
                            && !is_black(c)
                        {
                            chunk.splats.push((at, c));
                        }
                    }
                    push_light_refs(ctx, path, merge, &mut chunk.refs);
                    let start = chunk.vertices.len() as u32;
                    chunk.vertices.extend_from_slice(path);
                    chunk.spans.push((start, chunk.vertices.len() as u32));
                }
            },
        );
        let mut stats = RayStats::default();
        for chunk in &light.chunks {
            stats.add(&chunk.stats);
        }
        // The light-tracing splats go in on one thread (plain adds, no atomics) while the
        // others build the merge grid and run the camera pass, which reads neither.
        let light = &*light;
        let ((), per_tile) = rayon::join(
            || {
                for &(at, c) in light.chunks.iter().flat_map(|c| &c.splats) {
                    splats.add_mut(scene, at, c);
                }
            },
            || {
                let grid = HashGrid::build(light.chunks.iter().flat_map(|c| &c.refs), r);
                let pass = CameraPass {
                    ctx,
                    vcm: self,
                    k,
                    r2: r * r,
                    merge,
                    grid: &grid,
                    light,
                };
                film.par_iter_mut()
                    .map(|t| pass.tile(t))
                    .collect::<Vec<RayStats>>()
            },
        );
        for st in &per_tile {
            stats.add(st);
        }
        stats
    }
}

/// Pixels per chunk of the light pass.
const CHUNK: u32 = 256;

/// An iteration's light subpaths, one per pixel, by chunks of consecutive pixels; the
/// buffers are kept from one iteration to the next (no allocation per path).
struct LightPaths {
    chunks: Vec<LightChunk>,
}

#[derive(Default)]
struct LightChunk {
    /// The chunk's subpaths one after another; `spans` gives each pixel's.
    vertices: Vec<Vertex>,
    spans: Vec<(u32, u32)>,
    refs: Vec<LightRef>,
    /// Light tracing's splats: where on the film, what.
    splats: Vec<(Vec2, Spectrum)>,
    stats: RayStats,
}

impl LightChunk {
    fn clear(&mut self) {
        self.vertices.clear();
        self.spans.clear();
        self.refs.clear();
        self.splats.clear();
        self.stats = RayStats::default();
    }
}

impl LightPaths {
    fn new(pixels: u32) -> Self {
        LightPaths {
            chunks: (0..pixels.div_ceil(CHUNK))
                .map(|_| LightChunk::default())
                .collect(),
        }
    }

    /// The light subpath of pixel `j` (row-major).
    fn path(&self, j: u32) -> &[Vertex] {
        let chunk = &self.chunks[(j / CHUNK) as usize];
        let (a, b) = chunk.spans[(j % CHUNK) as usize];
        &chunk.vertices[a as usize..b as usize]
    }
}

/// A light vertex in the merge grid, with what merging at it reads (light subpaths are not
/// revisited): its incoming direction, throughput, depth, and the light side's share of a
/// merge's MIS sum, `a + b p²` (p the merging camera vertex's density of sampling `wo`; see
/// [`push_light_refs`]).
#[derive(Debug, Clone, Copy)]
struct LightRef {
    p: Vec3,
    /// Scattering events before it (its index on the light subpath).
    depth: u32,
    /// Toward the previous vertex of its subpath: the direction light arrives from.
    wo: Vec3A,
    beta: Spectrum,
    /// Geometric normal of its surface.
    ng: Vec3A,
    a: f32,
    b: f32,
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
    grid: &'a HashGrid<LightRef>,
    light: &'a LightPaths,
}

impl CameraPass<'_> {
    fn tile(&self, sums: &mut TileF64) -> RayStats {
        let ctx = self.ctx;
        let scene = ctx.scene;
        let w = scene.film.width;
        let d = self.vcm.max_depth as usize;
        let mut stats = RayStats::default();
        let mut sampler = PixelSampler::new(scene.integrator.sampler, scene.integrator.seed);
        let mut cam = Vec::with_capacity(16);
        let tile = sums.tile;
        sums.samples += 1;
        for (k, pixel) in tile.pixels().enumerate() {
            sampler.start_pixel_sample(pixel, self.k);
            let (ray, fw) = camera_ray(scene, ctx.camera, pixel, &mut sampler);
            ctx.camera_subpath(ray, d + 2, &mut sampler, &mut stats, &mut cam);
            let lig = self.light.path(pixel.y * w + pixel.x);
            let mut l = Spectrum::ZERO;
            let mut toward_eye = 0.0;
            for t in 2..=cam.len() {
                // Connections to this pixel's light subpath (light tracing was the light pass's;
                // s = 1 samples its own light point, whether or not the subpath started).
                for s in 0..=lig.len().max(1) {
                    if s + t - 2 > d {
                        continue;
                    }
                    // (Only light tracing, t = 1, lands elsewhere on the film.)
                    let (c, _) = ctx.connect(lig, &cam, s, t, self.merge, &mut sampler, &mut stats);
                    l += c;
                }
                if t >= 3 {
                    toward_eye = eye_sum(&cam, t - 3, toward_eye, self.merge);
                }
                l += self.merge_at(&cam, t, toward_eye);
            }
            stats.samples += 1;
            let mut l = l * ctx.camera.exposure;
            if !l.is_finite() {
                stats.nonfinite += 1;
                l = Spectrum::ZERO;
            }
            sums.add(k, fw, l);
        }
        stats
    }

    /// Merges at camera vertex x = `cam[t − 1]` with every light vertex y within r, weighted
    /// by the power heuristic over every connection and merge that makes the same path (y
    /// standing in for x). As SmallVCM, the densities the join changes are evaluated at x:
    /// x's BSDF density of sampling y's incoming direction (toward the light) and of
    /// sampling the direction to `cam[t − 2]` given it (toward the eye), the camera subpath's
    /// own densities for x and its predecessors. The rest are sums along each subpath, kept
    /// with the light vertex ([`push_light_refs`]) and carried along the camera subpath
    /// (`toward_eye`, [`eye_sum`]): O(1) per merge, and exact as r → 0.
    fn merge_at(&self, cam: &[Vertex], t: usize, toward_eye: f32) -> Spectrum {
        let ctx = self.ctx;
        let x = &cam[t - 1];
        let Some(si) = x.si.as_ref().filter(|_| !x.delta && ctx.connectible(x)) else {
            return Spectrum::ZERO;
        };
        let d = self.vcm.max_depth as usize;
        let m = self.merge;
        let material = ctx.scene.material(si.material);
        let frame = material.frame(si, x.wo);
        let wo_l = frame.to_local(x.wo);
        let eye = EyeSums::new(cam, t, toward_eye, m);
        let mut l = Spectrum::ZERO;
        self.grid.within(x.p, self.r2, &mut |y| {
            if y.depth as usize + t - 2 > d {
                return;
            }
            if x.ng.dot(y.ng).abs() < MERGE_COS {
                return;
            }
            // (f is zero for light arriving on the other side of x's surface.)
            let wi_l = frame.to_local(y.wo);
            if !consistent(si, x.wo, y.wo, wo_l, wi_l) {
                return;
            }
            let bsdf = material.bsdf_at(si);
            let f = bsdf.eval(wo_l, wi_l, TransportMode::Radiance);
            if is_black(f) {
                return;
            }
            let to_light = bsdf.pdf(wo_l, wi_l, TransportMode::Radiance);
            let to_eye = bsdf.pdf(wi_l, wo_l, TransportMode::Radiance);
            let sum = merge_sum(y, &eye, to_light, to_eye);
            if sum.is_finite() {
                l += f * y.beta * (1.0 / sum);
            }
        });
        l * x.beta * (1.0 / m)
    }
}

/// The camera side's share of a merge's MIS sum at x = `cam[t − 1]`, `e0 + e1 p²` (p x's BSDF
/// density of sampling the direction to `cam[t − 2]` given the light vertex's), given W_{t−3}
/// = `toward_eye` ([`eye_sum`]): with r = 1 / (p→(x) M), c = `cam[t − 2]` and h the
/// conversion to area at c, e0 = r² [c not specular] (the connection joining y and c) and
/// e1 = r² h² ([c not specular] M² + W_{t−3} / p←(c)²) (the merge at c and on toward the eye);
/// for t = 2 (c the lens) e0 = r² (light tracing), e1 = 0.
struct EyeSums {
    e0: f32,
    e1: f32,
}

impl EyeSums {
    fn new(cam: &[Vertex], t: usize, toward_eye: f32, m: f32) -> Self {
        let x = &cam[t - 1];
        let r2 = sq(1.0 / (one(x.pdf_fwd) * m));
        if t == 2 {
            return EyeSums { e0: r2, e1: 0.0 };
        }
        let c = &cam[t - 2];
        let h = x.convert_density(1.0, c);
        let merge_c = if c.delta { 0.0 } else { sq(m) };
        EyeSums {
            e0: if c.delta { 0.0 } else { r2 },
            e1: r2 * h * h * (merge_c + toward_eye / sq(one(c.pdf_fwd))),
        }
    }
}

/// Σ_k (P_k / P_merge)² of merging light vertex `y` at a camera vertex whose BSDF samples y's
/// incoming direction with density `to_light` and, given it, the direction back toward the
/// eye with `to_eye` (solid angle): the merge itself, the light side, the camera side.
fn merge_sum(y: &LightRef, eye: &EyeSums, to_light: f32, to_eye: f32) -> f32 {
    1.0 + y.a + y.b * sq(to_light) + eye.e0 + eye.e1 * sq(to_eye)
}

/// A density as MIS weighs it: zero (a film edge, a neighbour behind a surface) counts as 1,
/// as in BDPT's weights (pbrt's remap), so that connections and merges weigh each path alike.
fn one(p: f32) -> f32 {
    if p == 0.0 { 1.0 } else { p }
}

fn sq(v: f32) -> f32 {
    v * v
}

/// The merging MIS sums of one light subpath, into `refs` with its mergeable vertices.
///
/// Write a path z_0 … z_n (z_0 on the light, z_n the lens) with densities p→(z_j) sampled from
/// the light side and p←(z_j) from the eye side; connection s (light vertices z_0 … z_{s−1})
/// has density P_s = Π_{j<s} p→(z_j) Π_{j≥s} p←(z_j), and merging at z_j, P_{j+1} p←(z_j) M
/// with M = η π r² (η light subpaths per iteration; Georgiev et al. 2012). A merge at y = z_i
/// weighs 1 / Σ_k (P_k / P_merge)² over the strategies k that make the path — connections
/// whose ends are not specular (s = 0 only on an area light), merges at non-specular vertices
/// z_j, j ≥ 2 ([`FIRST_MERGE`]). The strategies on the light side of y (connections s ≤ i,
/// merges at z_{i−1} … z_2) give, with r_i = 1 / (p→(y) M) and q = p←(z_{i−1}) the only density
/// there that the camera vertex changes,
///
///   a + b q²,   a = r_i² [z_{i−1} not specular],
///               b = r_i² ([i ≥ 3, z_{i−1} not specular] M² + T_{i−1} / p→(z_{i−1})²),
///
/// T_j the sum from connection j on toward the light with ratio 1:
/// T_0 = [the light is not a delta light], T_j = [z_{j−1}, z_j not specular] k_j + [j ≥ 3,
/// z_{j−1} not specular] (p←(z_{j−1}) M)² + (p←(z_{j−1}) / p→(z_{j−1}))² T_{j−1}, with k_1 the
/// square of z_0's [`Ctx::nee_ratio`] (P_1 picks z_0 by light sampling) and k_j = 1 after.
/// Here q = p g with p the camera vertex's BSDF density (solid angle) of y's incoming
/// direction and g the conversion to area at z_{i−1}, known now, so b holds g². Specular
/// vertices carry the delta convention of [`super::bdpt::Ctx::delta_lobe`], so the chain
/// S D S of a caustic seen through glass weighs right.
fn push_light_refs(ctx: &Ctx, path: &[Vertex], merge: f32, refs: &mut Vec<LightRef>) {
    let Some(first) = path.first() else {
        return;
    };
    let m = merge;
    let mut toward_light = if ctx.is_delta_light(first) || first.delta {
        0.0
    } else {
        1.0
    };
    for (i, pair) in path.windows(2).enumerate() {
        let (z, y, i) = (&pair[0], &pair[1], i + 1);
        let merge_z = if i > FIRST_MERGE && !z.delta {
            sq(m)
        } else {
            0.0
        };
        if i >= FIRST_MERGE && !y.delta && ctx.connectible(y) {
            let r2 = sq(1.0 / (one(y.pdf_fwd) * m));
            let g = y.convert_density(1.0, z);
            refs.push(LightRef {
                p: Vec3::from(y.p),
                depth: i as u32,
                wo: y.wo,
                beta: y.beta,
                ng: y.ng,
                a: if z.delta { 0.0 } else { r2 },
                b: r2 * g * g * (merge_z + toward_light / sq(one(z.pdf_fwd))),
            });
        }
        let (fwd, rev) = (one(z.pdf_fwd), one(z.pdf_rev));
        let join = f32::from(!z.delta && !y.delta) * if i == 1 { sq(z.nee) } else { 1.0 };
        toward_light = join + merge_z * sq(rev) + sq(rev / fwd) * toward_light;
    }
}

/// The camera side's counterpart of T (see [`push_light_refs`]), for camera vertex k (the lens
/// is 0) given W_{k−1} = `prev`: the sum from the connection whose camera end is `cam[k]` on
/// toward the eye, with ratio 1. W_0 = [cam[1] not specular]; W_k = [cam[k + 1], cam[k] not
/// specular] + [cam[k] not specular] (p→(cam[k]) M)² + (p→(cam[k]) / p←(cam[k]))² W_{k−1}, p→
/// here the density from the light side (`pdf_rev`, as the camera subpath stored it).
fn eye_sum(cam: &[Vertex], k: usize, prev: f32, merge: f32) -> f32 {
    let (v, next) = (&cam[k], &cam[k + 1]);
    if k == 0 {
        return f32::from(!next.delta);
    }
    let (fwd, rev) = (one(v.pdf_rev), one(v.pdf_fwd));
    let merge_v = if v.delta { 0.0 } else { sq(fwd * merge) };
    f32::from(!next.delta && !v.delta) + merge_v + sq(fwd / rev) * prev
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{NO_LIGHT, SurfaceInteraction};

    /// A small xorshift generator: the test's paths are the same on every run.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }

        fn density(&mut self) -> f32 {
            0.05 + 20.0 * self.next() * self.next()
        }

        fn point(&mut self) -> Vec3A {
            Vec3A::new(self.next(), self.next(), self.next()) * 10.0
        }

        fn surface(&mut self, delta: bool) -> Vertex {
            let ng = (self.point() - 5.0).normalize();
            let si = SurfaceInteraction {
                p: self.point(),
                p_error: Vec3A::ZERO,
                t: 1.0,
                ng,
                ns: ng,
                material: 0,
                light: NO_LIGHT,
                uv: [glam::Vec2::ZERO; 2],
                uv_width: [0.0; 2],
                interior: 0.0,
            };
            let mut v = Vertex::surface(si, (self.point() - 5.0).normalize());
            v.pdf_fwd = self.density();
            v.pdf_rev = self.density();
            v.delta = delta;
            v
        }
    }

    /// The O(1) merge weight — sums kept along the light subpath ([`push_light_refs`]) and the
    /// camera subpath ([`eye_sum`], [`EyeSums`]) — equals the power heuristic written out:
    /// P_merge² / Σ_k P_k² over every connection and merge of the path, each P_k the product of
    /// the path's densities (f64), for random densities, specular flags, depths and M.
    #[test]
    fn merge_weights_are_the_power_heuristic_over_every_strategy() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
        let desc = tessera_scene::load(&root.join("cornell-box/scene.json")).expect("scene");
        let scene = Scene::build(&desc);
        let camera = Camera::new(&desc.camera, &desc.film);
        let ctx = Ctx::new(&scene, &camera, 5);
        assert!(scene.material(0).flags.smooth, "material 0 is diffuse");
        let mut rng = Rng(0x2545_f491_4f6c_dd1d);
        let mut specular = 0;
        for trial in 0..4000 {
            let i = 2 + (rng.next() * 5.0) as usize;
            let t = 2 + (rng.next() * 5.0) as usize;
            let m = 10f32.powf(rng.next() * 5.0 - 2.0);
            let mut light = vec![Vertex::point(
                Kind::Light(0),
                rng.point(),
                Vec3A::ZERO,
                Vec3A::Y,
                Spectrum::ONE,
                rng.density(),
            )];
            light[0].pdf_rev = rng.density();
            // Light sampling's density of z_0 over the light subpath's (a sphere's cone).
            light[0].nee = 0.25 + 4.0 * rng.next();
            for j in 1..=i {
                let delta = j < i && rng.next() < 0.3;
                light.push(rng.surface(delta));
            }
            let mut cam = vec![Vertex::point(
                Kind::Camera,
                rng.point(),
                Vec3A::ZERO,
                Vec3A::ZERO,
                Spectrum::ONE,
                0.0,
            )];
            for k in 1..t {
                let delta = k < t - 1 && rng.next() < 0.3;
                cam.push(rng.surface(delta));
            }
            specular += light.iter().chain(&cam).any(|v| v.delta) as u32;
            let mut refs = Vec::new();
            push_light_refs(&ctx, &light, m, &mut refs);
            let y = refs.last().expect("y is mergeable");
            assert_eq!(y.depth as usize, i);
            let toward_eye = (0..t.saturating_sub(2)).fold(0.0, |w, k| eye_sum(&cam, k, w, m));
            let eye = EyeSums::new(&cam, t, toward_eye, m);
            let (to_light, to_eye) = (rng.density(), rng.density());
            let ours = 1.0 / merge_sum(y, &eye, to_light, to_eye) as f64;

            // The merged path z_0 … z_n: light[..i], x standing for y, cam[t − 2] … cam[0].
            let n = i + t - 1;
            let x = &cam[t - 1];
            let g = light[i].convert_density(1.0, &light[i - 1]) as f64;
            let h = x.convert_density(1.0, &cam[t - 2]) as f64;
            let (mut fwd, mut rev, mut delta) = (vec![0.0f64; n], vec![0.0f64; n], vec![false; n]);
            for j in 0..n {
                (fwd[j], rev[j], delta[j]) = if j < i {
                    let v = &light[j];
                    let r = if j + 1 == i {
                        to_light as f64 * g
                    } else {
                        v.pdf_rev as f64
                    };
                    (v.pdf_fwd as f64, r, v.delta)
                } else if j == i {
                    (light[i].pdf_fwd as f64, x.pdf_fwd as f64, false)
                } else {
                    let v = &cam[n - j];
                    let f = if j == i + 1 {
                        to_eye as f64 * h
                    } else {
                        v.pdf_rev as f64
                    };
                    (f, v.pdf_fwd as f64, v.delta)
                };
            }
            let nee = |s: usize| if s == 1 { light[0].nee as f64 } else { 1.0 };
            let p = |s: usize| {
                nee(s) * fwd[..s].iter().product::<f64>() * rev[s..].iter().product::<f64>()
            };
            let joins = |s: usize| (s == 0 || !delta[s - 1]) && (s == n || !delta[s]);
            let merge = |j: usize| p(j + 1) * rev[j] * m as f64;
            let own = merge(i);
            let total = (0..=n)
                .filter(|&s| joins(s))
                .map(|s| (p(s) / own).powi(2))
                .sum::<f64>()
                + (FIRST_MERGE..n)
                    .filter(|&j| !delta[j])
                    .map(|j| (merge(j) / own).powi(2))
                    .sum::<f64>();
            let want = 1.0 / total;
            assert!(
                (ours - want).abs() <= 1e-4 * want + 1e-9,
                "trial {trial}: i = {i}, t = {t}, M = {m}: O(1) weight {ours:e}, power heuristic {want:e}"
            );
        }
        assert!(specular > 1000, "{specular} paths with specular vertices");
    }
}
