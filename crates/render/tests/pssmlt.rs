//! Multiplexed primary-sample-space MLT is unbiased (up to its brightness estimate, whose
//! share of the budget grows with it): on the Cornell box and cornell-glass it converges to
//! the path-traced 32×32 references (`tests/photon.rs`), emitter pixels left out as there.

mod common;

use common::{assert_falls, error_against, pool, scene_and_reference};
use tessera_render::Scene;
use tessera_render::camera::Camera;
use tessera_render::integrator::pssmlt::Pssmlt;

/// relMSE and mean ratio of PSSMLT at `mutations` per pixel against scene `name`'s reference.
fn pssmlt_error(name: &str, mutations: u32) -> (f64, f64) {
    let (desc, reference) = scene_and_reference(name);
    let scene = Scene::build(&desc);
    let camera = Camera::new(&desc.camera, &desc.film);
    let (image, _) = pool()
        .install(|| Pssmlt::new(&desc).render(&scene, &camera, mutations, &|_| {}))
        .expect("renders");
    error_against(&image, &reference)
}

#[test]
fn pssmlt_converges_to_the_path_traced_reference() {
    let budgets = [4, 32, 256];
    let labels: Vec<String> = budgets
        .iter()
        .map(|m| format!("{m} mutations/px"))
        .collect();
    for name in ["cornell-box", "cornell-glass"] {
        let errors: Vec<(f64, f64)> = budgets.iter().map(|&m| pssmlt_error(name, m)).collect();
        assert_falls(&format!("{name}: pssmlt"), &labels, &errors, 0.01);
    }
}

#[test]
fn pssmlt_is_the_same_on_one_thread_and_on_two() {
    let (desc, _) = scene_and_reference("cornell-glass");
    let scene = Scene::build(&desc);
    let camera = Camera::new(&desc.camera, &desc.film);
    let m = Pssmlt::new(&desc);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a pool");
    let a = one
        .install(|| m.render(&scene, &camera, 8, &|_| {}))
        .expect("renders")
        .0;
    let b = pool()
        .install(|| m.render(&scene, &camera, 8, &|_| {}))
        .expect("renders")
        .0;
    assert!(a.pixels.iter().zip(&b.pixels).all(|(p, q)| p.rgb == q.rgb));
}
