//! glTF materials as Tessera materials: the metallic-roughness BRDF with KHR_materials_ior
//! and KHR_materials_specular; transmissive ones (KHR_materials_transmission) as a dielectric
//! interface; emission from `emissiveFactor` × KHR_materials_emissive_strength. Textures are
//! not read yet: each one present is named in a warning, and its factor alone is used.

use glam::Vec3;

use super::named;
use crate::desc::{EmissionDesc, MaterialDesc, MaterialKind, Roughness};
use crate::file::Distribution;

/// Transmission at or above this makes a material a dielectric interface.
const TRANSMISSIVE: f32 = 0.5;

/// The materials of `doc` by index, and what each emits.
pub(super) fn read(
    doc: &gltf::Document,
    warnings: &mut Vec<String>,
) -> (Vec<MaterialDesc>, Vec<Option<EmissionDesc>>) {
    let mut materials = Vec::new();
    let mut emission = Vec::new();
    for m in doc.materials() {
        let index = m.index().unwrap_or(materials.len());
        let at = named("materials", index, m.name());
        let (kind, emits) = material(&m, &at, warnings);
        materials.push(MaterialDesc {
            name: m
                .name()
                .map_or_else(|| format!("material {index}"), str::to_string),
            kind,
        });
        emission.push(emits);
    }
    (materials, emission)
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
        },
    }
}

fn material(
    m: &gltf::Material,
    at: &str,
    warnings: &mut Vec<String>,
) -> (MaterialKind, Option<EmissionDesc>) {
    let pbr = m.pbr_metallic_roughness();
    let mut textures = Vec::new();
    if pbr.base_color_texture().is_some() {
        textures.push("baseColorTexture");
    }
    if pbr.metallic_roughness_texture().is_some() {
        textures.push("metallicRoughnessTexture");
    }
    if m.normal_texture().is_some() {
        textures.push("normalTexture");
    }
    if m.emissive_texture().is_some() {
        textures.push("emissiveTexture");
    }
    if !textures.is_empty() {
        warnings.push(format!(
            "{at}: {} not applied (image textures are not supported yet): its factors alone are used",
            textures.join(", ")
        ));
    }
    let alpha = m.alpha_mode();
    if alpha != gltf::material::AlphaMode::Opaque {
        warnings.push(format!("{at}: alphaMode {alpha:?} rendered as opaque"));
    }
    let [r, g, b, _] = pbr.base_color_factor();
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
    let emits = (e.max_element() > 0.0 && e.is_finite()).then_some(EmissionDesc {
        radiance: e,
        two_sided: m.double_sided(),
    });

    let transmission = m.transmission().map_or(0.0, |t| t.transmission_factor());
    if transmission > 0.0 {
        if transmission >= TRANSMISSIVE && metallic < 0.5 {
            if transmission < 1.0 {
                warnings.push(format!(
                    "{at}: transmission {transmission} rendered as fully transmissive glass"
                ));
            }
            if let Some(v) = m.volume()
                && v.attenuation_distance().is_finite()
            {
                warnings.push(format!(
                    "{at}: KHR_materials_volume attenuation not modelled yet (clear glass)"
                ));
            }
            // Below GGX α 1e-3 the interface is a mirror in every respect but its float range.
            let alpha = roughness * roughness;
            let alpha = if alpha < 1e-3 { 0.0 } else { alpha };
            let roughness = Roughness {
                distribution: Distribution::Ggx,
                alpha_u: alpha,
                alpha_v: alpha,
            };
            return (
                MaterialKind::Dielectric {
                    eta: ior,
                    roughness,
                },
                emits,
            );
        }
        warnings.push(format!(
            "{at}: transmission {transmission} below {TRANSMISSIVE} (or on a metal) ignored: opaque"
        ));
    }
    (
        MaterialKind::MetallicRoughness {
            base_color,
            metallic,
            roughness,
            ior,
            specular_color,
            specular,
        },
        emits,
    )
}
