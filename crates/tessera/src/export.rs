//! `tessera export`: a scene as another renderer reads it, for references made by someone
//! else's code (scripts/references/). The scene is exported as Tessera resolved it — boxes,
//! quads and OBJ files as triangles in world space, photometric emitters as radiance with the
//! camera's exposure folded in — so the other renderer sees the same numbers, not a second
//! reading of the scene file.
//!
//! Mitsuba 3: an XML scene (format version 3.0.0) beside binary PLY meshes. A pixel is the
//! box-filtered integral of radiance (the tests render Tessera with the same filter), and
//! `max_depth` counts segments as Mitsuba does (Tessera's bounces + 1). What Mitsuba 3 has no
//! plugin for (Oren–Nayar, Phong, Ward, the glTF BRDF, layered materials, textures, spot
//! lights, two-sided emitters, environment images) is an error naming the material or light,
//! never an approximation.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use clap::Args;
use glam::Vec3;
use tessera_scene::{EmissionDesc, LightDesc, MaterialKind, Roughness, SceneDesc};

use crate::render::Size;

#[derive(Args)]
pub struct ExportArgs {
    /// The scene file (scene.json, .glb or .gltf).
    pub scene: PathBuf,
    /// Output directory (scene.xml and meshes/).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Film size WxH (overrides the scene's film).
    #[arg(long)]
    pub size: Option<Size>,
}

pub fn run(args: ExportArgs) -> anyhow::Result<()> {
    let mut desc = tessera_scene::load(&args.scene)?;
    if let Some(Size([w, h])) = args.size {
        desc.film.width = w;
        desc.film.height = h;
    }
    std::fs::create_dir_all(args.output.join("meshes"))
        .with_context(|| format!("creating {}", args.output.display()))?;
    let xml = mitsuba_xml(&desc, &args.output)
        .with_context(|| format!("exporting {} to Mitsuba 3", args.scene.display()))?;
    let path = args.output.join("scene.xml");
    std::fs::write(&path, xml).with_context(|| format!("writing {}", path.display()))?;
    crate::print(&format!("wrote {}\n", path.display()))
}

fn rgb(v: Vec3) -> String {
    format!("{}, {}, {}", v.x, v.y, v.z)
}

/// The Mitsuba 3 scene of `desc`, its meshes written under `dir/meshes/`.
pub fn mitsuba_xml(desc: &SceneDesc, dir: &Path) -> anyhow::Result<String> {
    let mut x = String::new();
    let exposure = desc.camera.exposure_scale;
    writeln!(x, "<scene version=\"3.0.0\">")?;
    writeln!(
        x,
        "  <!-- {} (exported by tessera export) -->",
        desc.name.replace("--", "-")
    )?;
    writeln!(
        x,
        "  <default name=\"max_depth\" value=\"{}\"/>\n  <integrator type=\"path\">\n    \
         <integer name=\"max_depth\" value=\"$max_depth\"/>\n  </integrator>",
        desc.integrator.max_depth + 1
    )?;
    x.push_str(&sensor(desc));
    let mut media = Vec::new();
    for (i, m) in desc.materials.iter().enumerate() {
        let b = bsdf(&m.kind).with_context(|| format!("material \"{}\"", m.name))?;
        let element =
            |id: &str| format!("<bsdf type=\"{}\"{id}>\n{}    </bsdf>", b.plugin, b.params);
        let own_id = format!(" id=\"m{i}\"");
        media.push(b.medium.is_some());
        match &b.medium {
            Some(medium) => writeln!(
                x,
                "  {}\n  <medium type=\"homogeneous\" id=\"v{i}\">\n{medium}  </medium>",
                element(&own_id)
            )?,
            // An interface has an inside: a dielectric is one-sided, as it is in Tessera.
            None if b.plugin.ends_with("dielectric") => writeln!(x, "  {}", element(&own_id))?,
            None => writeln!(
                x,
                "  <bsdf type=\"twosided\" id=\"m{i}\">\n    {}\n  </bsdf>",
                element("")
            )?,
        }
    }
    let material_ref = |m: u32| -> String {
        match media.get(m as usize) {
            Some(true) => {
                format!("    <ref id=\"m{m}\"/>\n    <ref name=\"interior\" id=\"v{m}\"/>\n")
            }
            _ => format!("    <ref id=\"m{m}\"/>\n"),
        }
    };
    for (i, mesh) in desc.meshes.iter().enumerate() {
        let file = format!("meshes/{i}.ply");
        write_ply(&dir.join(&file), mesh).with_context(|| format!("writing {file}"))?;
        writeln!(
            x,
            "  <shape type=\"ply\">\n    <string name=\"filename\" value=\"{file}\"/>"
        )?;
        if mesh.normals.is_none() {
            writeln!(x, "    <boolean name=\"face_normals\" value=\"true\"/>")?;
        }
        x.push_str(&material_ref(mesh.material));
        x.push_str(
            &emitter(mesh.emission.as_ref(), exposure).with_context(|| mesh.origin.clone())?,
        );
        writeln!(x, "  </shape>")?;
    }
    for s in &desc.spheres {
        writeln!(
            x,
            "  <shape type=\"sphere\">\n    <point name=\"center\" value=\"{}\"/>\n    \
             <float name=\"radius\" value=\"{}\"/>",
            rgb(s.center),
            s.radius
        )?;
        x.push_str(&material_ref(s.material));
        x.push_str(&emitter(s.emission.as_ref(), exposure).with_context(|| s.origin.clone())?);
        writeln!(x, "  </shape>")?;
    }
    for (i, l) in desc.lights.iter().enumerate() {
        x.push_str(&light(l, exposure).with_context(|| format!("lights[{i}]"))?);
    }
    x.push_str("</scene>\n");
    Ok(x)
}

fn sensor(desc: &SceneDesc) -> String {
    let c = &desc.camera;
    let (plugin, lens) = match c.lens {
        tessera_scene::Lens::Pinhole => ("perspective", String::new()),
        tessera_scene::Lens::Thin {
            aperture_radius,
            focus_distance,
        } => (
            "thinlens",
            param("float", "aperture_radius", aperture_radius)
                + &param("float", "focus_distance", focus_distance),
        ),
    };
    format!(
        "  <sensor type=\"{plugin}\">\n{lens}{}{}      <transform name=\"to_world\">\n        \
         <lookat origin=\"{}\" target=\"{}\" up=\"{}\"/>\n      </transform>\n      \
         <sampler type=\"independent\"/>\n      <film type=\"hdrfilm\">\n{}{}{}      \
         <rfilter type=\"box\"/>\n      </film>\n  </sensor>\n",
        param("float", "fov", c.fov_y.to_degrees()),
        param("string", "fov_axis", "y"),
        rgb(c.position),
        rgb(c.look_at),
        rgb(c.up),
        param("integer", "width", desc.film.width),
        param("integer", "height", desc.film.height),
        param("string", "pixel_format", "rgb"),
    )
}

/// A Mitsuba BSDF: its plugin, its parameters (XML lines) and the parameters of the
/// homogeneous medium inside, if the material has one.
struct Bsdf {
    plugin: &'static str,
    params: String,
    medium: Option<String>,
}

fn param(kind: &str, name: &str, value: impl std::fmt::Display) -> String {
    format!("      <{kind} name=\"{name}\" value=\"{value}\"/>\n")
}

/// σt as Mitsuba's RGB modes take it: a colour in [0, 1] times a scale.
fn extinction(sigma_t: Vec3) -> String {
    let scale = sigma_t.max_element();
    param("rgb", "sigma_t", rgb(sigma_t / scale)) + &param("float", "scale", scale)
}

fn bsdf(kind: &MaterialKind) -> anyhow::Result<Bsdf> {
    let roughness = |r: &Roughness| {
        let d = match r.distribution {
            tessera_scene::Distribution::Ggx => "ggx",
            tessera_scene::Distribution::Beckmann => "beckmann",
        };
        param("string", "distribution", d)
            + &param("float", "alpha_u", r.alpha_u)
            + &param("float", "alpha_v", r.alpha_v)
    };
    let dielectric = |eta: f32, r: &Roughness, medium: Option<String>| Bsdf {
        plugin: if r.is_smooth() {
            "dielectric"
        } else {
            "roughdielectric"
        },
        params: param("float", "int_ior", eta)
            + &param("float", "ext_ior", 1)
            + &if r.is_smooth() {
                String::new()
            } else {
                roughness(r)
            },
        medium,
    };
    Ok(match kind {
        MaterialKind::Diffuse { albedo } => Bsdf {
            plugin: "diffuse",
            params: param("rgb", "reflectance", rgb(*albedo)),
            medium: None,
        },
        MaterialKind::Conductor {
            eta,
            k,
            specular,
            roughness: r,
        } => Bsdf {
            plugin: if r.is_smooth() {
                "conductor"
            } else {
                "roughconductor"
            },
            params: param("rgb", "eta", rgb(*eta))
                + &param("rgb", "k", rgb(*k))
                + &param("rgb", "specular_reflectance", rgb(*specular))
                + &if r.is_smooth() {
                    String::new()
                } else {
                    roughness(r)
                },
            medium: None,
        },
        MaterialKind::Mirror { reflectance } => Bsdf {
            plugin: "conductor",
            params: param("string", "material", "none")
                + &param("rgb", "specular_reflectance", rgb(*reflectance)),
            medium: None,
        },
        MaterialKind::Dielectric {
            eta,
            roughness: r,
            absorption,
            tint,
            thin,
        } => {
            if *thin || *tint != Vec3::ONE {
                bail!("thin or tinted glass is not exported");
            }
            let medium = (*absorption != Vec3::ZERO)
                .then(|| param("rgb", "albedo", rgb(Vec3::ZERO)) + &extinction(*absorption));
            dielectric(*eta, r, medium)
        }
        MaterialKind::Subsurface {
            sigma_s_prime,
            sigma_a,
            eta,
            g,
        } => {
            // Tessera keeps σs′ = σs (1 − g); Mitsuba wants σt = σs + σa and albedo σs/σt.
            let sigma_s = *sigma_s_prime / (1.0 - g);
            let sigma_t = sigma_s + *sigma_a;
            let medium = param("rgb", "albedo", rgb(sigma_s / sigma_t))
                + &extinction(sigma_t)
                + &format!(
                    "      <phase type=\"hg\">\n  {}      </phase>\n",
                    param("float", "g", g)
                );
            let smooth = Roughness {
                distribution: Default::default(),
                alpha_u: 0.0,
                alpha_v: 0.0,
            };
            dielectric(*eta, &smooth, Some(medium))
        }
        other => bail!(
            "Mitsuba 3 has no {} BSDF",
            format!("{other:?}")
                .split([' ', '{'])
                .next()
                .unwrap_or("such")
        ),
    })
}

fn emitter(e: Option<&EmissionDesc>, exposure: f32) -> anyhow::Result<String> {
    let Some(e) = e else { return Ok(String::new()) };
    if e.two_sided {
        bail!("a two-sided emitter: Mitsuba 3's area lights emit on the front only");
    }
    if e.texture.is_some() {
        bail!("a textured emitter is not exported");
    }
    Ok(format!(
        "    <emitter type=\"area\">\n      <rgb name=\"radiance\" value=\"{}\"/>\n    </emitter>\n",
        rgb(e.radiance * exposure)
    ))
}

fn light(l: &LightDesc, exposure: f32) -> anyhow::Result<String> {
    let (plugin, params) = match l {
        LightDesc::Point {
            position,
            intensity,
        } => (
            "point",
            param("point", "position", rgb(*position))
                + &param("rgb", "intensity", rgb(*intensity * exposure)),
        ),
        LightDesc::Directional {
            direction,
            irradiance,
        } => (
            "directional",
            param("vector", "direction", rgb(*direction))
                + &param("rgb", "irradiance", rgb(*irradiance * exposure)),
        ),
        LightDesc::Environment {
            image: None, scale, ..
        } => ("constant", param("rgb", "radiance", rgb(*scale * exposure))),
        LightDesc::Environment { image: Some(_), .. } => {
            bail!("an environment image is not exported (Mitsuba's envmap orientation differs)")
        }
        LightDesc::Spot { .. } => bail!("Mitsuba 3's spot light falls off differently"),
    };
    Ok(format!(
        "  <emitter type=\"{plugin}\">\n{params}  </emitter>\n"
    ))
}

/// A binary little-endian PLY of `mesh`, its triangles wound as Tessera winds them (to agree
/// with the vertex normals), so an emitter's front face is the same.
fn write_ply(path: &Path, mesh: &tessera_scene::MeshDesc) -> anyhow::Result<()> {
    let mut out = Vec::new();
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\n",
        mesh.positions.len()
    )?;
    if mesh.normals.is_some() {
        out.extend_from_slice(b"property float nx\nproperty float ny\nproperty float nz\n");
    }
    write!(
        out,
        "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.triangles.len()
    )?;
    for (i, p) in mesh.positions.iter().enumerate() {
        for v in p.to_array() {
            out.extend_from_slice(&v.to_le_bytes());
        }
        if let Some(n) = &mesh.normals {
            for v in n[i].to_array() {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    for &[a, b, c] in &mesh.triangles {
        let idx = if mesh.faces_against_normals([a, b, c]) {
            [a, c, b]
        } else {
            [a, b, c]
        };
        out.push(3);
        for i in idx {
            out.extend_from_slice(&(i as i32).to_le_bytes());
        }
    }
    std::fs::File::create(path)?.write_all(&out)?;
    Ok(())
}
