//! Photon mapping is biased but consistent: as photons and final-gather rays grow (and with
//! them the search radius shrinks), the image converges toward the path-traced reference.
//!
//! References (32×32, in the scene folders; their EXR headers hold the stopping rule):
//! `tessera reference scenes/cornell-box/scene.json --size 32x32 --target-error 2e-5` and
//! `tessera reference scenes/cornell-glass/scene.json --size 32x32 --target-error 5e-5` (it
//! stopped at its 65536-spp cap, estimated relMSE 6.5e-5).

mod common;

use common::{
    assert_falls, error_against, pool, render_by_method, scene_and_reference, scene_at_reference,
};
use tessera_render::Scene;
use tessera_render::camera::Camera;
use tessera_render::film::SampleRange;
use tessera_render::render::render_frame;

/// relMSE and mean ratio against `reference-32.exr` of scene `name` rendered by photon mapping
/// (no irradiance cache: final gathering at every sample) with `photons` global and caustic
/// photons, `gather` final-gather rays and `spp` samples per pixel.
fn photon_error(name: &str, photons: u32, gather: u32, spp: u32) -> (f64, f64) {
    let (mut desc, reference) = scene_and_reference(name);
    desc.integrator.method = "photon".into();
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
        let integ = tessera_render::method::for_scene(&desc, &scene).expect("a per-ray method");
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

fn assert_converges(name: &str) {
    // One spp for all three (the same pixel samples): only photons and gather rays change.
    let settings = [(10_000, 4, 16), (40_000, 16, 16), (160_000, 64, 16)];
    let errors: Vec<(f64, f64)> = settings
        .iter()
        .map(|&(n, g, spp)| photon_error(name, n, g, spp))
        .collect();
    let labels: Vec<String> = settings
        .iter()
        .map(|(n, g, spp)| format!("{n} photons, {g} gather rays, {spp} spp"))
        .collect();
    // And the finest setting is close: its mean within 3 % of the reference.
    assert_falls(&format!("{name}: photon mapping"), &labels, &errors, 0.03);
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
    desc.integrator.method = "sppm".into();
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
    let labels: Vec<String> = iterations
        .iter()
        .map(|t| format!("{t} iterations of 20000 photons"))
        .collect();
    assert_falls(&format!("{name}: sppm"), &labels, &errors, 0.03);
}

#[test]
fn sppm_converges_to_the_path_traced_reference() {
    assert_sppm_converges("cornell-box");
    assert_sppm_converges("cornell-glass");
}

/// Under a Mitchell filter, whose negative lobes now and then give a pixel's samples weights
/// that nearly cancel, SPPM's error falls from its first iterations on: the material spheres
/// against their 128×64 reference. Dividing by the weights' sum made four iterations 10³
/// times worse than one.
#[test]
fn sppm_under_a_mitchell_filter_improves_from_its_first_iterations() {
    let (desc, reference) = scene_at_reference("material-spheres", "reference-128.exr");
    assert!(matches!(
        desc.film.filter,
        tessera_scene::FilterDesc::Mitchell { .. }
    ));
    let iterations = [1, 4, 16];
    let errors: Vec<(f64, f64)> = iterations
        .iter()
        .map(|&t| error_against(&render_by_method(&desc, "sppm", t, 1), &reference))
        .collect();
    let labels: Vec<String> = iterations
        .iter()
        .map(|t| format!("{t} iterations"))
        .collect();
    assert_falls("material spheres: sppm", &labels, &errors, 0.05);
}

/// SPPM with a target error stops at the first iteration whose estimated relMSE (the
/// variance of its iterations' mean) reaches it: the Cornell box at 32×32 with a target
/// between its estimates at two and at the iteration it stops, the same image as that many
/// fixed iterations (the stop changes nothing else), and a target it cannot reach runs to the
/// cap. The header says which.
#[test]
fn sppm_with_a_target_error_stops_at_the_iteration_whose_estimate_reaches_it() {
    use tessera_render::method::{self, Finished, Job, local::Local};
    let (mut desc, _) = scene_and_reference("cornell-box");
    desc.integrator.method = "sppm".into();
    desc.integrator.photon.photons = Some(5_000);
    let run = |spp: u32, target: Option<f64>| -> Finished {
        let mut d = desc.clone();
        d.integrator.spp = spp;
        let scene = Scene::build(&d);
        let job = Job {
            target_error: target,
            ..Job::new(d.clone(), 1)
        };
        let plan = method::plan(&job).unwrap_or_else(|e| panic!("{e}"));
        let noop = |_| {};
        pool().install(|| {
            let local = Local::new(plan.as_ref(), &scene, &d, 2, &noop);
            local.frame(1).unwrap_or_else(|e| panic!("{e}"))
        })
    };
    let meta = |f: &Finished, key: &str| -> String {
        f.metadata
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.clone())
            .unwrap_or_else(|| panic!("no {key} in {:?}", f.metadata))
    };
    let at = |n: u32| run(n, None).estimated_rel_mse.expect("an estimate");
    let (two, eight) = (at(2), at(8));
    assert!(
        eight < two,
        "estimates at 2 and 8 iterations: {two}, {eight}"
    );
    let target = 0.5 * (two + eight);
    let stopped = run(64, Some(target));
    let said = meta(&stopped, "sppm_stopped");
    let n: u32 = said
        .strip_prefix("iteration ")
        .and_then(|r| r.split(':').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{said}"));
    assert!((3..=8).contains(&n), "stopped at {n}: {said}");
    assert!(said.contains("reached the target"), "{said}");
    let e = stopped.estimated_rel_mse.expect("an estimate");
    assert!(e <= target, "estimate {e} over the target {target}");
    assert!(
        at(n - 1) > target,
        "iteration {} had reached {target}",
        n - 1
    );
    let fixed = run(n, None);
    let rgb = |f: &Finished| -> Vec<[f32; 3]> { f.image.pixels.iter().map(|p| p.rgb).collect() };
    assert_eq!(rgb(&stopped), rgb(&fixed), "the stop changed the image");

    let capped = run(4, Some(1e-12));
    let said = meta(&capped, "sppm_stopped");
    assert!(said.starts_with("iteration 4: the cap"), "{said}");
    assert_eq!(meta(&capped, "target_rel_mse"), "1e-12");
}

/// Ward's irradiance cache replaces final gathering at most pixels by interpolated records
/// whose relative error its accuracy a bounds (Ward, Rubinstein & Clear 1988: a record serves
/// where its estimated error, ∝ distance over its harmonic mean distance, is below a). Against
/// the same photon maps gathered at every sample (no cache), on the Cornell box: the cached
/// image's mean relative difference per pixel exceeds that of two uncached renders of other
/// seeds (the noise) by less than a, its mean by less than a/4, and both shrink as a does.
#[test]
fn the_irradiance_cache_is_as_accurate_as_its_error_bound() {
    use tessera_scene::IrradianceCacheDesc;
    let render = |cache: Option<f32>, seed: u64| {
        let (mut desc, _) = scene_and_reference("cornell-box");
        desc.integrator.method = "photon".into();
        desc.integrator.seed = seed;
        let p = &mut desc.integrator.photon;
        p.photons = Some(100_000);
        p.gather_rays = Some(64);
        p.irradiance_cache = cache.map(|a| IrradianceCacheDesc {
            accuracy: Some(a),
            gather_rays: Some(512),
            ..Default::default()
        });
        let scene = Scene::build(&desc);
        let camera = Camera::new(&desc.camera, &desc.film);
        pool().install(|| {
            let integ = tessera_render::method::for_scene(&desc, &scene).expect("a per-ray method");
            let range = SampleRange { start: 0, end: 32 };
            render_frame(&scene, &camera, integ.as_ref(), 8, range).0
        })
    };
    // (mean relative difference per pixel, mean ratio) of `img` against `reference`.
    let difference = |img: &tessera_render::Image, reference: &tessera_render::Image| {
        let (mut rel, mut sx, mut sr) = (0.0f64, 0.0f64, 0.0f64);
        for (p, q) in img.pixels.iter().zip(&reference.pixels) {
            for c in 0..3 {
                let (x, r) = (p.rgb[c] as f64, q.rgb[c] as f64);
                rel += (x - r).abs() / (r + 0.01);
                sx += x;
                sr += r;
            }
        }
        (rel / (3 * img.pixels.len()) as f64, sx / sr)
    };
    let reference = render(None, 1);
    let (noise, _) = difference(&render(None, 2), &reference);
    let accuracies = [0.4f32, 0.2, 0.05];
    let errors: Vec<(f64, f64)> = accuracies
        .iter()
        .map(|&a| difference(&render(Some(a), 2), &reference))
        .collect();
    eprintln!(
        "irradiance cache: (mean relative difference, mean ratio) against gathering everywhere \
         {errors:?} at a = {accuracies:?}; two uncached seeds differ by {noise:.4}"
    );
    for (a, (e, m)) in accuracies.iter().zip(&errors) {
        let a = *a as f64;
        assert!(
            e - noise < a,
            "a = {a}: relative difference {e}, noise {noise}"
        );
        assert!((m - 1.0).abs() < a / 4.0, "a = {a}: mean ratio {m}");
    }
    assert!(
        errors[2].0 < errors[0].0,
        "a tighter bound must interpolate less error: {errors:?}"
    );
}
