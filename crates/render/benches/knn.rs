//! k-NN query speed: our photon kd-tree against kiddo on the Cornell box's global photon map
//! (the measurement behind `photon/kdtree.rs`'s choice).
//!
//! `cargo bench -p tessera-render --bench knn` (k = the scene's default 64; `K=1` or `K=8` in
//! the environment for the radiance-photon and small lookups). Plain Euclidean queries so
//! kiddo can run them too, and our disc-flattened ones beside them.
use std::time::Instant;

use glam::Vec3A;
use kiddo::SquaredEuclidean;
use tessera_render::photon::{KdTree, Knn, MapKind, PhotonSettings, Shooter};

fn main() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes/cornell-box/scene.json");
    let desc = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let scene = tessera_render::Scene::build(&desc);
    let analysis = tessera_render::analysis::analyze(&desc);
    let (settings, _) = PhotonSettings::resolve(&desc, &analysis);
    let photons = Shooter::new(&scene, &settings, MapKind::Global).shoot(0..settings.photons);
    println!(
        "{} photons stored, k {}, radius {}",
        photons.len(),
        settings.k,
        settings.radius
    );
    let queries: Vec<(Vec3A, Vec3A)> = photons
        .iter()
        .step_by(4)
        .map(|p| (Vec3A::from(p.p) + Vec3A::splat(1e-3), Vec3A::from(p.n)))
        .collect();
    let k: usize = std::env::var("K")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(settings.k as usize);
    let r2 = settings.radius * settings.radius;

    let t = Instant::now();
    let ours = KdTree::build(photons.clone());
    let build_ours = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let mut kd: kiddo::KdTree<f32, 3> = kiddo::KdTree::with_capacity(photons.len());
    for (i, p) in photons.iter().enumerate() {
        kd.add(&p.p.to_array(), i as u64);
    }
    let build_kiddo = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let pts: Vec<[f32; 3]> = photons.iter().map(|p| p.p.to_array()).collect();
    let imm: kiddo::ImmutableKdTree<f32, 3> = kiddo::ImmutableKdTree::new_from_slice(&pts);
    let build_imm = t.elapsed().as_secs_f64();

    let nonzero_k = std::num::NonZero::new(k.max(1)).expect("k ≥ 1");
    // µs per query and the neighbours found in all, for one way of answering each query.
    let run = |f: &dyn Fn(Vec3A, Vec3A) -> usize| {
        let t = Instant::now();
        let found: usize = queries.iter().map(|&(p, n)| f(p, n)).sum();
        (
            t.elapsed().as_secs_f64() / queries.len() as f64 * 1e6,
            found,
        )
    };
    let tree = &ours;
    let ours = |flatten: f32| {
        move |p: Vec3A, n: Vec3A| {
            let mut knn = Knn::<1024>::new(k, r2);
            tree.nearest(p, n, flatten, &mut knn);
            knn.found().len()
        }
    };
    for round in 0..2 {
        let (ours_s, sum) = run(&ours(0.0));
        let (flat_s, sum_flat) = run(&ours(24.0));
        let (kiddo_s, sum_k) = run(&|p, _| {
            kd.nearest_n_within::<SquaredEuclidean>(&p.to_array(), r2, nonzero_k, false)
                .len()
        });
        let (imm_s, sum_i) = run(&|p, _| {
            imm.nearest_n_within::<SquaredEuclidean>(&p.to_array(), r2, nonzero_k, false)
                .len()
        });
        println!(
            "round {round}: {} queries of k={k}: ours (Euclidean) {ours_s:.3} µs/query [{sum}], ours (disc-flattened) {flat_s:.3} µs [{sum_flat}], kiddo KdTree {kiddo_s:.3} µs [{sum_k}], kiddo ImmutableKdTree {imm_s:.3} µs [{sum_i}]",
            queries.len(),
        );
    }
    println!(
        "build: ours {:.1} ms, kiddo KdTree {:.1} ms, ImmutableKdTree {:.1} ms",
        build_ours * 1e3,
        build_kiddo * 1e3,
        build_imm * 1e3
    );
}
