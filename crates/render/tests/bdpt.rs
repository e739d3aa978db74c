//! Bidirectional path tracing is unbiased: on the Cornell box and cornell-glass its image
//! converges to the path-traced references (`reference-32.exr` in the scene folders, made by
//! `tessera reference`; see `tests/photon.rs`). Measured here (emitter pixels left out as
//! there), relMSE at 4 / 32 / 256 spp: box 2.4e-2 / 2.8e-3 / 3.4e-4, glass 3.3e-2 / 1.9e-2 /
//! 7.3e-3 (2.7 s for all six on 2 threads; 6.9 s, and box 3.2e-4, glass 4.5e-3 at 256 spp,
//! before the subpaths had Russian roulette). The path tracer at 4 / 256 spp, all pixels:
//! box 9.3e-2 / 9.1e-4, glass 1.4 / 6.5e-3.

mod common;

use common::{
    assert_falls, assert_strategies_agree, depth1_unweighted, error_against, image_mean, pool,
    scene_and_reference, strategy_batches,
};
use tessera_render::Scene;
use tessera_render::camera::Camera;
use tessera_render::film::SampleRange;
use tessera_render::integrator::bdpt::Bdpt;

/// relMSE and mean ratio of BDPT at `spp` against the 32×32 reference of scene `name`.
fn bdpt_error(name: &str, spp: u32) -> (f64, f64) {
    let (desc, reference) = scene_and_reference(name);
    let scene = Scene::build(&desc);
    let camera = Camera::new(&desc.camera, &desc.film);
    let bdpt = Bdpt::new(&desc);
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

#[test]
fn a_sample_range_is_the_same_bits_on_any_threads_and_ranges_merge_into_the_whole() {
    // A farm task is a sample range over the whole film, run on a worker's threads: fixed-point
    // sums within it make its result independent of how the threads shared the work. Ranges
    // add up to the whole range: the splats exactly (fixed point), the camera side to f32.
    let (desc, _) = scene_and_reference("cornell-glass");
    let scene = Scene::build(&desc);
    let camera = Camera::new(&desc.camera, &desc.film);
    let bdpt = Bdpt::new(&desc);
    let range = |start, end| SampleRange { start, end };
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a pool");
    let (whole, _) = one
        .install(|| bdpt.render_range(&scene, &camera, range(0, 6), &|_| {}))
        .expect("renders");
    let (again, _) = pool()
        .install(|| bdpt.render_range(&scene, &camera, range(0, 6), &|_| {}))
        .expect("renders");
    assert_eq!(whole, again, "one thread and several gave different sums");
    let parts: Vec<_> = [range(0, 1), range(1, 4), range(4, 6)]
        .into_iter()
        .map(|r| {
            pool()
                .install(|| bdpt.render_range(&scene, &camera, r, &|_| {}))
                .expect("renders")
                .0
        })
        .collect();
    let mut merged = parts[2].clone();
    merged.merge(&parts[0]);
    merged.merge(&parts[1]);
    assert_eq!(merged.samples, 6);
    assert!(
        whole.splats.iter().any(|s| s.iter().any(|&v| v != 0)),
        "light tracing splatted something"
    );
    assert_eq!(merged.splats, whole.splats);
    for (a, b) in merged.sums.sum.iter().zip(&whole.sums.sum) {
        for c in 0..3 {
            assert!(
                (a[c] - b[c]).abs() <= 1e-5 * b[c].abs().max(1e-3),
                "{a:?} {b:?}"
            );
        }
    }
}

#[test]
fn each_strategy_alone_estimates_the_same_light_and_so_do_the_weighted_ones_together() {
    // Unweighted, every strategy of a depth is its own estimator of all light of that depth
    // (on the Cornell box each can make every such path): their image means must agree within
    // their noise, estimated from 8 independent batches of samples. Direct light (depth 1):
    // s = 0 (a camera path hits the light), s = 1 (light sampling), s = 2 (light tracing).
    let (desc, _) = scene_and_reference("cornell-box");
    let batches = strategy_batches(&desc, 32);
    let stats = depth1_unweighted(&batches);
    eprintln!("depth 1, unweighted (s, mean, standard error): {stats:?}");
    assert_eq!(stats.len(), 3);
    assert_strategies_agree(&stats);
    // MIS weights sum to one over a path's strategies, so the weighted depth-1 images add up
    // to one more estimate of the same light.
    let sums: Vec<f64> = batches
        .iter()
        .map(|b| {
            b.iter()
                .filter(|s| s.s + s.t == 3)
                .map(|s| image_mean(&s.weighted))
                .sum()
        })
        .collect();
    let avg = sums.iter().sum::<f64>() / sums.len() as f64;
    let var = sums.iter().map(|x| (x - avg).powi(2)).sum::<f64>() / (sums.len() - 1) as f64;
    let se = (var / sums.len() as f64).sqrt();
    let nee = &stats[1];
    assert!(
        (avg - nee.1).abs() <= 4.0 * (se * se + nee.2 * nee.2).sqrt(),
        "weighted sum {avg} ± {se} vs light sampling {} ± {}",
        nee.1,
        nee.2
    );
}
