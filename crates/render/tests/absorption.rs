//! Tinted glass (KHR_materials_volume), through every method: a smooth glass slab 1 m thick
//! whose interior keeps attenuationColor c after attenuationDistance 2 m, seen face-on in
//! front of a wide emitter of radiance 1 (behind the camera: nothing). Light crossing the
//! slab keeps a = c^(1/2) per crossing (Beer–Lambert); with Fresnel reflectance R at each
//! face (normal incidence, R = 0.04 at IOR 1.5) the camera sees the emitter through both
//! faces, directly and after pairs of reflections inside: (1 − R)² a / (1 − R² a²).

mod common;

use common::{data_uri, load_gltf, mean_rgb};
use serde_json::{Value, json};
use tessera_render::method;
use tessera_scene::SceneDesc;

/// The slab (x, y in [−2, 2] m, z in [−0.5, 0.5] m, faces wound outward), a camera on +z
/// looking at it, and behind it at z = −3 an emitter 40 m wide facing +z.
fn slab(volume: Option<Value>) -> Value {
    let mut b = Vec::new();
    let half = [2.0f32, 2.0, 0.5];
    let axis = |i: usize, s: f32| {
        let mut v = [0.0f32; 3];
        v[i] = s * half[i];
        v
    };
    // (outward normal axis and sign, u axis, v axis) with u × v along the normal.
    let faces = [
        (0, 1.0, 1, 2),
        (0, -1.0, 2, 1),
        (1, 1.0, 2, 0),
        (1, -1.0, 0, 2),
        (2, 1.0, 0, 1),
        (2, -1.0, 1, 0),
    ];
    let mut indices: Vec<u16> = Vec::new();
    for (k, (n, sign, u, v)) in faces.into_iter().enumerate() {
        let c = axis(n, sign);
        let (du, dv) = (axis(u, 1.0), axis(v, 1.0));
        for (su, sv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            for i in 0..3 {
                b.extend((c[i] + su * du[i] + sv * dv[i]).to_le_bytes());
            }
        }
        let first = (4 * k) as u16;
        indices.extend([first, first + 1, first + 2, first, first + 2, first + 3]);
    }
    for [x, y] in [[-20f32, -20.0], [20.0, -20.0], [20.0, 20.0], [-20.0, 20.0]] {
        for c in [x, y, -3.0] {
            b.extend(c.to_le_bytes());
        }
    }
    for i in &indices {
        b.extend(i.to_le_bytes());
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        b.extend(i.to_le_bytes());
    }
    let mut glass = json!({
        "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.0},
        "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                       "KHR_materials_ior": {"ior": 1.5}}
    });
    if let Some(v) = volume {
        glass["extensions"]["KHR_materials_volume"] = v;
    }
    json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_ior",
                           "KHR_materials_volume", "KHR_materials_specular"],
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [{"mesh": 0}, {"mesh": 1}, {"camera": 0, "translation": [0.0, 0.0, 3.0]}],
        "cameras": [{"type": "perspective",
                     "perspective": {"yfov": 0.3, "aspectRatio": 1.0, "znear": 0.01}}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": 0}, "indices": 2, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": 1}, "indices": 3, "material": 1}]}
        ],
        "materials": [glass, {
            "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0},
            "emissiveFactor": [1.0, 1.0, 1.0],
            "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}
        }],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 24, "type": "VEC3",
             "min": [-2, -2, -0.5], "max": [2, 2, 0.5]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [-20, -20, -3], "max": [20, 20, -3]},
            {"bufferView": 2, "componentType": 5123, "count": 36, "type": "SCALAR"},
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 288},
            {"buffer": 0, "byteOffset": 288, "byteLength": 48},
            {"buffer": 0, "byteOffset": 336, "byteLength": 72},
            {"buffer": 0, "byteOffset": 408, "byteLength": 12}
        ],
        "buffers": [{"byteLength": b.len(), "uri": data_uri(&b)}]
    })
}

fn load(doc: &Value) -> SceneDesc {
    load_gltf(doc, 16)
}

#[test]
fn every_method_tints_light_by_the_glass_it_crosses() {
    let colour = [0.5f64, 0.7, 0.9];
    let tinted = load(&slab(Some(json!({
        "thicknessFactor": 1.0,
        "attenuationDistance": 2.0,
        "attenuationColor": colour
    }))));
    // A volume without attenuation: solid, clear glass.
    let clear = load(&slab(Some(json!({"thicknessFactor": 1.0}))));
    let r = 0.04f64;
    let through = |a: f64| (1.0 - r) * (1.0 - r) * a / (1.0 - r * r * a * a);
    let expected = colour.map(|c| through(c.sqrt()));
    let clear_expected = through(1.0);
    for name in method::names() {
        let spp = 64;
        let t = mean_rgb(&tinted, name, spp, 11);
        let c = mean_rgb(&clear, name, spp, 11);
        println!(
            "{name}: tinted {t:.4?} (expected {expected:.4?}), clear {c:.4?} (expected \
             {clear_expected:.4})"
        );
        for k in 0..3 {
            assert!(
                (c[k] / clear_expected - 1.0).abs() < 0.01,
                "{name}: clear glass passes {c:?}, expected {clear_expected}"
            );
            assert!(
                (t[k] / expected[k] - 1.0).abs() < 0.01,
                "{name}: channel {k}: {} against {}",
                t[k],
                expected[k]
            );
        }
    }
}
