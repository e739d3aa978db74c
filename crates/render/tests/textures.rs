//! Image textures in a render: a floor with a checker of single texels, repeated, seen from
//! near to the horizon under a sun straight above (so a pixel's value is the albedo it sees).
//! At one sample per pixel, far away (beyond 80 m, where a pixel covers a few checks), each
//! pixel must show their average (the mip-map's work) instead of one check's black or white
//! (aliasing); near (about 2.4 m, where a check covers several pixels), the checks must stay
//! sharp.
//!
//! Normal maps: on the same floor, a texel tilting the normal toward the tangent (+u) or the
//! bitangent (up the image, i.e. toward −v in glTF's coordinates; tangents generated in
//! MikkTSpace from the file's coordinates) makes the floor face a sun tilted the same way:
//! exactly what the cosine law says.

mod common;

use common::data_uri;
use serde_json::json;
use tessera_render::Scene;
use tessera_render::camera::Camera;
use tessera_render::film::SampleRange;
use tessera_render::render::render_frame;

fn png_of(img: &image::RgbaImage) -> Vec<u8> {
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .expect("png");
    png
}

fn floor_scene(repeat: f32) -> serde_json::Value {
    floor_with(repeat, None)
}

/// The floor: a 2 km square at y = 0 (from z = 0 away from the camera) with texture
/// coordinates 0..`repeat` both ways (u along +x, v along −z), the camera 1 m above it
/// looking 10° down, a directional light of π W/m² from straight above.
///
/// With `normal`, a white material with that normal-map texel everywhere instead with that normal-map texel everywhere instead
/// of the checker.
fn floor_with(repeat: f32, normal: Option<[u8; 3]>) -> serde_json::Value {
    let mut b = Vec::new();
    let positions = [
        [-1000f32, 0.0, 0.0],
        [1000.0, 0.0, 0.0],
        [1000.0, 0.0, -2000.0],
        [-1000.0, 0.0, -2000.0],
    ];
    for p in positions {
        for c in p {
            b.extend(c.to_le_bytes());
        }
    }
    let uvs = [[0f32, 0.0], [repeat, 0.0], [repeat, repeat], [0.0, repeat]];
    for t in uvs {
        for c in t {
            b.extend(c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        b.extend(i.to_le_bytes());
    }
    // Two by two checks of 8×8 texels, white and black, 8-bit sRGB (0 and 255 decode exactly).
    let img = image::RgbaImage::from_fn(16, 16, |x, y| {
        let v = if (x / 8 + y / 8) % 2 == 0 { 255 } else { 0 };
        image::Rgba([v, v, v, 255])
    });
    let png = png_of(&img);
    let (material, image) = match normal {
        None => (
            json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0},
                   "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}}),
            png,
        ),
        Some([x, y, z]) => (
            json!({"pbrMetallicRoughness": {"metallicFactor": 0.0},
                   "normalTexture": {"index": 0},
                   "extensions": {"KHR_materials_specular": {"specularFactor": 0.0}}}),
            png_of(&image::RgbaImage::from_pixel(
                4,
                4,
                image::Rgba([x, y, z, 255]),
            )),
        ),
    };
    let (s, c) = (-5f32).to_radians().sin_cos(); // half of −10° about x
    json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_materials_specular"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "directional", "intensity": std::f32::consts::PI * 683.002}
        ]}},
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [
            {"mesh": 0},
            {"camera": 0, "translation": [0.0, 1.0, 0.0], "rotation": [s, 0.0, 0.0, c]},
            // −z rotated −90° about x: straight down.
            {"rotation": [-0.70710677, 0.0, 0.0, 0.70710677],
             "extensions": {"KHR_lights_punctual": {"light": 0}}}
        ],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.5, "aspectRatio": 1.0, "znear": 0.01}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
        "materials": [material],
        "textures": [{"source": 0}],
        "images": [{"uri": data_uri(&image)}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [-1000, 0, -2000], "max": [1000, 0, 0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 32},
            {"buffer": 0, "byteOffset": 80, "byteLength": 12}
        ],
        "buffers": [{"byteLength": b.len(), "uri": data_uri(&b)}]
    })
}

#[test]
fn a_checker_is_averaged_where_pixels_cover_many_checks_and_sharp_where_they_do_not() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("floor.gltf");
    // The image 4000 times across 2 km: checks of 25 cm, 3 cm texels.
    std::fs::write(&path, floor_scene(4000.0).to_string()).expect("write");
    let mut desc = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    (desc.film.width, desc.film.height) = (64, 64);
    desc.film.filter = tessera_scene::FilterDesc::Box { radius: 0.5 };
    desc.integrator.method = "direct".into();
    desc.integrator.spp = 1;
    let scene = Scene::build(&desc);
    assert!(scene.stats.texture_bytes > 0);
    let camera = Camera::new(&desc.camera, &desc.film);
    let integ = tessera_render::method::for_scene(&desc, &scene).expect("a per-ray method");
    let image = render_frame(
        &scene,
        &camera,
        integ.as_ref(),
        8,
        SampleRange { start: 0, end: 1 },
    )
    .0;
    let value = |x: usize, y: usize| image.pixels[y * 64 + x].rgb[1];
    // Rows by their distance: the horizon is 10° above the centre (row ≈ 32 − 10/0.5 rad…),
    // the floor below it. Count grey (averaged) pixels among far rows and near rows.
    let grey = |rows: std::ops::Range<usize>| {
        let (mut g, mut n) = (0, 0);
        for y in rows {
            for x in 8..56 {
                let v = value(x, y);
                n += 1;
                if (0.25..=0.75).contains(&v) {
                    g += 1;
                }
            }
        }
        g as f64 / n as f64
    };
    // Find the horizon: the first row from the top that sees the lit floor.
    let horizon = (0..64)
        .find(|&y| (8..56).all(|x| value(x, y) > 0.0))
        .expect("the floor is in view");
    let far = grey(horizon + 1..horizon + 3);
    let near = grey(56..64);
    println!("horizon at row {horizon}; grey pixels far {far:.2}, near {near:.2}");
    assert!(
        far > 0.9,
        "far away {far:.2} of pixels show the checks' average"
    );
    assert!(
        near < 0.5,
        "near {near:.2} of pixels are grey: the checks are blurred"
    );
    // The average is right: albedo ½ under π W/m² from above is ½ W·sr⁻¹·m⁻².
    let mut far_mean = 0.0;
    for y in horizon + 1..horizon + 3 {
        for x in 8..56 {
            far_mean += value(x, y) as f64 / (2.0 * 48.0);
        }
    }
    assert!((far_mean - 0.5).abs() < 0.03, "far mean {far_mean}");
}

/// The floor's radiance (all pixels agree: a plane under a sun) with normal-map texel
/// `normal` (none: no normal map), the sun arriving from `from`.
fn lit_floor(normal: Option<[u8; 3]>, from: glam::Vec3) -> f32 {
    lit_floor_through(normal, from, None)
}

/// As [`lit_floor`], the normal map's coordinates through KHR_texture_transform `transform`.
fn lit_floor_through(
    normal: Option<[u8; 3]>,
    from: glam::Vec3,
    transform: Option<serde_json::Value>,
) -> f32 {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("floor.gltf");
    let mut doc = floor_with(100.0, normal);
    if let Some(t) = transform {
        doc["materials"][0]["normalTexture"]["extensions"] = json!({"KHR_texture_transform": t});
        doc["extensionsUsed"]
            .as_array_mut()
            .expect("extensionsUsed")
            .push(json!("KHR_texture_transform"));
    }
    std::fs::write(&path, doc.to_string()).expect("write");
    let mut desc = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    if normal.is_none() {
        // The checker's material, made white: compare like with like.
        if let tessera_scene::MaterialKind::MetallicRoughness { textures, .. } =
            &mut desc.materials[0].kind
        {
            textures.base_color = None;
        }
    }
    assert!(
        desc.warnings.iter().all(|w| !w.contains("normal")),
        "{:?}",
        desc.warnings
    );
    (desc.film.width, desc.film.height) = (16, 16);
    // Looking straight down, so that no tilt here turns the shading normal from the viewer.
    desc.camera.position = glam::Vec3::new(0.0, 2.0, -5.0);
    desc.camera.look_at = glam::Vec3::new(0.0, 0.0, -5.0);
    desc.camera.up = glam::Vec3::new(0.0, 0.0, -1.0);
    desc.integrator.method = "direct".into();
    desc.integrator.spp = 1;
    desc.lights = vec![tessera_scene::LightDesc::Directional {
        direction: -from.normalize(),
        irradiance: glam::Vec3::splat(std::f32::consts::PI),
    }];
    let scene = Scene::build(&desc);
    let camera = Camera::new(&desc.camera, &desc.film);
    let integ = tessera_render::method::for_scene(&desc, &scene).expect("a per-ray method");
    let image = render_frame(
        &scene,
        &camera,
        integ.as_ref(),
        8,
        SampleRange { start: 0, end: 1 },
    )
    .0;
    image.pixels[8 * 16 + 8].rgb[1]
}

#[test]
fn normal_maps_turn_the_shading_normal_toward_the_tangent_and_the_bitangent() {
    let (s, c) = 30f32.to_radians().sin_cos();
    // The sun 30° from straight above, toward +x (the tangent, +u) or toward +z (up the
    // image: the floor's v grows toward −z, away from the camera).
    let toward_u = glam::Vec3::new(s, c, 0.0);
    let toward_up = glam::Vec3::new(0.0, c, s);
    let enc = |v: f32| (((v * 0.5 + 0.5) * 255.0).round()) as u8;
    let plain = lit_floor(None, toward_u);
    assert!(
        (plain - c).abs() < 1e-3,
        "without a normal map: {plain}, cos 30° = {c}"
    );
    // A flat normal map changes nothing (beyond 8 bits' rounding of 0.5).
    let flat = lit_floor(Some([128, 128, 255]), toward_u);
    assert!(
        (flat - plain).abs() < 5e-3,
        "flat map {flat} against {plain}"
    );
    // Tilted 30° toward the sun: facing it.
    let tilt_u = lit_floor(Some([enc(s), 128, enc(c)]), toward_u);
    assert!(
        tilt_u > 0.995,
        "tilted toward +u, facing a sun there: {tilt_u}"
    );
    let tilt_v = lit_floor(Some([128, enc(s), enc(c)]), toward_up);
    assert!(
        tilt_v > 0.995,
        "tilted up the image, facing a sun there: {tilt_v}"
    );
    // Tilted away from the sun: 60° off it.
    let away = lit_floor(Some([enc(-s), 128, enc(c)]), toward_u);
    assert!(
        (away - 0.5).abs() < 0.01,
        "tilted away: {away}, cos 60° = 0.5"
    );
}

/// A normal map's texture transform turns its tangent frame with its coordinates: rotated by
/// 90° (KHR_texture_transform: u' = v, v' = −u, as Blender's exporter and the sample model
/// mean it), a texel tilting toward +s tilts the floor toward +v (toward −z here: down the
/// image); mirrored in u (scale −1), toward −u.
#[test]
fn a_normal_maps_texture_transform_turns_its_tilt_with_it() {
    let (s, c) = 30f32.to_radians().sin_cos();
    let enc = |v: f32| (((v * 0.5 + 0.5) * 255.0).round()) as u8;
    let tilt = Some([enc(s), 128, enc(c)]);
    let quarter = json!({"rotation": std::f32::consts::FRAC_PI_2});
    let toward_plus_v = glam::Vec3::new(0.0, c, -s);
    let turned = lit_floor_through(tilt, toward_plus_v, Some(quarter.clone()));
    assert!(
        turned > 0.995,
        "rotated a quarter turn, facing +v: {turned}"
    );
    let toward_u = glam::Vec3::new(s, c, 0.0);
    let not_there = lit_floor_through(tilt, toward_u, Some(quarter));
    assert!(
        (not_there - c * c).abs() < 0.01,
        "rotated away from +u: {not_there}, expected cos² 30° = {}",
        c * c
    );
    let mirrored = lit_floor_through(
        tilt,
        glam::Vec3::new(-s, c, 0.0),
        Some(json!({"scale": [-1.0, 1.0]})),
    );
    assert!(mirrored > 0.995, "mirrored in u, facing −u: {mirrored}");
    // Offsets and uniform scales leave the frame alone.
    let moved = lit_floor_through(
        tilt,
        toward_u,
        Some(json!({"offset": [0.3, 0.1], "scale": [2.0, 2.0]})),
    );
    assert!(moved > 0.995, "moved and scaled, facing +u: {moved}");
}

/// The checker floor rendered from `doc`, 32×32 pixels at one sample each.
fn render_doc(doc: &serde_json::Value) -> Vec<f32> {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("floor.gltf");
    std::fs::write(&path, doc.to_string()).expect("write");
    let mut desc = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert!(desc.warnings.is_empty(), "{:?}", desc.warnings);
    (desc.film.width, desc.film.height) = (32, 32);
    desc.integrator.method = "direct".into();
    desc.integrator.spp = 1;
    let scene = Scene::build(&desc);
    let camera = Camera::new(&desc.camera, &desc.film);
    let integ = tessera_render::method::for_scene(&desc, &scene).expect("a per-ray method");
    let image = render_frame(
        &scene,
        &camera,
        integ.as_ref(),
        8,
        SampleRange { start: 0, end: 1 },
    )
    .0;
    image.pixels.iter().map(|p| p.rgb[1]).collect()
}

/// A texture reading TEXCOORD_1 finds its coordinates there: the floor's coordinates moved
/// to the second set (the first made constant) give the same image when the texture names
/// set 1, and a flat one when it does not.
#[test]
fn a_texture_reads_the_coordinate_set_it_names() {
    let plain = floor_scene(400.0);
    let constant: Vec<u8> = (0..4)
        .flat_map(|_| [0.3f32, 0.3])
        .flat_map(|c| c.to_le_bytes())
        .collect();
    let moved = |set: u32| {
        let mut doc = plain.clone();
        doc["buffers"]
            .as_array_mut()
            .expect("buffers")
            .push(json!({"byteLength": constant.len(), "uri": data_uri(&constant)}));
        let views = doc["bufferViews"].as_array_mut().expect("views");
        views.push(json!({"buffer": 1, "byteOffset": 0, "byteLength": constant.len()}));
        let view = views.len() - 1;
        let accessors = doc["accessors"].as_array_mut().expect("accessors");
        accessors
            .push(json!({"bufferView": view, "componentType": 5126, "count": 4, "type": "VEC2"}));
        let constant_accessor = accessors.len() - 1;
        let attributes = &mut doc["meshes"][0]["primitives"][0]["attributes"];
        attributes["TEXCOORD_1"] = attributes["TEXCOORD_0"].clone();
        attributes["TEXCOORD_0"] = json!(constant_accessor);
        doc["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"] = json!(set);
        doc
    };
    let reference = render_doc(&plain);
    assert_eq!(render_doc(&moved(1)), reference);
    let flat = render_doc(&moved(0));
    let spread = |v: &[f32]| {
        v.iter().cloned().fold(f32::MIN, f32::max) - v.iter().cloned().fold(f32::MAX, f32::min)
    };
    assert!(
        spread(&reference) > 0.5,
        "the checker shows: {}",
        spread(&reference)
    );
    // One texel everywhere (lit alike): every floor pixel the same; the sky above is black.
    let lit: Vec<f32> = flat.iter().cloned().filter(|&v| v > 0.0).collect();
    assert!(
        spread(&lit) < 1e-3,
        "constant coordinates: {}",
        spread(&lit)
    );
}
