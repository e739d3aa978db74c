//! Vertex connection and merging is consistent: on the Cornell box and cornell-glass it
//! converges to the path-traced 32×32 references (`tests/photon.rs`), emitter pixels left out
//! as there; and it is deterministic whatever the threads.

mod common;

use common::{assert_falls, error_against, scene_and_reference, vcm_image};

fn vcm_of(name: &str, iterations: u32, threads: usize) -> tessera_render::Image {
    vcm_image(&scene_and_reference(name).0, iterations, threads)
}

#[test]
fn vcm_converges_to_the_path_traced_reference() {
    let budgets = [4, 32, 256];
    let labels: Vec<String> = budgets.iter().map(|n| format!("{n} iterations")).collect();
    for name in ["cornell-box", "cornell-glass"] {
        let (_, reference) = scene_and_reference(name);
        let errors: Vec<(f64, f64)> = budgets
            .iter()
            .map(|&n| error_against(&vcm_of(name, n, 2), &reference))
            .collect();
        assert_falls(&format!("{name}: vcm"), &labels, &errors, 0.01);
    }
}

#[test]
fn vcm_is_the_same_on_one_thread_and_on_two() {
    let (a, b) = (vcm_of("cornell-glass", 3, 1), vcm_of("cornell-glass", 3, 2));
    assert!(a.pixels.iter().zip(&b.pixels).all(|(p, q)| p.rgb == q.rgb));
}
