//! Small real files the targets' inputs sit among, and seeds made from them: images written
//! by the `image` and `exr` crates, the repository's example scenes.

use std::io::Cursor;

use base64::Engine;
use base64::engine::general_purpose::STANDARD;

use crate::{Mem, files_of, repo};

/// A PNG of `w`×`h` (8-bit RGBA, a gradient).
pub fn png(w: u32, h: u32) -> Vec<u8> {
    let img = image::RgbaImage::from_fn(w, h, |x, y| {
        image::Rgba([(x * 40 % 256) as u8, (y * 40 % 256) as u8, 128, 255])
    });
    let mut out = Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png)
        .expect("a PNG encodes");
    out.into_inner()
}

/// A JPEG of `w`×`h`.
pub fn jpeg(w: u32, h: u32) -> Vec<u8> {
    let img = image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([(x * 30 % 256) as u8, (y * 30 % 256) as u8, 90])
    });
    let mut out = Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Jpeg)
        .expect("a JPEG encodes");
    out.into_inner()
}

/// An OpenEXR of `w`×`h` (RGB, half floats), an environment map's shape.
pub fn exr(w: usize, h: usize) -> Vec<u8> {
    use exr::prelude::*;
    let image = Image::from_channels(
        (w, h),
        SpecificChannels::rgb(|p: Vec2<usize>| {
            (
                f16::from_f32(p.0 as f32 / w as f32),
                f16::from_f32(p.1 as f32 / h as f32),
                f16::from_f32(0.5),
            )
        }),
    );
    let mut out = Cursor::new(Vec::new());
    image.write().to_buffered(&mut out).expect("an EXR encodes");
    out.into_inner()
}

/// The Cornell box's folder (its meshes, no reference images) with a small environment map
/// (`sky.exr`) and texture (`texture.png`) beside it: what the `scene` target's scene files
/// may reference.
pub fn scene_folder() -> Mem {
    let mut mem = Mem::default();
    for (name, bytes) in files_of(&repo().join("scenes/cornell-box")) {
        if name.ends_with(".obj") {
            mem = mem.with(&name, bytes);
        }
    }
    mem.with("sky.exr", exr(16, 8))
        .with("texture.png", png(4, 4))
}

/// A one-triangle glTF (JSON, its buffer a data URI) with a base-colour texture.
pub fn gltf_triangle() -> Vec<u8> {
    // Three positions (36 bytes) and three u16 indices (6 bytes, padded to 8).
    let mut buffer = Vec::new();
    for p in [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]] {
        for c in p {
            buffer.extend_from_slice(&c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0] {
        buffer.extend_from_slice(&i.to_le_bytes());
    }
    let uri = format!(
        "data:application/octet-stream;base64,{}",
        STANDARD.encode(&buffer)
    );
    serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [
            {"mesh": 0},
            {"camera": 0, "translation": [0.3, 0.3, 2.0]}
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.01}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}, "emissiveFactor": [1, 1, 1]}],
        "textures": [{"source": 0}],
        "images": [{"uri": "texture.png"}],
        "buffers": [{"byteLength": buffer.len(), "uri": uri}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 6}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
             "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}
        ]
    })
    .to_string()
    .into_bytes()
}

/// `json` (a glTF document) as a GLB container: its buffers' data URIs moved into the binary
/// chunk (glTF 2.0 §4.4: a 12-byte header, a JSON chunk padded with spaces, a BIN chunk padded
/// with zeros).
pub fn glb(json: &[u8]) -> Vec<u8> {
    let mut doc: serde_json::Value = serde_json::from_slice(json).expect("a glTF document");
    let mut bin = Vec::new();
    if let Some(buffer) = doc["buffers"].get_mut(0) {
        let uri = buffer["uri"].as_str().unwrap_or("").to_string();
        if let Some((_, data)) = uri.split_once("base64,") {
            bin = STANDARD.decode(data).expect("the fixture's own base64");
            buffer.as_object_mut().expect("an object").remove("uri");
        }
    }
    let mut text = doc.to_string().into_bytes();
    while text.len() % 4 != 0 {
        text.push(b' ');
    }
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let total = 12 + 8 + text.len() + if bin.is_empty() { 0 } else { 8 + bin.len() };
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&text);
    if !bin.is_empty() {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
    }
    out
}
