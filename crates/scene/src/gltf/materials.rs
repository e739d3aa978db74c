//! glTF materials as Tessera materials: the metallic-roughness BRDF with KHR_materials_ior
//! and KHR_materials_specular; fully transmissive ones (KHR_materials_transmission) as a
//! dielectric interface, thin-walled without KHR_materials_volume, tinted by the base colour
//! and absorbing inside by the volume's attenuation; partly transmissive ones (and
//! KHR_materials_diffuse_transmission) as the BRDF with transmitting shares; a dense
//! translucent solid (diffuse transmission through a volume) as a subsurface medium; emission from `emissiveFactor` × KHR_materials_emissive_strength × the
//! emissive texture; alphaMode as coverage (MASK cut out at the cutoff, BLEND stochastic).
//! The base colour, metallic-roughness, normal and emissive textures are read (with their
//! samplers and KHR_texture_transform); the occlusion texture never (a rasteriser's stand-in
//! for what we compute).

use std::collections::HashMap;
use std::sync::Arc;

use glam::{Affine2, Vec2, Vec3};

use super::{GltfError, buffers, named};
use crate::desc::{
    Coverage, CoverageMode, EmissionDesc, MaterialDesc, MaterialKind, PbrTextures, PbrTransmission,
    Roughness,
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

/// Diffuse transmission at or above this, through a volume, makes a material translucent.
const TRANSMISSIVE: f32 = 0.5;

/// The materials of a glTF file by index, what each emits, and which are thin-walled only
/// because the file does not say otherwise (transmission without KHR_materials_volume).
pub(super) struct Materials {
    pub(super) materials: Vec<MaterialDesc>,
    pub(super) emission: Vec<Option<EmissionDesc>>,
    pub(super) thin_by_default: Vec<bool>,
}

/// The materials of `doc`.
pub(super) fn read(
    doc: &gltf::Document,
    images: &mut Images,
    warnings: &mut Vec<String>,
) -> Result<Materials, GltfError> {
    let mut out = Materials {
        materials: Vec::new(),
        emission: Vec::new(),
        thin_by_default: Vec::new(),
    };
    for m in doc.materials() {
        let index = m.index().unwrap_or(out.materials.len());
        let at = named("materials", index, m.name());
        let (kind, emits) = material(&m, &at, images, warnings)?;
        out.thin_by_default
            .push(m.volume().is_none() && thin_walled(&kind));
        out.materials.push(MaterialDesc {
            name: m
                .name()
                .map_or_else(|| format!("material {index}"), str::to_string),
            kind,
        });
        out.emission.push(emits);
    }
    Ok(out)
}

/// Whether `kind` transmits specularly through a thin wall.
fn thin_walled(kind: &MaterialKind) -> bool {
    match kind {
        MaterialKind::Dielectric { thin, .. } => *thin,
        MaterialKind::MetallicRoughness { transmission, .. } => {
            transmission.thin && transmission.specular > 0.0
        }
        _ => false,
    }
}

/// `kind` as a solid with an interior instead of a thin wall.
pub(super) fn solid(kind: &MaterialKind) -> MaterialKind {
    let mut kind = kind.clone();
    match &mut kind {
        MaterialKind::Dielectric { thin, .. } => *thin = false,
        MaterialKind::MetallicRoughness { transmission, .. } => transmission.thin = false,
        _ => {}
    }
    kind
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
            transmission: Default::default(),
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

    let transmission = m
        .transmission()
        .map_or(0.0, |t| t.transmission_factor())
        .clamp(0.0, 1.0);
    if m.transmission()
        .is_some_and(|t| t.transmission_texture().is_some())
    {
        warnings.push(format!(
            "{at}: transmissionTexture not read: the factor {transmission} applies everywhere"
        ));
    }
    let diffuse = diffuse_transmission(m, at, warnings)?;
    // KHR_materials_volume with a thickness: a solid object with an interior; without it
    // glTF means a thin wall.
    let volume = m.volume().filter(|v| v.thickness_factor() > 0.0);
    let absorption = match &volume {
        Some(v) => absorption(v, at)?,
        None => Vec3::ZERO,
    };
    // A dense translucent solid (wax, skin, marble): the extension invites a diffusion
    // approximation, which our subsurface material is.
    if let (Some((d, _)), Some(v)) = (diffuse, &volume)
        && d >= TRANSMISSIVE
        && transmission < TRANSMISSIVE
        && metallic < 0.5
    {
        let distance = v.attenuation_distance();
        let mfp = if distance.is_finite() && distance > 0.0 {
            distance
        } else {
            v.thickness_factor()
        };
        let (sigma_s_prime, sigma_a) =
            crate::media::from_diffuse_reflectance(base_color.to_array(), mfp, ior);
        warnings.push(format!(
            "{at}: diffuse transmission {d} through a volume rendered as a subsurface medium \
             (diffusion; Jensen & Buhler 2002's parameters): diffuse reflectance {base_color} \
             (the base colour), diffuse mean free path {mfp} m ({}), σs′ {:?} and σa {:?} per \
             metre",
            if distance.is_finite() {
                "attenuationDistance"
            } else {
                "thicknessFactor, as no attenuationDistance is given"
            },
            sigma_s_prime,
            sigma_a
        ));
        return Ok((
            MaterialKind::Subsurface {
                sigma_s_prime: Vec3::from(sigma_s_prime),
                sigma_a: Vec3::from(sigma_a),
                eta: ior.min(3.0),
                g: 0.0,
            },
            emits,
        ));
    }
    // Clear or tinted glass: the exact (delta, if smooth) interface.
    if transmission >= 1.0 && metallic == 0.0 && diffuse.is_none() && maps.is_empty() {
        return Ok((
            MaterialKind::Dielectric {
                eta: ior,
                roughness: Roughness::ggx(roughness),
                absorption,
                tint: base_color,
                thin: volume.is_none(),
            },
            emits,
        ));
    }
    if absorption.max_element() > 0.0 && transmission > 0.0 {
        warnings.push(format!(
            "{at}: KHR_materials_volume attenuation not applied: the material transmits only \
             in part ({transmission}), or is textured or metallic, so it is rendered as the \
             glTF BRDF with a clear transmitting share"
        ));
    }
    let transmission = PbrTransmission {
        specular: transmission,
        diffuse: diffuse.map_or(0.0, |d| d.0),
        diffuse_color: diffuse.map_or(Vec3::ONE, |d| d.1),
        thin: volume.is_none(),
    };
    Ok((
        MaterialKind::MetallicRoughness {
            base_color,
            metallic,
            roughness,
            ior,
            specular_color,
            specular,
            textures: maps,
            transmission,
        },
        emits,
    ))
}

/// σa of a KHR_materials_volume interior that keeps attenuationColor c after
/// attenuationDistance d (metres): −ln(c) / d per metre; zero without attenuation.
fn absorption(v: &gltf::material::Volume, at: &str) -> Result<Vec3, GltfError> {
    let d = v.attenuation_distance();
    let c = Vec3::from(v.attenuation_color());
    if !(d.is_finite() && d > 0.0 && c.min_element() < 1.0) {
        return Ok(Vec3::ZERO);
    }
    if c.min_element() <= 0.0 {
        return Err(GltfError::new(
            format!("{at} KHR_materials_volume.attenuationColor"),
            format!("expected components in (0, 1], got {c}"),
        ));
    }
    Ok(-c.min(Vec3::ONE).map(f32::ln) / d)
}

/// KHR_materials_diffuse_transmission's factor and colour, if the material has it (the
/// `gltf` crate leaves it unparsed).
fn diffuse_transmission(
    m: &gltf::Material,
    at: &str,
    warnings: &mut Vec<String>,
) -> Result<Option<(f32, Vec3)>, GltfError> {
    let Some(v) = m.extension_value(DIFFUSE_TRANSMISSION) else {
        return Ok(None);
    };
    #[derive(serde::Deserialize)]
    #[serde(rename_all = "camelCase")]
    struct Ext {
        #[serde(default)]
        diffuse_transmission_factor: f32,
        #[serde(default = "white")]
        diffuse_transmission_color_factor: [f32; 3],
        #[serde(default)]
        diffuse_transmission_texture: Option<serde_json::Value>,
        #[serde(default)]
        diffuse_transmission_color_texture: Option<serde_json::Value>,
    }
    fn white() -> [f32; 3] {
        [1.0; 3]
    }
    let here = format!("{at} {DIFFUSE_TRANSMISSION}");
    let e: Ext = serde_json::from_value(v.clone()).map_err(|e| {
        GltfError::new(
            &here,
            format!(
                "expected diffuseTransmissionFactor (a number in [0, 1]) and \
                 diffuseTransmissionColorFactor (three numbers in [0, 1]): {e}"
            ),
        )
    })?;
    let factor = e.diffuse_transmission_factor;
    let color = Vec3::from(e.diffuse_transmission_color_factor);
    if !((0.0..=1.0).contains(&factor) && color.min_element() >= 0.0 && color.max_element() <= 1.0)
    {
        return Err(GltfError::new(
            here,
            format!("expected a factor and colour in [0, 1], got {factor} and {color}"),
        ));
    }
    if e.diffuse_transmission_texture.is_some() || e.diffuse_transmission_color_texture.is_some() {
        warnings.push(format!(
            "{here}: its textures are not read: the factors apply everywhere"
        ));
    }
    Ok((factor > 0.0).then_some((factor, color)))
}

/// The glTF name of the diffuse transmission extension.
pub(super) const DIFFUSE_TRANSMISSION: &str = "KHR_materials_diffuse_transmission";
