//! A mesh shape without a `material`: the OBJ's own materials (its MTL library), one mesh per
//! `usemtl` group, as the glTF metallic-roughness BRDF.
//!
//! The mapping follows Blender's OBJ exporter (the inverse of what it writes for a
//! Principled BSDF): base colour `Kd` (× `map_Kd`, sRGB), roughness 1 − √(`Ns`/1000) (or
//! `Pr`), metalness `Pm` (else 0), the specular layer's strength 2 · max(`Ks`) (Blender's
//! "Specular IOR level" 0.5 is glTF's specular 1, F0 = 0.04 at `Ni` 1.5) tinted by `Ks`,
//! `Ni` as the IOR, emission `Ke` as radiance (W·sr⁻¹·m⁻², from both faces), `map_Ke` multiplying it, `d` < 1 as
//! blended coverage, `Kd` absent as 1 under a `map_Kd` (Blender omits it) and 0.8 otherwise,
//! `map_Bump`/`bump`/`norm` as a tangent-space normal map (Blender writes its normal maps
//! there; `-bm` is its scale), and `illum` 4, 6, 7 or 9 (refraction) as a dielectric of index
//! `Ni`. Texture options `-s`/`-o` (scale and offset of the coordinates) and `-clamp on` are
//! read; what is not (`map_Ks`, `map_Ns`, `map_d`, `Tf`, other options) is named in
//! a warning.

use super::*;
use crate::desc::{Coverage, CoverageMode, PbrTextures, Roughness};
use crate::mesh::MtlMaterial;
use crate::texture::{TextureDesc, TextureRole, Wrap};
use glam::{Affine2, Vec2};

/// A texture statement split into its file and the options read.
struct TextureStatement {
    file: String,
    scale: Vec2,
    offset: Vec2,
    clamp: bool,
    bump: f32,
    ignored: Vec<String>,
}

/// `-s 2 2 1 -bm 0.5 wood grain.png` → the options and the file (which may hold spaces).
fn statement(text: &str) -> TextureStatement {
    let mut t = TextureStatement {
        file: String::new(),
        scale: Vec2::ONE,
        offset: Vec2::ZERO,
        clamp: false,
        bump: 1.0,
        ignored: Vec::new(),
    };
    let tokens: Vec<&str> = text.split_whitespace().collect();
    let mut i = 0;
    while i < tokens.len() && tokens[i].starts_with('-') && tokens[i].len() > 1 {
        let option = tokens[i];
        i += 1;
        // Up to three numbers (-s, -o, -t), or one argument.
        let numbers: Vec<f32> = tokens[i..]
            .iter()
            .take(3)
            .map_while(|s| s.parse::<f32>().ok())
            .collect();
        match option {
            "-s" | "-o" | "-t" => {
                i += numbers.len().max(1);
                let v = Vec2::new(
                    numbers.first().copied().unwrap_or(0.0),
                    numbers.get(1).copied().unwrap_or(0.0),
                );
                match option {
                    "-s" => {
                        t.scale = Vec2::new(
                            numbers.first().copied().unwrap_or(1.0),
                            numbers.get(1).copied().unwrap_or(1.0),
                        )
                    }
                    "-o" => t.offset = v,
                    _ => t.ignored.push(option.into()),
                }
            }
            "-mm" => {
                i += 2;
                t.ignored.push(option.into());
            }
            "-bm" => {
                t.bump = numbers.first().copied().unwrap_or(1.0);
                i += 1;
            }
            "-clamp" => {
                t.clamp = tokens.get(i) == Some(&"on");
                i += 1;
            }
            _ => {
                i += 1;
                t.ignored.push(option.into());
            }
        }
    }
    t.file = tokens[i.min(tokens.len())..].join(" ");
    t
}

impl Ctx<'_> {
    /// The shape's OBJ with the materials of its MTL library.
    pub(super) fn mtl_mesh(
        &mut self,
        path: &str,
        parent: Affine3A,
        s: &MeshShape,
        out: &mut Shapes,
    ) {
        let Some(raw) = self.mesh_file(&format!("{path}.file"), &s.file) else {
            return;
        };
        if let Some(e) = &raw.library_error {
            self.problem(format!("{path}.file"), format!("{}: {e}", s.file));
            return;
        }
        let Some(faces) = &raw.face_materials else {
            self.problem(
                format!("{path}.material"),
                format!(
                    "expected a material: {} names none of its own (no mtllib and usemtl)",
                    s.file
                ),
            );
            return;
        };
        let dir = Path::new(&s.file)
            .parent()
            .unwrap_or(Path::new(""))
            .to_path_buf();
        let to_world = parent * self.transform(path, &s.transform);
        // Our materials' first index among the shapes' (`local`) and the scene's (`base`).
        let local = out.materials.len();
        let base = out.first_material + local as u32;
        let mut emission = Vec::new();
        for m in &raw.materials {
            let (kind, emits) = self.mtl_material(path, &s.file, &dir, m);
            out.materials.push(MaterialDesc {
                name: format!("{} / {}", s.file, m.name),
                kind,
            });
            emission.push(emits);
        }
        if faces.contains(&u32::MAX) {
            self.warnings.push(format!(
                "{path}: faces of {} before any usemtl have the OBJ default material (grey, \
                 diffuse)",
                s.file
            ));
            out.materials.push(MaterialDesc {
                name: format!("{} / OBJ default", s.file),
                kind: MaterialKind::Diffuse {
                    albedo: Vec3::splat(0.8),
                },
            });
            emission.push(None);
        }
        let default = (out.materials.len() - 1 - local) as u32;
        let groups = raw.materials.len() + usize::from(faces.contains(&u32::MAX));
        for g in 0..groups as u32 {
            let id = |f: u32| if f == u32::MAX { default } else { f };
            let picked: Vec<usize> = (0..faces.len()).filter(|&t| id(faces[t]) == g).collect();
            if picked.is_empty() {
                continue;
            }
            // The group's own vertices, numbered afresh.
            let mut new_index = vec![u32::MAX; raw.positions.len()];
            let mut used = Vec::new();
            let triangles: Vec<[u32; 3]> = picked
                .iter()
                .map(|&t| {
                    raw.triangles[t].map(|v| {
                        if new_index[v as usize] == u32::MAX {
                            new_index[v as usize] = used.len() as u32;
                            used.push(v as usize);
                        }
                        new_index[v as usize]
                    })
                })
                .collect();
            let positions: Vec<Vec3> = used.iter().map(|&v| raw.positions[v]).collect();
            let normals: Option<Vec<Vec3>> = raw
                .normals
                .as_ref()
                .filter(|_| s.smooth_normals)
                .map(|n| used.iter().map(|&v| n[v]).collect());
            let uvs: Option<Vec<glam::Vec2>> = raw
                .uvs
                .as_ref()
                .map(|u| used.iter().map(|&v| u[v]).collect());
            let normal_mapped = matches!(
                out.materials.get(local + g as usize).map(|m| &m.kind),
                Some(MaterialKind::MetallicRoughness { textures, .. }) if textures.normal.is_some()
            );
            let tangents = match (&uvs, normal_mapped) {
                (Some(uv), true) => {
                    let t = crate::gltf::mikktspace(&positions, normals.as_deref(), uv, &triangles);
                    if t.is_none() {
                        self.warnings.push(format!(
                            "{path}: no tangent frames could be made for {}'s material {}: its \
                             normal map is not applied",
                            s.file,
                            out.materials[local + g as usize].name
                        ));
                    }
                    t
                }
                _ => None,
            };
            let geometry = Geometry {
                positions: &positions,
                normals: normals.as_deref(),
                uvs: uvs.as_deref(),
                uvs1: None,
                tangents: tangents.as_deref(),
                triangles: &triangles,
            };
            let surface = Surface {
                to_world,
                material: base + g,
                emission: s.emission.as_ref(),
            };
            let name = out.materials[local + g as usize].name.clone();
            self.push_mesh(path, format!("{path} ({name})"), geometry, surface, out);
            if s.emission.is_none()
                && let Some(e) = &emission[g as usize]
                && let Some(last) = out.meshes.last_mut()
            {
                last.emission = Some(e.clone());
            }
        }
    }

    /// One MTL material as ours, and what it emits.
    fn mtl_material(
        &mut self,
        path: &str,
        file: &str,
        dir: &Path,
        m: &MtlMaterial,
    ) -> (MaterialKind, Option<EmissionDesc>) {
        let at = format!("{path}: {file}'s material \"{}\"", m.name);
        let number = |key: &str| m.get(key).and_then(|v| v.trim().parse::<f32>().ok());
        // Without Kd: white under a map_Kd (Blender writes none there), else the MTL
        // specification's 0.8.
        let default_kd = if m.map_kd.is_some() { 1.0 } else { 0.8 };
        let base_color = m.kd.unwrap_or(Vec3::splat(default_kd));
        let base_color = base_color.clamp(Vec3::ZERO, Vec3::ONE);
        let roughness = number("Pr")
            .unwrap_or_else(|| 1.0 - (m.ns.unwrap_or(0.0).max(0.0) / 1000.0).sqrt())
            .clamp(0.0, 1.0);
        let metallic = number("Pm").unwrap_or(0.0).clamp(0.0, 1.0);
        let ks = m.ks.unwrap_or(Vec3::ZERO).max(Vec3::ZERO);
        let (specular, specular_color) = if ks.max_element() > 0.0 {
            ((2.0 * ks.max_element()).min(1.0), ks / ks.max_element())
        } else {
            (0.0, Vec3::ONE)
        };
        let ior = m.ni.filter(|n| n.is_finite() && *n >= 1.0).unwrap_or(1.5);
        // Ke (1 under a map_Ke without it) times map_Ke; from both faces, as Blender's and
        // Cycles' emitters (an OBJ face has no back).
        let map_ke = m.get("map_Ke").map(str::to_string);
        let default_ke = if map_ke.is_some() {
            Vec3::ONE
        } else {
            Vec3::ZERO
        };
        let ke = m.ke.unwrap_or(default_ke);
        let emits = if ke.is_finite() && ke.max_element() > 0.0 {
            let texture = map_ke
                .and_then(|text| self.mtl_texture(&at, "map_Ke", dir, &text, TextureRole::Color));
            Some(EmissionDesc {
                radiance: ke.max(Vec3::ZERO),
                two_sided: true,
                texture,
            })
        } else {
            None
        };
        let mut unread: Vec<&str> = Vec::new();
        for (key, present) in [
            ("map_Ks", m.map_ks.is_some()),
            ("map_Ns", m.map_ns.is_some()),
            ("map_d", m.map_d.is_some()),
            (
                "Tf",
                m.get("Tf")
                    .is_some_and(|t| t.trim() != "1 1 1" && t.trim() != "1.0 1.0 1.0"),
            ),
        ] {
            if present {
                unread.push(key);
            }
        }
        if !unread.is_empty() {
            self.warnings
                .push(format!("{at}: {} not applied yet", unread.join(", ")));
        }

        if matches!(m.illum, Some(4 | 6 | 7 | 9)) {
            return (
                MaterialKind::Dielectric {
                    eta: ior,
                    roughness: Roughness::ggx(roughness),
                    absorption: Vec3::ZERO,
                    tint: Vec3::ONE,
                    thin: false,
                },
                emits,
            );
        }
        let mut textures = PbrTextures::default();
        if let Some(text) = &m.map_kd {
            textures.base_color = self.mtl_texture(&at, "map_Kd", dir, text, TextureRole::Color);
        }
        if let Some(text) = &m.map_bump {
            let scale = statement(text).bump;
            textures.normal = self
                .mtl_texture(&at, "map_Bump", dir, text, TextureRole::Data)
                .map(|t| (t, scale));
        }
        if let Some(d) = m.d.filter(|d| *d < 1.0) {
            textures.coverage = Some(Coverage {
                factor: d.max(0.0),
                mode: CoverageMode::Blend,
            });
        }
        (
            MaterialKind::MetallicRoughness {
                base_color,
                metallic,
                roughness,
                ior,
                specular_color,
                specular,
                textures,
                transmission: Default::default(),
            },
            emits,
        )
    }

    /// The texture a statement names, beside the OBJ.
    fn mtl_texture(
        &mut self,
        at: &str,
        key: &str,
        dir: &Path,
        text: &str,
        role: TextureRole,
    ) -> Option<TextureDesc> {
        let t = statement(text);
        if !t.ignored.is_empty() {
            self.warnings.push(format!(
                "{at} {key}: options {} not applied",
                t.ignored.join(", ")
            ));
        }
        let joined = dir.join(&t.file);
        let rel = match confine(&joined.to_string_lossy()) {
            Ok(r) => r,
            Err(msg) => {
                self.problem("", format!("{at} {key}: {msg}"));
                return None;
            }
        };
        // Each file is read and decoded once per role, however many materials name it.
        let image = match self.images.get(&(rel.clone(), role)) {
            Some(i) => i.clone(),
            None => {
                let shown = self.source.display_path(&rel);
                let bytes = match self.source.read(&rel) {
                    Ok(b) => b,
                    Err(e) => {
                        self.problem(
                            "",
                            format!("{at} {key}: cannot read {}: {e}", shown.display()),
                        );
                        return None;
                    }
                };
                let image = match crate::texture::decode(&bytes, &t.file, role) {
                    Ok(i) => Arc::new(i),
                    Err(msg) => {
                        self.problem("", format!("{at} {key} {}: {msg}", shown.display()));
                        return None;
                    }
                };
                self.images.insert((rel, role), image.clone());
                image
            }
        };
        let mut desc = TextureDesc::new(image);
        if t.clamp {
            desc.wrap = [Wrap::ClampToEdge; 2];
        }
        // The options act in the OBJ's coordinates (v up); ours are v' = 1 − v, so
        // t' = 1 − ((1 − t)·sv + ov) = t·sv + 1 − sv − ov.
        desc.transform = Affine2::from_cols(
            Vec2::new(t.scale.x, 0.0),
            Vec2::new(0.0, t.scale.y),
            Vec2::new(t.offset.x, 1.0 - t.scale.y - t.offset.y),
        );
        Some(desc)
    }
}

#[cfg(test)]
mod tests {
    use super::statement;

    #[test]
    fn texture_statements_split_options_from_a_file_with_spaces() {
        let t = statement("-s 2 3 1 -bm 0.5 -clamp on wood grain.png");
        assert_eq!(t.file, "wood grain.png");
        assert_eq!(
            (t.scale.x, t.scale.y, t.bump, t.clamp),
            (2.0, 3.0, 0.5, true)
        );
        let t = statement("-o 0.5 -imfchan r bump.png");
        assert_eq!((t.file.as_str(), t.offset.x), ("bump.png", 0.5));
        assert_eq!(t.ignored, vec!["-imfchan".to_string()]);
        assert_eq!(statement("plain.png").file, "plain.png");
    }
}
