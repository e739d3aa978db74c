//! Bidirectional path tracing is unbiased: on the Cornell box and cornell-glass its image
//! converges to the path-traced references (`reference-32.exr` in the scene folders, made by
//! `tessera reference`; see `tests/photon.rs`). Measured here (emitter pixels left out as
//! there), relMSE at 4 / 32 / 256 spp: box 2.4e-2 / 2.8e-3 / 3.4e-4, glass 3.3e-2 / 1.9e-2 /
//! 7.3e-3 (2.7 s for all six on 2 threads; 6.9 s, and box 3.2e-4, glass 4.5e-3 at 256 spp,
//! before the subpaths had Russian roulette). The path tracer at 4 / 256 spp, all pixels:
//! box 9.3e-2 / 9.1e-4, glass 1.4 / 6.5e-3.

mod common;

use common::{assert_falls, error_against, pool, scene_and_reference};
use tessera_render::Scene;
use tessera_render::camera::Camera;
use tessera_render::film::SampleRange;
use tessera_render::integrator::bdpt::Bdpt;

/// relMSE and mean ratio of BDPT at `spp` against the 32×32 reference of scene `name`.
fn bdpt_error(name: &str, spp: u32) -> (f64, f64) {
    let (desc, reference) = scene_and_reference(name);
    let scene = Scene::build(&desc);
    let camera = Camera::new(&desc.camera, &desc.film);
    let bdpt = Bdpt {
        max_depth: desc.integrator.max_depth,
        rr_depth: desc.integrator.rr_depth,
    };
    let (image, _) = pool()
        .install(|| bdpt.render(&scene, &camera, SampleRange { start: 0, end: spp }, &|_| {}))
        .expect("renders");
    error_against(&image, &reference)
}

#[test]
fn bdpt_converges_to_the_path_traced_reference() {
    // Budgets 8× apart: caustic paths through glass give single samples large weights, so
    // budgets 4× apart swapped by chance (glass, all pixels: 16 spp 1.08e-2, 64 spp 1.83e-2).
    let budgets = [4, 32, 256];
    let labels: Vec<String> = budgets.iter().map(|spp| format!("{spp} spp")).collect();
    for name in ["cornell-box", "cornell-glass"] {
        let errors: Vec<(f64, f64)> = budgets.iter().map(|&spp| bdpt_error(name, spp)).collect();
        // Unbiased: the mean within 1 % of the reference.
        assert_falls(&format!("{name}: bdpt"), &labels, &errors, 0.01);
    }
}
