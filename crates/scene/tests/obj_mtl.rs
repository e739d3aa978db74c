//! OBJ files with their MTL materials: a mesh shape without `material` takes the OBJ's own,
//! one mesh per `usemtl` group, mapped as Blender's OBJ exporter writes them; what cannot be
//! read is an error naming the file, the material and the statement; what is not modelled is
//! a warning.

use std::path::Path;

use glam::Vec3;
use tessera_scene::{CoverageMode, MaterialKind, SceneDesc, SceneError};

const OBJ: &str = "mtllib lib.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n\
                   f 1/1 2/2 3/3\nusemtl plastic\nf 2/2 4/1 3/3\nusemtl glass\nf 1 3 4\n\
                   usemtl lamp\nf 1 2 4\nusemtl fog\nf 2 3 4\n";

const MTL: &str = "newmtl plastic\nKd 0.8 0.2 0.1\nKs 0.5 0.5 0.5\nNs 250\nNi 1.45\nillum 2\n\
                   map_Ks spec.png\n\
                   newmtl glass\nNi 1.5\nNs 1000\nillum 7\n\
                   newmtl lamp\nKd 0 0 0\nKe 4 3 2\n\
                   newmtl fog\nKd 1 1 1\nd 0.25\nPr 0.3\nPm 1\n";

fn scene_json(shape: &str) -> String {
    format!(
        r#"{{"units": "m",
            "camera": {{"type": "pinhole", "position": [0.5, 0.5, 3], "look_at": [0.5, 0.5, 0], "fov_deg": 40}},
            "film": {{"width": 8, "height": 8}},
            "materials": {{"white": {{"type": "diffuse", "albedo": [0.8, 0.8, 0.8]}}}},
            "shapes": [{shape}]}}"#
    )
}

fn load(
    files: &[(&str, &[u8])],
    shape: &str,
) -> (tempfile::TempDir, Result<SceneDesc, SceneError>) {
    let dir = tempfile::tempdir().expect("a temporary folder");
    for (name, bytes) in files {
        let p = dir.path().join(name);
        std::fs::create_dir_all(p.parent().expect("folder")).expect("mkdir");
        std::fs::write(p, bytes).expect("write");
    }
    std::fs::write(dir.path().join("scene.json"), scene_json(shape)).expect("write");
    let r = tessera_scene::load(&dir.path().join("scene.json"));
    (dir, r)
}

fn material<'a>(d: &'a SceneDesc, name: &str) -> &'a MaterialKind {
    &d.materials
        .iter()
        .find(|m| m.name.ends_with(&format!("/ {name}")))
        .unwrap_or_else(|| panic!("no material {name}"))
        .kind
}

#[test]
fn usemtl_groups_become_meshes_with_the_mtl_materials() {
    let (_dir, r) = load(
        &[("m/a.obj", OBJ.as_bytes()), ("m/lib.mtl", MTL.as_bytes())],
        r#"{"type": "mesh", "file": "m/a.obj"}"#,
    );
    let d = r.unwrap_or_else(|e| panic!("{e}"));
    // Four materials and the default one for the face before any usemtl.
    let origins: Vec<(&str, usize)> = d
        .meshes
        .iter()
        .map(|m| (m.origin.as_str(), m.triangles.len()))
        .collect();
    assert_eq!(d.meshes.len(), 5, "{origins:?}");
    let w = d.warnings.join("\n");
    assert!(w.contains("before any usemtl"), "{w}");
    assert!(w.contains("\"plastic\": map_Ks not applied"), "{w}");
    match material(&d, "plastic") {
        MaterialKind::MetallicRoughness {
            base_color,
            roughness,
            specular,
            ior,
            metallic,
            ..
        } => {
            assert_eq!(*base_color, Vec3::new(0.8, 0.2, 0.1));
            // Blender writes Ns = 1000 (1 − roughness)² and Ks = its specular level.
            assert!((roughness - 0.5).abs() < 1e-6 && *specular == 1.0);
            assert!(*ior == 1.45 && *metallic == 0.0);
        }
        k => panic!("plastic: {k:?}"),
    }
    assert!(matches!(
        material(&d, "glass"),
        MaterialKind::Dielectric { eta, roughness, .. } if *eta == 1.5 && roughness.alpha_u == 0.0
    ));
    let lamp = d
        .meshes
        .iter()
        .find(|m| m.origin.contains("lamp"))
        .expect("the lamp");
    assert_eq!(
        lamp.emission.as_ref().map(|e| e.radiance),
        Some(Vec3::new(4.0, 3.0, 2.0))
    );
    match material(&d, "fog") {
        MaterialKind::MetallicRoughness {
            roughness,
            metallic,
            textures,
            ..
        } => {
            assert!((roughness - 0.3).abs() < 1e-6 && *metallic == 1.0);
            let c = textures.coverage.expect("d < 1 is coverage");
            assert!(c.factor == 0.25 && c.mode == CoverageMode::Blend);
        }
        k => panic!("fog: {k:?}"),
    }
    // OBJ's v grows up the image, ours down it.
    let plastic = d
        .meshes
        .iter()
        .find(|m| m.origin.contains("plastic"))
        .expect("plastic");
    let uvs = plastic.uvs.as_ref().expect("texture coordinates");
    assert!(uvs.contains(&glam::Vec2::new(0.0, 1.0)) && uvs.contains(&glam::Vec2::new(0.0, 0.0)));
}

#[test]
fn a_material_on_the_shape_overrides_the_files_own() {
    let (_dir, r) = load(
        &[("a.obj", OBJ.as_bytes())],
        r#"{"type": "mesh", "file": "a.obj", "material": "white"}"#,
    );
    let d = r.unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(d.meshes.len(), 1);
    assert_eq!(d.materials.len(), 1);
}

#[test]
fn what_cannot_be_read_is_an_error_naming_the_file_material_and_statement() {
    let error = |files: &[(&str, &[u8])]| -> String {
        let (_dir, r) = load(files, r#"{"type": "mesh", "file": "a.obj"}"#);
        match r {
            Ok(_) => panic!("expected an error"),
            Err(e) => e.to_string(),
        }
    };
    let msg = error(&[("a.obj", OBJ.as_bytes())]);
    assert!(msg.contains("a.obj") && msg.contains("lib.mtl"), "{msg}");
    let msg = error(&[("a.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")]);
    assert!(
        msg.contains("shapes[0].material") && msg.contains("names none of its own"),
        "{msg}"
    );
    let mtl = "newmtl plastic\nmap_Kd -s 2 2 1 missing wood.png\n";
    let obj = "mtllib lib.mtl\nusemtl plastic\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n";
    let msg = error(&[("a.obj", obj.as_bytes()), ("lib.mtl", mtl.as_bytes())]);
    assert!(
        msg.contains("\"plastic\" map_Kd") && msg.contains("missing wood.png"),
        "{msg}"
    );
    // Found by the `obj` fuzz target: a colour of two values made tobj panic.
    let mtl = "newmtl plastic\nKd 0.7 0.25\n";
    let msg = error(&[("a.obj", obj.as_bytes()), ("lib.mtl", mtl.as_bytes())]);
    assert!(
        msg.contains("lib.mtl") && msg.contains("line 2") && msg.contains("`Kd r g b`"),
        "{msg}"
    );
}

/// The textured Blender scene through Blender's OBJ exporter (`scripts/blender/diffuse_shot.py
/// --textured --obj`): the same materials as its glTF export.
#[test]
fn blenders_obj_export_reads_as_its_gltf_export() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/gltf/textured-shot");
    let obj = tessera_scene::load(&dir.join("obj.json")).unwrap_or_else(|e| panic!("{e}"));
    let glb = tessera_scene::load(&dir.join("textured-shot.glb")).unwrap_or_else(|e| panic!("{e}"));
    assert!(obj.warnings.is_empty(), "{:?}", obj.warnings);
    for g in &glb.materials {
        let name = g.name.rsplit(" / ").next().expect("a name");
        let o = material(&obj, name);
        match (o, &g.kind) {
            (
                MaterialKind::MetallicRoughness {
                    base_color: a,
                    roughness: ra,
                    specular: sa,
                    textures: ta,
                    ..
                },
                MaterialKind::MetallicRoughness {
                    base_color: b,
                    roughness: rb,
                    specular: sb,
                    textures: tb,
                    ..
                },
            ) => {
                assert!((*a - *b).abs().max_element() < 1e-6, "{name}: {a} vs {b}");
                assert!(ra == rb && sa == sb, "{name}");
                assert_eq!(ta.base_color.is_some(), tb.base_color.is_some(), "{name}");
                assert_eq!(ta.normal.is_some(), tb.normal.is_some(), "{name}");
                if let (Some(x), Some(y)) = (&ta.base_color, &tb.base_color) {
                    assert_eq!(x.image.hash, y.image.hash, "{name}: the same texels");
                }
            }
            (a, b) => panic!("{name}: {a:?} vs {b:?}"),
        }
    }
}
