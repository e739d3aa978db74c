//! Translucent materials on a scene: a marble block (200 × 100 × 200 mm, many diffusion
//! lengths in every direction: a semi-infinite slab to the light that reaches the middle of its
//! top face) under a uniform white sky, seen straight down at the middle of the top face.
//!
//! There the radiance is known. The sampled dipole BSSRDF must give, per channel,
//! L = Fr(0°) + (1 − Fr(0°)) T with T = ∫ Rd dA over the sampled disc (the dipole's total
//! diffuse reflectance less the truncated tail): specular reflection of the sky, plus what
//! entered, spread by Rd and leaving through the exit lobe, whose cosine integral is 1. The
//! random walk inside the block is the brute-force truth, which the dipole approximates: they
//! must agree within the dipole's error under diffuse light, stated below. The hierarchical
//! method (a point cloud with its irradiance, summed through an octree) approximates the same
//! integral as the sampled dipole, within its quadrature error.

use tessera_render::Scene;
use tessera_render::bssrdf::dipole::{Dipole, Medium};
use tessera_render::bssrdf::profile::RadialTable;
use tessera_render::camera::Camera;
use tessera_render::film::SampleRange;
use tessera_render::integrator::for_scene;
use tessera_render::render::render_frame;
use tessera_scene::SubsurfaceMethod;

/// The block, `half` mm to each side of the middle of its top face and `half` deep.
fn block(method: &str, spp: u32, half: f32) -> tessera_scene::SceneDesc {
    let json = format!(
        r#"{{
  "name": "marble block under a white sky",
  "units": "mm",
  "camera": {{ "type": "pinhole", "position": [0, 50, 0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_deg": 2 }},
  "film": {{ "width": 16, "height": 16, "filter": {{ "type": "box", "radius": 0.5 }} }},
  "integrator": {{ "type": "path", "subsurface": "{method}", "spp": {spp}, "max_depth": 16, "rr_depth": 8, "seed": 7 }},
  "materials": {{ "marble": {{ "type": "subsurface", "preset": "marble" }} }},
  "shapes": [{{ "type": "box", "min": [-{half}, -{half}, -{half}], "max": [{half}, 0, {half}], "material": "marble" }}],
  "lights": [{{ "type": "environment", "radiance": 1 }}]
}}"#
    );
    let dir = std::env::temp_dir().join(format!(
        "tessera-subsurface-{method}-{}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("scene.json");
    std::fs::write(&path, json).expect("write scene");
    tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// Mean over the film's pixels per channel, and its standard error from their scatter (the
/// box filter keeps pixels independent).
fn mean_and_error(method: SubsurfaceMethod, spp: u32, half: f32) -> ([f64; 3], [f64; 3]) {
    let name = match method {
        SubsurfaceMethod::Dipole => "dipole",
        SubsurfaceMethod::Hierarchical => "hierarchical",
        SubsurfaceMethod::RandomWalk => "random_walk",
    };
    let desc = block(name, spp, half);
    let scene = Scene::build(&desc);
    let camera = Camera::new(&desc.camera, &desc.film);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("pool");
    let integrator = pool.install(|| for_scene(&desc, &scene));
    let range = SampleRange { start: 0, end: spp };
    let (image, _) = pool.install(|| render_frame(&scene, &camera, integrator.as_ref(), 8, range));
    let n = image.pixels.len() as f64;
    let mut mean = [0.0f64; 3];
    let mut se = [0.0f64; 3];
    for c in 0..3 {
        let v: Vec<f64> = image.pixels.iter().map(|p| p.rgb[c] as f64).collect();
        mean[c] = v.iter().sum::<f64>() / n;
        let var = v.iter().map(|x| (x - mean[c]).powi(2)).sum::<f64>() / (n - 1.0);
        se[c] = (var / n).sqrt();
    }
    (mean, se)
}

/// The dipole model's radiance at the middle of the top face, per channel.
fn dipole_expectation() -> [f64; 3] {
    let m = Medium::named("marble").expect("marble");
    let fr = tessera_render::bsdf::fresnel::dielectric(1.0, m.eta as f32) as f64;
    [0, 1, 2].map(|c| {
        let t = RadialTable::new(&Dipole::new(&m, c)).total() as f64;
        fr + (1.0 - fr) * t
    })
}

#[test]
fn sampled_dipole_gives_the_dipoles_reflectance() {
    let expected = dipole_expectation();
    let (mean, se) = mean_and_error(SubsurfaceMethod::Dipole, 64, 100.0);
    for c in 0..3 {
        eprintln!(
            "dipole, channel {c}: {:.4} ± {:.4} (expected {:.4})",
            mean[c], se[c], expected[c]
        );
        // Four standard errors, and 1e-3 for the table's quadrature.
        assert!(
            (mean[c] - expected[c]).abs() < 4.0 * se[c] + 1e-3 * expected[c],
            "channel {c}: {} ± {} vs {}",
            mean[c],
            se[c],
            expected[c]
        );
    }
}

#[test]
fn random_walk_agrees_with_the_dipole_within_its_error() {
    let expected = dipole_expectation();
    let (mean, se) = mean_and_error(SubsurfaceMethod::RandomWalk, 64, 100.0);
    for c in 0..3 {
        eprintln!(
            "random walk, channel {c}: {:.4} ± {:.4} (dipole {:.4}, ratio {:.4})",
            mean[c],
            se[c],
            expected[c],
            mean[c] / expected[c]
        );
        // The dipole's error under diffuse light, measured here: the walk reflects 0.9 % (red),
        // 1.5 % (green) and 0.9 % (blue) more, ± 0.4 % (at normal incidence on the slab the
        // walk reflected 0.75 % less: `random_walk` tests). Allowed: 2.5 % and four standard
        // errors.
        assert!(
            (mean[c] - expected[c]).abs() < 0.025 * expected[c] + 4.0 * se[c],
            "channel {c}: walk {} ± {} vs dipole {}",
            mean[c],
            se[c],
            expected[c]
        );
    }
}

/// The hierarchical method on a smaller block (60 × 30 × 60 mm: its point cloud is 130 000
/// points; still 3.5 diffusion lengths of the reddest channel to every side): the sum over
/// the cloud approximates the same integral as the sampled dipole.
#[test]
fn hierarchical_dipole_gives_the_dipoles_reflectance() {
    let expected = dipole_expectation();
    let (mean, se) = mean_and_error(SubsurfaceMethod::Hierarchical, 4, 30.0);
    for c in 0..3 {
        eprintln!(
            "hierarchical, channel {c}: {:.4} ± {:.4} (expected {:.4}, ratio {:.4})",
            mean[c],
            se[c],
            expected[c],
            mean[c] / expected[c]
        );
        // Measured −0.6 to −0.8 %: the cloud's points sample Rd's peak under x coarsely (one
        // point per mean free path squared), and the octree's nodes take Rd at their centre
        // (−0.1 %). Allowed: 1.5 % and four standard errors.
        assert!(
            (mean[c] - expected[c]).abs() < 0.015 * expected[c] + 4.0 * se[c],
            "channel {c}: {} ± {} vs {}",
            mean[c],
            se[c],
            expected[c]
        );
    }
}

/// A white furnace for the random walk: a sphere of a medium that scatters and does not absorb
/// (σs′ 1, 2, 4 per mm; 5 mm radius) under a uniform white sky gives back all the light it
/// receives — radiance 1 in every pixel it covers, whatever the walks do inside. The dipole
/// fails this test by design (measured 0.75, 0.87, 0.94: its half-space profile reaches past
/// a 5 mm sphere, most in the channel with the longest mean free path), which is the known
/// error that the walk is the reference for.
#[test]
fn random_walk_keeps_the_energy_of_a_white_furnace() {
    let json = r#"{
  "name": "furnace", "units": "mm",
  "camera": { "type": "pinhole", "position": [0, 0, -60], "look_at": [0, 0, 0], "fov_deg": 12 },
  "film": { "width": 32, "height": 32, "filter": { "type": "box", "radius": 0.5 } },
  "integrator": { "type": "path", "subsurface": "random_walk", "spp": 64, "max_depth": 64, "rr_depth": 64, "seed": 3 },
  "materials": { "m": { "type": "subsurface", "sigma_s_prime_per_mm": [1, 2, 4], "sigma_a_per_mm": 0 } },
  "shapes": [{ "type": "sphere", "center": [0, 0, 0], "radius": 5, "material": "m" }],
  "lights": [{ "type": "environment", "radiance": 1 }]
}"#;
    let dir = std::env::temp_dir().join(format!("tessera-furnace-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    std::fs::write(dir.join("scene.json"), json).expect("write scene");
    let desc = tessera_scene::load(&dir.join("scene.json")).unwrap_or_else(|e| panic!("{e}"));
    let scene = Scene::build(&desc);
    let camera = Camera::new(&desc.camera, &desc.film);
    let integrator = for_scene(&desc, &scene);
    let range = SampleRange { start: 0, end: 64 };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("pool");
    let (image, _) = pool.install(|| render_frame(&scene, &camera, integrator.as_ref(), 8, range));
    // The middle 16 × 16 pixels see only the sphere.
    let inner: Vec<[f32; 3]> = (8..24)
        .flat_map(|y| (8..24).map(move |x| (x, y)))
        .map(|(x, y)| image.pixels[y * 32 + x].rgb)
        .collect();
    let n = inner.len() as f64;
    for c in 0..3 {
        let mean = inner.iter().map(|p| p[c] as f64).sum::<f64>() / n;
        let var = inner
            .iter()
            .map(|p| (p[c] as f64 - mean).powi(2))
            .sum::<f64>()
            / (n - 1.0);
        let se = (var / n).sqrt();
        eprintln!("furnace, channel {c}: {mean:.4} ± {se:.4}");
        assert!(
            (mean - 1.0).abs() < 4.0 * se + 1e-3,
            "channel {c}: {mean} ± {se}"
        );
    }
}
