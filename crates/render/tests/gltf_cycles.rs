//! A glTF file written by Blender's exporter, rendered by Tessera, against the same Blender
//! scene rendered by Cycles: someone else's importer-free answer. What it checks is the whole
//! way in — node transforms, the camera, spot and point lights converted from Blender's watts
//! to candela by the exporter and back by us, emission strength, Lambertian materials.
//!
//! `scenes/gltf/diffuse-shot/` was made by `scripts/blender/diffuse_shot.py
//! scenes/gltf/diffuse-shot --spp 2048 --size 160x90` (Blender 5.0.1 from PyPI: `bpy`):
//! `diffuse-shot.glb` is the export, `cycles.exr` Cycles' path-traced render (no denoiser,
//! Standard view transform, linear EXR, 2048 spp). `scenes/gltf/textured-shot/` likewise with
//! `--textured`: an sRGB board texture on the floor and a picture on the wall, embedded PNGs.

use std::path::Path;

mod common;

use common::render_by_method;
use tessera_render::read_exr;

const SPP: u32 = 256;

fn scenes() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes")
}

#[test]
fn blenders_export_renders_as_cycles_renders_the_blender_scene() {
    let dir = scenes().join("gltf/diffuse-shot");
    agrees_with_cycles(&dir.join("diffuse-shot.glb"), "path", 2048, 0.01, 0.02, 1.5);
}

/// Two known differences, both systematic, widen the tolerances here. The normal-mapped wall
/// comes out 1.3–2.2 % brighter than Cycles' (4×4 blocks at 1024 spp): Cycles flattens a
/// bumped normal that would reflect the view below the surface (its
/// `ensure_valid_reflection`); we keep it, and drop only the light its shading and geometric
/// normals disagree on. The board texture on the floor is 0.4 % brighter: Cycles interpolates
/// 8-bit sRGB texels before decoding them, we decode first. Without the normal map the
/// relMSE away from edges was 1.4× the noise's prediction, with it 1.7×.
#[test]
fn blenders_textured_export_renders_as_cycles_renders_the_blender_scene() {
    let dir = scenes().join("gltf/textured-shot");
    agrees_with_cycles(
        &dir.join("textured-shot.glb"),
        "path",
        2048,
        0.01,
        0.035,
        2.0,
    );
}

/// The Blender interior (`scenes/gltf-interior/`, `scripts/blender/interior.py --spp 4096
/// --size 192x108`): textures, a normal-mapped wall, a spot and a point light, gold and glass
/// spheres, the sky through a window (the world's environment texture in Blender, the glTF
/// scene's extras for us), Cycles at 4096 spp.
///
/// Rendered by BDPT: light from the spot reflected by the gold sphere onto the walls is a
/// caustic that path tracing (ours, and Cycles') finds only by chance, in fireflies that
/// swing a quarter of the image by a quarter at 256 spp. Known, systematic differences: the
/// spot's edge (Blender's exporter writes its blend as an inner cone; Cycles fades with a
/// smoothstep over its own blend width, we with pbrt's smoothstep from the inner to the outer
/// cone) darkens the blocks around the pedestal by 2–4 %, and the normal-mapped wall is
/// brighter as in the textured shot.
#[test]
fn blenders_interior_renders_as_cycles_renders_the_blender_scene() {
    let dir = scenes().join("gltf-interior");
    agrees_with_cycles(&dir.join("scene.glb"), "bdpt", 4096, 0.02, 0.06, 1.5);
}

/// Tessera's render of the glTF file `glb` against Cycles' render of the Blender scene beside
/// it (`cycles.exr`, `reference_spp` samples per pixel): the image mean within
/// `mean_tolerance`, each of 4×4 blocks within `block_tolerance`, and the relMSE away from
/// edges at most `noise_factor` times what the two renders' noise explains.
fn agrees_with_cycles(
    glb: &Path,
    method: &str,
    reference_spp: u32,
    mean_tolerance: f64,
    block_tolerance: f64,
    noise_factor: f64,
) {
    let desc = tessera_scene::load(glb).unwrap_or_else(|e| panic!("{e}"));
    // Blender's glass is closed and written without KHR_materials_volume: solid, as in
    // Cycles, with a warning saying so; nothing else may be left unread.
    assert!(
        desc.warnings
            .iter()
            .all(|w| w.contains("rendered solid on them")),
        "{:?}",
        desc.warnings
    );
    desc_agrees_with_cycles(
        desc,
        glb,
        method,
        reference_spp,
        mean_tolerance,
        block_tolerance,
        noise_factor,
    );
}

/// The same textured Blender scene through Blender's OBJ exporter (`diffuse_shot.py
/// --textured --obj`: OBJ + MTL, PNG textures beside it, the normal map as `map_Bump`), its
/// materials read from the MTL; the camera and lights (which OBJ cannot carry) the glTF
/// export's. Against the same Cycles render, with the glTF export's tolerances.
#[test]
fn blenders_obj_and_mtl_export_renders_as_cycles_renders_the_blender_scene() {
    let dir = scenes().join("gltf/textured-shot");
    let glb = tessera_scene::load(&dir.join("textured-shot.glb")).unwrap_or_else(|e| panic!("{e}"));
    let mut desc = tessera_scene::load(&dir.join("obj.json")).unwrap_or_else(|e| panic!("{e}"));
    assert!(desc.warnings.is_empty(), "{:?}", desc.warnings);
    assert_eq!(desc.materials.len(), glb.materials.len());
    desc.camera = glb.camera;
    desc.film = glb.film;
    desc.lights = glb.lights.clone();
    desc_agrees_with_cycles(
        desc,
        &dir.join("textured-shot.obj"),
        "path",
        2048,
        0.01,
        0.035,
        2.0,
    );
}

#[allow(clippy::too_many_arguments)]
fn desc_agrees_with_cycles(
    mut desc: tessera_scene::SceneDesc,
    glb: &Path,
    method: &str,
    reference_spp: u32,
    mean_tolerance: f64,
    block_tolerance: f64,
    noise_factor: f64,
) {
    let root = glb.parent().expect("a folder");
    let reference = read_exr(&root.join("cycles.exr")).expect("the Cycles render");
    desc.film.width = reference.width;
    desc.film.height = reference.height;
    desc.integrator.method = method.into();
    desc.integrator.seed = 7;
    let render = |seed: u64| render_by_method(&desc, method, SPP, seed);
    let image = render(7);
    let other = render(8);

    let (w, h) = (reference.width as usize, reference.height as usize);
    let r = |i: usize| reference.pixels[i].to_array();
    let ours: f64 = image.pixels.iter().flat_map(|p| p.rgb).map(f64::from).sum();
    let theirs: f64 = (0..w * h).flat_map(r).map(f64::from).sum();
    let ratio = ours / theirs;
    println!("{}: mean ours/Cycles {ratio:.5}", glb.display());

    // And over each of 4×4 blocks, so that one light's error cannot hide behind another's:
    // pixel filters move light between neighbours, not between blocks.
    let mut worst = (0.0f64, 1.0, 0, 0);
    for by in 0..4 {
        for bx in 0..4 {
            let (mut a, mut b) = (0.0f64, 0.0f64);
            for y in by * h / 4..(by + 1) * h / 4 {
                for x in bx * w / 4..(bx + 1) * w / 4 {
                    let i = y * w + x;
                    // Both renders: twice the samples against the blocks' noise.
                    a += image.pixels[i].rgb.iter().map(|&v| v as f64).sum::<f64>();
                    a += other.pixels[i].rgb.iter().map(|&v| v as f64).sum::<f64>();
                    b += 2.0 * r(i).iter().map(|&v| v as f64).sum::<f64>();
                }
            }
            let q = a / b;
            print!("{q:.3} ");
            if (q - 1.0).abs() > worst.0 {
                worst = ((q - 1.0).abs(), q, bx, by);
            }
        }
        println!();
    }
    assert!(
        (ratio - 1.0).abs() < mean_tolerance,
        "mean ours/Cycles = {ratio}"
    );
    let (_, q, bx, by) = worst;
    assert!(
        (q - 1.0).abs() < block_tolerance,
        "block ({bx}, {by}): ours/Cycles = {q}"
    );

    // Pixel by pixel away from edges (where the two renderers' pixel filters differ): the
    // relMSE against Cycles is what the two renders' noise explains. Ours is measured between
    // two seeds (their relMSE is twice one render's); Cycles' is taken as ours per sample
    // over its samples.
    let luminance = |i: usize| {
        let [a, b, c] = r(i);
        (a + b + c) / 3.0
    };
    let gradient = |i: usize| {
        let (x, y) = (i % w, i / w);
        let right = if x + 1 < w {
            (luminance(i + 1) - luminance(i)).abs()
        } else {
            0.0
        };
        let down = if y + 1 < h {
            (luminance(i + w) - luminance(i)).abs()
        } else {
            0.0
        };
        right + down
    };
    let mut g: Vec<f32> = (0..w * h).map(gradient).collect();
    g.sort_by(f32::total_cmp);
    let edge = g[(w * h) * 70 / 100];
    let (mut measured, mut expected, mut n) = (0.0f64, 0.0f64, 0usize);
    for (i, p) in image.pixels.iter().enumerate() {
        if gradient(i) > edge {
            continue;
        }
        for c in 0..3 {
            let (x, rv) = (p.rgb[c] as f64, r(i)[c] as f64);
            let var = (x - other.pixels[i].rgb[c] as f64).powi(2) / 2.0;
            let denom = rv * rv + 0.01;
            measured += (x - rv).powi(2) / denom;
            expected += var * (1.0 + SPP as f64 / reference_spp as f64) / denom;
            n += 1;
        }
    }
    let (measured, expected) = (measured / n as f64, expected / n as f64);
    println!(
        "mean ratio {ratio:.5}; relMSE away from edges {measured:.3e}, noise predicts {expected:.3e}"
    );
    assert!(
        measured < noise_factor * expected,
        "relMSE {measured:.3e} against Cycles where the noise predicts {expected:.3e}"
    );
}
