//! The `tessera` binary as a user runs it: renders write their files, bad input exits with a
//! message naming file, field and expectation (and never panics), images are independent of
//! threads and tiles, and the Cornell box agrees with the Mitsuba reference.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn tessera(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tessera"))
        .args(args)
        .output()
        .expect("run tessera")
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn cornell() -> String {
    repo()
        .join("scenes/cornell-box/scene.json")
        .display()
        .to_string()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Renders the Cornell box quietly to `out` with extra arguments; panics with stderr if the
/// render fails.
fn render_cornell(out: &Path, extra: &[&str]) -> Output {
    let scene = cornell();
    let out = out.to_str().expect("utf-8 temp path");
    let mut args = vec!["render", &scene, "-o", out, "-q"];
    args.extend_from_slice(extra);
    let o = tessera(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    o
}

#[test]
fn render_writes_exr_and_png_and_reports_throughput() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("cb.exr");
    let o = render_cornell(&out, &["--spp", "1"]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("M samples/s") && stdout.contains("M rays/s") && stdout.contains(" s wall"),
        "{stdout}"
    );
    let img = tessera_render::read_exr(&out).expect("readable EXR");
    assert_eq!((img.width, img.height), (256, 256));
    assert!(dir.path().join("cb.png").exists());
}

fn bad_scene(json: &str) -> (i32, String) {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("scene.json");
    std::fs::write(&path, json).expect("write");
    let o = tessera(&[
        "render",
        path.to_str().unwrap(),
        "-o",
        dir.path().join("x.exr").to_str().unwrap(),
        "-q",
    ]);
    let err = stderr(&o);
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        !dir.path().join("x.exr").exists(),
        "no image may be written for a bad scene"
    );
    (o.status.code().unwrap_or(-1), err)
}

#[test]
fn bad_scenes_exit_with_code_2_and_a_message_naming_file_field_and_expectation() {
    let base = r#"{ "units": "m", "camera": { "type": "pinhole", "position": [0, 0, -3], "look_at": [0, 0, 0], "fov_deg": 40 },
                   "film": { "width": 8, "height": 8 }, "materials": { "m": { "type": "diffuse", "albedo": 0.5 } },
                   "shapes": [ SHAPE ] }"#;
    let cases = [
        (
            r#"{ "type": "mesh", "file": "missing.obj", "material": "m" }"#,
            "shapes[0].file",
            "cannot read mesh file",
        ),
        (
            r#"{ "type": "sphere", "center": [0, 0, 0], "radius": -1, "material": "m" }"#,
            "shapes[0].radius",
            "expected a positive number",
        ),
        (
            r#"{ "type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "steel" }"#,
            "shapes[0].material",
            "unknown material \"steel\"",
        ),
        (
            r#"{ "type": "mesh", "file": "../../etc/passwd", "material": "m" }"#,
            "shapes[0].file",
            "leaves it",
        ),
    ];
    for (shape, field, expected) in cases {
        let (code, err) = bad_scene(&base.replace("SHAPE", shape));
        assert_eq!(code, 2, "{err}");
        assert!(
            err.contains("scene.json") && err.contains(field) && err.contains(expected),
            "{err}"
        );
    }
    let (code, err) = bad_scene(
        &base
            .replace("SHAPE", "")
            .replace(r#""width": 8"#, r#""width": 0"#),
    );
    assert_eq!(code, 2);
    assert!(
        err.contains("film.width") && err.contains("expected a size"),
        "{err}"
    );
    let (code, err) = bad_scene("{ not json");
    assert_eq!(code, 2);
    assert!(
        err.contains("scene.json") && err.contains("line 1"),
        "{err}"
    );
}

#[test]
fn missing_scene_file_and_bad_arguments_fail_cleanly() {
    let o = tessera(&["render", "/nonexistent/scene.json", "-q"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("/nonexistent/scene.json") && stderr(&o).contains("cannot read"),
        "{}",
        stderr(&o)
    );
    for args in [
        ["--spp", "0"],
        ["--spp", "99999999999"],
        ["--tile", "0"],
        ["--threads", "x"],
    ] {
        let o = tessera(&["render", &cornell(), args[0], args[1], "-q"]);
        assert!(
            !o.status.success() && !stderr(&o).contains("panicked"),
            "{args:?}: {}",
            stderr(&o)
        );
    }
}

#[test]
fn images_are_bit_identical_for_any_threads_and_tile_size() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut files = Vec::new();
    for (threads, tile) in [("1", "16"), ("2", "64"), ("2", "16"), ("1", "64")] {
        let out = dir.path().join(format!("t{threads}-{tile}.exr"));
        render_cornell(&out, &["--spp", "3", "--threads", threads, "--tile", tile]);
        files.push(std::fs::read(&out).expect("exr"));
    }
    assert!(
        files.windows(2).all(|w| w[0] == w[1]),
        "EXR files differ between thread counts or tile sizes"
    );
}

#[test]
fn cornell_box_matches_the_mitsuba_reference_without_bias() {
    // At 64 spp Mitsuba 3 reaches relMSE 4.77e-3 on this frame; the bar for 1024 spp is 1.25×
    // Mitsuba's figure, so the same factor at 64 spp. The mean must agree within 0.5 % (the
    // issue asks for 1 %; the mean over 196 608 values at this noise level is good to 0.02 %).
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("cb.exr");
    render_cornell(&out, &["--spp", "64"]);
    let img = tessera_render::read_exr(&out).expect("render");
    let reference = tessera_render::read_exr(&repo().join("scenes/cornell-box/reference.exr"))
        .expect("reference");
    let a = |v: &[glam::Vec3]| v.iter().map(|&p| p.into()).collect::<Vec<glam::Vec3A>>();
    let e = tessera_render::metrics::compare(&a(&img.pixels), &a(&reference.pixels));
    assert!(e.rel_mse <= 1.25 * 4.77e-3, "relMSE {:.3e}", e.rel_mse);
    assert!(
        (e.mean_ratio - 1.0).abs() < 0.005,
        "mean ratio {}",
        e.mean_ratio
    );
    assert!(img.pixels.iter().all(|p| p.is_finite()));
}

#[test]
fn compare_reports_errors_and_refuses_mismatched_sizes() {
    let reference = repo().join("scenes/cornell-box/reference.exr");
    let o = tessera(&[
        "compare",
        reference.to_str().unwrap(),
        reference.to_str().unwrap(),
    ]);
    assert!(o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("relMSE 0.0000e0"),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    let sky = repo().join("scenes/material-spheres/sky.exr");
    let o = tessera(&[
        "compare",
        sky.to_str().unwrap(),
        reference.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("differs from the reference"),
        "{}",
        stderr(&o)
    );
    // Mitsuba's 512² box, averaged over 2 × 2 pixels, against its 256² box (both box-filtered
    // renders of the same view, each converged): refused without --downsample,
    // with a hint; with it, the two agree to their own noise.
    let big = repo().join("scenes/cornell-box/reference-512.exr");
    let args = |more: &[&'static str]| {
        let mut a = vec![
            "compare",
            big.to_str().unwrap(),
            reference.to_str().unwrap(),
        ];
        a.extend(more);
        a
    };
    let o = tessera(&args(&[]));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--downsample"), "{}", stderr(&o));
    let o = tessera(&args(&["--downsample"]));
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(
        out.starts_with("averaged over 2×2 pixels to 256×256"),
        "{out}"
    );
    let number = |key: &str| -> f64 {
        out.split(key)
            .nth(1)
            .and_then(|r| r.split_whitespace().next())
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("no {key} in {out}"))
    };
    assert!(number("relMSE ") < 2e-4, "{out}");
    assert!((number("mean/reference ") - 1.0).abs() < 1e-3, "{out}");
    // Not a whole multiple of the reference.
    let o = tessera(&[
        "compare",
        sky.to_str().unwrap(),
        reference.to_str().unwrap(),
        "--downsample",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("not the reference's"), "{}", stderr(&o));
}

/// `tessera bench` of the Cornell box against `reference` (in its scene folder) with `args`:
/// the report folder (kept while the returned temporary directory lives) and report.json.
fn bench_cornell(
    reference: &str,
    args: &[&str],
) -> (tempfile::TempDir, PathBuf, serde_json::Value) {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("report");
    let reference = repo().join("scenes/cornell-box").join(reference);
    let mut all = vec![
        "bench",
        "--reference",
        reference.to_str().expect("utf-8"),
        "-o",
        out.to_str().expect("utf-8"),
    ];
    all.extend_from_slice(args);
    let scene = cornell();
    all.push(&scene);
    let o = tessera(&all);
    assert!(o.status.success(), "{}", stderr(&o));
    let json =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).expect("report.json"))
            .expect("JSON");
    (dir, out, json)
}

#[test]
fn bench_with_seeds_renders_each_seed_and_reports_when_half_reached_an_error() {
    let (_dir, out, json) = bench_cornell(
        "reference-32.exr",
        &[
            "--budgets",
            "1,16,256",
            "--integrators",
            "path",
            "--seeds",
            "3",
        ],
    );
    let seed = |v: &serde_json::Value| v["seed"].as_u64().expect("seed");
    let runs = json["runs"].as_array().expect("runs");
    assert_eq!(runs.len(), 9);
    let seeds: Vec<u64> = runs.iter().map(seed).collect();
    assert_eq!(seeds, [0, 0, 0, 1, 1, 1, 2, 2, 2], "{runs:?}");
    assert_eq!(json["seeds"], serde_json::json!([0, 1, 2]));
    // Each seed is its own render: the same budget, a different error.
    let err = |i: usize| runs[i]["rel_mse"].as_f64().unwrap_or(f64::NAN);
    assert!(err(0) != err(3) && err(3) != err(6), "{runs:?}");
    // The reported time is the second smallest of the three seeds' times (every seed
    // reaches 1e-2 by 256 spp).
    let times = json["time_to_error"].as_array().expect("time_to_error");
    assert!(
        times[0]["rel_mse"] == 1e-2
            && times[0]["per_seed"]
                .as_array()
                .is_some_and(|s| s.iter().all(|v| v.is_f64())),
        "{times:?}"
    );
    for t in times {
        let per_seed = t["per_seed"].as_array().expect("per_seed");
        assert_eq!(per_seed.len(), 3);
        let mut reached: Vec<f64> = per_seed.iter().filter_map(|v| v.as_f64()).collect();
        reached.sort_by(f64::total_cmp);
        assert_eq!(t["wall_s"].as_f64(), reached.get(1).copied(), "{t}");
    }
    let md = std::fs::read_to_string(out.join("report.md")).expect("md");
    assert!(
        md.contains("half of the 3 seeds") && md.contains("| path | 1e-2 |"),
        "{md}"
    );
}

#[test]
fn bench_writes_a_speed_against_error_report() {
    let (_dir, out, json) = bench_cornell(
        "reference.exr",
        &["--budgets", "2,4", "--integrators", "path,direct"],
    );
    let runs = json["runs"].as_array().expect("runs");
    assert_eq!(runs.len(), 4);
    for r in runs {
        for key in [
            "spp",
            "wall_s",
            "rel_mse",
            "rmse",
            "mean_ratio",
            "estimated_rel_mse",
        ] {
            assert!(r[key].is_number(), "{key} in {r}");
        }
    }
    // Path tracing converges: error falls with samples; direct lighting misses light (biased).
    let err = |i: usize| runs[i]["rel_mse"].as_f64().unwrap_or(f64::NAN);
    assert!(err(1) < err(0), "{runs:?}");
    assert!(runs[3]["mean_ratio"].as_f64().unwrap_or(1.0) < 0.9);
    let csv = std::fs::read_to_string(out.join("report.csv")).expect("csv");
    assert_eq!(csv.lines().count(), 5);
    let md = std::fs::read_to_string(out.join("report.md")).expect("md");
    assert!(
        md.contains("| path | 0 | 4 spp | 4 |") && md.contains("Wall seconds to reach"),
        "{md}"
    );
    let png = std::fs::read(out.join("report.png")).expect("png");
    assert!(png.starts_with(b"\x89PNG"));
    // Without a reference, or with an unknown integrator: a clear error.
    let o = tessera(&["bench", &cornell()]);
    assert!(
        !o.status.success() && stderr(&o).contains("--reference"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn adaptive_render_writes_its_error_estimate_into_the_exr_header() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out = dir.path().join("ad.exr");
    let o = render_cornell(&out, &["--spp", "64", "--target-error", "0.05"]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("target error reached"), "{stdout}");
    let bytes = std::fs::read(&out).expect("exr");
    let header = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]);
    for key in ["estimated_rel_mse", "target_rel_mse", "adaptive_spp_max"] {
        assert!(header.contains(key), "{key} not in the EXR header");
    }
    let o = tessera(&[
        "render",
        &cornell(),
        "--target-error=-1",
        "-o",
        out.to_str().expect("utf-8"),
    ]);
    assert!(!o.status.success() && stderr(&o).contains("target_error: expected a positive"));
}

/// `tessera export` writes the scene as Mitsuba reads it: the sensor at the asked size, one
/// PLY per mesh whose header counts the mesh's vertices and faces, the sphere lights with
/// their radiance; and refuses, naming it, a material Mitsuba has no plugin for.
#[test]
fn export_writes_mitsuba_xml_and_refuses_what_mitsuba_lacks() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().to_str().expect("utf-8 temp path");
    let scene = repo().join("scenes/veach-mis/scene.json");
    let o = tessera(&[
        "export",
        scene.to_str().expect("utf-8"),
        "--size",
        "96x64",
        "-o",
        out,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let xml = std::fs::read_to_string(dir.path().join("scene.xml")).expect("scene.xml");
    assert!(
        xml.contains(r#"<integer name="width" value="96"/>"#),
        "{xml}"
    );
    assert!(
        xml.contains(r#"<string name="fov_axis" value="y"/>"#),
        "{xml}"
    );
    assert_eq!(
        xml.matches(r#"<bsdf type="roughconductor">"#).count(),
        4,
        "{xml}"
    );
    assert_eq!(xml.matches(r#"<shape type="sphere">"#).count(), 4, "{xml}");
    assert_eq!(xml.matches(r#"<emitter type="area">"#).count(), 4, "{xml}");
    let desc = tessera_scene::load(&scene).expect("scene");
    assert_eq!(
        xml.matches(r#"<shape type="ply">"#).count(),
        desc.meshes.len()
    );
    for (i, m) in desc.meshes.iter().enumerate() {
        let ply = std::fs::read(dir.path().join(format!("meshes/{i}.ply"))).expect("ply");
        let header = String::from_utf8_lossy(&ply[..ply.len().min(400)]).into_owned();
        assert!(
            header.contains(&format!("element vertex {}\n", m.positions.len())),
            "{header}"
        );
        assert!(
            header.contains(&format!("element face {}\n", m.triangles.len())),
            "{header}"
        );
        let body = ply.len() - (header.find("end_header\n").expect("end_header") + 11);
        assert_eq!(body, m.positions.len() * 12 + m.triangles.len() * 13);
    }
    let spheres = repo().join("scenes/material-spheres/scene.json");
    let o = tessera(&["export", spheres.to_str().expect("utf-8"), "-o", out]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("material \"brushed\": Mitsuba 3 has no Ward BSDF"),
        "{}",
        stderr(&o)
    );
}

/// `tessera serve` with `args` and the environment `env`, everything else valid, in a new
/// data directory (for configurations it must refuse: it would serve forever otherwise).
fn serve_with(args: &[&str], env: &[(&str, &str)]) -> Output {
    let dir = tempfile::tempdir().expect("temp dir");
    Command::new(env!("CARGO_BIN_EXE_tessera"))
        .args(["serve", "--listen", "127.0.0.1:0", "--data"])
        .arg(dir.path().join("data"))
        .args(args)
        .envs(env.iter().copied())
        .output()
        .expect("run tessera")
}

/// `tessera serve --store URL`.
fn serve_with_store(url: &str) -> Output {
    serve_with(&["--store", url], &[])
}

#[test]
fn serve_refuses_a_job_store_it_cannot_use_naming_it() {
    let o = serve_with_store("mysql://tessera@127.0.0.1/tessera");
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("--store") && err.contains("PostgreSQL URL"),
        "{err}"
    );

    // Nothing listens on port 1: the coordinator exits naming the database and the host.
    let o = serve_with_store("postgres://tessera:tessera@127.0.0.1:1/farm");
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("job store")
            && err.contains("\"farm\"")
            && err.contains("127.0.0.1")
            && err.to_lowercase().contains("refused"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");

    // Wrong credentials, where the suite runs on PostgreSQL (CI's second run).
    let Ok(base) = std::env::var("TESSERA_TEST_POSTGRES") else {
        eprintln!("wrong credentials: not checked (TESSERA_TEST_POSTGRES is not set)");
        return;
    };
    let (scheme, rest) = base.split_once("://").expect("a URL");
    let (userinfo, host) = rest.split_once('@').expect("a URL with a user");
    let user = userinfo.split(':').next().unwrap_or(userinfo);
    let o = serve_with_store(&format!("{scheme}://{user}:not-the-password@{host}"));
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("password authentication failed") && err.contains(user),
        "{err}"
    );
}

/// `tessera serve --objects LOCATION`, with `env`.
fn serve_with_objects(location: &str, env: &[(&str, &str)]) -> Output {
    serve_with(&["--objects", location], env)
}

#[test]
fn serve_refuses_an_object_store_it_cannot_write_naming_it() {
    // A directory that cannot be made: a file is where it would go.
    let dir = tempfile::tempdir().expect("temp dir");
    let file = dir.path().join("a-file");
    std::fs::write(&file, b"x").expect("file");
    let objects = file.join("objects");
    let o = serve_with_objects(objects.to_str().expect("utf-8"), &[]);
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("object store")
            && err.contains("cannot be written")
            && err.contains("a-file/objects"),
        "{err}"
    );

    // S3 that does not answer (nothing listens on port 1): the probe write fails, named.
    let o = serve_with_objects(
        "s3://tessera-test/farm",
        &[
            ("AWS_ENDPOINT_URL", "http://127.0.0.1:1"),
            ("AWS_ALLOW_HTTP", "true"),
            ("AWS_ACCESS_KEY_ID", "tessera"),
            ("AWS_SECRET_ACCESS_KEY", "tessera"),
            ("AWS_REGION", "us-east-1"),
        ],
    );
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("the object store s3://tessera-test/farm cannot be written")
            && err.contains("127.0.0.1:1"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");

    // A kind of store there is no backend for.
    let o = serve_with_objects("ftp://host/farm", &[]);
    let err = stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("--objects ftp://host/farm") && err.contains("s3://"),
        "{err}"
    );
}
