//! The hard cases of `scenes/hard/`: each folder holds a scene and `expect.json`, what its
//! render must show — an analytic value (with a tolerance of several standard errors of the
//! film's own variance estimate plus a stated relative slack), bounds, coverage or blackness.
//! Every render must also be free of NaN and Inf. Per-pixel bounds allow the noise a render
//! of another seed estimates for the pixel (so a firefly fails them), not the pixel's own.

use std::path::{Path, PathBuf};

use serde_json::Value;
use tessera_render::camera::Camera;
use tessera_render::film::SampleRange;
use tessera_render::render::render_frame;
use tessera_render::{Image, Scene};

fn hard_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/hard")
}

struct Region<'a> {
    pixels: Vec<&'a tessera_render::film::Pixel>,
    /// The same pixels' places in the image.
    index: Vec<usize>,
}

fn region<'a>(img: &'a Image, check: &Value) -> Region<'a> {
    let r: Vec<u32> = check["region"]
        .as_array()
        .expect("region [x0, y0, x1, y1]")
        .iter()
        .map(|v| v.as_u64().expect("pixel coordinate") as u32)
        .collect();
    let mut pixels = Vec::new();
    let mut index = Vec::new();
    for y in r[1]..r[3] {
        for x in r[0]..r[2] {
            let i = (y * img.width + x) as usize;
            pixels.push(&img.pixels[i]);
            index.push(i);
        }
    }
    assert!(!pixels.is_empty(), "empty region {r:?}");
    Region { pixels, index }
}

/// Checks one case; returns the failures.
fn check_case(dir: &Path) -> Vec<String> {
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let expect: Value =
        serde_json::from_slice(&std::fs::read(dir.join("expect.json")).expect("expect.json"))
            .expect("expect.json is JSON");
    let desc = tessera_scene::load(&dir.join("scene.json")).unwrap_or_else(|e| panic!("{e}"));
    let scene = Scene::build(&desc);
    let camera = Camera::new(&desc.camera, &desc.film);
    let integ = tessera_render::method::for_scene(&desc, &scene).expect("a per-ray method");
    let range = SampleRange {
        start: 0,
        end: desc.integrator.spp,
    };
    let (img, stats) = render_frame(&scene, &camera, integ.as_ref(), 16, range);
    // The same scene with another seed: an independent estimate of every pixel's noise.
    let mut other = desc.clone();
    other.integrator.seed ^= 0x5eed_0a1e;
    let other_integ = tessera_render::method::for_scene(&other, &scene).expect("a per-ray method");
    let (img2, _) = render_frame(&scene, &camera, other_integ.as_ref(), 16, range);
    let mut failures = Vec::new();
    let mut fail = |what: &str, msg: String| failures.push(format!("{name}: {what}: {msg}"));
    if stats.nonfinite > 0
        || !img
            .pixels
            .iter()
            .all(|p| p.rgb.iter().chain(&p.variance).all(|v| v.is_finite()))
    {
        fail("film", format!("{} non-finite samples", stats.nonfinite));
    }
    for check in expect["checks"].as_array().expect("checks") {
        let what = check["what"].as_str().unwrap_or("check");
        let reg = region(&img, check);
        let sigmas = check["sigmas"].as_f64().unwrap_or(5.0);
        let rel = check["rel"].as_f64().unwrap_or(0.0);
        let n = reg.pixels.len() as f64;
        for c in 0..3 {
            let mean = reg.pixels.iter().map(|p| p.rgb[c] as f64).sum::<f64>() / n;
            // Standard error of the region mean: pixels are independent.
            let se = reg
                .pixels
                .iter()
                .map(|p| p.variance[c] as f64)
                .sum::<f64>()
                .sqrt()
                / n;
            if let Some(v) = check["mean"].as_f64()
                && (mean - v).abs() > sigmas * se + rel * v.abs()
            {
                fail(
                    what,
                    format!("channel {c}: mean {mean:.6} ± {se:.2e}, expected {v:.6}"),
                );
            }
            if let Some(v) = check["min"].as_f64()
                && mean + sigmas * se < v
            {
                fail(
                    what,
                    format!("channel {c}: mean {mean:.6} ± {se:.2e} below {v}"),
                );
            }
            if let Some(v) = check["max"].as_f64()
                && mean - sigmas * se > v * (1.0 + rel)
            {
                fail(
                    what,
                    format!("channel {c}: mean {mean:.6} ± {se:.2e} above {v}"),
                );
            }
            let pixels: Vec<(f64, f64)> = reg
                .pixels
                .iter()
                .zip(&reg.index)
                .map(|(p, &i)| (p.rgb[c] as f64, img2.pixels[i].variance[c] as f64))
                .collect();
            if let Some(problem) = pixel_problem(&pixels, check, sigmas, rel) {
                fail(what, format!("channel {c}: {problem}"));
            }
        }
        if let Some(a) = check["alpha"].as_f64()
            && let Some(p) = reg
                .pixels
                .iter()
                .find(|p| (p.alpha as f64 - a).abs() > 1e-6)
        {
            fail(what, format!("coverage {} , expected {a}", p.alpha));
        }
    }
    failures
}

/// The first of a region's pixels — (value, variance of the same pixel in an independent
/// render) — that breaks a per-pixel bound of `check` (`every_pixel`, `min_pixel`,
/// `max_pixel`, `black`), if one does. A pixel is judged against the noise another seed sees
/// there, not its own: a firefly carries its own huge variance with it.
fn pixel_problem(pixels: &[(f64, f64)], check: &Value, sigmas: f64, rel: f64) -> Option<String> {
    for &(x, variance) in pixels {
        let sd = variance.sqrt();
        if let Some(v) = check["every_pixel"].as_f64()
            && (x - v).abs() > sigmas * sd + rel * v.abs()
        {
            return Some(format!(
                "pixel {x:.6}, independent noise {sd:.2e}, expected {v:.6}"
            ));
        }
        if let Some(v) = check["min_pixel"].as_f64()
            && x + sigmas * sd < v * (1.0 - rel)
        {
            return Some(format!("pixel {x:.6} below {v}"));
        }
        if let Some(v) = check["max_pixel"].as_f64()
            && x - sigmas * sd > v * (1.0 + rel)
        {
            return Some(format!("pixel {x:.6} above {v}"));
        }
        if check["black"].as_bool() == Some(true) && x != 0.0 {
            return Some(format!("pixel {x:e}, expected black"));
        }
    }
    None
}

#[test]
fn a_firefly_fails_the_per_pixel_bounds_though_its_own_variance_is_huge() {
    // 99 pixels at 0.5 ± 0.01 and one at 50 (its own σ, from its huge sample, would be 20;
    // another seed's render of that pixel has the usual 0.01).
    let mut pixels = vec![(0.5, 1e-4); 99];
    pixels.push((50.0, 1e-4));
    let check = serde_json::json!({"max_pixel": 0.6});
    assert!(pixel_problem(&pixels, &check, 5.0, 0.0).is_some());
    let check = serde_json::json!({"every_pixel": 0.5});
    assert!(pixel_problem(&pixels, &check, 5.0, 0.0).is_some());
    pixels.pop();
    assert!(pixel_problem(&pixels, &check, 5.0, 0.0).is_none());
}

#[test]
fn every_hard_case_renders_what_it_must() {
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(hard_dir())
        .expect("scenes/hard")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join("expect.json").exists())
        .collect();
    dirs.sort();
    assert!(dirs.len() >= 12, "{dirs:?}");
    let failures: Vec<String> = dirs.iter().flat_map(|d| check_case(d)).collect();
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
