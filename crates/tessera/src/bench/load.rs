//! `tessera bench load SCENE`: how long a scene takes to read, to build its BVH and lights,
//! and to give its first pixels, and the memory it takes — for production-size scenes (a glTF
//! of millions of triangles, e.g. from `scripts/gltf/make_dense.py`).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use tessera_render::camera::Camera;
use tessera_render::film::{SampleRange, Tile};

#[derive(clap::Args)]
pub struct LoadArgs {
    /// The scene: a scene.json, or a .glb/.gltf.
    pub scene: PathBuf,
    /// Film size WxH for the first tile's camera (default: the scene's).
    #[arg(long)]
    pub size: Option<crate::render::Size>,
}

pub fn run(args: LoadArgs) -> anyhow::Result<()> {
    let bytes = std::fs::metadata(&args.scene)
        .with_context(|| format!("{}", args.scene.display()))?
        .len();
    let start = Instant::now();
    let mut desc = tessera_scene::load(&args.scene)?;
    let load_s = start.elapsed().as_secs_f64();
    if let Some(crate::render::Size([w, h])) = args.size {
        (desc.film.width, desc.film.height) = (w, h);
    }
    let rss_loaded = crate::render::peak_rss_mib();
    let building = Instant::now();
    let scene = tessera_render::Scene::build(&desc);
    let build_s = building.elapsed().as_secs_f64();
    let camera = Camera::new(&desc.camera, &desc.film);
    let integrator = tessera_render::method::for_scene(&desc, &scene)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.scene.display()))?;
    // The tile at the film's centre, one sample per pixel: the first pixels a user sees.
    let (w, h) = (desc.film.width, desc.film.height);
    let side = 32.min(w).min(h);
    let (x0, y0) = ((w - side) / 2, (h - side) / 2);
    let tile = Tile {
        x0,
        y0,
        x1: x0 + side,
        y1: y0 + side,
    };
    let tile_once = || {
        let t = Instant::now();
        let (_, stats) = tessera_render::render::render_tile(
            &scene,
            &camera,
            integrator.as_ref(),
            tile,
            SampleRange { start: 0, end: 1 },
        );
        (t.elapsed().as_secs_f64(), stats)
    };
    // The first time includes what is built once per process on first use (BRDF tables).
    let (first_s, stats) = tile_once();
    let (again_s, _) = tile_once();
    let s = &scene.stats;
    println!(
        "{}: {:.1} MiB file, {} triangles, {} spheres, {} lights ({} emissive triangles)",
        args.scene.display(),
        bytes as f64 / (1 << 20) as f64,
        s.triangles,
        s.spheres,
        s.lights,
        s.emissive_triangles
    );
    println!(
        "textures {:.1} MiB (mip-map pyramids)",
        s.texture_bytes as f64 / (1 << 20) as f64
    );
    println!("load (read, decode, validate, flatten) {load_s:.2} s");
    println!("build (BVH, lights) {build_s:.2} s");
    println!(
        "first {side}×{side} tile at 1 spp {first_s:.3} s, again {again_s:.3} s ({} rays)",
        stats.rays
    );
    println!(
        "to first pixels {:.2} s; peak resident memory {} after load, {} in all",
        load_s + build_s + first_s,
        rss_loaded.map_or("?".into(), |m| format!("{m:.0} MiB")),
        crate::render::peak_rss_mib().map_or("?".into(), |m| format!("{m:.0} MiB"))
    );
    for w in &desc.warnings {
        println!("warning: {w}");
    }
    Ok(())
}
