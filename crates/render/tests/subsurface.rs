//! Translucent materials on a scene: a marble block (200 × 100 × 200 mm, many diffusion
//! lengths in every direction: a semi-infinite slab to the light that reaches the middle of its
//! top face) under a uniform white sky, seen straight down at the middle of the top face.
//!
//! There the radiance is known. The sampled dipole BSSRDF must give, per channel,
//! L = Fr(0°) + (1 − Fr(0°)) (T + S) with T = ∫ Rd dA over the sampled disc (the dipole's total
//! diffuse reflectance less the truncated tail): specular reflection of the sky, plus what
//! entered, spread by Rd and leaving through the exit lobe, whose cosine integral is 1; and S,
//! Jensen et al. 2001's single scattering, which on a flat surface under a uniform sky is
//! S = α/η² · 2π ∫₀¹ (1 − Fr(μ)) μ p(−μ′) / (1 + μ′) dμ (μ′ the refracted cosine). The
//! random walk inside the block is the brute-force truth, which the diffusion term
//! approximates: they must agree within the dipole's error under diffuse light, stated below.
//! The hierarchical method (a point cloud with its irradiance, summed through an octree)
//! approximates the same integral as the sampled dipole, within its quadrature error.

mod common;

use common::load_json;
use tessera_render::Scene;
use tessera_render::bssrdf::dipole::{Dipole, Medium};
use tessera_render::bssrdf::profile::RadialTable;
use tessera_render::camera::Camera;
use tessera_render::film::SampleRange;
use tessera_render::method::for_scene;
use tessera_render::render::render_frame;
use tessera_scene::SubsurfaceMethod;

/// The block, `half` mm to each side of the middle of its top face and `half` deep.
fn block(method: SubsurfaceMethod, spp: u32, half: f32) -> tessera_scene::SceneDesc {
    let method = match method {
        SubsurfaceMethod::Dipole => "dipole",
        SubsurfaceMethod::Hierarchical => "hierarchical",
        SubsurfaceMethod::RandomWalk => "random_walk",
    };
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
    load_json(&format!("subsurface-{method}"), &json, &[])
}

/// `desc` rendered at its spp on two threads, with the integrator it asks for (and its pass).
fn render(desc: &tessera_scene::SceneDesc) -> tessera_render::Image {
    let scene = Scene::build(desc);
    let camera = Camera::new(&desc.camera, &desc.film);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("pool");
    let integrator = pool
        .install(|| for_scene(desc, &scene))
        .expect("a per-ray method");
    let range = SampleRange {
        start: 0,
        end: desc.integrator.spp,
    };
    pool.install(|| render_frame(&scene, &camera, integrator.as_ref(), 8, range))
        .0
}

/// Mean of `pixels` per channel, and its standard error from their scatter (the box filter
/// keeps pixels independent).
fn mean_and_error(pixels: &[[f32; 3]]) -> ([f64; 3], [f64; 3]) {
    let n = pixels.len() as f64;
    let mean = [0, 1, 2].map(|c| pixels.iter().map(|p| p[c] as f64).sum::<f64>() / n);
    let se = [0, 1, 2].map(|c| {
        let var = pixels
            .iter()
            .map(|p| (p[c] as f64 - mean[c]).powi(2))
            .sum::<f64>()
            / (n - 1.0);
        (var / n).sqrt()
    });
    (mean, se)
}

/// Prints `what` per channel against `expected`, and asserts each channel within `rel` of it
/// plus four standard errors.
fn assert_within(what: &str, (mean, se): ([f64; 3], [f64; 3]), expected: [f64; 3], rel: f64) {
    for c in 0..3 {
        eprintln!(
            "{what}, channel {c}: {:.4} ± {:.4} (expected {:.4}, ratio {:.4})",
            mean[c],
            se[c],
            expected[c],
            mean[c] / expected[c]
        );
        assert!(
            (mean[c] - expected[c]).abs() < rel * expected[c] + 4.0 * se[c],
            "{what}, channel {c}: {} ± {} vs {}",
            mean[c],
            se[c],
            expected[c]
        );
    }
}

/// The block's pixels, by `method`.
fn block_mean(method: SubsurfaceMethod, spp: u32, half: f32) -> ([f64; 3], [f64; 3]) {
    let image = render(&block(method, spp, half));
    let pixels: Vec<[f32; 3]> = image.pixels.iter().map(|p| p.rgb).collect();
    mean_and_error(&pixels)
}

/// The radiance at the middle of the top face per channel: the specular reflection of the
/// sky and the dipole's diffusion term, and with `single` Jensen et al. 2001's single
/// scattering (marble: g = 0, so p = 1/4π).
fn dipole_expectation(single: bool) -> [f64; 3] {
    let m = Medium::named("marble").expect("marble");
    let fresnel =
        |cos: f64| tessera_render::bsdf::fresnel::dielectric(cos as f32, m.eta as f32) as f64;
    let fr = fresnel(1.0);
    // ∫₀¹ (1 − Fr(μ)) μ / (1 + μ′) dμ by the midpoint rule.
    let n = 100_000;
    let cosines = (0..n).map(|i| (i as f64 + 0.5) / n as f64);
    let integral = cosines
        .map(|mu| {
            let mu_t = (1.0 - (1.0 - mu * mu) / (m.eta * m.eta)).sqrt();
            (1.0 - fresnel(mu)) * mu / (1.0 + mu_t)
        })
        .sum::<f64>()
        / n as f64;
    [0, 1, 2].map(|c| {
        let t = RadialTable::new(&Dipole::new(&m, c)).total() as f64;
        let albedo = m.sigma_s_prime[c] / (m.sigma_s_prime[c] + m.sigma_a[c]);
        let s = albedo / (m.eta * m.eta) * 0.5 * integral;
        fr + (1.0 - fr) * (t + if single { s } else { 0.0 })
    })
}

#[test]
fn sampled_dipole_gives_the_models_reflectance() {
    // Four standard errors, and 1e-3 for the table's quadrature. Single scattering alone,
    // measured by hand (0.0917 ± 0.0006 red with the diffusion term left out; the walk's
    // once-scattered light 0.0908 ± 0.0015; the formula 0.0914, all with Fr = 0.017).
    let measured = block_mean(SubsurfaceMethod::Dipole, 64, 100.0);
    assert_within("dipole", measured, dipole_expectation(true), 1e-3);
}

#[test]
fn random_walk_agrees_with_the_diffusion_term_within_its_error() {
    // The diffusion term's error under diffuse light, measured here: the walk reflects 0.9 %
    // (red), 1.5 % (green) and 0.9 % (blue) more, ± 0.4 % (at normal incidence on the slab the
    // walk reflected 0.75 % less: `random_walk` tests). Allowed: 2.5 % and four standard
    // errors. Jensen's sum with single scattering (7.7 % of the light here) is 7.5 % above the
    // walk: the dipole's source already holds the first scattering, so on a half-space under a
    // uniform sky the sum counts it twice.
    let measured = block_mean(SubsurfaceMethod::RandomWalk, 64, 100.0);
    assert_within("random walk", measured, dipole_expectation(false), 0.025);
}

/// The hierarchical method on a smaller block (60 × 30 × 60 mm: its point cloud is 130 000
/// points; still 3.5 diffusion lengths of the reddest channel to every side): the sum over
/// the cloud approximates the same integral as the sampled dipole.
#[test]
fn hierarchical_dipole_gives_the_dipoles_reflectance() {
    // Measured −0.3 to −0.4 % (−0.6 to −0.8 % of the diffusion term, which alone it
    // approximates; single scattering is the sampled dipole's): the cloud's points sample Rd's peak under x coarsely (one point
    // per mean free path squared), and the octree's nodes take Rd at their centre (−0.16 %).
    // Allowed: 1.5 % and four standard errors.
    let measured = block_mean(SubsurfaceMethod::Hierarchical, 4, 30.0);
    assert_within("hierarchical", measured, dipole_expectation(true), 0.015);
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
    let image = render(&load_json("furnace", json, &[]));
    let pixels = &image.pixels;
    // The middle 16 × 16 pixels see only the sphere.
    let inner: Vec<[f32; 3]> = (8..24)
        .flat_map(|y| (8..24).map(move |x| pixels[y * 32 + x].rgb))
        .collect();
    assert_within("furnace", mean_and_error(&inner), [1.0; 3], 1e-3);
}
