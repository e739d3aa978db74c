//! Coverage (glTF alphaMode) in a render, through every method: a white floor lit by a point
//! light, seen from the light's own position through a black sheet 0.5 m above it.
//!
//! - MASK with a checker of alpha 0 and 1 (0.1 m checks): a camera ray and the shadow ray of
//!   the floor point it finds cross the sheet at the same point (both lie on the line from the
//!   light), so what the camera sees through a hole is lit: the image is half the unscreened
//!   floor's. Were holes ignored by shadow rays, it would be black.
//! - BLEND with α = 0.3: camera and shadow rays each pass with probability 0.7, independently
//!   (a ray's number hashes the ray): 0.49 of the unscreened floor. Were coverage applied to
//!   camera rays only, 0.7.
//!
//! The sheet is black with no specular layer, so no light reaches the camera from it.

mod common;

use common::{data_uri, load_gltf, render_by_method};
use serde_json::{Value, json};
use tessera_render::{Image, method};
use tessera_scene::SceneDesc;

fn render(desc: &SceneDesc, name: &str, spp: u32) -> Image {
    render_by_method(desc, name, spp, 3)
}

/// The floor (y = 0) and, with `sheet`, the screen 0.5 m above it with that material; both
/// 20 m squares, the screen's texture coordinates repeating 100 times across it.
fn scene(sheet: Option<Value>) -> Value {
    let mut b = Vec::new();
    for y in [0f32, 0.5] {
        for [x, z] in [[-10f32, 10.0], [10.0, 10.0], [10.0, -10.0], [-10.0, -10.0]] {
            for c in [x, y, z] {
                b.extend(c.to_le_bytes());
            }
        }
    }
    for [u, v] in [[0f32, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]] {
        for c in [u, v] {
            b.extend(c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        b.extend(i.to_le_bytes());
    }
    // 2×2 texels: alpha 0 and 1 in a checker (colour black).
    let img = image::RgbaImage::from_fn(2, 2, |x, y| {
        image::Rgba([0, 0, 0, if (x + y) % 2 == 0 { 255 } else { 0 }])
    });
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("png");
    let no_specular = json!({"KHR_materials_specular": {"specularFactor": 0.0}});
    let floor = json!({"pbrMetallicRoughness": {"metallicFactor": 0.0},
                       "extensions": no_specular});
    let mut nodes = vec![
        json!({"mesh": 0}),
        // −z rotated −90° about x: straight down, from where the light is.
        json!({"camera": 0, "translation": [0.0, 2.0, 0.0],
               "rotation": [-0.70710677, 0.0, 0.0, 0.70710677]}),
        json!({"translation": [0.0, 2.0, 0.0],
               "extensions": {"KHR_lights_punctual": {"light": 0}}}),
    ];
    let mut materials = vec![floor.clone()];
    match sheet {
        Some(mut m) => {
            m["extensions"] = no_specular.clone();
            m["doubleSided"] = json!(true);
            materials.push(m);
            nodes.push(json!({"mesh": 1}));
        }
        // The screen's mesh stays in the file (unplaced), so its material must exist.
        None => materials.push(floor),
    }
    let node_ids: Vec<usize> = (0..nodes.len()).collect();
    json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_specular"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "intensity": 683.002}
        ]}},
        "scene": 0,
        "scenes": [{"nodes": node_ids}],
        "nodes": nodes,
        "cameras": [{"type": "perspective",
                     "perspective": {"yfov": 0.5, "aspectRatio": 1.0, "znear": 0.01}}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": 0}, "indices": 3, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": 1, "TEXCOORD_0": 2}, "indices": 3,
                             "material": 1}]}
        ],
        "materials": materials,
        "textures": [{"source": 0}],
        "images": [{"uri": data_uri(&png)}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [-10, 0, -10], "max": [10, 0, 10]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [-10, 0.5, -10], "max": [10, 0.5, 10]},
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
fn every_method_sees_and_lights_through_cut_out_and_blended_surfaces() {
    let open = load(&scene(None));
    let mask = load(&scene(Some(json!({
        "alphaMode": "MASK",
        "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}
    }))));
    let blend = load(&scene(Some(json!({
        "alphaMode": "BLEND",
        "pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 0.3], "metallicFactor": 0.0}
    }))));
    for name in method::names() {
        let spp = if name == "path" { 256 } else { 64 };
        let reference = mean(&render(&open, name, spp));
        let m = mean(&render(&mask, name, spp)) / reference;
        let b = mean(&render(&blend, name, spp)) / reference;
        println!("{name}: mask {m:.4} (expected 0.5), blend {b:.4} (expected 0.49)");
        assert!((m - 0.5).abs() < 0.02, "{name}: mask {m}");
        assert!((b - 0.49).abs() < 0.02, "{name}: blend {b}");
    }
}
