//! Rendering against what is known exactly: tiles and threads change nothing, closed and
//! open furnaces have analytic radiance, lights give their analytic irradiance, sealed boxes
//! stay black at any scale. Images are tiny; tolerances come from the per-pixel variance the
//! film estimates (several standard errors), not from guesses.

use tessera_render::Scene;
use tessera_render::camera::Camera;
use tessera_render::film::{Image, PixelSums, SampleRange, Tile, TileSums, tiles};
use tessera_render::integrator::Integrator;
use tessera_render::render::{render_frame, render_tile};
use tessera_scene::SceneDesc;

fn load(json: &str) -> SceneDesc {
    let dir = tempfile::tempdir().expect("temp dir");
    std::fs::write(dir.path().join("scene.json"), json).expect("write");
    tessera_scene::load(&dir.path().join("scene.json")).unwrap_or_else(|e| panic!("{e}"))
}

fn cornell(width: u32, height: u32) -> SceneDesc {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes/cornell-box/scene.json");
    let mut d = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    d.film.width = width;
    d.film.height = height;
    d
}

fn render(desc: &SceneDesc, spp: u32, threads: usize) -> Image {
    let scene = Scene::build(desc);
    let camera = Camera::new(&desc.camera, &desc.film);
    let integrator = tessera_render::method::for_scene(desc, &scene).expect("a per-ray method");
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool");
    pool.install(|| {
        render_frame(
            &scene,
            &camera,
            integrator.as_ref(),
            16,
            SampleRange { start: 0, end: spp },
        )
        .0
    })
}

fn sums(
    scene: &(Scene, Camera),
    integrator: &dyn Integrator,
    tile: Tile,
    start: u32,
    end: u32,
) -> TileSums {
    render_tile(
        &scene.0,
        &scene.1,
        integrator,
        tile,
        SampleRange { start, end },
    )
    .0
}

/// The sums of pixel (x, y) from a set of tiles.
fn pixel(tiles: &[TileSums], x: u32, y: u32) -> &PixelSums {
    let t = tiles
        .iter()
        .find(|t| (t.tile.x0..t.tile.x1).contains(&x) && (t.tile.y0..t.tile.y1).contains(&y))
        .expect("covered");
    &t.pixels[((y - t.tile.y0) * t.tile.width() + (x - t.tile.x0)) as usize]
}

#[test]
fn a_tile_rendered_alone_equals_the_same_pixels_of_the_full_frame() {
    let mut desc = cornell(40, 28);
    desc.film.filter = tessera_scene::FilterDesc::Mitchell {
        radius: 2.0,
        b: 1.0 / 3.0,
        c: 1.0 / 3.0,
    };
    let scene = (Scene::build(&desc), Camera::new(&desc.camera, &desc.film));
    let integ = tessera_render::method::for_scene(&desc, &scene.0).expect("a per-ray method");
    let full = vec![sums(
        &scene,
        integ.as_ref(),
        Tile {
            x0: 0,
            y0: 0,
            x1: 40,
            y1: 28,
        },
        0,
        6,
    )];
    for size in [1, 7, 16] {
        let parts: Vec<TileSums> = tiles(40, 28, size)
            .into_iter()
            .map(|t| sums(&scene, integ.as_ref(), t, 0, 6))
            .collect();
        for y in 0..28 {
            for x in 0..40 {
                assert_eq!(
                    pixel(&full, x, y),
                    pixel(&parts, x, y),
                    "pixel ({x}, {y}) with {size}-pixel tiles"
                );
            }
        }
    }
    // A sample range split in two and merged gives the same sums as in one piece.
    let tile = Tile {
        x0: 5,
        y0: 3,
        x1: 21,
        y1: 19,
    };
    let mut split = sums(&scene, integ.as_ref(), tile, 4, 6);
    split.merge(&sums(&scene, integ.as_ref(), tile, 0, 4));
    for (a, p) in split.pixels.iter().zip(tile.pixels()) {
        assert_eq!(a, pixel(&full, p.x, p.y));
    }
}

#[test]
fn the_image_does_not_depend_on_the_number_of_threads() {
    let desc = cornell(48, 32);
    assert_eq!(render(&desc, 4, 1), render(&desc, 4, 2));
}

/// Mean of the colour channels over the image and the standard error of that mean, from the
/// per-pixel variance estimates.
fn mean_and_error(img: &Image) -> (f64, f64) {
    let n = (img.pixels.len() * 3) as f64;
    let mean = img
        .pixels
        .iter()
        .flat_map(|p| p.rgb)
        .map(|v| v as f64)
        .sum::<f64>()
        / n;
    let var = img
        .pixels
        .iter()
        .flat_map(|p| p.variance)
        .map(|v| v as f64)
        .sum::<f64>()
        / (n * n);
    (mean, var.sqrt())
}

#[test]
fn white_furnace_diffuse_sphere_under_a_uniform_sky_is_invisible() {
    // A white (albedo 1) Lambertian sphere in a constant environment of radiance 1 reflects
    // exactly 1 everywhere (it is convex, so every reflected ray escapes).
    let desc = load(
        r#"{ "units": "m",
        "camera": { "type": "pinhole", "position": [0, 0, -4], "look_at": [0, 0, 0], "fov_deg": 35 },
        "film": { "width": 32, "height": 32 },
        "integrator": { "spp": 64, "seed": 3 },
        "materials": { "white": { "type": "diffuse", "albedo": 1 } },
        "shapes": [ { "type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "white" } ],
        "lights": [ { "type": "environment", "radiance": 1 } ] }"#,
    );
    let img = render(&desc, 64, 2);
    let (mean, err) = mean_and_error(&img);
    assert!((mean - 1.0).abs() < 4.0 * err + 1e-6, "mean {mean} ± {err}");
    for p in &img.pixels {
        for c in 0..3 {
            let sigma = (p.variance[c] as f64).sqrt();
            assert!(
                (p.rgb[c] as f64 - 1.0).abs() < 6.0 * sigma + 1e-5,
                "pixel {} ± {sigma}",
                p.rgb[c]
            );
        }
    }
}

#[test]
fn inside_a_closed_emitting_sphere_radiance_is_le_over_one_minus_albedo() {
    // Every point of the inner surface emits Le and reflects ρ of the radiance arriving, so
    // L = Le + ρ L: L = Le / (1 − ρ) = 1 / (1 − 0.5) = 2. Exercises area-light sampling from
    // inside a sphere, MIS and Russian roulette.
    let desc = load(
        r#"{ "units": "m",
        "camera": { "type": "pinhole", "position": [0, 0, 0], "look_at": [0, 0, 1], "fov_deg": 60 },
        "film": { "width": 24, "height": 24 },
        "integrator": { "spp": 64, "rr_depth": 2, "seed": 5 },
        "materials": { "grey": { "type": "diffuse", "albedo": 0.5 } },
        "shapes": [ { "type": "sphere", "center": [0, 0, 0], "radius": 3, "material": "grey",
                      "emission": { "radiance": 1, "two_sided": true } } ] }"#,
    );
    let img = render(&desc, 64, 2);
    let (mean, err) = mean_and_error(&img);
    assert!((mean - 2.0).abs() < 4.0 * err, "mean {mean} ± {err}");
    assert!(err < 0.01, "the estimate should be good to 1 %: ±{err}");
}

/// A camera looking straight down at a Lambertian plane from `h` above: the centre pixel's
/// radiance, by the direct-lighting integrator.
fn centre_pixel(units: &str, h: f32, lights: &str, shapes_extra: &str) -> (f32, f32) {
    let json = format!(
        r#"{{ "units": "{units}",
        "camera": {{ "type": "pinhole", "position": [0, {h}, 0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov_deg": 2 }},
        "film": {{ "width": 9, "height": 9 }},
        "integrator": {{ "type": "direct", "spp": 256, "seed": 1 }},
        "materials": {{ "paper": {{ "type": "diffuse", "albedo": 0.6 }}, "lamp": {{ "type": "diffuse", "albedo": 0 }} }},
        "shapes": [ {{ "type": "quad", "origin": [-1e4, 0, -1e4], "edge_u": [0, 0, 2e4], "edge_v": [2e4, 0, 0], "material": "paper" }} {shapes_extra} ],
        "lights": [ {lights} ] }}"#
    );
    let img = render(&load(&json), 256, 2);
    let p = img.pixels[4 * 9 + 4];
    (p.rgb[1], p.variance[1].sqrt())
}

#[test]
fn point_light_over_a_plane_gives_rho_over_pi_times_intensity_over_distance_squared() {
    // The scene is in millimetres, the light 2000 mm = 2 m up: E = I / (2 m)², L = ρ E / π.
    let (l, _) = centre_pixel(
        "mm",
        2000.0,
        r#"{ "type": "point", "position": [0, 2000, 0], "intensity": 8 }"#,
        "",
    );
    let expect = 0.6 / std::f32::consts::PI * 8.0 / 4.0;
    assert!((l - expect).abs() < 1e-3 * expect, "{l} vs {expect}");
}

#[test]
fn directional_and_spot_lights() {
    // A sun 60° from the zenith with irradiance 5 W/m² on a surface facing it: E cos 60°.
    let sun = r#"{ "type": "directional", "direction": [0.8660254, -0.5, 0], "irradiance": 5 }"#;
    let (l, _) = centre_pixel("m", 3.0, sun, "");
    let expect = 0.6 / std::f32::consts::PI * 5.0 * 0.5;
    assert!((l - expect).abs() < 1e-3 * expect, "{l} vs {expect}");
    // A spot aimed at the centre lights it fully; one aimed 45° away leaves it dark.
    let on = r#"{ "type": "spot", "position": [0, 2, 0], "look_at": [0, 0, 0], "cone_angle_deg": 20, "intensity": 4 }"#;
    let (l, _) = centre_pixel("m", 3.0, on, "");
    let expect = 0.6 / std::f32::consts::PI * 4.0 / 4.0;
    assert!((l - expect).abs() < 1e-3 * expect, "{l} vs {expect}");
    let off = r#"{ "type": "spot", "position": [0, 2, 0], "look_at": [2, 0, 0], "cone_angle_deg": 20, "intensity": 4 }"#;
    assert_eq!(centre_pixel("m", 3.0, off, "").0, 0.0);
}

#[test]
fn rectangular_area_light_matches_the_view_factor() {
    // A 2 × 1 m Lambertian emitter of radiance 3, facing down 1.5 m above the point seen.
    // Irradiance under its centre: E = 4 π L F(a/2h, b/2h), with the view factor of a
    // rectangle from a parallel point below its corner (Howell's catalogue, B-3):
    // F = (1/2π) [X/√(1+X²) atan(Y/√(1+X²)) + Y/√(1+Y²) atan(X/√(1+Y²))].
    let light = r#", { "type": "quad", "origin": [-1, 1.5, -0.5], "edge_u": [2, 0, 0], "edge_v": [0, 0, 1], "material": "lamp",
                        "emission": { "radiance": 3 } }"#;
    let (l, sigma) = centre_pixel("m", 1.0, "", light);
    let f = |x: f64, y: f64| {
        let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
        (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * std::f64::consts::PI)
    };
    let e = 4.0 * std::f64::consts::PI * 3.0 * f(1.0 / 1.5, 0.5 / 1.5);
    let expect = 0.6 / std::f64::consts::PI * e;
    // The camera sits between the plane and the light. 4σ of the pixel estimate, plus the
    // pixel's 2°/9 footprint.
    assert!(
        ((l as f64) - expect).abs() < 4.0 * sigma as f64 + 2e-3 * expect,
        "{l} ± {sigma} vs {expect}"
    );
}

#[test]
fn sealed_boxes_stay_black_at_any_scale() {
    // A camera inside a closed box under a bright sky: no light may leak in through edges,
    // corners or by rounding, whether the box is 1 mm across or 100 km from the origin.
    for (offset, size) in [(0.0f32, 1e-3f32), (1e5, 500.0), (-3.0, 2.0)] {
        let c = offset + 0.5 * size;
        let json = format!(
            r#"{{ "units": "m",
            "camera": {{ "type": "pinhole", "position": [{c}, {c}, {c}], "look_at": [{c}, {c}, {f}], "fov_deg": 120 }},
            "film": {{ "width": 24, "height": 24 }},
            "integrator": {{ "spp": 32, "rr_depth": 8 }},
            "materials": {{ "grey": {{ "type": "diffuse", "albedo": 0.7 }} }},
            "shapes": [ {{ "type": "box", "min": [{offset}, {offset}, {offset}], "max": [{m}, {m}, {m}], "material": "grey" }} ],
            "lights": [ {{ "type": "environment", "radiance": 100 }} ] }}"#,
            f = c + size,
            m = offset + size
        );
        // 24 × 24 × 32 paths of about ten bounces each.
        let img = render(&load(&json), 32, 2);
        assert!(
            img.pixels
                .iter()
                .all(|p| p.rgb == [0.0; 3] && p.alpha == 1.0),
            "light leaked into the box at scale {size}"
        );
    }
}

#[test]
fn no_nan_or_inf_reaches_the_film() {
    let desc = cornell(32, 32);
    let img = render(&desc, 8, 2);
    assert!(img.pixels.iter().all(|p| {
        p.rgb
            .iter()
            .chain(&p.variance)
            .chain(&p.albedo)
            .all(|v| v.is_finite())
    }));
}

#[test]
fn no_shadow_acne_far_from_the_origin_or_at_millimetre_scale_under_grazing_light() {
    // A plane lit by a sun 80° from the zenith: every pixel is exactly ρ/π · E · cos 80°
    // (a delta light, no noise); self-shadowing from a poorly offset shadow ray would darken
    // some. At 10⁵ units from the origin and in a scene 10⁻³ units across.
    let (s80, c80) = 80f32.to_radians().sin_cos();
    for (offset, h) in [(1e5f32, 50.0f32), (0.0, 1e-3), (-3e4, 2.0)] {
        let json = format!(
            r#"{{ "units": "m",
            "camera": {{ "type": "pinhole", "position": [{offset}, {y}, {offset}], "look_at": [{offset}, {offset}, {offset}], "up": [0, 0, 1], "fov_deg": 30 }},
            "film": {{ "width": 32, "height": 32 }},
            "integrator": {{ "type": "direct", "spp": 4 }},
            "materials": {{ "paper": {{ "type": "diffuse", "albedo": 0.6 }} }},
            "shapes": [ {{ "type": "quad", "origin": [{lo}, {offset}, {lo}], "edge_u": [0, 0, {w}], "edge_v": [{w}, 0, 0], "material": "paper" }} ],
            "lights": [ {{ "type": "directional", "direction": [{s80}, {nc}, 0], "irradiance": 2 }} ] }}"#,
            y = offset + h,
            lo = offset - 4.0 * h,
            w = 8.0 * h,
            nc = -c80,
        );
        let img = render(&load(&json), 4, 2);
        let expect = 0.6 / std::f32::consts::PI * 2.0 * c80;
        for p in &img.pixels {
            assert!(
                (p.rgb[0] - expect).abs() <= 1e-5 * expect,
                "acne at offset {offset}, scale {h}: {} vs {expect}",
                p.rgb[0]
            );
        }
    }
}

/// The film's variance estimate is honest: on the Cornell box at 32 spp, the relMSE it predicts
/// without a reference and the relMSE measured against Mitsuba's converged reference agree
/// within a factor of 2 (the reference's own noise is ~100× smaller at 1024+ spp).
#[test]
fn estimated_rel_mse_agrees_with_the_measured_one() {
    let desc = cornell(256, 256);
    let img = render(&desc, 32, 2);
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes/cornell-box/reference.exr");
    let reference = tessera_render::read_exr(&path).expect("reference");
    let rgb: Vec<glam::Vec3A> = img.pixels.iter().map(|p| p.rgb.into()).collect();
    let refs: Vec<glam::Vec3A> = reference.pixels.iter().map(|&p| p.into()).collect();
    let measured = tessera_render::metrics::compare(&rgb, &refs).rel_mse;
    let estimated = tessera_render::metrics::estimated_rel_mse(&img);
    let ratio = estimated / measured;
    assert!(
        (0.5..=2.0).contains(&ratio),
        "estimated {estimated:.3e}, measured {measured:.3e}"
    );
}
