//! Light through glTF's transmitting materials, in every method: a 4 m pane 3 m in front of
//! the camera, and 3 m behind it an emitter of radiance 1, 40 m wide and facing the pane.
//! Nothing else is in the scene and the emitter reflects nothing, so the camera sees only
//! what the pane lets through from behind:
//!
//! - a thin-walled glass pane (KHR_materials_transmission without KHR_materials_volume, on
//!   an open mesh) passes the emitter straight through, tinted by the base colour c, keeping
//!   T = 1 − 2F/(1 + F) of it (two faces and the echoes between them, F = 0.04 at normal
//!   incidence for IOR 1.5);
//! - the same glass transmitting only half (transmissionFactor 0.5, rendered by the glTF
//!   BRDF's transmitting share, a nearly smooth microfacet sheet): 0.5 c T;
//! - a diffusely transmitting sheet (KHR_materials_diffuse_transmission 1, colour t, no
//!   specular layer) sends on t/π of the irradiance E from behind: t E/π = t F, where F is
//!   the form factor of the emitter seen from the pane's centre (the view covers its middle
//!   0.9 m, where E varies by less than 0.1 %).

mod common;

use common::{Quad, load_gltf, mean_rgb, quads_gltf};
use serde_json::{Value, json};
use tessera_render::method;

fn scene(pane: Value) -> tessera_scene::SceneDesc {
    let emitter = json!({
        "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0},
        "emissiveFactor": [1.0, 1.0, 1.0],
        "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}
    });
    let quads = [
        Quad {
            centre: [0.0, 0.0, 0.0],
            u: [2.0, 0.0, 0.0],
            v: [0.0, 2.0, 0.0],
            material: 0,
        },
        Quad {
            centre: [0.0, 0.0, -3.0],
            u: [20.0, 0.0, 0.0],
            v: [0.0, 20.0, 0.0],
            material: 1,
        },
    ];
    let doc = quads_gltf(
        &quads,
        vec![pane, emitter],
        json!({"translation": [0.0, 0.0, 3.0]}),
        0.3,
        vec![],
    );
    load_gltf(&doc, 16)
}

/// Form factor from a point to a parallel rectangle of half-sizes a, b centred opposite it
/// at distance h: four corner rectangles, each
/// (1/2π)[X/√(1+X²) atan(Y/√(1+X²)) + Y/√(1+Y²) atan(X/√(1+Y²))], X = a/h, Y = b/h.
fn form_factor(a: f64, b: f64, h: f64) -> f64 {
    let (x, y) = (a / h, b / h);
    let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    4.0 * (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * std::f64::consts::PI)
}

#[test]
fn every_method_sees_through_thin_partial_and_diffusely_transmitting_sheets() {
    let colour = [0.9f64, 0.6, 0.3];
    let glass = |factor: f64| {
        json!({
            "pbrMetallicRoughness": {"baseColorFactor": [colour[0], colour[1], colour[2], 1.0],
                                     "metallicFactor": 0.0, "roughnessFactor": 0.0},
            "extensions": {"KHR_materials_transmission": {"transmissionFactor": factor}}
        })
    };
    let thin = scene(glass(1.0));
    let half = scene(glass(0.5));
    let tint = [1.0f64, 0.5, 0.25];
    let diffuse = scene(json!({
        "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0],
                                 "metallicFactor": 0.0, "roughnessFactor": 0.5},
        "extensions": {"KHR_materials_diffuse_transmission": {
                           "diffuseTransmissionFactor": 1.0,
                           "diffuseTransmissionColorFactor": tint},
                       "KHR_materials_specular": {"specularFactor": 0.0}}
    }));
    let f = 0.04f64;
    let t = 1.0 - 2.0 * f / (1.0 + f);
    let expected_thin = colour.map(|c| c * t);
    let expected_half = colour.map(|c| 0.5 * c * t);
    let ff = form_factor(20.0, 20.0, 3.0);
    let expected_diffuse = tint.map(|c| c * ff);
    let mut failures = Vec::new();
    for name in method::names() {
        let spp = 64;
        for (what, desc, expected) in [
            ("thin glass", &thin, expected_thin),
            ("half transmission", &half, expected_half),
            ("diffuse transmission", &diffuse, expected_diffuse),
        ] {
            let m = mean_rgb(desc, name, spp, 5);
            let ok = (0..3).all(|k| (m[k] / expected[k] - 1.0).abs() < 0.01);
            println!(
                "{name}, {what}: {m:.4?} (expected {expected:.4?}){}",
                if ok { "" } else { "  <-- off" }
            );
            if !ok {
                failures.push(format!("{name}, {what}: {m:.4?} against {expected:.4?}"));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
