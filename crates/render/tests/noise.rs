//! Image tests that scale with noise (after Mitsuba 3's render tests): a render agrees with a
//! converged reference pixel by pixel within their joint statistical error, using the variance
//! both carry in their EXR. One test serves every unbiased integrator; a biased one fails it.
//!
//! The reference `scenes/cornell-box/reference-32.exr` was made by
//! `tessera reference scenes/cornell-box/scene.json --size 32x32 --target-error 2e-5`
//! (32768 spp; its header holds the stopping rule and the estimate).

use std::path::Path;

use tessera_render::camera::Camera;
use tessera_render::film::SampleRange;
use tessera_render::render::render_frame;
use tessera_render::{Image, Scene};

const SPP: u32 = 256;

/// (value, variance) per pixel and channel of an EXR written by `tessera`.
fn read_with_variance(path: &Path) -> (usize, usize, Vec<[(f32, f32); 3]>) {
    let bytes = std::fs::read(path).expect("reference EXR");
    let names = ["R", "G", "B", "variance.R", "variance.G", "variance.B"];
    let (w, h, c) = tessera_scene::image::read_exr_channels(&bytes, &names).expect("channels");
    let pixels = (0..(w * h) as usize)
        .map(|i| [(c[0][i], c[3][i]), (c[1][i], c[4][i]), (c[2][i], c[5][i])])
        .collect();
    (w as usize, h as usize, pixels)
}

/// Fraction of pixel channels with |x − r| ≤ z √(Var x + Var r).
fn pass_rate(img: &Image, reference: &[[(f32, f32); 3]], z: f64) -> f64 {
    let mut pass = 0usize;
    for (p, r) in img.pixels.iter().zip(reference) {
        for (c, &(rv, vr)) in r.iter().enumerate() {
            let (x, vx) = (p.rgb[c] as f64, p.variance[c] as f64);
            let (rv, vr) = (rv as f64, vr as f64);
            if (x - rv).abs() <= z * (vx + vr).sqrt() {
                pass += 1;
            }
        }
    }
    pass as f64 / (reference.len() * 3) as f64
}

#[test]
fn unbiased_integrators_agree_with_the_reference_within_their_noise() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-box");
    let (w, h, reference) = read_with_variance(&root.join("reference-32.exr"));
    let mut desc = tessera_scene::load(&root.join("scene.json")).unwrap_or_else(|e| panic!("{e}"));
    desc.film.width = w as u32;
    desc.film.height = h as u32;
    let camera = Camera::new(&desc.camera, &desc.film);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("pool");
    // z = 4 leaves a Gaussian error outside 0.006 % of the time; we ask that 99.5 % of pixel
    // channels pass. The slack is for the variance estimates themselves: at 256 spp of a
    // heavy-tailed path-space integrand the sample variance is often below the true one (measured
    // here: 99.45 % pass at z = 3.29, 99.84–99.87 % at z = 4).
    let z = 4.0;
    let run = |kind: &str, seed: u64| {
        let mut d = desc.clone();
        d.integrator.method = kind.into();
        d.integrator.seed = seed;
        // The seed lives in the scene the sampler reads: build it per run.
        let scene = Scene::build(&d);
        let integ = tessera_render::method::for_scene(&d, &scene).expect("a per-ray method");
        let range = SampleRange { start: 0, end: SPP };
        pool.install(|| render_frame(&scene, &camera, integ.as_ref(), 8, range).0)
    };
    for (kind, seed) in [("path", 1), ("path", 2), ("auto", 3)] {
        let img = run(kind, seed);
        let rate = pass_rate(&img, &reference, z);
        assert!(
            rate >= 0.995,
            "{kind:?} seed {seed}: {:.2} % of pixels agree",
            rate * 100.0
        );
    }
    // The test has power: direct lighting misses the indirect light and fails it.
    let rate = pass_rate(&run("direct", 1), &reference, z);
    eprintln!("direct lighting: {:.1} % pass", rate * 100.0);
    assert!(
        rate < 0.5,
        "direct lighting passed {:.1} % of pixels",
        rate * 100.0
    );
}
