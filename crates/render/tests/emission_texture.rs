//! An emissive texture, through every method: a ceiling panel whose emissiveTexture is white
//! on its left half and black on its right (clamped at the edges; the one-texel blend at the
//! seam is antisymmetric) lights a white floor exactly as a panel of its left half alone,
//! untextured, does. The camera sees only the floor, so what differs is how light leaves the
//! panel: sampled toward a point (next-event estimation, BDPT connections), emitted as
//! photons and light paths, and met by paths that hit it.

mod common;

use common::{data_uri, load_gltf, render_by_method};
use serde_json::{Value, json};
use tessera_render::{Image, method};
use tessera_scene::SceneDesc;

fn render(desc: &SceneDesc, name: &str, spp: u32) -> Image {
    render_by_method(desc, name, spp, 5)
}

/// The floor and a panel over x ∈ [−1, `right`] at y = 2 facing down, emitting 4 W·sr⁻¹·m⁻²
/// (times the texture, `textured`).
fn scene(right: f32, textured: bool) -> Value {
    let mut b = Vec::new();
    let floor = [
        [-10f32, 0.0, -10.0],
        [-10.0, 0.0, 10.0],
        [10.0, 0.0, 10.0],
        [10.0, 0.0, -10.0],
    ];
    let panel = [
        [-1f32, 2.0, -1.0],
        [right, 2.0, -1.0],
        [right, 2.0, 1.0],
        [-1.0, 2.0, 1.0],
    ];
    for p in floor.iter().chain(&panel) {
        for c in p {
            b.extend(c.to_le_bytes());
        }
    }
    for [u, v] in [[0f32, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]] {
        for c in [u, v] {
            b.extend(c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        b.extend(i.to_le_bytes());
    }
    let img = image::RgbaImage::from_fn(64, 1, |x, _| {
        let v = if x < 32 { 255 } else { 0 };
        image::Rgba([v, v, v, 255])
    });
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("png");
    let mut lamp = json!({
        "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0},
        "emissiveFactor": [1.0, 1.0, 1.0],
        "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0},
                       "KHR_materials_specular": {"specularFactor": 0.0}}
    });
    if textured {
        lamp["emissiveTexture"] = json!({"index": 0});
    }
    json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_specular"],
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [
            {"mesh": 0},
            {"mesh": 1},
            // Looking at the floor's centre from (0, 1.5, 4), below the panel's height.
            {"camera": 0, "translation": [0.0, 1.5, 4.0],
             "rotation": [-0.18223552, 0.0, 0.0, 0.98325491]}
        ],
        "cameras": [{"type": "perspective",
                     "perspective": {"yfov": 0.6, "aspectRatio": 1.0, "znear": 0.01}}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": 0}, "indices": 3, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": 1, "TEXCOORD_0": 2}, "indices": 3,
                             "material": 1}]}
        ],
        "materials": [
            {"pbrMetallicRoughness": {"metallicFactor": 0.0},
             "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}},
            lamp
        ],
        "samplers": [{"wrapS": 33071, "wrapT": 33071}],
        "textures": [{"source": 0, "sampler": 0}],
        "images": [{"uri": data_uri(&png)}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [-10, 0, -10], "max": [10, 0, 10]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [-1, 2, -1], "max": [right, 2, 1]},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 48},
            {"buffer": 0, "byteOffset": 96, "byteLength": 32},
            {"buffer": 0, "byteOffset": 128, "byteLength": 12}
        ],
        "buffers": [{"byteLength": b.len(), "uri": data_uri(&b)}]
    })
}

fn load(doc: &Value) -> SceneDesc {
    load_gltf(doc, 48)
}

fn mean(image: &Image) -> f64 {
    let n = image.pixels.len() as f64;
    image.pixels.iter().map(|p| p.rgb[1] as f64).sum::<f64>() / n
}

#[test]
fn every_method_emits_an_emissive_texture_where_it_is_bright() {
    let textured = load(&scene(1.0, true));
    let half = load(&scene(0.0, false));
    let untextured = load(&scene(1.0, false));
    for name in method::names() {
        let spp = if name == "path" { 256 } else { 64 };
        let a = mean(&render(&textured, name, spp));
        let b = mean(&render(&half, name, spp));
        let full = mean(&render(&untextured, name, spp));
        println!(
            "{name}: textured {a:.5}, left half {b:.5} (ratio {:.4}), whole panel {full:.5}",
            a / b
        );
        assert!(
            (a / b - 1.0).abs() < 0.02,
            "{name}: textured / half panel = {}",
            a / b
        );
        // Not the whole panel's light: the texture is applied.
        assert!(full > 1.5 * a, "{name}: {full} vs {a}");
    }
}
