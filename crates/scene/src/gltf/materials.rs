//! glTF materials as Tessera materials: the metallic-roughness BRDF with KHR_materials_ior
//! and KHR_materials_specular; transmissive ones (KHR_materials_transmission) as a dielectric
//! interface; emission from `emissiveFactor` × KHR_materials_emissive_strength × the
//! emissive texture; alphaMode as coverage (MASK cut out at the cutoff, BLEND stochastic).
//! The base colour, metallic-roughness, normal and emissive textures are read (with their
//! samplers and KHR_texture_transform); the occlusion texture never (a rasteriser's stand-in
//! for what we compute).

use std::collections::HashMap;
use std::sync::Arc;

use glam::{Affine2, Vec2, Vec3};

use super::{GltfError, buffers, named};
use crate::desc::{
    Coverage, CoverageMode, EmissionDesc, MaterialDesc, MaterialKind, PbrTextures, Roughness,
};
use crate::source::SceneSource;
use crate::texture::{self, TextureDesc, TextureImage, TextureRole, Wrap};

/// Where images come from, and those decoded so far (each image once per role).
pub(super) struct Images<'a> {
    pub(super) data: &'a [Vec<u8>],
    pub(super) source: &'a dyn SceneSource,
    pub(super) dir: &'a std::path::Path,
    decoded: HashMap<(usize, TextureRole), Arc<TextureImage>>,
}

impl<'a> Images<'a> {
    pub(super) fn new(
        data: &'a [Vec<u8>],
        source: &'a dyn SceneSource,
        dir: &'a std::path::Path,
    ) -> Self {
        Images {
            data,
            source,
            dir,
            decoded: HashMap::new(),
        }
    }

    /// The texture `info` names, decoded for `role`, with its sampler and transform.
    fn texture(
        &mut self,
        texture: gltf::Texture,
        tex_coord: u32,
        transform: Option<Transform>,
        role: TextureRole,
        at: &str,
    ) -> Result<TextureDesc, GltfError> {
        let img = texture.source();
        let key = (img.index(), role);
        let image = match self.decoded.get(&key) {
            Some(i) => i.clone(),
            None => {
                let here = format!(
                    "{} ({} of {at})",
                    named("images", img.index(), img.name()),
                    named("textures", texture.index(), texture.name())
                );
                let bytes = buffers::image_bytes(&img, self.data, self.source, self.dir, &here)?;
                let name = img.name().map_or_else(|| here.clone(), str::to_string);
                let decoded =
                    texture::decode(&bytes, &name, role).map_err(|m| GltfError::new(&here, m))?;
                let decoded = Arc::new(decoded);
                self.decoded.insert(key, decoded.clone());
                decoded
            }
        };
        let sampler = texture.sampler();
        let wrap = |w: gltf::texture::WrappingMode| match w {
            gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
            gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
            gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        };
        let mut desc = TextureDesc::new(image);
        desc.wrap = [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())];
        desc.texcoord = tex_coord;
        if let Some(t) = transform {
            // KHR_texture_transform: T · R · S, R = [[cos, sin], [−sin, cos]] (row-major).
            let (s, c) = t.rotation.sin_cos();
            let rs = Affine2::from_cols(
                Vec2::new(c, -s) * t.scale[0],
                Vec2::new(s, c) * t.scale[1],
                Vec2::from(t.offset),
            );
            if !rs.is_finite() || rs.matrix2.determinant() == 0.0 {
                return Err(GltfError::new(
                    format!("{at} KHR_texture_transform"),
                    "expected a finite, invertible transform (non-zero scale)",
                ));
            }
            desc.transform = rs;
            if let Some(tc) = t.tex_coord {
                desc.texcoord = tc;
            }
        }
        Ok(desc)
    }
}

/// KHR_texture_transform's content: uv' = T(offset) · R(rotation) · S(scale) · uv.
#[derive(serde::Deserialize)]
#[serde(rename_all = "camelCase")]
pub(super) struct Transform {
    #[serde(default)]
    offset: [f32; 2],
    #[serde(default)]
    rotation: f32,
    #[serde(default = "unit_scale")]
    scale: [f32; 2],
    #[serde(default)]
    tex_coord: Option<u32>,
}

fn unit_scale() -> [f32; 2] {
    [1.0, 1.0]
}

impl Transform {
    fn of(t: gltf::texture::TextureTransform) -> Transform {
        Transform {
            offset: t.offset(),
            rotation: t.rotation(),
            scale: t.scale(),
            tex_coord: t.tex_coord(),
        }
    }
}

/// Transmission at or above this makes a material a dielectric interface.
const TRANSMISSIVE: f32 = 0.5;

/// The materials of `doc` by index, and what each emits.
pub(super) fn read(
    doc: &gltf::Document,
    images: &mut Images,
    warnings: &mut Vec<String>,
) -> Result<(Vec<MaterialDesc>, Vec<Option<EmissionDesc>>), GltfError> {
    let mut materials = Vec::new();
    let mut emission = Vec::new();
    for m in doc.materials() {
        let index = m.index().unwrap_or(materials.len());
        let at = named("materials", index, m.name());
        let (kind, emits) = material(&m, &at, images, warnings)?;
        materials.push(MaterialDesc {
            name: m
                .name()
                .map_or_else(|| format!("material {index}"), str::to_string),
            kind,
        });
        emission.push(emits);
    }
    Ok((materials, emission))
}

/// glTF's default material: white, fully metallic, fully rough (the specification's defaults).
pub(super) fn default_material() -> MaterialDesc {
    MaterialDesc {
        name: "glTF default material".into(),
        kind: MaterialKind::MetallicRoughness {
            base_color: Vec3::ONE,
            metallic: 1.0,
            roughness: 1.0,
            ior: 1.5,
            specular_color: Vec3::ONE,
            specular: 1.0,
            textures: Default::default(),
        },
    }
}

fn material(
    m: &gltf::Material,
    at: &str,
    images: &mut Images,
    warnings: &mut Vec<String>,
) -> Result<(MaterialKind, Option<EmissionDesc>), GltfError> {
    let pbr = m.pbr_metallic_roughness();
    let mut maps = PbrTextures::default();
    if let Some(info) = pbr.base_color_texture() {
        let at = format!("{at} baseColorTexture");
        maps.base_color = Some(images.texture(
            info.texture(),
            info.tex_coord(),
            info.texture_transform().map(Transform::of),
            TextureRole::Color,
            &at,
        )?);
    }
    if let Some(info) = pbr.metallic_roughness_texture() {
        let at = format!("{at} metallicRoughnessTexture");
        maps.metallic_roughness = Some(images.texture(
            info.texture(),
            info.tex_coord(),
            info.texture_transform().map(Transform::of),
            TextureRole::Data,
            &at,
        )?);
    }
    if let Some(n) = m.normal_texture() {
        let at = format!("{at} normalTexture");
        // The crate leaves a normal texture's KHR_texture_transform unparsed.
        let transform = match n.extension_value("KHR_texture_transform") {
            None => None,
            Some(v) => Some(serde_json::from_value::<Transform>(v.clone()).map_err(|e| {
                GltfError::new(
                    format!("{at} KHR_texture_transform"),
                    format!("expected offset, rotation, scale and texCoord: {e}"),
                )
            })?),
        };
        let tex = images.texture(
            n.texture(),
            n.tex_coord(),
            transform,
            TextureRole::Data,
            &at,
        )?;
        maps.normal = Some((tex, n.scale()));
    }
    let normal = maps.normal.as_ref().map(|n| &n.0);
    for t in [
        maps.base_color.as_ref(),
        maps.metallic_roughness.as_ref(),
        normal,
    ]
    .into_iter()
    .flatten()
    {
        if t.texcoord > 1 {
            warnings.push(format!(
                "{at}: a texture reads TEXCOORD_{}; only TEXCOORD_0 and 1 are read, so 0 is used",
                t.texcoord
            ));
        }
    }
    let [r, g, b, a] = pbr.base_color_factor();
    let factor = a.clamp(0.0, 1.0);
    maps.coverage = match m.alpha_mode() {
        gltf::material::AlphaMode::Opaque => None,
        gltf::material::AlphaMode::Mask => {
            let cutoff = m.alpha_cutoff().unwrap_or(0.5);
            if !(cutoff.is_finite() && cutoff >= 0.0) {
                return Err(GltfError::new(
                    format!("{at} alphaCutoff"),
                    format!("expected a non-negative number, got {cutoff}"),
                ));
            }
            Some(Coverage {
                factor,
                mode: CoverageMode::Mask { cutoff },
            })
        }
        // Fully covered everywhere is opaque; say nothing more.
        gltf::material::AlphaMode::Blend if factor >= 1.0 && maps.base_color.is_none() => None,
        gltf::material::AlphaMode::Blend => Some(Coverage {
            factor,
            mode: CoverageMode::Blend,
        }),
    };
    let base_color = Vec3::new(r, g, b).clamp(Vec3::ZERO, Vec3::ONE);
    let metallic = pbr.metallic_factor().clamp(0.0, 1.0);
    let roughness = pbr.roughness_factor().clamp(0.0, 1.0);
    let ior = m.ior().unwrap_or(1.5);
    let ior = if ior.is_finite() && ior >= 1.0 {
        ior
    } else {
        warnings.push(format!("{at}: ior {ior} outside [1, ∞): 1.5 used"));
        1.5
    };
    let (specular_color, specular) = m.specular().map_or((Vec3::ONE, 1.0), |s| {
        (
            Vec3::from(s.specular_color_factor()).max(Vec3::ZERO),
            s.specular_factor().clamp(0.0, 1.0),
        )
    });
    let strength = m.emissive_strength().unwrap_or(1.0).max(0.0);
    let e = Vec3::from(m.emissive_factor()).max(Vec3::ZERO) * strength;
    // A double-sided material emits from both faces, as Blender's and Cycles' emitters do.
    let texture = match m.emissive_texture() {
        Some(info) if e.max_element() > 0.0 => Some(images.texture(
            info.texture(),
            info.tex_coord(),
            info.texture_transform().map(Transform::of),
            TextureRole::Color,
            &format!("{at} emissiveTexture"),
        )?),
        _ => None,
    };
    if let Some(t) = &texture
        && t.texcoord > 1
    {
        warnings.push(format!(
            "{at}: emissiveTexture reads TEXCOORD_{}; only TEXCOORD_0 and 1 are read, so 0 is \
             used",
            t.texcoord
        ));
    }
    let emits = (e.max_element() > 0.0 && e.is_finite()).then_some(EmissionDesc {
        radiance: e,
        two_sided: m.double_sided(),
        texture,
    });

    let transmission = m.transmission().map_or(0.0, |t| t.transmission_factor());
    if transmission > 0.0 {
        if transmission >= TRANSMISSIVE && metallic < 0.5 {
            if transmission < 1.0 {
                warnings.push(format!(
                    "{at}: transmission {transmission} rendered as fully transmissive glass"
                ));
            }
            // KHR_materials_volume: a solid object (thickness > 0) whose interior keeps
            // attenuationColor after attenuationDistance (metres): σa = −ln(c) / d per metre.
            // Without the extension, or with thickness 0, glTF means a thin wall; we render
            // the closed meshes exporters write as solid glass either way, clear.
            let absorption = match m.volume() {
                Some(v) if v.thickness_factor() > 0.0 => {
                    let d = v.attenuation_distance();
                    let c = Vec3::from(v.attenuation_color());
                    if d.is_finite() && d > 0.0 && c.min_element() < 1.0 {
                        if c.min_element() <= 0.0 {
                            return Err(GltfError::new(
                                format!("{at} KHR_materials_volume.attenuationColor"),
                                format!("expected components in (0, 1], got {c}"),
                            ));
                        }
                        -c.min(Vec3::ONE).map(f32::ln) / d
                    } else {
                        Vec3::ZERO
                    }
                }
                _ => Vec3::ZERO,
            };
            let roughness = Roughness::ggx(roughness);
            if !maps.is_empty() {
                warnings.push(format!(
                    "{at}: textures of a transmissive material not applied"
                ));
            }
            return Ok((
                MaterialKind::Dielectric {
                    eta: ior,
                    roughness,
                    absorption,
                },
                emits,
            ));
        }
        warnings.push(format!(
            "{at}: transmission {transmission} below {TRANSMISSIVE} (or on a metal) ignored: opaque"
        ));
    }
    Ok((
        MaterialKind::MetallicRoughness {
            base_color,
            metallic,
            roughness,
            ior,
            specular_color,
            specular,
            textures: maps,
        },
        emits,
    ))
}
