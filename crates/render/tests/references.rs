//! Every method against references made by someone else's renderer: Mitsuba 3's path tracer
//! (its volumetric path tracer through the dielectric boundary of a translucent object), by
//! scripts/references/ from the scenes as `tessera export` writes them, stored with each
//! pixel's variance in tests/data/references (its README says how they were made). One bug
//! shared by our methods cannot pass these, as it could pass a comparison with our own path
//! tracer.
//!
//! The test is Jung, Hanika & Dachsbacher's ("Detecting bias in Monte Carlo renderers using
//! Welch's t-test", JCGT 2020), as Mitsuba 3's own render tests use it: a method renders `K`
//! images with independent seeds, whose per-pixel mean and sample variance meet the
//! reference's mean and variance in Welch's t-test, per pixel and channel. Where both
//! converge to the same image the p-values are uniform, so the share of pixels under α is
//! about α; a wrong light path shows up as a region of pixels far beyond it. The image means
//! must agree too, within a few of their standard errors (taken from the K images' means, so
//! that pixels correlated by shared photons or Markov chains count as they should).
//!
//! Few renders of heavy-tailed pixels (a caustic, a lamp seen only through a bounce) make the
//! per-pixel test reject more often than α even where the images agree, so a method passes
//! with at most 5α rejected; a wrong region rejects far more (the last test shows one).
//!
//! The film is box-filtered (a pixel is the integral of radiance over its square), and paths
//! end after 64 bounces, as the references were made.

mod common;

use common::{BATCHES, Reference, mitsuba_reference, render_by_method};
use statrs::distribution::{ContinuousCDF, StudentsT};
use tessera_scene::{SceneDesc, SubsurfaceMethod};

/// Independent renders per method.
const K: usize = 8;
/// Significance level of each pixel's test.
const ALPHA: f64 = 0.01;

/// What Welch's test found for one method.
struct Outcome {
    /// Share of tested channels (of pixels, or of blocks) with p < α.
    rejected: f64,
    /// Image mean over the reference's, and the difference in standard errors.
    mean_ratio: f64,
    mean_z: f64,
}

/// How a method is tested: `spp` per render; `block` × `block` pixel blocks (1: per pixel);
/// `bias` the relative difference a consistent but biased method is allowed before its noise
/// is weighed (0 for the unbiased methods).
#[derive(Clone, Copy)]
struct Test {
    method: &'static str,
    spp: u32,
    block: u32,
    bias: f64,
}

/// Two renderers agree within this beyond their noise (Mitsuba's and ours differ in float
/// details: ray offsets, sphere intersection, sampling of small spheres).
const AGREEMENT: f64 = 0.005;

/// An unbiased method: per pixel, within the renderers' agreement.
const fn unbiased(method: &'static str, spp: u32) -> Test {
    Test {
        method,
        spp,
        block: 1,
        bias: AGREEMENT,
    }
}

/// A consistent but biased method (a photon map's kernel, an irradiance cache): on 4×4
/// blocks, where its blur averages out, beyond a bias of `bias` of the reference — a bound
/// measured on the scene and written beside it, since neither method estimates its bias per
/// pixel yet.
const fn biased(method: &'static str, spp: u32, bias: f64) -> Test {
    Test {
        method,
        spp,
        block: 4,
        bias,
    }
}

/// The per-block means of an image given per pixel (`value(i)`), row-major blocks.
fn block_means(
    w: u32,
    h: u32,
    b: u32,
    value: impl Fn(usize) -> [f64; 3],
    scale: f64,
) -> Vec<[f64; 3]> {
    let (bw, bh) = (w / b, h / b);
    let mut out = vec![[0.0; 3]; (bw * bh) as usize];
    for y in 0..bh * b {
        for x in 0..bw * b {
            let v = value((y * w + x) as usize);
            let o = &mut out[((y / b) * bw + x / b) as usize];
            for c in 0..3 {
                o[c] += v[c] * scale;
            }
        }
    }
    out
}

/// `K` renders of `desc` by `test.method` (seeds 1..=K), tested against `reference`.
fn welch(desc: &SceneDesc, test: Test, reference: &Reference) -> Outcome {
    let images: Vec<_> = (1..=K as u64)
        .map(|seed| render_by_method(desc, test.method, test.spp, seed))
        .collect();
    let (w, h, b) = (desc.film.width, desc.film.height, test.block);
    let n = (b * b) as f64;
    let blocks: Vec<Vec<[f64; 3]>> = images
        .iter()
        .map(|im| block_means(w, h, b, |i| im.pixels[i].rgb.map(f64::from), 1.0 / n))
        .collect();
    let ref_mean = block_means(w, h, b, |i| reference.mean[i], 1.0 / n);
    let ref_var = block_means(w, h, b, |i| reference.var[i], 1.0 / (n * n));
    let k = K as f64;
    let (mut tested, mut rejected) = (0usize, 0usize);
    let mut map = vec![b'.'; ref_mean.len()];
    for (i, (r, rv)) in ref_mean.iter().zip(&ref_var).enumerate() {
        for c in 0..3 {
            let x: Vec<f64> = blocks.iter().map(|im| im[i][c]).collect();
            let mean = x.iter().sum::<f64>() / k;
            let s2 = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (k - 1.0);
            let (a, v) = (s2 / k, rv[c]);
            if a + v == 0.0 {
                continue; // both exactly constant (the background): nothing to test
            }
            // Welch–Satterthwaite degrees of freedom.
            let dof = (a + v).powi(2)
                / (a * a / (k - 1.0) + v * v / (BATCHES - 1.0)).max(f64::MIN_POSITIVE);
            let d = ((mean - r[c]).abs() - test.bias * r[c].abs()).max(0.0);
            let t = d / (a + v).sqrt();
            let p = match StudentsT::new(0.0, 1.0, dof.max(1.0)) {
                Ok(dist) => 2.0 * dist.cdf(-t),
                Err(e) => panic!("t distribution of {dof} degrees: {e}"),
            };
            tested += 1;
            if p < ALPHA {
                rejected += 1;
                map[i] = if p < 1e-6 {
                    b'#'
                } else if map[i] == b'.' {
                    b'+'
                } else {
                    map[i]
                };
            }
        }
    }
    if std::env::var_os("TESSERA_REFERENCE_MAP").is_some() {
        // Where the rejections are: scattered is noise, a region is a difference.
        for row in map.chunks((w / b) as usize) {
            println!("{}", String::from_utf8_lossy(row));
        }
    }
    // The image mean: its standard error from the K images' means (pixels correlated by
    // shared photons count as they should) and the reference's summed variance.
    let px = (w * h) as f64;
    let means: Vec<f64> = images
        .iter()
        .map(|im| {
            im.pixels
                .iter()
                .map(|p| p.rgb.iter().map(|&v| v as f64).sum::<f64>())
                .sum::<f64>()
                / px
        })
        .collect();
    let ref_total = reference
        .mean
        .iter()
        .map(|p| p.iter().sum::<f64>())
        .sum::<f64>()
        / px;
    let ref_se2 = reference
        .var
        .iter()
        .map(|p| p.iter().sum::<f64>())
        .sum::<f64>()
        / (px * px);
    let mean = means.iter().sum::<f64>() / k;
    let s2 = means.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (k - 1.0);
    Outcome {
        rejected: rejected as f64 / tested.max(1) as f64,
        mean_ratio: mean / ref_total,
        mean_z: (mean - ref_total) / (s2 / k + ref_se2).sqrt(),
    }
}

/// Each `(method, spp)` tested on scene `name`; every failure is reported at once.
fn check(name: &str, tests: &[Test], edit: impl Fn(&mut SceneDesc)) {
    let (mut desc, reference) = mitsuba_reference(name);
    edit(&mut desc);
    let mut report = Vec::new();
    let mut failures = Vec::new();
    for &test in tests {
        let o = welch(&desc, test, &reference);
        let Test {
            method,
            spp,
            block,
            bias,
        } = test;
        let line = format!(
            "{name} {method} ({K} × {spp} spp): {:.2} % of {block}×{block} blocks' channels under \
             p = {ALPHA} beyond a bias of {bias} (expected {:.0} %), mean ratio {:.4} (z {:.2})",
            100.0 * o.rejected,
            100.0 * ALPHA,
            o.mean_ratio,
            o.mean_z
        );
        println!("{line}");
        // Three times α allows for channels of one pixel failing together and for the
        // non-normal means of few renders; a biased region fails by far more.
        if o.rejected > 5.0 * ALPHA || (o.mean_z.abs() > 4.0 && (o.mean_ratio - 1.0).abs() > bias) {
            failures.push(line.clone());
        }
        report.push(line);
    }
    assert!(
        failures.is_empty(),
        "failed:\n{}\n\nall:\n{}",
        failures.join("\n"),
        report.join("\n")
    );
}

#[test]
fn glass_caustics_and_total_internal_reflection() {
    check(
        "cornell-glass",
        &[
            unbiased("path", 256),
            unbiased("bdpt", 16),
            unbiased("vcm", 16),
            unbiased("pssmlt", 32),
            unbiased("mlt", 32),
            biased("photon", 16, 0.05),
            biased("sppm", 64, 0.05),
        ],
        |_| {},
    );
}

#[test]
fn strongly_indirect_light() {
    check(
        "indirect-room",
        &[
            Test {
                block: 2,
                ..unbiased("path", 1024)
            },
            unbiased("bdpt", 16),
            unbiased("vcm", 32),
            unbiased("pssmlt", 32),
            unbiased("mlt", 32),
            // Measured bounds, not derived ones: the photon map is 4.4 % dark here in the
            // mean at 64×48 (its irradiance cache is sparse at that size). SPPM gathering in
            // a sphere leaked the shade's inside through its 2 cm walls (the shade's outside
            // 5–10× too bright, the image mean 1.13×): this is the test that found it.
            biased("photon", 16, 0.15),
            biased("sppm", 64, 0.05),
        ],
        |_| {},
    );
}

#[test]
fn rough_metal_under_lights_of_four_sizes() {
    check(
        "veach-mis",
        &[
            unbiased("path", 64),
            unbiased("bdpt", 8),
            unbiased("vcm", 8),
            unbiased("pssmlt", 32),
            unbiased("mlt", 32),
            biased("photon", 8, 0.1),
            biased("sppm", 32, 0.05),
        ],
        |_| {},
    );
}

#[test]
fn translucent_random_walk() {
    check(
        "translucent",
        &[Test {
            block: 2,
            ..unbiased("path", 256)
        }],
        |d| d.integrator.subsurface = SubsurfaceMethod::RandomWalk,
    );
}

/// The dipole methods approximate the random walk by diffusion in a semi-infinite medium,
/// which a 16 mm tube is not: per block they differ by more than the noise (printed), so only
/// their image mean is held to the reference, within 2 %.
fn dipole_mean(method: SubsurfaceMethod) {
    let (mut desc, reference) = mitsuba_reference("translucent");
    desc.integrator.subsurface = method;
    let o = welch(&desc, biased("path", 64, 0.2), &reference);
    println!(
        "translucent {method:?}: {:.2} % of 4×4 blocks' channels under p = {ALPHA} beyond a \
         bias of 20 %, mean ratio {:.4} (z {:.2})",
        100.0 * o.rejected,
        o.mean_ratio,
        o.mean_z
    );
    assert!(
        (o.mean_ratio - 1.0).abs() < 0.02,
        "{method:?}: mean ratio {:.4}",
        o.mean_ratio
    );
}

#[test]
fn translucent_dipole() {
    dipole_mean(SubsurfaceMethod::Dipole);
}

#[test]
fn translucent_hierarchical() {
    dipole_mean(SubsurfaceMethod::Hierarchical);
}

/// The test can fail: the same scene with the floor's albedo a quarter higher than the
/// reference's (0.5 for 0.4) fails it, by BDPT at the budget that passes above. (Per pixel
/// at these budgets the test sees errors of this size, not of a few per cent: each pixel's
/// noise is that large.)
#[test]
fn a_floor_a_quarter_too_bright_fails() {
    let (mut desc, reference) = mitsuba_reference("veach-mis");
    let floor = desc
        .materials
        .iter_mut()
        .find(|m| m.name == "floor")
        .expect("veach-mis has a floor");
    floor.kind = tessera_scene::MaterialKind::Diffuse {
        albedo: glam::Vec3::splat(0.5),
    };
    let o = welch(&desc, unbiased("bdpt", 8), &reference);
    println!(
        "floor 0.5 for 0.4: {:.2} % of pixel channels under p = {ALPHA}, mean ratio {:.4} (z {:.2})",
        100.0 * o.rejected,
        o.mean_ratio,
        o.mean_z
    );
    assert!(
        o.rejected > 5.0 * ALPHA,
        "a wrong floor passed: {:.2} %",
        100.0 * o.rejected
    );
}
