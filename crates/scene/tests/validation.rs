//! Bad scenes are rejected before rendering, with a message naming the file, the field path
//! and what was expected — never a panic. Good scenes resolve to canonical units.

use std::path::{Path, PathBuf};

use tessera_scene::{LightDesc, MaterialKind, SceneDesc, SceneError, load};

/// A minimal valid scene; tests replace parts of it.
const BASE: &str = r#"{
  "units": "m",
  "camera": { "type": "pinhole", "position": [0, 1, -5], "look_at": [0, 1, 0], "fov_deg": 40 },
  "film": { "width": 32, "height": 24 },
  "materials": { "white": { "type": "diffuse", "albedo": 0.8 } },
  "shapes": [ SHAPES ],
  "lights": [ LIGHTS ]
}"#;

const QUAD: &str = r#"{ "type": "quad", "origin": [-1, 0, -1], "edge_u": [0, 0, 2], "edge_v": [2, 0, 0], "material": "white" }"#;
const POINT: &str = r#"{ "type": "point", "position": [0, 3, 0], "intensity": 10 }"#;

/// Writes `scene.json` (and extra files) into a fresh folder and loads it.
fn try_load(
    json: &str,
    files: &[(&str, &str)],
) -> (tempfile::TempDir, Result<SceneDesc, SceneError>) {
    let dir = tempfile::tempdir().expect("temp dir");
    std::fs::write(dir.path().join("scene.json"), json).expect("write scene");
    for (name, content) in files {
        let path = dir.path().join(name);
        std::fs::create_dir_all(path.parent().expect("parent")).expect("mkdir");
        std::fs::write(path, content).expect("write file");
    }
    let result = load(&dir.path().join("scene.json"));
    (dir, result)
}

fn scene(shapes: &str, lights: &str) -> String {
    BASE.replace("SHAPES", shapes).replace("LIGHTS", lights)
}

/// Loads a bad scene and returns its problems as (file name, path, message).
fn problems(json: &str, files: &[(&str, &str)]) -> Vec<(String, String, String)> {
    let (_dir, result) = try_load(json, files);
    let err = result.expect_err("the scene should be rejected");
    // The Display of the error lists every problem too.
    let shown = err.to_string();
    err.problems()
        .iter()
        .map(|p| {
            assert!(shown.contains(&p.message), "{shown}");
            let name = p
                .file
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            (name, p.path.clone(), p.message.clone())
        })
        .collect()
}

fn one_problem(json: &str, files: &[(&str, &str)]) -> (String, String, String) {
    let mut p = problems(json, files);
    assert_eq!(p.len(), 1, "expected one problem, got {p:?}");
    p.remove(0)
}

#[test]
fn the_base_scene_is_valid() {
    let (_dir, r) = try_load(&scene(QUAD, POINT), &[]);
    let d = r.expect("valid");
    assert_eq!(d.meshes.len(), 1);
    assert_eq!((d.film.width, d.film.height), (32, 24));
}

#[test]
fn missing_mesh_file() {
    let (file, path, msg) = one_problem(
        &scene(
            r#"{ "type": "mesh", "file": "gone.obj", "material": "white" }"#,
            POINT,
        ),
        &[],
    );
    assert_eq!(
        (file.as_str(), path.as_str()),
        ("scene.json", "shapes[0].file")
    );
    assert!(
        msg.contains("cannot read mesh file") && msg.contains("gone.obj"),
        "{msg}"
    );
}

#[test]
fn nan_coordinate_in_a_mesh_names_the_mesh_file_and_line() {
    let obj = "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n";
    let (file, path, msg) = one_problem(
        &scene(
            r#"{ "type": "mesh", "file": "meshes/tri.obj", "material": "white" }"#,
            POINT,
        ),
        &[("meshes/tri.obj", obj)],
    );
    assert_eq!((file.as_str(), path.as_str()), ("tri.obj", "line 3"));
    assert!(
        msg.contains("finite") && msg.contains("shapes[0].file"),
        "{msg}"
    );
}

#[test]
fn out_of_range_face_index() {
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n";
    let (file, path, msg) = one_problem(
        &scene(
            r#"{ "type": "mesh", "file": "t.obj", "material": "white" }"#,
            POINT,
        ),
        &[("t.obj", obj)],
    );
    assert_eq!((file.as_str(), path.as_str()), ("t.obj", "line 4"));
    assert!(msg.contains("out of range"), "{msg}");
}

#[test]
fn negative_radius() {
    let (file, path, msg) = one_problem(
        &scene(
            r#"{ "type": "sphere", "center": [0, 1, 0], "radius": -2, "material": "white" }"#,
            POINT,
        ),
        &[],
    );
    assert_eq!(
        (file.as_str(), path.as_str()),
        ("scene.json", "shapes[0].radius")
    );
    assert!(
        msg.contains("expected a positive number") && msg.contains("-2"),
        "{msg}"
    );
}

#[test]
fn unknown_material_lists_the_known_ones() {
    let (_, path, msg) = one_problem(&scene(&QUAD.replace("\"white\"", "\"whte\""), POINT), &[]);
    assert_eq!(path, "shapes[0].material");
    assert!(
        msg.contains("unknown material \"whte\"") && msg.contains("white"),
        "{msg}"
    );
}

#[test]
fn zero_size_film() {
    let json = scene(QUAD, POINT).replace(r#""width": 32"#, r#""width": 0"#);
    let (_, path, msg) = one_problem(&json, &[]);
    assert_eq!(path, "film.width");
    assert!(msg.contains("expected a size from 1"), "{msg}");
}

#[test]
fn a_path_that_leaves_the_scene_folder() {
    for file in ["../outside.obj", "/etc/passwd", "a/../../b.obj"] {
        let shape = format!(r#"{{ "type": "mesh", "file": "{file}", "material": "white" }}"#);
        let (_, path, msg) = one_problem(&scene(&shape, POINT), &[]);
        assert_eq!(path, "shapes[0].file");
        assert!(
            msg.contains("leaves it") || msg.contains("absolute"),
            "{msg}"
        );
    }
}

#[test]
fn malformed_json_gives_position() {
    let json = scene(QUAD, POINT).replace("\"fov_deg\": 40 }", "\"fov_deg\": 40 ");
    let (file, _path, msg) = one_problem(&json, &[]);
    assert_eq!(file, "scene.json");
    assert!(msg.contains("line") && msg.contains("column"), "{msg}");
}

#[test]
fn misspelt_field_and_wrong_type_inside_a_tagged_object() {
    let (_, path, msg) = one_problem(
        &scene(
            r#"{ "type": "sphere", "center": [0, 1, 0], "raduis": 2, "material": "white" }"#,
            POINT,
        ),
        &[],
    );
    assert_eq!(path, "shapes[0].raduis");
    assert!(
        msg.contains("unknown field `raduis`") && msg.contains("radius"),
        "{msg}"
    );
    let (_, path, msg) = one_problem(
        &scene(
            r#"{ "type": "sphere", "center": [0, 1, 0], "radius": "big", "material": "white" }"#,
            POINT,
        ),
        &[],
    );
    assert_eq!(path, "shapes[0].radius");
    assert!(msg.contains("expected f32"), "{msg}");
    let (_, path, msg) = one_problem(
        &scene(
            r#"{ "type": "sphere", "center": [0, 1], "radius": 1, "material": "white" }"#,
            POINT,
        ),
        &[],
    );
    assert_eq!(path, "shapes[0].center");
    assert!(msg.contains("array of length 3"), "{msg}");
}

#[test]
fn unknown_types_list_the_known_ones() {
    let (_, path, msg) = one_problem(
        &scene(r#"{ "type": "torus", "material": "white" }"#, POINT),
        &[],
    );
    assert_eq!(path, "shapes[0].type");
    assert!(msg.contains("\"torus\"") && msg.contains("sphere"), "{msg}");
    let json = scene(QUAD, POINT).replace(
        r#"{ "type": "diffuse", "albedo": 0.8 }"#,
        r#"{ "type": "velvet" }"#,
    );
    let (_, path, _) = one_problem(&json, &[]);
    assert_eq!(path, "materials.white.type");
}

#[test]
fn albedo_above_one_and_energy_gain_are_rejected() {
    let json = scene(QUAD, POINT).replace(r#""albedo": 0.8"#, r#""albedo": [0.5, 1.2, 0.5]"#);
    let (_, path, msg) = one_problem(&json, &[]);
    assert_eq!(path, "materials.white.albedo");
    assert!(msg.contains("[0, 1]"), "{msg}");
    let json = scene(QUAD, POINT).replace(
        r#"{ "type": "diffuse", "albedo": 0.8 }"#,
        r#"{ "type": "phong", "diffuse": 0.6, "specular": 0.6, "exponent": 20 }"#,
    );
    let (_, path, msg) = one_problem(&json, &[]);
    assert_eq!(path, "materials.white.specular");
    assert!(msg.contains("energy conservation"), "{msg}");
}

#[test]
fn radiant_watts_without_a_spectrum() {
    let light = r#"{ "type": "point", "position": [0, 3, 0], "power": { "watts": 40 }, "color": [1, 0.9, 0.8] }"#;
    let (_, path, msg) = one_problem(&scene(QUAD, light), &[]);
    assert_eq!(path, "lights[0].power.efficacy_lm_per_w");
    assert!(msg.contains("temperature_k"), "{msg}");
}

#[test]
fn instances_may_not_recurse() {
    let json = scene(r#"{ "type": "instance", "object": "a" }"#, POINT).replace(
        r#""shapes": ["#,
        r#""objects": { "a": [{ "type": "instance", "object": "b" }], "b": [{ "type": "instance", "object": "a" }] }, "shapes": ["#,
    );
    let p = problems(&json, &[]);
    assert!(
        p.iter()
            .any(|(_, path, msg)| path.ends_with(".object") && msg.contains("instances itself")),
        "{p:?}"
    );
}

#[test]
fn all_problems_are_reported_together() {
    let json = scene(
        r#"{ "type": "sphere", "center": [0, 1, 0], "radius": 0, "material": "nope" }, { "type": "mesh", "file": "x.ply", "material": "white" }"#,
        POINT,
    )
    .replace(r#""height": 24"#, r#""height": 0"#);
    let paths: Vec<String> = problems(&json, &[]).into_iter().map(|p| p.1).collect();
    for expected in [
        "film.height",
        "shapes[0].radius",
        "shapes[0].material",
        "shapes[1].file",
    ] {
        assert!(
            paths.iter().any(|p| p == expected),
            "{expected} missing from {paths:?}"
        );
    }
}

#[test]
fn thin_lens_needs_its_parameters_and_pinhole_rejects_them() {
    let json = scene(QUAD, POINT).replace(r#""type": "pinhole""#, r#""type": "thin_lens""#);
    let paths: Vec<String> = problems(&json, &[]).into_iter().map(|p| p.1).collect();
    assert!(
        paths.contains(&"camera.aperture_radius".into())
            && paths.contains(&"camera.focus_distance".into())
    );
    let json = scene(QUAD, POINT).replace(
        r#""fov_deg": 40"#,
        r#""fov_deg": 40, "aperture_radius": 0.1"#,
    );
    let (_, path, msg) = one_problem(&json, &[]);
    assert_eq!(path, "camera.aperture_radius");
    assert!(msg.contains("thin_lens"), "{msg}");
}

#[test]
fn camera_looking_along_up_is_rejected() {
    let json = scene(QUAD, POINT).replace(r#""look_at": [0, 1, 0]"#, r#""look_at": [0, 5, -5]"#);
    let (_, path, _) = one_problem(&json, &[]);
    assert_eq!(path, "camera.up");
}

#[test]
fn squashed_sphere_is_rejected() {
    let shape = r#"{ "type": "sphere", "center": [0, 1, 0], "radius": 1, "material": "white", "transform": [{ "scale": [1, 2, 1] }] }"#;
    let (_, path, msg) = one_problem(&scene(shape, POINT), &[]);
    assert_eq!(path, "shapes[0].transform");
    assert!(msg.contains("uniform"), "{msg}");
}

#[test]
fn a_garbage_file_is_an_error_not_a_panic() {
    for junk in [
        "",
        "null",
        "[]",
        "{}",
        "{\"units\": 3}",
        "\u{0}\u{1}\u{2}",
        "{\"shapes\": [{}]}",
    ] {
        let (_dir, r) = try_load(junk, &[]);
        assert!(r.is_err(), "accepted {junk:?}");
    }
    let obj = "f 1 2 3\n";
    let (_, path, _) = one_problem(
        &scene(
            r#"{ "type": "mesh", "file": "t.obj", "material": "white" }"#,
            POINT,
        ),
        &[("t.obj", obj)],
    );
    assert_eq!(path, "line 1");
}

// ---- resolution into canonical units ---------------------------------------------------

#[test]
fn emitter_power_becomes_radiance_over_its_area_in_square_metres() {
    // A 2 m × 2 m quad in a scene in centimetres (200 × 200 cm) emitting 1000 lm, one-sided:
    // L = Φ / (683 lm/W · π · A) with A = 4 m², white (luminance 1).
    let shape = r#"{ "type": "quad", "origin": [0, 0, 0], "edge_u": [200, 0, 0], "edge_v": [0, 0, 200], "material": "white",
                    "emission": { "power": { "lumens": 1000 } } }"#;
    let json = scene(shape, POINT).replace(r#""units": "m""#, r#""units": "cm""#);
    let (_dir, r) = try_load(&json, &[]);
    let d = r.expect("valid");
    let l = d.meshes[0].emission.as_ref().expect("emissive").radiance;
    let expect = 1000.0 / (683.002 * std::f32::consts::PI * 4.0);
    assert!(
        (l.x - expect).abs() < 1e-4 * expect && l.x == l.y && l.y == l.z,
        "{l} vs {expect}"
    );
}

#[test]
fn point_light_intensity_is_per_scene_unit_squared() {
    // 100 W/sr-equivalent in a scene in millimetres: irradiance at d mm is I / (d·1e-3)²,
    // i.e. intensity / d² with intensity stored as I / 1e-6.
    let light = r#"{ "type": "point", "position": [0, 3, 0], "intensity": 100 }"#;
    let json = scene(QUAD, light).replace(r#""units": "m""#, r#""units": "mm""#);
    let (_dir, r) = try_load(&json, &[]);
    match &r.expect("valid").lights[0] {
        LightDesc::Point { intensity, .. } => {
            assert!((intensity.x - 1.0e8).abs() < 1.0, "{intensity}")
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn exposure_fraction_and_bulb_with_efficacy() {
    let json = scene(QUAD, r#"{ "type": "point", "position": [0, 3, 0], "power": { "watts": 27, "efficacy_lm_per_w": 62.963 }, "temperature_k": 6500 }"#)
        .replace(r#""fov_deg": 40"#, r#""fov_deg": 40, "exposure": { "iso": 200, "shutter_s": "1/90", "f_number": 8 }"#);
    let (_dir, r) = try_load(&json, &[]);
    let d = r.expect("valid");
    let expect = 683.002 * (1.0 / 90.0) * 200.0 / (120.0 * 64.0);
    assert!(
        (d.camera.exposure_scale - expect).abs() < 1e-6,
        "{}",
        d.camera.exposure_scale
    );
    match &d.lights[0] {
        LightDesc::Point { intensity, .. } => {
            // 1700 lm over 4π sr, as luminous-equivalent watts, Y = 1 colour.
            let y = 0.2126 * intensity.x + 0.7152 * intensity.y + 0.0722 * intensity.z;
            let expect = 27.0 * 62.963 / 683.002 / (4.0 * std::f32::consts::PI);
            assert!((y - expect).abs() < 1e-3 * expect, "{y} vs {expect}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn instances_are_flattened_with_their_transforms() {
    let json = scene(
        r#"{ "type": "instance", "object": "ball", "transform": [{ "translate": [2, 0, 0] }] },
           { "type": "instance", "object": "ball", "transform": [{ "scale": 3 }, { "translate": [-2, 0, 0] }] }"#,
        POINT,
    )
    .replace(r#""shapes": ["#, r#""objects": { "ball": [{ "type": "sphere", "center": [0, 1, 0], "radius": 0.5, "material": "white" }] }, "shapes": ["#);
    let (_dir, r) = try_load(&json, &[]);
    let d = r.expect("valid");
    assert_eq!(d.spheres.len(), 2);
    assert_eq!(d.spheres[0].center, glam::Vec3::new(2.0, 1.0, 0.0));
    assert_eq!(
        (d.spheres[1].center, d.spheres[1].radius),
        (glam::Vec3::new(-2.0, 3.0, 0.0), 1.5)
    );
}

#[test]
fn named_metals_and_dielectric_ratio() {
    let json = scene(QUAD, POINT).replace(
        r#""materials": { "white": { "type": "diffuse", "albedo": 0.8 } }"#,
        r#""materials": { "white": { "type": "diffuse", "albedo": 0.8 }, "au": { "type": "conductor", "metal": "gold", "alpha": [0.1, 0.3] },
                          "water": { "type": "dielectric", "ior": 1.33, "ext_ior": 1.5, "sigma_a_per_mm": [0.001, 0, 0.002] } }"#,
    );
    let (_dir, r) = try_load(&json, &[]);
    let d = r.expect("valid");
    let find = |n: &str| {
        d.materials
            .iter()
            .find(|m| m.name == n)
            .map(|m| m.kind.clone())
    };
    match find("au") {
        Some(MaterialKind::Conductor { roughness, .. }) => {
            assert_eq!((roughness.alpha_u, roughness.alpha_v), (0.1, 0.3))
        }
        other => panic!("{other:?}"),
    }
    match find("water") {
        Some(MaterialKind::Dielectric {
            eta, absorption, ..
        }) => {
            assert!((eta - 1.33 / 1.5).abs() < 1e-6);
            // Per millimetre to per scene unit (this scene's units: metres).
            assert!(
                (absorption - glam::Vec3::new(1.0, 0.0, 2.0))
                    .abs()
                    .max_element()
                    < 1e-5
            );
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn example_scenes_in_the_repository_load() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut found = 0;
    for entry in std::fs::read_dir(&root).expect("scenes folder") {
        let path: PathBuf = entry.expect("entry").path().join("scene.json");
        if path.exists() {
            load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            found += 1;
        }
    }
    assert!(found >= 4, "expected the example scenes, found {found}");
}

/// The base scene with a camera path of the given keyframes (JSON array body).
fn with_path(keyframes: &str) -> String {
    scene(QUAD, POINT).replace(
        r#""fov_deg": 40 }"#,
        &format!(r#""fov_deg": 40, "path": {{ "fps": 10, "keyframes": [{keyframes}] }} }}"#),
    )
}

#[test]
fn camera_path_gives_frames_and_interpolated_cameras() {
    let (_dir, d) = try_load(
        &with_path(
            r#"{ "time": 0, "position": [0, 1, -5], "look_at": [0, 1, 0] },
               { "time": 1, "position": [2, 1, -4], "look_at": [0, 1, 0], "fov_deg": 60 }"#,
        ),
        &[],
    );
    let d = d.unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(d.frame_count(), 11);
    assert_eq!(d.camera_at(1).position, glam::Vec3::new(0.0, 1.0, -5.0));
    let last = d.camera_at(11);
    assert!((last.position - glam::Vec3::new(2.0, 1.0, -4.0)).length() < 1e-5);
    assert!((last.fov_y - 60f32.to_radians()).abs() < 1e-5);
    let mid = d.camera_at(6).position;
    assert!(mid.x > 0.5 && mid.x < 1.5, "{mid}");
}

#[test]
fn bad_camera_paths_name_the_keyframe_and_field() {
    let (file, path, msg) = one_problem(
        &with_path(
            r#"{ "time": 1, "position": [0, 1, -5], "look_at": [0, 1, 0] },
               { "time": 0.5, "position": [2, 1, -4], "look_at": [0, 1, 0] }"#,
        ),
        &[],
    );
    assert_eq!(
        (file.as_str(), path.as_str()),
        ("scene.json", "camera.path.keyframes[1].time")
    );
    assert!(msg.contains("increase"), "{msg}");
    let (_, path, msg) = one_problem(
        &with_path(r#"{ "time": 0, "position": [0, 1, -5], "look_at": [0, 1, -5] }"#),
        &[],
    );
    assert_eq!(path, "camera.path.keyframes[0].look_at");
    assert!(msg.contains("different from"), "{msg}");
    let (_, path, _) = one_problem(&with_path(""), &[]);
    assert_eq!(path, "camera.path.keyframes");
}

/// Translucent materials: a preset by name (its mm⁻¹ coefficients converted to scene units and
/// scaled), coefficients of one's own, and what a bad one is told.
#[test]
fn subsurface_presets_units_and_errors() {
    let with = |materials: &str| {
        scene(QUAD, POINT)
            .replace(r#""units": "m""#, r#""units": "cm""#)
            .replace(
                r#""materials": { "white": { "type": "diffuse", "albedo": 0.8 } }"#,
                &format!(r#""materials": {{ "white": {{ "type": "diffuse", "albedo": 0.8 }}, {materials} }}"#),
            )
    };
    let (_dir, r) = try_load(
        &with(r#""marble": { "type": "subsurface", "preset": "Marble", "scale": 2, "g": 0.5 }"#),
        &[],
    );
    let d = r.expect("valid");
    match d
        .materials
        .iter()
        .find(|m| m.name == "marble")
        .map(|m| &m.kind)
    {
        Some(MaterialKind::Subsurface {
            sigma_s_prime,
            sigma_a,
            eta,
            g,
        }) => {
            // Marble's σs′ red 2.19 mm⁻¹ = 21.9 cm⁻¹, × scale 2.
            assert!((sigma_s_prime.x - 43.8).abs() < 1e-3, "{sigma_s_prime}");
            assert!((sigma_a.z - 0.142).abs() < 1e-5, "{sigma_a}");
            assert_eq!((*eta, *g), (1.3, 0.5));
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(d.translucent_materials(), vec!["marble"]);

    let p = problems(
        &with(r#""jade": { "type": "subsurface", "preset": "jade" }"#),
        &[],
    );
    assert_eq!(p[0].1, "materials.jade.preset");
    assert!(
        p[0].2.contains("unknown medium \"jade\"") && p[0].2.contains("skim-milk"),
        "{p:?}"
    );
    let p = problems(
        &with(
            r#""wax": { "type": "subsurface", "sigma_s_prime_per_mm": [1, 0, 1], "sigma_a_per_mm": 0.1, "ior": 0.5 }"#,
        ),
        &[],
    );
    let paths: Vec<&str> = p.iter().map(|x| x.1.as_str()).collect();
    assert_eq!(
        paths,
        ["materials.wax.sigma_s_prime_per_mm", "materials.wax.ior"],
        "{p:?}"
    );
    let p = problems(
        &with(r#""half": { "type": "subsurface", "sigma_a_per_mm": 0.1 }"#),
        &[],
    );
    assert!(p[0].2.contains("expected either `preset` or both"), "{p:?}");
}

#[test]
fn layered_materials_and_their_errors() {
    let with = |materials: &str| {
        scene(QUAD, POINT).replace(
            r#""materials": { "white": { "type": "diffuse", "albedo": 0.8 } }"#,
            &format!(
                r#""materials": {{ "white": {{ "type": "diffuse", "albedo": 0.8 }}, {materials} }}"#
            ),
        )
    };
    let (_dir, r) = try_load(
        &with(
            r#""paint": { "type": "kubelka_munk", "substrate": 0.9, "layers": [
                { "absorption_per_mm": [1, 2, 3], "scattering_per_mm": 20, "thickness_mm": 0.05 },
                { "absorption_per_mm": 0, "scattering_per_mm": 5, "thickness_mm": 1 } ] },
               "skin": { "type": "hanrahan_krueger", "sigma_s_per_mm": 8, "sigma_a_per_mm": [0.2, 0.6, 1.2], "thickness_mm": 0.05, "g": 0.8 }"#,
        ),
        &[],
    );
    let d = r.expect("valid");
    let kind = |name: &str| {
        d.materials
            .iter()
            .find(|m| m.name == name)
            .map(|m| m.kind.clone())
    };
    match kind("paint") {
        Some(MaterialKind::KubelkaMunk { layers, substrate }) => {
            assert_eq!(layers.len(), 2);
            assert_eq!(layers[0].absorption, glam::Vec3::new(1.0, 2.0, 3.0));
            assert_eq!((layers[1].scattering.y, layers[1].thickness), (5.0, 1.0));
            assert_eq!(substrate, glam::Vec3::splat(0.9));
        }
        other => panic!("{other:?}"),
    }
    match kind("skin") {
        Some(MaterialKind::HanrahanKrueger {
            sigma_a,
            thickness,
            g,
            eta,
            substrate,
            ..
        }) => {
            assert_eq!((sigma_a.z, thickness, g), (1.2, 0.05, 0.8));
            // The defaults: skin's index, a black substrate.
            assert_eq!((eta, substrate), (1.4, glam::Vec3::ZERO));
        }
        other => panic!("{other:?}"),
    }

    let p = problems(
        &with(
            r#""paint": { "type": "kubelka_munk", "substrate": 1.5, "layers": [
                { "absorption_per_mm": -1, "scattering_per_mm": 2, "thickness_mm": 0 } ] },
               "leaf": { "type": "hanrahan_krueger", "sigma_s_per_mm": 8, "sigma_a_per_mm": 1, "thickness_mm": 0.1, "ior": 0.9 },
               "bare": { "type": "kubelka_munk", "layers": [] }"#,
        ),
        &[],
    );
    let paths: Vec<&str> = p.iter().map(|x| x.1.as_str()).collect();
    for expected in [
        "materials.paint.layers[0].absorption_per_mm",
        "materials.paint.layers[0].thickness_mm",
        "materials.paint.substrate",
        "materials.leaf.ior",
        "materials.bare.layers",
    ] {
        assert!(paths.contains(&expected), "{expected} not in {p:?}");
    }
}

#[test]
fn a_top_level_environment_is_the_environment_light_it_stands_for() {
    let top = scene(QUAD, POINT).replace(
        r#""lights": ["#,
        r#""environment": { "strength": 2, "rotation_deg": 90 }, "lights": ["#,
    );
    let light = scene(
        QUAD,
        &format!(
            r#"{POINT}, {{ "type": "environment", "radiance": 2, "transform": [{{ "rotate": {{ "axis": [0, 1, 0], "angle_deg": 90 }} }}] }}"#
        ),
    );
    let (_a, a) = try_load(&top, &[]);
    let (_b, b) = try_load(&light, &[]);
    let (a, b) = (a.expect("valid"), b.expect("valid"));
    match (&a.lights[1], &b.lights[1]) {
        (
            LightDesc::Environment {
                image: None,
                scale: sa,
                to_world: ma,
            },
            LightDesc::Environment {
                image: None,
                scale: sb,
                to_world: mb,
            },
        ) => {
            assert_eq!(sa, sb);
            assert!(ma.abs_diff_eq(*mb, 1e-6), "{ma} against {mb}");
        }
        other => panic!("{other:?}"),
    }
    // Given twice, or with an image that is not there: refused, saying where.
    let twice = light.replace(
        r#""lights": ["#,
        r#""environment": { "strength": 1 }, "lights": ["#,
    );
    let (_, path, msg) = one_problem(&twice, &[]);
    assert_eq!(path, "environment");
    assert!(msg.contains("lights[1]"), "{msg}");
    let missing = scene(QUAD, POINT).replace(
        r#""lights": ["#,
        r#""environment": { "image": "sky.exr" }, "lights": ["#,
    );
    let (_, path, msg) = one_problem(&missing, &[]);
    assert_eq!(path, "environment.image");
    assert!(msg.contains("sky.exr"), "{msg}");
}

#[test]
fn thin_glass_and_transmitting_metallic_roughness_from_json() {
    let json = scene(QUAD, POINT).replace(
        r#""materials": { "white": { "type": "diffuse", "albedo": 0.8 } }"#,
        r#""materials": { "white": { "type": "diffuse", "albedo": 0.8 },
                          "pane": { "type": "dielectric", "ior": 1.5, "thin": true, "tint": [1, 0.9, 0.8] },
                          "leaf": { "type": "metallic_roughness", "base_color": [0.2, 0.5, 0.1], "metallic": 0, "roughness": 0.6,
                                    "transmission": 0.25, "diffuse_transmission": 0.5, "diffuse_transmission_color": [0.5, 1, 0.2], "thin": true } }"#,
    );
    let (_dir, r) = try_load(&json, &[]);
    let d = r.expect("valid");
    let find = |n: &str| {
        d.materials
            .iter()
            .find(|m| m.name == n)
            .map(|m| m.kind.clone())
    };
    match find("pane") {
        Some(MaterialKind::Dielectric {
            thin: true, tint, ..
        }) => assert_eq!(tint, glam::Vec3::new(1.0, 0.9, 0.8)),
        other => panic!("{other:?}"),
    }
    match find("leaf") {
        Some(MaterialKind::MetallicRoughness { transmission, .. }) => {
            assert_eq!(
                (
                    transmission.specular,
                    transmission.diffuse,
                    transmission.thin
                ),
                (0.25, 0.5, true)
            );
            assert_eq!(transmission.diffuse_color, glam::Vec3::new(0.5, 1.0, 0.2));
        }
        other => panic!("{other:?}"),
    }
    // A thin sheet has no interior to absorb in; a share is in [0, 1].
    let bad = scene(QUAD, POINT).replace(
        r#""materials": { "white": { "type": "diffuse", "albedo": 0.8 } }"#,
        r#""materials": { "white": { "type": "diffuse", "albedo": 0.8 },
                          "pane": { "type": "dielectric", "ior": 1.5, "thin": true, "sigma_a_per_mm": 0.1 },
                          "leaf": { "type": "metallic_roughness", "diffuse_transmission": 1.5 } }"#,
    );
    let found = problems(&bad, &[]);
    assert!(
        found
            .iter()
            .any(|(_, field, msg)| field.ends_with("pane.sigma_a_per_mm") && msg.contains("thin")),
        "{found:?}"
    );
    assert!(
        found.iter().any(
            |(_, field, msg)| field.ends_with("leaf.diffuse_transmission")
                && msg.contains("[0, 1]")
        ),
        "{found:?}"
    );
}
