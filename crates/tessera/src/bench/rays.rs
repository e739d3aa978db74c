//! `tessera bench rays [SCENE...]`: ray casting throughput of the renderer's BVH on one core,
//! closest-hit and occlusion queries, for coherent and incoherent rays.
//!
//! For a scene file the coherent rays are its camera's, one per pixel of a `--size` film in
//! 16 × 16 tiles (the order a tile renderer casts them); the incoherent rays leave each camera
//! ray's hit in a uniformly random direction of the hemisphere facing the camera (the rays of a
//! path's next bounce). Without scenes: the Cornell box, Cornell glass and a generated height
//! field of 2 M triangles, whose coherent rays are a grid of parallel rays from above and whose
//! incoherent rays start at random points above it and point almost straight down in random
//! directions (the memory-bound case of the shared BENCHMARKS.md).
//!
//! Each query runs over the whole ray set `--repeat` times; the best run counts (these machines
//! are noisy). Built with `--features embree` (Debian's libembree-dev, Embree 3), the same rays
//! go through Embree's BVH too, for triangle-only scenes: one at a time, and in packets of eight
//! consecutive rays (what a wavefront path tracer's ray batches could gain).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use glam::{Vec2, Vec3A};
use tessera_render::camera::Camera;
use tessera_render::geometry::Accel;
use tessera_render::math::offset_ray_origin;
use tessera_render::ray::Ray;
use tessera_render::sampler::hash::{mix64, u32_to_unit};
use tessera_render::sampling::square_to_uniform_sphere;

#[derive(clap::Args)]
pub struct RaysArgs {
    /// Scene files (default: the repository's Cornell box and Cornell glass, and a generated
    /// 2 M-triangle height field).
    pub scenes: Vec<PathBuf>,
    /// Film size WxH of the camera rays (default 1024x1024).
    #[arg(long)]
    pub size: Option<crate::render::Size>,
    /// Runs of each query; the fastest counts.
    #[arg(long, default_value_t = 3)]
    pub repeat: u32,
}

/// A BVH with its two ray sets.
struct Case {
    name: String,
    accel: Accel,
    coherent: Vec<Ray>,
    incoherent: Vec<Ray>,
}

/// One query over one ray set: Mrays/s and how many rays hit.
#[derive(Clone, Copy, PartialEq)]
struct Rate {
    mrays: f64,
    hits: usize,
}

/// The four measurements of a row: closest hit and occlusion, coherent and incoherent rays.
type Row = [Rate; 4];

/// Measures `closest` and `occluded` over both ray sets of `case`.
fn measure(
    case: &Case,
    repeat: u32,
    closest: impl Fn(&Ray) -> bool,
    occluded: impl Fn(&Ray) -> bool,
) -> Row {
    let query = |rays: &[Ray], q: &dyn Fn(&Ray) -> bool| {
        rate(rays.len(), repeat, || rays.iter().filter(|r| q(r)).count())
    };
    [
        query(&case.coherent, &closest),
        query(&case.coherent, &occluded),
        query(&case.incoherent, &closest),
        query(&case.incoherent, &occluded),
    ]
}

pub fn run(args: RaysArgs) -> anyhow::Result<()> {
    let crate::render::Size([w, h]) = args.size.unwrap_or(crate::render::Size([1024, 1024]));
    let repeat = args.repeat.max(1);
    let mut cases = Vec::new();
    if args.scenes.is_empty() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        for scene in [
            "scenes/cornell-box/scene.json",
            "scenes/cornell-glass/scene.json",
        ] {
            cases.push(scene_case(&root.join(scene), w, h)?);
        }
        cases.push(height_field(w, h));
    } else {
        for scene in &args.scenes {
            cases.push(scene_case(scene, w, h)?);
        }
    }
    println!(
        "one thread; Mrays/s (best of {repeat}); coherent: camera rays ({w}x{h}, 16x16 tiles); \
         incoherent: random bounce rays from their hits (height field: random near-vertical rays); \
         BVH node test: {}",
        if tessera_render::geometry::bvh8::avx_available() {
            "eight boxes at once (AVX)"
        } else {
            "two groups of four boxes (SSE)"
        }
    );
    println!();
    let mut header = "| scene | triangles | spheres | BVH nodes, blocks | rays | coherent closest | coherent occluded | incoherent closest | incoherent occluded |".to_string();
    let mut rule = "|---|---:|---:|---:|---:|---:|---:|---:|---:|".to_string();
    if cfg!(feature = "embree") {
        header += " Embree 3: coherent closest | coherent occluded | incoherent closest | incoherent occluded |";
        header += " Embree 3, packets of 8: coherent closest | coherent occluded | incoherent closest | incoherent occluded |";
        rule += "---:|---:|---:|---:|---:|---:|---:|---:|";
    }
    println!("{header}\n{rule}");
    for case in &cases {
        let ours = measure(
            case,
            repeat,
            |r| case.accel.intersect(r, f32::INFINITY).is_some(),
            |r| case.accel.occluded(r, f32::INFINITY),
        );
        let (nodes, blocks) = case.accel.triangle_bvh_size();
        let row = format!(
            "| {} | {} | {} | {nodes}, {blocks} | {} + {} |{}",
            case.name,
            case.accel.triangle_count(),
            case.accel.sphere_count(),
            case.coherent.len(),
            case.incoherent.len(),
            labelled(&ours, &ours),
        );
        #[cfg(feature = "embree")]
        let row = row + &embree_columns(case, repeat, &ours)?;
        println!("{row}");
    }
    Ok(())
}

/// The row's Embree columns: the same rays through Embree's BVH (triangle scenes only). Where
/// Embree's hit counts differ from ours, the count follows its figure.
#[cfg(feature = "embree")]
fn embree_columns(case: &Case, repeat: u32, ours: &Row) -> anyhow::Result<String> {
    if case.accel.sphere_count() > 0 {
        return Ok(" — | — | — | — |".repeat(2));
    }
    let scene = super::embree::Scene::new(&case.accel.triangles())?;
    let single = measure(case, repeat, |r| scene.intersect(r), |r| scene.occluded(r));
    let packet = packets(
        case,
        repeat,
        |p, coherent| scene.intersect8(p, coherent),
        |p, coherent| scene.occluded8(p, coherent),
    );
    Ok(labelled(&single, ours) + &labelled(&packet, ours))
}

/// The row's figures, each with its hit count where that differs from ours.
fn labelled(row: &Row, ours: &Row) -> String {
    row.iter()
        .zip(ours)
        .map(|(t, o)| {
            if t.hits == o.hits {
                format!(" {:.2} |", t.mrays)
            } else {
                format!(" {:.2} ({} hits, ours {}) |", t.mrays, t.hits, o.hits)
            }
        })
        .collect()
}

/// A query over `rays` in packets of eight consecutive rays: neighbouring pixels of a tile
/// row, or their bounces. `q` returns how many of a packet's rays hit.
#[cfg(feature = "embree")]
fn packet_rate(rays: &[Ray], repeat: u32, q: &dyn Fn(&[Ray]) -> usize) -> Rate {
    rate(rays.len(), repeat, || rays.chunks(8).map(q).sum())
}

/// [`measure`] for packet queries, which are told whether the rays are the coherent set.
#[cfg(feature = "embree")]
fn packets(
    case: &Case,
    repeat: u32,
    closest: impl Fn(&[Ray], bool) -> usize,
    occluded: impl Fn(&[Ray], bool) -> usize,
) -> Row {
    [
        packet_rate(&case.coherent, repeat, &|p| closest(p, true)),
        packet_rate(&case.coherent, repeat, &|p| occluded(p, true)),
        packet_rate(&case.incoherent, repeat, &|p| closest(p, false)),
        packet_rate(&case.incoherent, repeat, &|p| occluded(p, false)),
    ]
}

/// The fastest of `repeat` runs of `f` over `n` rays; `f` returns how many hit.
fn rate(n: usize, repeat: u32, f: impl Fn() -> usize) -> Rate {
    let mut best = f64::INFINITY;
    let mut hits = 0;
    for _ in 0..repeat {
        let t = Instant::now();
        hits = std::hint::black_box(f());
        best = best.min(t.elapsed().as_secs_f64());
    }
    Rate {
        mrays: n as f64 / best / 1e6,
        hits,
    }
}

/// Two uniform numbers in [0, 1) from index `i`.
fn unit2(i: u64) -> Vec2 {
    let h = mix64(i ^ 0xbe7c);
    Vec2::new(u32_to_unit(h as u32), u32_to_unit((h >> 32) as u32))
}

/// Pixel centres of a `w` × `h` film in 16 × 16 tiles, each tile row by row.
fn tiled_pixels(w: u32, h: u32) -> impl Iterator<Item = (u32, u32)> {
    let tile = 16;
    (0..h.div_ceil(tile)).flat_map(move |ty| {
        (0..w.div_ceil(tile)).flat_map(move |tx| {
            (ty * tile..((ty + 1) * tile).min(h))
                .flat_map(move |y| (tx * tile..((tx + 1) * tile).min(w)).map(move |x| (x, y)))
        })
    })
}

/// Bounce rays: from each coherent ray's hit, a uniformly random direction on the side the
/// ray came from.
fn bounces(accel: &Accel, coherent: &[Ray]) -> Vec<Ray> {
    coherent
        .iter()
        .enumerate()
        .filter_map(|(i, r)| {
            let hit = accel.intersect(r, f32::INFINITY)?;
            let n = if hit.n.dot(r.d) < 0.0 { hit.n } else { -hit.n };
            let mut d = square_to_uniform_sphere(unit2(i as u64));
            if d.dot(n) < 0.0 {
                d = -d;
            }
            Some(Ray::new(offset_ray_origin(hit.p, hit.p_error, n, d), d))
        })
        .collect()
}

fn scene_case(path: &Path, w: u32, h: u32) -> anyhow::Result<Case> {
    let mut desc = tessera_scene::load(path).with_context(|| format!("{}", path.display()))?;
    (desc.film.width, desc.film.height) = (w, h);
    let scene = tessera_render::Scene::build(&desc);
    let camera = Camera::new(&desc.camera, &desc.film);
    let coherent: Vec<Ray> = tiled_pixels(w, h)
        .map(|(x, y)| camera.generate_ray(Vec2::new(x as f32 + 0.5, y as f32 + 0.5), Vec2::ZERO))
        .collect();
    let accel = scene.into_accel();
    let incoherent = bounces(&accel, &coherent);
    let name = path.parent().and_then(|p| p.file_name()).map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    Ok(Case {
        name,
        accel,
        coherent,
        incoherent,
    })
}

/// A 1000 × 1000 grid height field: 2 M triangles over [0, 1000]², heights up to 50.
fn height_field(w: u32, h: u32) -> Case {
    let n = 1000usize;
    let height = |x: usize, z: usize| {
        let (x, z) = (x as f32, z as f32);
        20.0 * (x * 0.05).sin() * (z * 0.043).cos() + 10.0 * (x * 0.31 + z * 0.17).sin() + 25.0
    };
    let v = |x: usize, z: usize| Vec3A::new(x as f32, height(x, z), z as f32);
    let mut tris = Vec::with_capacity(2 * n * n);
    for z in 0..n {
        for x in 0..n {
            tris.push([v(x, z), v(x + 1, z), v(x + 1, z + 1)]);
            tris.push([v(x, z), v(x + 1, z + 1), v(x, z + 1)]);
        }
    }
    let accel = Accel::build(&tris, &[]);
    let down = Vec3A::new(0.1, -1.0, 0.07).normalize();
    let coherent = tiled_pixels(w, h)
        .map(|(x, y)| {
            let o = Vec3A::new(
                (x as f32 + 0.5) * 1000.0 / w as f32,
                100.0,
                (y as f32 + 0.5) * 1000.0 / h as f32,
            );
            Ray::new(o, down)
        })
        .collect::<Vec<_>>();
    let incoherent = (0..coherent.len() as u64)
        .map(|i| {
            let a = unit2(2 * i);
            let b = unit2(2 * i + 1);
            let o = Vec3A::new(a.x * 1000.0, 100.0, a.y * 1000.0);
            let d = Vec3A::new((b.x - 0.5) * 0.2, -1.0, (b.y - 0.5) * 0.2).normalize();
            Ray::new(o, d)
        })
        .collect();
    Case {
        name: "height field".into(),
        accel,
        coherent,
        incoherent,
    }
}
