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

    for round in 0..2 {
        let mut sum = 0usize;
        let t = Instant::now();
        for (p, n) in &queries {
            let mut knn = Knn::<1024>::new(k, r2);
            ours.nearest(*p, *n, 0.0, &mut knn);
            sum += knn.found().len();
        }
        let ours_s = t.elapsed().as_secs_f64();
        let mut sum_flat = 0usize;
        let t = Instant::now();
        for (p, n) in &queries {
            let mut knn = Knn::<1024>::new(k, r2);
            ours.nearest(*p, *n, 24.0, &mut knn);
            sum_flat += knn.found().len();
        }
        let flat_s = t.elapsed().as_secs_f64();
        let mut sum_k = 0usize;
        let t = Instant::now();
        for (p, _) in &queries {
            let r = kd.nearest_n_within::<SquaredEuclidean>(
                &p.to_array(),
                r2,
                std::num::NonZero::new(k.max(1)).expect("k ≥ 1"),
                false,
            );
            sum_k += r.len();
        }
        let kiddo_s = t.elapsed().as_secs_f64();
        let mut sum_i = 0usize;
        let t = Instant::now();
        for (p, _) in &queries {
            let r = imm.nearest_n_within::<SquaredEuclidean>(
                &p.to_array(),
                r2,
                std::num::NonZero::new(k.max(1)).expect("k ≥ 1"),
                false,
            );
            sum_i += r.len();
        }
        let imm_s = t.elapsed().as_secs_f64();
        let q = queries.len() as f64;
        println!(
            "round {round}: {} queries of k={k}: ours (Euclidean) {:.3} µs/query [{sum}], ours (disc-flattened) {:.3} µs [{sum_flat}], kiddo KdTree {:.3} µs [{sum_k}], kiddo ImmutableKdTree {:.3} µs [{sum_i}]",
            queries.len(),
            ours_s / q * 1e6,
            flat_s / q * 1e6,
            kiddo_s / q * 1e6,
            imm_s / q * 1e6
        );
    }
    println!(
        "build: ours {:.1} ms, kiddo KdTree {:.1} ms, ImmutableKdTree {:.1} ms",
        build_ours * 1e3,
        build_kiddo * 1e3,
        build_imm * 1e3
    );
}
