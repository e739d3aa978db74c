//! Photon mapping is biased but consistent: as photons and final-gather rays grow (and with
//! them the search radius shrinks), the image converges toward the path-traced reference.
//!
//! References (32×32, in the scene folders; their EXR headers hold the stopping rule):
//! `tessera reference scenes/cornell-box/scene.json --size 32x32 --target-error 2e-5` and
//! `tessera reference scenes/cornell-glass/scene.json --size 32x32 --target-error 5e-5` (it
//! stopped at its 65536-spp cap, estimated relMSE 6.5e-5).

use std::path::Path;

use tessera_render::camera::Camera;
use tessera_render::film::SampleRange;
use tessera_render::metrics::compare;
use tessera_render::render::render_frame;
use tessera_render::{Scene, integrator, read_exr};
use tessera_scene::IntegratorKind;

/// relMSE and mean ratio against `reference-32.exr` of scene `name` rendered by photon mapping
/// (no irradiance cache: final gathering at every sample) with `photons` global and caustic
/// photons, `gather` final-gather rays and `spp` samples per pixel.
/// The two threads CI has.
fn pool() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("pool")
}

/// Scene `name` at the size of its 32×32 reference, and the reference.
fn scene_and_reference(name: &str) -> (tessera_scene::SceneDesc, tessera_scene::image::RgbImage) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(name);
    let reference = read_exr(&root.join("reference-32.exr")).expect("reference");
    let mut desc = tessera_scene::load(&root.join("scene.json")).unwrap_or_else(|e| panic!("{e}"));
    desc.film.width = reference.width;
    desc.film.height = reference.height;
    (desc, reference)
}

fn photon_error(name: &str, photons: u32, gather: u32, spp: u32) -> (f64, f64) {
    let (mut desc, reference) = scene_and_reference(name);
    desc.integrator.kind = IntegratorKind::Photon;
    let p = &mut desc.integrator.photon;
    p.photons = Some(photons);
    p.gather_rays = Some(gather);
    p.irradiance_cache = None;
    // As many caustic photons where the scene has caustics (none otherwise).
    if tessera_render::analysis::analyze(&desc).caustics {
        desc.integrator.photon.caustic_photons = Some(photons);
    }
    let scene = Scene::build(&desc);
    let camera = Camera::new(&desc.camera, &desc.film);
    let pool = pool();
    let image = pool.install(|| {
        let integ = integrator::for_scene(&desc, &scene);
        render_frame(
            &scene,
            &camera,
            integ.as_ref(),
            8,
            SampleRange { start: 0, end: spp },
        )
        .0
    });
    error_against(&image, &reference)
}

/// relMSE and mean ratio of `image` against `reference`, emitter pixels left out.
fn error_against(
    image: &tessera_render::Image,
    reference: &tessera_scene::image::RgbImage,
) -> (f64, f64) {
    let rgb: Vec<glam::Vec3A> = image.pixels.iter().map(|p| p.rgb.into()).collect();
    let refs: Vec<glam::Vec3A> = reference.pixels.iter().map(|&t| t.into()).collect();
    // Pixels on or beside the visible emitter are left out: their error is the film's
    // antialiasing of a light 60× brighter than the walls (whether a sample lands on it), the
    // same for every integrator at this spp, and it would drown the effect measured here.
    let (w, h) = (reference.width as i32, reference.height as i32);
    let bright = |x: i32, y: i32| {
        x >= 0 && y >= 0 && x < w && y < h && refs[(y * w + x) as usize].max_element() > 1.0
    };
    let keep: Vec<usize> = (0..w * h)
        .filter(|&i| {
            let (x, y) = (i % w, i / w);
            !(-1..=1).any(|dy| (-1..=1).any(|dx| bright(x + dx, y + dy)))
        })
        .map(|i| i as usize)
        .collect();
    let pick = |v: &[glam::Vec3A]| keep.iter().map(|&i| v[i]).collect::<Vec<_>>();
    let e = compare(&pick(&rgb), &pick(&refs));
    (e.rel_mse, e.mean_ratio)
}

fn assert_converges(name: &str) {
    // One spp for all three (the same pixel samples): only photons and gather rays change.
    let settings = [(10_000, 4, 16), (40_000, 16, 16), (160_000, 64, 16)];
    let errors: Vec<(f64, f64)> = settings
        .iter()
        .map(|&(n, g, spp)| photon_error(name, n, g, spp))
        .collect();
    for (&(n, g, spp), (rel, mean)) in settings.iter().zip(&errors) {
        eprintln!(
            "{name}: {n} photons, {g} gather rays, {spp} spp: relMSE {rel:.3e}, mean/ref {mean:.4}"
        );
    }
    assert!(
        errors.windows(2).all(|w| w[1].0 < w[0].0),
        "{name}: relMSE must fall as photons and gather rays grow: {errors:?}"
    );
    // And the finest setting is close: its mean within 3 % of the reference.
    let (_, mean) = errors[2];
    assert!((mean - 1.0).abs() < 0.03, "{name}: mean/ref {mean}");
}

#[test]
fn photon_mapped_cornell_box_converges_to_the_path_traced_reference() {
    assert_converges("cornell-box");
}

#[test]
fn photon_mapped_cornell_glass_converges_to_the_path_traced_reference() {
    assert_converges("cornell-glass");
}

/// SPPM of `name` at 32×32 with `iterations` iterations of `photons` photons.
fn sppm_error(name: &str, photons: u32, iterations: u32) -> (f64, f64) {
    use tessera_render::integrator::sppm::{SppmSettings, render};
    let (mut desc, reference) = scene_and_reference(name);
    desc.integrator.kind = IntegratorKind::Sppm;
    desc.integrator.photon.photons = Some(photons);
    let analysis = tessera_render::analysis::analyze(&desc);
    let settings = tessera_render::photon::PhotonSettings::resolve(&desc, &analysis).0;
    let s = SppmSettings::from_photon_settings(&settings, iterations, 2.0 / 3.0);
    let scene = Scene::build(&desc);
    let camera = Camera::new(&desc.camera, &desc.film);
    let pool = pool();
    let (image, _) = pool.install(|| render(&scene, &camera, &settings, &s, &|_| ()));
    error_against(&image, &reference)
}

fn assert_sppm_converges(name: &str) {
    let iterations = [4, 16, 64];
    let errors: Vec<(f64, f64)> = iterations
        .iter()
        .map(|&t| sppm_error(name, 20_000, t))
        .collect();
    for (t, (rel, mean)) in iterations.iter().zip(&errors) {
        eprintln!(
            "{name}: sppm {t} iterations of 20000 photons: relMSE {rel:.3e}, mean/ref {mean:.4}"
        );
    }
    assert!(
        errors.windows(2).all(|w| w[1].0 < w[0].0),
        "{name}: SPPM's relMSE must fall with iterations: {errors:?}"
    );
    let (_, mean) = errors[2];
    assert!((mean - 1.0).abs() < 0.03, "{name}: mean/ref {mean}");
}

#[test]
fn sppm_converges_to_the_path_traced_reference() {
    assert_sppm_converges("cornell-box");
    assert_sppm_converges("cornell-glass");
}
