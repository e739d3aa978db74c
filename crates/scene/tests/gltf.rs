//! glTF 2.0 import: each feature read from a small file written here byte by byte (JSON and
//! little-endian buffers as the specification lays them out), and each bad input refused with
//! the file, the object and what was expected. Files written by Blender's exporter are tested
//! in `crates/render/tests/gltf_blender.rs`.

use std::path::Path;

use base64::Engine;
use glam::Vec3;
use serde_json::{Value, json};
use tessera_scene::{LightDesc, MaterialKind, SceneDesc, SceneError};

/// A unit right triangle in z = 0 facing +z: positions, normals and u16 indices in one buffer.
fn triangle_buffer() -> Vec<u8> {
    let mut b = Vec::new();
    for p in [[0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        for c in p {
            b.extend(c.to_le_bytes());
        }
    }
    for _ in 0..3 {
        for c in [0f32, 0.0, 1.0] {
            b.extend(c.to_le_bytes());
        }
    }
    for i in [0u16, 1, 2] {
        b.extend(i.to_le_bytes());
    }
    b.extend([0, 0]); // pad to 4 bytes
    b
}

fn data_uri(bytes: &[u8]) -> String {
    format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

/// A glTF document with the triangle as mesh 0 and whatever `extra` adds or overrides.
fn document(extra: Value) -> Value {
    let buf = triangle_buffer();
    let mut doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "Tri"}],
        "meshes": [{"name": "Triangle", "primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 0
        }]}],
        "materials": [{"name": "Paint", "pbrMetallicRoughness": {
            "baseColorFactor": [0.8, 0.4, 0.2, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.5
        }}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
             "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5123, "count": 3, "type": "SCALAR"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 36},
            {"buffer": 0, "byteOffset": 72, "byteLength": 6}
        ],
        "buffers": [{"byteLength": buf.len(), "uri": data_uri(&buf)}]
    });
    merge(&mut doc, extra);
    doc
}

/// Overwrites `doc`'s fields with `extra`'s, recursively for objects.
fn merge(doc: &mut Value, extra: Value) {
    match (doc, extra) {
        (Value::Object(d), Value::Object(e)) => {
            for (k, v) in e {
                match d.get_mut(&k) {
                    Some(slot) if slot.is_object() && v.is_object() => merge(slot, v),
                    _ => {
                        d.insert(k, v);
                    }
                }
            }
        }
        (d, e) => *d = e,
    }
}

/// Writes `files` into a fresh folder and loads `name` from it.
fn load_files(
    files: &[(&str, Vec<u8>)],
    name: &str,
) -> (tempfile::TempDir, Result<SceneDesc, SceneError>) {
    let dir = tempfile::tempdir().expect("a temporary folder");
    for (n, bytes) in files {
        std::fs::write(dir.path().join(n), bytes).expect("write");
    }
    let r = tessera_scene::load(&dir.path().join(name));
    (dir, r)
}

fn load_doc(doc: &Value) -> SceneDesc {
    let (_dir, r) = load_files(
        &[("scene.gltf", doc.to_string().into_bytes())],
        "scene.gltf",
    );
    r.unwrap_or_else(|e| panic!("{e}"))
}

fn error_of(files: &[(&str, Vec<u8>)], name: &str) -> String {
    let (_dir, r) = load_files(files, name);
    match r {
        Ok(_) => panic!("expected an error"),
        Err(e) => e.to_string(),
    }
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-5
}

#[test]
fn a_triangle_with_its_material_and_normals_becomes_a_mesh() {
    let d = load_doc(&document(json!({})));
    assert_eq!(d.meshes.len(), 1);
    let m = &d.meshes[0];
    assert_eq!(m.triangles, vec![[0, 1, 2]]);
    assert!(close(m.positions[1], Vec3::X));
    assert_eq!(m.normals.as_ref().map(|n| n[0]), Some(Vec3::Z));
    match &d.materials[m.material as usize].kind {
        MaterialKind::MetallicRoughness {
            base_color,
            metallic,
            roughness,
            ior,
            ..
        } => {
            assert!(close(*base_color, Vec3::new(0.8, 0.4, 0.2)));
            assert_eq!((*metallic, *roughness, *ior), (0.0, 0.5, 1.5));
        }
        k => panic!("expected the metallic-roughness BRDF, got {k:?}"),
    }
    // No camera in the file: the bounds are framed, and the user is told.
    assert!(
        d.warnings
            .iter()
            .any(|w| w.contains("no perspective camera")),
        "{:?}",
        d.warnings
    );
}

#[test]
fn the_node_hierarchy_composes_matrix_and_trs_transforms() {
    // Parent: a matrix translating by (10, 0, 0); child: rotate 90° about z, scale 2.
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let d = load_doc(&document(json!({
        "scenes": [{"nodes": [1]}],
        "nodes": [
            {"mesh": 0, "rotation": [0.0, 0.0, s, s], "scale": [2.0, 2.0, 2.0]},
            {"children": [0], "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 10,0,0,1]}
        ]
    })));
    let p = &d.meshes[0].positions;
    assert!(close(p[0], Vec3::new(10.0, 0.0, 0.0)), "{p:?}");
    assert!(close(p[1], Vec3::new(10.0, 2.0, 0.0)), "{p:?}"); // x rotated to y, doubled
    assert!(close(p[2], Vec3::new(8.0, 0.0, 0.0)), "{p:?}");
    let n = d.meshes[0].normals.as_ref().expect("normals");
    assert!(close(n[0], Vec3::Z));
}

#[test]
fn indices_of_every_width_and_unindexed_primitives_read_alike() {
    let base = load_doc(&document(json!({}))).meshes[0].triangles.clone();
    // u8 indices: a new view over the same bytes would not do (u16 there), so a second buffer.
    let u8_buf = [0u8, 1, 2, 0];
    let u32_buf: Vec<u8> = [0u32, 1, 2].iter().flat_map(|i| i.to_le_bytes()).collect();
    for (component, bytes) in [(5121, u8_buf.to_vec()), (5125, u32_buf)] {
        let mut doc = document(json!({}));
        doc["buffers"].as_array_mut().expect("buffers").push(json!({
            "byteLength": bytes.len(), "uri": data_uri(&bytes)
        }));
        doc["bufferViews"]
            .as_array_mut()
            .expect("views")
            .push(json!({
                "buffer": 1, "byteOffset": 0, "byteLength": bytes.len()
            }));
        doc["accessors"][2] =
            json!({"bufferView": 3, "componentType": component, "count": 3, "type": "SCALAR"});
        assert_eq!(
            load_doc(&doc).meshes[0].triangles,
            base,
            "component type {component}"
        );
    }
    let mut doc = document(json!({}));
    doc["meshes"][0]["primitives"][0]
        .as_object_mut()
        .expect("primitive")
        .remove("indices");
    assert_eq!(load_doc(&doc).meshes[0].triangles, base);
}

#[test]
fn the_camera_sets_the_view_and_the_film_aspect() {
    let d = load_doc(&document(json!({
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"camera": 0, "translation": [0.0, 0.5, 3.0]}],
        "cameras": [{"type": "perspective", "perspective": {
            "yfov": 0.6, "aspectRatio": 2.0, "znear": 0.1
        }}]
    })));
    assert_eq!((d.film.width, d.film.height), (1280, 640));
    assert!(close(d.camera.position, Vec3::new(0.0, 0.5, 3.0)));
    assert!(close(
        (d.camera.look_at - d.camera.position).normalize(),
        -Vec3::Z
    ));
    assert!(
        (d.camera.fov_y - 0.6).abs() < 1e-5,
        "fov {}",
        d.camera.fov_y
    );
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
}

#[test]
fn punctual_lights_become_radiometric_lights_where_their_nodes_put_them() {
    let d = load_doc(&document(json!({
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "color": [1.0, 0.5, 0.25], "intensity": 683.002},
            {"type": "spot", "intensity": 1366.004, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}},
            {"type": "directional", "intensity": 6.83002}
        ]}},
        "scenes": [{"nodes": [0, 1, 2, 3]}],
        "nodes": [
            {"mesh": 0},
            {"translation": [1.0, 2.0, 3.0], "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"translation": [0.0, 4.0, 0.0], "rotation": [-0.70710677, 0.0, 0.0, 0.70710677],
             "extensions": {"KHR_lights_punctual": {"light": 1}}},
            {"extensions": {"KHR_lights_punctual": {"light": 2}}}
        ]
    })));
    assert_eq!(d.lights.len(), 3);
    match d.lights[0] {
        LightDesc::Point {
            position,
            intensity,
        } => {
            assert!(close(position, Vec3::new(1.0, 2.0, 3.0)));
            // 683 cd of luminous-equivalent light is 1 W/sr.
            assert!(close(intensity, Vec3::new(1.0, 0.5, 0.25)), "{intensity}");
        }
        ref l => panic!("expected a point light, got {l:?}"),
    }
    match d.lights[1] {
        LightDesc::Spot {
            position,
            direction,
            intensity,
            cos_falloff_start,
            cos_cone,
        } => {
            assert!(close(position, Vec3::new(0.0, 4.0, 0.0)));
            // −z rotated −90° about x points down.
            assert!(close(direction, -Vec3::Y), "{direction}");
            assert!(close(intensity, Vec3::splat(2.0)));
            assert!(
                (cos_falloff_start - 0.2f32.cos()).abs() < 1e-6
                    && (cos_cone - 0.5f32.cos()).abs() < 1e-6
            );
        }
        ref l => panic!("expected a spot light, got {l:?}"),
    }
    match d.lights[2] {
        LightDesc::Directional {
            direction,
            irradiance,
        } => {
            assert!(close(direction, -Vec3::Z));
            assert!(close(irradiance, Vec3::splat(0.01)), "{irradiance}");
        }
        ref l => panic!("expected a directional light, got {l:?}"),
    }
}

#[test]
fn emission_transmission_ior_and_specular_extensions_are_read() {
    let d = load_doc(&document(json!({
        "extensionsUsed": ["KHR_materials_emissive_strength", "KHR_materials_transmission",
                           "KHR_materials_ior", "KHR_materials_specular"],
        "meshes": [{"primitives": [
            {"attributes": {"POSITION": 0}, "material": 0},
            {"attributes": {"POSITION": 0}, "material": 1},
            {"attributes": {"POSITION": 0}, "material": 2}
        ]}],
        "materials": [
            {"name": "Lamp", "emissiveFactor": [1.0, 0.5, 0.0], "doubleSided": true,
             "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}}},
            {"name": "Glass", "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.0},
             "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                            "KHR_materials_ior": {"ior": 1.45}}},
            {"name": "Coat", "pbrMetallicRoughness": {"metallicFactor": 0.0},
             "extensions": {"KHR_materials_specular": {"specularFactor": 0.5,
                                                        "specularColorFactor": [1.0, 0.0, 0.0]},
                            "KHR_materials_ior": {"ior": 2.0}}}
        ]
    })));
    let e = d.meshes[0].emission.clone().expect("the lamp emits");
    assert!(close(e.radiance, Vec3::new(4.0, 2.0, 0.0)) && e.two_sided);
    assert!(d.meshes[1].emission.is_none());
    match d.materials[d.meshes[1].material as usize].kind {
        MaterialKind::Dielectric { eta, roughness, .. } => {
            assert!((eta - 1.45).abs() < 1e-6 && roughness.is_smooth());
        }
        ref k => panic!("expected glass, got {k:?}"),
    }
    match d.materials[d.meshes[2].material as usize].kind {
        MaterialKind::MetallicRoughness {
            ior,
            specular,
            specular_color,
            ..
        } => assert!(ior == 2.0 && specular == 0.5 && close(specular_color, Vec3::X)),
        ref k => panic!("expected the metallic-roughness BRDF, got {k:?}"),
    }
}

/// The emissive texture multiplies the emission; a texture reading coordinates the mesh
/// lacks, or a set past TEXCOORD_1, is named in a warning.
#[test]
fn emissive_textures_are_read_and_unread_coordinates_named_in_warnings() {
    let image = png([[255, 0, 0, 255], [255; 4], [0, 0, 0, 255], [255; 4]]);
    let d = load_doc(&textured(
        json!({"name": "Lamp", "emissiveFactor": [1.0, 0.5, 0.25],
               "emissiveTexture": {"index": 0, "texCoord": 1}}),
        json!({"images": [{"uri": data_uri(&image)}], "textures": [{"source": 0}]}),
    ));
    let e = d.meshes[0].emission.as_ref().expect("the lamp emits");
    assert!(close(e.radiance, Vec3::new(1.0, 0.5, 0.25)));
    let t = e.texture.as_ref().expect("the emissive texture");
    // Colour: decoded from sRGB (255 → 1).
    assert_eq!(t.image.texel(0, 0).x, 1.0);
    let w = d.warnings.join("\n");
    assert!(
        w.contains("textures read TEXCOORD_1, which it lacks"),
        "{w}"
    );
    // Sets past 1 are not read.
    let d = load_doc(&textured(
        json!({"name": "Lamp", "emissiveFactor": [1.0, 0.5, 0.25],
               "emissiveTexture": {"index": 0, "texCoord": 2}}),
        json!({"images": [{"uri": data_uri(&image)}], "textures": [{"source": 0}]}),
    ));
    let w = d.warnings.join("\n");
    assert!(
        w.contains("emissiveTexture reads TEXCOORD_2; only TEXCOORD_0 and 1"),
        "{w}"
    );
}

/// alphaMode: MASK with its cutoff (0.5 by default), BLEND, and OPAQUE (whatever the alpha);
/// coverage is the base colour factor's alpha (times the texture's, at render time).
#[test]
fn alpha_modes_become_coverage() {
    use tessera_scene::{Coverage, CoverageMode};
    let coverage = |material: Value| {
        let d = load_doc(&document(json!({"materials": [material]})));
        assert!(
            d.warnings.iter().all(|w| !w.contains("alpha")),
            "{:?}",
            d.warnings
        );
        match &d.materials[0].kind {
            MaterialKind::MetallicRoughness { textures, .. } => textures.coverage,
            k => panic!("expected the metallic-roughness BRDF, got {k:?}"),
        }
    };
    let pbr = json!({"baseColorFactor": [1, 1, 1, 0.25]});
    assert_eq!(
        coverage(json!({"alphaMode": "MASK", "alphaCutoff": 0.2, "pbrMetallicRoughness": pbr})),
        Some(Coverage {
            factor: 0.25,
            mode: CoverageMode::Mask { cutoff: 0.2 }
        })
    );
    assert_eq!(
        coverage(json!({"alphaMode": "MASK"})),
        Some(Coverage {
            factor: 1.0,
            mode: CoverageMode::Mask { cutoff: 0.5 }
        })
    );
    assert_eq!(
        coverage(json!({"alphaMode": "BLEND", "pbrMetallicRoughness": pbr})),
        Some(Coverage {
            factor: 0.25,
            mode: CoverageMode::Blend
        })
    );
    assert_eq!(
        coverage(json!({"alphaMode": "OPAQUE", "pbrMetallicRoughness": pbr})),
        None
    );
    assert_eq!(
        coverage(json!({"alphaMode": "BLEND"})),
        None,
        "fully covered is opaque"
    );
}

#[test]
fn a_glb_and_a_gltf_with_an_external_buffer_load_the_same_mesh() {
    let buf = triangle_buffer();
    let mut doc = document(json!({}));
    doc["buffers"] = json!([{"byteLength": buf.len(), "uri": "tri%20angle.bin"}]);
    let (_d, external) = load_files(
        &[
            ("s.gltf", doc.to_string().into_bytes()),
            ("tri angle.bin", buf.clone()),
        ],
        "s.gltf",
    );
    let external = external.unwrap_or_else(|e| panic!("{e}"));

    doc["buffers"] = json!([{"byteLength": buf.len()}]);
    let mut json_chunk = doc.to_string().into_bytes();
    while !json_chunk.len().is_multiple_of(4) {
        json_chunk.push(b' ');
    }
    let mut glb = Vec::new();
    let total = 12 + 8 + json_chunk.len() + 8 + buf.len();
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend((total as u32).to_le_bytes());
    glb.extend((json_chunk.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&json_chunk);
    glb.extend((buf.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(&buf);
    let (_d, binary) = load_files(&[("s.glb", glb.clone())], "s.glb");
    let binary = binary.unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(binary.meshes[0].positions, external.meshes[0].positions);
    assert_eq!(binary.meshes[0].triangles, external.meshes[0].triangles);

    // A truncated GLB is refused as such.
    let msg = error_of(&[("s.glb", glb[..glb.len() - 10].to_vec())], "s.glb");
    assert!(
        msg.contains("s.glb") && msg.contains("not a valid glTF"),
        "{msg}"
    );
}

#[test]
fn a_scene_json_places_a_gltf_file_in_its_own_units() {
    let scene = json!({
        "units": "cm",
        "camera": {"type": "pinhole", "position": [0, 0, 500], "look_at": [0, 0, 0], "fov_deg": 40},
        "film": {"width": 32, "height": 32},
        "materials": {"white": {"type": "diffuse", "albedo": 0.5}},
        "shapes": [
            {"type": "quad", "origin": [0, 0, 0], "edge_u": [1, 0, 0], "edge_v": [0, 1, 0], "material": "white"},
            {"type": "gltf", "file": "tri.gltf", "transform": [{"translate": [100, 0, 0]}]}
        ]
    });
    let (_d, r) = load_files(
        &[
            ("scene.json", scene.to_string().into_bytes()),
            ("tri.gltf", document(json!({})).to_string().into_bytes()),
        ],
        "scene.json",
    );
    let d = r.unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(d.meshes.len(), 2);
    // 1 m of glTF is 100 cm, then moved 100 cm along x.
    assert!(
        close(d.meshes[1].positions[1], Vec3::new(200.0, 0.0, 0.0)),
        "{:?}",
        d.meshes[1].positions
    );
    assert_eq!(d.materials.len(), 2);
    assert_eq!(d.meshes[1].material, 1);
    assert_eq!(d.materials[1].name, "tri.gltf / Paint");
}

#[test]
fn bad_input_is_refused_naming_the_file_the_object_and_what_was_expected() {
    let gltf = |doc: Value| vec![("bad.gltf", doc.to_string().into_bytes())];
    // The triangle with field `at` (a JSON pointer) set to `value`.
    let edited = |at: &str, value: Value| {
        let mut d = document(json!({}));
        let (object, field) = at.rsplit_once('/').expect("a pointer");
        d.pointer_mut(object).expect("an object of the triangle")[field] = value;
        gltf(d)
    };
    type Files<'a> = Vec<(&'a str, Vec<u8>)>;
    let cases: Vec<(Files, &[&str])> = vec![
        (
            vec![("bad.gltf", b"{\"asset\": ".to_vec())],
            &["bad.gltf", "not a valid glTF"],
        ),
        (
            gltf(document(
                json!({"buffers": [{"byteLength": 80, "uri": "missing.bin"}]}),
            )),
            &["buffers[0]", "missing.bin"],
        ),
        (
            edited("/accessors/0/count", json!(30)),
            &[
                "meshes[0] \"Triangle\" primitives[0]",
                "POSITION",
                "bufferView 0",
            ],
        ),
        (
            gltf(document(
                json!({"extensionsUsed": ["KHR_draco_mesh_compression"],
                "extensionsRequired": ["KHR_draco_mesh_compression"]}),
            )),
            &["extensionsRequired", "KHR_draco_mesh_compression"],
        ),
        (
            gltf(document(
                json!({"buffers": [{"byteLength": 200, "uri": data_uri(&triangle_buffer())}]}),
            )),
            &["buffers[0]", "expected byteLength 200"],
        ),
        (
            edited("/accessors/1/count", json!(0)),
            &["primitives[0]", "NORMAL (accessors[1])", "0 elements"],
        ),
        (
            edited("/accessors/2/count", json!((1u64 << 63) + 1)),
            &["indices", "more than 2^64", "bufferView 2"],
        ),
        (
            gltf(document(json!({"images": [{"bufferView": 0}]}))),
            &["images[0].mimeType", "expected a MIME type"],
        ),
        (
            gltf(document(json!({"images": [{"name": "nothing"}]}))),
            &["images[0]", "expected a uri or a bufferView"],
        ),
        (
            edited("/bufferViews/0/byteStride", json!(4)),
            &[
                "bufferViews[0].byteStride",
                "accessors[0] reads elements of 12 bytes",
                "at least 12",
            ],
        ),
        (
            // A GLB whose header gives a length shorter than the header.
            vec![(
                "bad.glb",
                [
                    &b"glTF"[..],
                    &2u32.to_le_bytes(),
                    &4u32.to_le_bytes(),
                    &[0; 20],
                ]
                .concat(),
            )],
            &[
                "bad.glb",
                "GLB header",
                "given as 4 bytes",
                "at least the header's 12",
            ],
        ),
    ];
    for (files, expected) in cases {
        let msg = error_of(&files, files[0].0);
        for e in expected {
            assert!(msg.contains(e), "expected {e:?} in: {msg}");
        }
    }
    // A NaN position (written into the buffer: JSON cannot hold one).
    let mut buf = triangle_buffer();
    buf[4..8].copy_from_slice(&f32::NAN.to_le_bytes());
    let doc = document(json!({"buffers": [{"byteLength": buf.len(), "uri": data_uri(&buf)}]}));
    let msg = error_of(&gltf(doc), "bad.gltf");
    assert!(
        msg.contains("POSITION 0") && msg.contains("finite"),
        "{msg}"
    );
    // An index past the vertices.
    let mut buf = triangle_buffer();
    buf[76..78].copy_from_slice(&7u16.to_le_bytes());
    let doc = document(json!({"buffers": [{"byteLength": buf.len(), "uri": data_uri(&buf)}]}));
    let msg = error_of(&gltf(doc), "bad.gltf");
    assert!(msg.contains("index 7 refers past the 3 vertices"), "{msg}");
}

/// `scenes/gltf/product-shot.glb`, written by Blender 5.0's own glTF exporter from
/// `scripts/blender/product_shot.py`: Blender's watts come back as the same radiometric
/// intensities (the exporter wrote candela = W/4π × 683).
#[test]
fn blenders_exported_product_shot_reads_as_blender_made_it() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/gltf/product-shot.glb");
    let bytes = std::fs::read(&path).expect("the committed .glb");
    let generator = String::from_utf8_lossy(&bytes[..2048.min(bytes.len())]).into_owned();
    assert!(
        generator.contains("Khronos glTF Blender I/O"),
        "not Blender's file"
    );
    let d = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    // Blender writes its glass without KHR_materials_volume (a thin wall, by the letter of
    // glTF) on a closed sphere: solid, and said so.
    assert!(
        d.warnings.len() == 1 && d.warnings[0].contains("\"Glass\" transmits without"),
        "{:?}",
        d.warnings
    );
    assert_eq!(d.meshes.len(), 5);
    assert_eq!((d.film.width, d.film.height), (1280, 720));
    assert!((d.camera.fov_y.to_degrees() - 35.0).abs() < 1e-3);
    assert!(
        close(d.camera.position, Vec3::new(0.0, 2.4, 6.0)),
        "{}",
        d.camera.position
    );
    let four_pi = 4.0 * std::f32::consts::PI;
    let rel = |a: f32, b: f32| (a - b).abs() <= 1e-4 * b;
    match d.lights[0] {
        LightDesc::Spot {
            intensity,
            cos_cone,
            ..
        } => {
            assert!(rel(intensity.x, 800.0 / four_pi), "{intensity}");
            assert!((cos_cone - 25f32.to_radians().cos()).abs() < 1e-5);
        }
        ref l => panic!("expected the spot light first, got {l:?}"),
    }
    match d.lights[1] {
        LightDesc::Point { intensity, .. } => assert!(rel(intensity.y, 150.0 / four_pi)),
        ref l => panic!("expected the point light, got {l:?}"),
    }
    let kind = |name: &str| {
        let m = d
            .meshes
            .iter()
            .find(|m| m.origin.contains(name))
            .expect(name);
        (
            d.materials[m.material as usize].kind.clone(),
            m.emission.clone(),
        )
    };
    assert!(
        matches!(kind("\"Metal\"").0, MaterialKind::MetallicRoughness { metallic, .. } if metallic == 1.0)
    );
    assert!(
        matches!(kind("\"Glass\"").0, MaterialKind::Dielectric { eta, thin: false, .. } if eta == 1.5)
    );
    let panel = kind("\"Panel\"").1.expect("the panel emits");
    assert!(
        close(panel.radiance, Vec3::new(6.0, 5.4, 4.8)),
        "{}",
        panel.radiance
    );
}

/// A 2×2 RGBA PNG, written by the image crate.
fn png(texels: [[u8; 4]; 4]) -> Vec<u8> {
    let img = image::RgbaImage::from_raw(2, 2, texels.concat()).expect("image");
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .expect("png");
    out
}

/// The triangle with TEXCOORD_0 (a second buffer) and `material`.
fn textured(material: Value, extra: Value) -> Value {
    let uv: Vec<u8> = [[0f32, 0.0], [1.0, 0.0], [0.0, 1.0]]
        .iter()
        .flatten()
        .flat_map(|c| c.to_le_bytes())
        .collect();
    let mut doc = document(extra);
    doc["buffers"].as_array_mut().expect("buffers").push(json!({
        "byteLength": uv.len(), "uri": data_uri(&uv)
    }));
    doc["bufferViews"]
        .as_array_mut()
        .expect("views")
        .push(json!({
            "buffer": 1, "byteOffset": 0, "byteLength": uv.len()
        }));
    doc["accessors"]
        .as_array_mut()
        .expect("accessors")
        .push(json!({
            "bufferView": 3, "componentType": 5126, "count": 3, "type": "VEC2"
        }));
    doc["meshes"][0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(3);
    doc["materials"][0] = material;
    doc
}

#[test]
fn textures_are_read_with_their_coordinates_samplers_transforms_and_colour_spaces() {
    let image = png([[128, 0, 255, 255], [255; 4], [0, 0, 0, 255], [255; 4]]);
    let d = load_doc(&textured(
        json!({"name": "Wood", "pbrMetallicRoughness": {
            "baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform": {
                "offset": [0.5, 0.0], "rotation": 0.0, "scale": [2.0, 3.0]}}},
            "metallicRoughnessTexture": {"index": 1}
        }}),
        json!({
            "extensionsUsed": ["KHR_texture_transform"],
            "images": [{"uri": data_uri(&image), "name": "wood"}],
            "samplers": [{"wrapS": 33648, "wrapT": 33071}],
            "textures": [{"source": 0, "sampler": 0}, {"source": 0}]
        }),
    ));
    assert!(
        d.warnings.iter().all(|w| !w.contains("materials")),
        "{:?}",
        d.warnings
    );
    let uvs = d.meshes[0].uvs.as_ref().expect("TEXCOORD_0");
    assert_eq!(uvs[1], glam::Vec2::new(1.0, 0.0));
    let MaterialKind::MetallicRoughness { textures, .. } = &d.materials[0].kind else {
        panic!("expected the metallic-roughness BRDF");
    };
    let base = textures.base_color.as_ref().expect("base colour texture");
    use tessera_scene::texture::Wrap;
    assert_eq!(base.wrap, [Wrap::MirroredRepeat, Wrap::ClampToEdge]);
    assert_eq!(
        base.map(glam::Vec2::new(1.0, 1.0)),
        glam::Vec2::new(2.5, 3.0)
    );
    // Colour is decoded from sRGB; the same image as data is read as stored.
    assert!((base.image.texel(0, 0).x - 0.215_860_5).abs() < 1e-5);
    let mr = textures
        .metallic_roughness
        .as_ref()
        .expect("metallic-roughness texture");
    assert!((mr.image.texel(0, 0).x - 128.0 / 255.0).abs() < 1e-6);
    assert_eq!(mr.wrap, [Wrap::Repeat; 2]);
}

#[test]
fn a_missing_or_broken_image_is_refused_naming_the_image_and_its_material() {
    let doc = |uri: String| {
        textured(
            json!({"name": "Wood", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}),
            json!({"images": [{"uri": uri}], "textures": [{"source": 0}]}),
        )
    };
    let msg = error_of(
        &[("bad.gltf", doc("wood.png".into()).to_string().into_bytes())],
        "bad.gltf",
    );
    assert!(
        msg.contains("images[0]")
            && msg.contains("wood.png")
            && msg.contains("materials[0] \"Wood\""),
        "{msg}"
    );
    let msg = error_of(
        &[(
            "bad.gltf",
            doc(data_uri(b"not a png")).to_string().into_bytes(),
        )],
        "bad.gltf",
    );
    assert!(
        msg.contains("images[0]") && msg.contains("cannot decode"),
        "{msg}"
    );
}

/// `scenes/gltf-interior/`: Blender's export of a textured room (`scene.glb`, from
/// `scripts/blender/interior.py`), alone a whole scene: its camera, and the sky seen through
/// its window named by the scene's extras.
#[test]
fn the_blender_interior_has_its_textures_normal_map_spot_light_and_sky() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/gltf-interior/scene.glb");
    let d = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        d.warnings.len() == 1 && d.warnings[0].contains("\"Glass\" transmits without"),
        "{:?}",
        d.warnings
    );
    let textured = |name: &str| {
        d.materials
            .iter()
            .find(|m| m.name.ends_with(name))
            .and_then(|m| match &m.kind {
                MaterialKind::MetallicRoughness { textures, .. } => Some(textures.clone()),
                _ => None,
            })
            .unwrap_or_else(|| panic!("no metallic-roughness material {name}"))
    };
    assert!(textured("Wood").base_color.is_some());
    assert!(textured("Painting").base_color.is_some());
    assert!(textured("Bumpy plaster").normal.is_some());
    let wall = d
        .meshes
        .iter()
        .find(|m| m.origin.contains("Back wall"))
        .expect("the back wall");
    assert!(wall.tangents.is_some() && wall.uvs.is_some());
    let sphere = d
        .meshes
        .iter()
        .find(|m| {
            matches!(
                d.materials[m.material as usize].kind,
                MaterialKind::Dielectric { .. }
            )
        })
        .expect("the glass sphere");
    assert!(matches!(
        d.materials[sphere.material as usize].kind,
        MaterialKind::Dielectric { thin: false, .. }
    ));
    assert!(d.lights.iter().any(|l| matches!(l, LightDesc::Spot { .. })));
    assert!(
        d.lights
            .iter()
            .any(|l| matches!(l, LightDesc::Environment { image: Some(_), .. }))
    );
}

/// glTF has no sky: a scene's `extras.tessera_environment` names one, relative to the file,
/// used when the file is the whole scene and named in a warning when a scene.json includes it.
#[test]
fn a_scenes_extras_name_its_sky_relative_to_the_file() {
    let sky = |strength: f32| {
        document(json!({"scenes": [{"nodes": [0], "extras": {
            "author": "someone",
            "tessera_environment": {"strength": strength, "rotation_deg": 90}
        }}]}))
    };
    let d = load_doc(&sky(2.0));
    let env = d
        .lights
        .iter()
        .find_map(|l| match l {
            LightDesc::Environment {
                image: None, scale, ..
            } => Some(*scale),
            _ => None,
        })
        .expect("a constant environment from the extras");
    assert!(close(env, Vec3::splat(2.0)));
    // Without the key the file has no sky; other extras are the user's business.
    let plain = load_doc(&document(
        json!({"scenes": [{"nodes": [0], "extras": {"a": 1}}]}),
    ));
    assert!(plain.lights.is_empty());
    assert!(
        !plain.warnings.iter().any(|w| w.contains("extras")),
        "{:?}",
        plain.warnings
    );

    // The image is found beside the file, here in a sub-folder of the scene.json's.
    let img = std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/gltf-interior/sky.exr"),
    )
    .expect("the interior's sky");
    let dir = tempfile::tempdir().expect("a temporary folder");
    std::fs::create_dir(dir.path().join("sub")).expect("mkdir");
    let with_image = document(json!({"scenes": [{"nodes": [0], "extras": {
        "tessera_environment": {"image": "sky.exr"}}}]}));
    std::fs::write(dir.path().join("sub/a.gltf"), with_image.to_string()).expect("write");
    std::fs::write(dir.path().join("sub/sky.exr"), &img).expect("write");
    let alone =
        tessera_scene::load(&dir.path().join("sub/a.gltf")).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        alone
            .lights
            .iter()
            .any(|l| matches!(l, LightDesc::Environment { image: Some(_), .. }))
    );
    let json = json!({"units": "m",
        "camera": {"type": "pinhole", "position": [0, 0, 5], "look_at": [0, 0, 0], "fov_deg": 40},
        "film": {"width": 8, "height": 8}, "materials": {},
        "shapes": [{"type": "gltf", "file": "sub/a.gltf"}]});
    std::fs::write(dir.path().join("scene.json"), json.to_string()).expect("write");
    let placed =
        tessera_scene::load(&dir.path().join("scene.json")).unwrap_or_else(|e| panic!("{e}"));
    assert!(placed.lights.is_empty());
    assert!(
        placed
            .warnings
            .iter()
            .any(|w| w.contains("tessera_environment") && w.contains("not used")),
        "{:?}",
        placed.warnings
    );

    // A malformed sky is an error naming the scene and the key.
    let bad = document(json!({"scenes": [{"nodes": [0], "extras": {
        "tessera_environment": {"strenght": 1}}}]}));
    let msg = error_of(&[("bad.gltf", bad.to_string().into_bytes())], "bad.gltf");
    assert!(
        msg.contains("scenes[0] extras.tessera_environment") && msg.contains("strenght"),
        "{msg}"
    );
}

/// KHR_materials_volume: σa = −ln(attenuationColor) / attenuationDistance per metre, per
/// scene unit once placed in a scene.json; thickness 0 (a thin wall) absorbs nothing; a black
/// attenuation colour is refused.
#[test]
fn volume_attenuation_becomes_absorption_per_scene_unit() {
    let glass = |volume: Value| {
        json!({"materials": [{"name": "Tinted",
            "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.0},
            "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                           "KHR_materials_volume": volume}}],
            "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_volume"]})
    };
    let absorption = |d: &SceneDesc| match d.materials[0].kind {
        MaterialKind::Dielectric { absorption, .. } => absorption,
        ref k => panic!("expected glass, got {k:?}"),
    };
    let tinted = glass(json!({"thicknessFactor": 0.1, "attenuationDistance": 2.0,
                              "attenuationColor": [0.5, 1.0, 0.25]}));
    let d = load_doc(&document(tinted.clone()));
    let expected = Vec3::new(0.5f32.ln(), 0.0, 0.25f32.ln()) / -2.0;
    assert!(close(absorption(&d), expected), "{}", absorption(&d));
    let thin = glass(json!({"thicknessFactor": 0.0, "attenuationDistance": 2.0,
                            "attenuationColor": [0.5, 0.5, 0.5]}));
    assert_eq!(absorption(&load_doc(&document(thin))), Vec3::ZERO);
    // In a scene.json measured in centimetres: per centimetre.
    let dir = tempfile::tempdir().expect("a temporary folder");
    std::fs::write(dir.path().join("g.gltf"), document(tinted).to_string()).expect("write");
    let json = json!({"units": "cm",
        "camera": {"type": "pinhole", "position": [0, 0, 500], "look_at": [0, 0, 0], "fov_deg": 40},
        "film": {"width": 8, "height": 8}, "materials": {},
        "shapes": [{"type": "gltf", "file": "g.gltf"}]});
    std::fs::write(dir.path().join("scene.json"), json.to_string()).expect("write");
    let placed =
        tessera_scene::load(&dir.path().join("scene.json")).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        close(absorption(&placed), expected * 0.01),
        "{}",
        absorption(&placed)
    );
    let black = glass(json!({"thicknessFactor": 1.0, "attenuationDistance": 1.0,
                             "attenuationColor": [0.0, 0.5, 0.5]}));
    let msg = error_of(
        &[("b.gltf", document(black).to_string().into_bytes())],
        "b.gltf",
    );
    assert!(
        msg.contains("attenuationColor") && msg.contains("(0, 1]"),
        "{msg}"
    );
}

/// A closed tetrahedron (4 vertices, 4 outward faces) beside the open triangle, both with
/// material 0: for thin-walled-by-default transmission.
fn tetrahedron_and_triangle(material: Value) -> Value {
    let mut b = triangle_buffer();
    let offset = b.len();
    for p in [
        [0f32, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ] {
        for c in p {
            b.extend(c.to_le_bytes());
        }
    }
    for i in [0u16, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2] {
        b.extend(i.to_le_bytes());
    }
    let mut doc = document(json!({
        "materials": [material],
        "extensionsUsed": ["KHR_materials_transmission", "KHR_materials_volume",
                           "KHR_materials_diffuse_transmission"]
    }));
    doc["scenes"][0]["nodes"] = json!([0, 1]);
    doc["nodes"] = json!([{"mesh": 0, "name": "Tri"}, {"mesh": 1, "name": "Tet"}]);
    doc["meshes"] = json!([
        {"name": "Triangle", "primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 0}]},
        {"name": "Tetrahedron", "primitives": [{
            "attributes": {"POSITION": 3}, "indices": 4, "material": 0}]}
    ]);
    let accessors = doc["accessors"].as_array_mut().expect("accessors");
    accessors.push(
        json!({"bufferView": 3, "componentType": 5126, "count": 4, "type": "VEC3",
                          "min": [0, 0, 0], "max": [1, 1, 1]}),
    );
    accessors.push(json!({"bufferView": 4, "componentType": 5123, "count": 12, "type": "SCALAR"}));
    let views = doc["bufferViews"].as_array_mut().expect("views");
    views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": 48}));
    views.push(json!({"buffer": 0, "byteOffset": offset + 48, "byteLength": 24}));
    doc["buffers"] = json!([{"byteLength": b.len(), "uri": data_uri(&b)}]);
    doc
}

/// KHR_materials_transmission without a volume is a thin wall: the open triangle keeps it,
/// the closed tetrahedron is rendered solid (and a warning says so); a stated volume of
/// thickness 0 keeps both thin; a partial transmission, diffuse transmission and a tint are
/// read into the BRDF; diffuse transmission through a volume becomes a subsurface medium of
/// the base colour's diffuse reflectance; bad diffuse transmission values are refused.
#[test]
fn transmission_is_thin_walled_or_solid_partial_or_diffuse_as_the_file_says() {
    let glass = |extensions: Value| {
        json!({"name": "Glass",
               "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.8, 0.7, 1.0],
                                        "metallicFactor": 0.0, "roughnessFactor": 0.0},
               "extensions": extensions})
    };
    let kinds = |d: &SceneDesc| -> Vec<MaterialKind> {
        d.meshes
            .iter()
            .map(|m| d.materials[m.material as usize].kind.clone())
            .collect()
    };
    let silent = load_doc(&tetrahedron_and_triangle(glass(
        json!({"KHR_materials_transmission": {"transmissionFactor": 1.0}}),
    )));
    match &kinds(&silent)[..] {
        [
            MaterialKind::Dielectric {
                thin: true, tint, ..
            },
            MaterialKind::Dielectric { thin: false, .. },
        ] => assert!(close(*tint, Vec3::new(0.9, 0.8, 0.7)), "{tint}"),
        k => panic!("expected a thin triangle and a solid tetrahedron, got {k:?}"),
    }
    assert!(
        silent
            .warnings
            .iter()
            .any(|w| w.contains("\"Glass\"") && w.contains("rendered solid")),
        "{:?}",
        silent.warnings
    );
    let stated_thin = load_doc(&tetrahedron_and_triangle(glass(json!({
        "KHR_materials_transmission": {"transmissionFactor": 1.0},
        "KHR_materials_volume": {"thicknessFactor": 0.0}
    }))));
    assert!(
        kinds(&stated_thin)
            .iter()
            .all(|k| matches!(k, MaterialKind::Dielectric { thin: true, .. })),
        "{:?}",
        kinds(&stated_thin)
    );
    assert!(
        !stated_thin
            .warnings
            .iter()
            .any(|w| w.contains("rendered solid")),
        "{:?}",
        stated_thin.warnings
    );

    let partial = load_doc(&document(json!({"materials": [glass(json!({
        "KHR_materials_transmission": {"transmissionFactor": 0.4},
        "KHR_materials_diffuse_transmission": {"diffuseTransmissionFactor": 0.25,
                                               "diffuseTransmissionColorFactor": [1.0, 0.5, 0.0]}
    }))]})));
    match &partial.materials[0].kind {
        MaterialKind::MetallicRoughness { transmission, .. } => {
            assert_eq!(
                (
                    transmission.specular,
                    transmission.diffuse,
                    transmission.thin
                ),
                (0.4, 0.25, true)
            );
            assert!(close(transmission.diffuse_color, Vec3::new(1.0, 0.5, 0.0)));
        }
        k => panic!("expected the glTF BRDF, got {k:?}"),
    }

    let wax = load_doc(&document(json!({"materials": [glass(json!({
        "KHR_materials_diffuse_transmission": {"diffuseTransmissionFactor": 1.0},
        "KHR_materials_volume": {"thicknessFactor": 0.05, "attenuationDistance": 0.01}
    }))]})));
    match wax.materials[0].kind {
        MaterialKind::Subsurface {
            sigma_s_prime,
            sigma_a,
            eta,
            ..
        } => {
            // Its dipole reflects the base colour, diffusing over 1 cm.
            let base = [0.9f64, 0.8, 0.7];
            for c in 0..3 {
                let t = (sigma_s_prime[c] + sigma_a[c]) as f64;
                let rd = tessera_scene::media::total_diffuse_reflectance(
                    sigma_s_prime[c] as f64 / t,
                    eta as f64,
                );
                assert!((rd - base[c]).abs() < 1e-3, "Rd {rd} for {}", base[c]);
                let ld = 1.0 / (3.0 * sigma_a[c] as f64 * t).sqrt();
                assert!((ld - 0.01).abs() < 1e-5, "ℓd {ld}");
            }
        }
        ref k => panic!("expected a subsurface medium, got {k:?}"),
    }
    assert!(
        wax.warnings.iter().any(|w| w.contains("subsurface medium")),
        "{:?}",
        wax.warnings
    );

    let bad = document(json!({"materials": [glass(json!({
        "KHR_materials_diffuse_transmission": {"diffuseTransmissionFactor": 1.5}
    }))]}));
    let msg = error_of(&[("bad.gltf", bad.to_string().into_bytes())], "bad.gltf");
    assert!(
        msg.contains("materials[0] \"Glass\" KHR_materials_diffuse_transmission")
            && msg.contains("expected a factor and colour in [0, 1]"),
        "{msg}"
    );
}

/// Found by the `gltf` fuzz target: a primitive whose POSITION names an accessor the file
/// does not have made the gltf crate's own validation index out of bounds (a panic).
#[test]
fn a_primitive_naming_a_missing_accessor_is_refused() {
    let mut doc = document(json!({}));
    doc["accessors"] = json!([]);
    let msg = error_of(&[("bad.gltf", doc.to_string().into_bytes())], "bad.gltf");
    assert!(
        msg.contains("meshes[0].primitives[0].attributes")
            && msg.contains("accessor")
            && msg.contains("expected an index below 0"),
        "{msg}"
    );
}
