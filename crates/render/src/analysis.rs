//! Scene analysis: which light paths a scene can have, and so what is worth computing
//! (invariant 4 of docs/src/design/overview.md, "only what a scene needs"). Pure: a function of the scene description,
//! run before rendering by every process that needs it, with each decision and its reason kept
//! for logs, the EXR header and the job status.
//!
//! Facts looked at: material classes (specular = mirror, smooth or nearly smooth conductors and
//! dielectrics; diffuse/glossy otherwise; black = pure emitters; IOR 1 = invisible), whether
//! reflective surfaces can light each other (two or more of them, or one that is neither a
//! sphere nor planar), whether light can reach a diffuse surface through a specular one
//! (caustics), how small the emitters are, whether they are in view.

use glam::Vec3A;
use tessera_scene::{LightDesc, MaterialKind, SceneDesc, SubsurfaceMethod};

use crate::camera::Camera;

/// Below this microfacet α an interface is treated as specular (its lobe is a near-delta that
/// next-event estimation cannot sample).
const SPECULAR_ALPHA: f32 = 0.1;

/// An emitter with less than this fraction of the scene's surface area is "small".
const SMALL_EMITTER: f64 = 0.005;

/// The share of an environment's directions in which a sun is looked for, and the share of its
/// power a sun must send from them.
const SUN_SOLID_ANGLE: f64 = 0.01;
const SUN_POWER: f64 = 0.5;

/// The share of `image`'s power (channel mean × solid angle) from its brightest
/// [`SUN_SOLID_ANGLE`] of directions, when at least [`SUN_POWER`].
fn sun_share(image: &tessera_scene::EnvImage) -> Option<f64> {
    let (w, h) = (image.width as usize, image.height as usize);
    let mut power: Vec<(f64, f64)> = image
        .texels
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let sin =
                (std::f64::consts::PI * ((i / w.max(1)) as f64 + 0.5) / h.max(1) as f64).sin();
            let radiance = (t.x + t.y + t.z) as f64 / 3.0;
            (radiance * sin, sin)
        })
        .collect();
    power.sort_by(|a, b| b.0.total_cmp(&a.0));
    let total: f64 = power.iter().map(|p| p.0).sum();
    let area: f64 = power.iter().map(|p| p.1).sum();
    if total <= 0.0 {
        return None;
    }
    let (mut p, mut a) = (0.0, 0.0);
    for (pi, ai) in power {
        if a + ai > SUN_SOLID_ANGLE * area {
            break;
        }
        p += pi;
        a += ai;
    }
    (p / total >= SUN_POWER).then_some(p / total)
}

/// One decision: what was decided and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Decision {
    pub topic: &'static str,
    pub choice: String,
    pub reason: String,
}

impl std::fmt::Display for Decision {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {} — {}", self.topic, self.choice, self.reason)
    }
}

/// How much of the light transport a scene needs computed, and how much a method computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Transport {
    /// Every path up to `max_depth`.
    Full,
    /// Emitted light and light reflected once (specular chains followed): exact where every
    /// light path has at most one diffuse or glossy bounce (or the scene has no light), and
    /// cheaper there.
    Direct,
}

/// What the analysis found and decided.
#[derive(Debug, Clone)]
pub struct Analysis {
    /// The light transport the scene needs: where direct lighting is exact, `auto` chooses a
    /// method of [`Transport::Direct`] without measuring.
    pub transport: Transport,
    /// Light can reach a diffuse surface through a specular one: a caustic map has work.
    pub caustics: bool,
    /// Emitters with less than [`SMALL_EMITTER`] of the scene's surface area.
    pub small_emitters: Vec<String>,
    pub decisions: Vec<Decision>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Class {
    /// Reflects or transmits only in (near-)delta directions.
    Specular,
    /// Has a diffuse or glossy lobe that light sampling can reach.
    Diffuse,
    /// Reflects nothing (a pure emitter).
    Black,
    /// Changes nothing (a dielectric of IOR 1).
    Invisible,
}

fn class(m: &MaterialKind) -> Class {
    let black = |v: glam::Vec3| v.max_element() <= 0.0;
    match m {
        MaterialKind::Diffuse { albedo } | MaterialKind::OrenNayar { albedo, .. } => {
            if black(*albedo) {
                Class::Black
            } else {
                Class::Diffuse
            }
        }
        MaterialKind::Phong {
            diffuse, specular, ..
        }
        | MaterialKind::BlinnPhong {
            diffuse, specular, ..
        }
        | MaterialKind::Ward {
            diffuse, specular, ..
        } => {
            if black(*diffuse) && black(*specular) {
                Class::Black
            } else {
                Class::Diffuse
            }
        }
        MaterialKind::Conductor { roughness, .. } => {
            if roughness.alpha_u.max(roughness.alpha_v) < SPECULAR_ALPHA {
                Class::Specular
            } else {
                Class::Diffuse
            }
        }
        MaterialKind::Dielectric { eta, roughness, .. } => {
            if *eta == 1.0 {
                Class::Invisible
            } else if roughness.alpha_u.max(roughness.alpha_v) < SPECULAR_ALPHA {
                Class::Specular
            } else {
                Class::Diffuse
            }
        }
        MaterialKind::MetallicRoughness {
            base_color,
            metallic,
            roughness,
            ..
        } => {
            let glossy = roughness * roughness >= SPECULAR_ALPHA;
            if *metallic >= 1.0 && black(*base_color) {
                Class::Black
            } else if *metallic >= 1.0 && !glossy {
                Class::Specular
            } else {
                Class::Diffuse
            }
        }
        // Light leaves a translucent surface in every direction, as from a diffuse one.
        MaterialKind::Subsurface { .. } => Class::Diffuse,
        MaterialKind::KubelkaMunk { .. } | MaterialKind::HanrahanKrueger { .. } => Class::Diffuse,
        MaterialKind::Mirror { reflectance } => {
            if black(*reflectance) {
                Class::Black
            } else {
                Class::Specular
            }
        }
    }
}

/// A shape as the analysis sees it.
struct Surface {
    name: String,
    class: Class,
    emissive: bool,
    /// A sphere or a planar mesh: cannot see itself.
    convex_or_flat: bool,
    centre: Vec3A,
    area: f64,
}

fn surfaces(desc: &SceneDesc) -> Vec<Surface> {
    let class_of = |m: u32| {
        desc.materials
            .get(m as usize)
            .map_or(Class::Black, |m| class(&m.kind))
    };
    let mut out = Vec::new();
    for m in &desc.meshes {
        let normal = |t: &[u32; 3]| {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            (b - a).cross(c - a).normalize_or_zero()
        };
        let first = m
            .triangles
            .iter()
            .map(normal)
            .find(|n| *n != glam::Vec3::ZERO);
        let flat = first.is_none_or(|n0| {
            m.triangles
                .iter()
                .map(normal)
                .all(|n| n == glam::Vec3::ZERO || n.dot(n0).abs() > 1.0 - 1e-5)
        });
        let (lo, hi) = m.positions.iter().fold(
            (glam::Vec3::splat(f32::MAX), glam::Vec3::splat(f32::MIN)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        out.push(Surface {
            name: m.origin.clone(),
            class: class_of(m.material),
            emissive: m.emission.is_some(),
            convex_or_flat: flat,
            centre: Vec3A::from((lo + hi) * 0.5),
            area: m.area(),
        });
    }
    for s in &desc.spheres {
        out.push(Surface {
            name: s.origin.clone(),
            class: class_of(s.material),
            emissive: s.emission.is_some(),
            convex_or_flat: true,
            centre: Vec3A::from(s.center),
            area: s.area(),
        });
    }
    out
}

fn names(list: &[&Surface]) -> String {
    let shown: Vec<&str> = list.iter().take(3).map(|s| s.name.as_str()).collect();
    let more = list.len().saturating_sub(3);
    if more > 0 {
        format!("{} and {more} more", shown.join(", "))
    } else {
        shown.join(", ")
    }
}

/// Lights that send most of their power from a point or a small solid angle (point, spot
/// and directional lights, small emitters, an environment's sun): caustics they cast are
/// paths a path tracer finds only by hitting them through the specular chain. Not part of
/// [`analyze`], which every plan runs: finding a sun sorts the environment's texels.
pub fn concentrated_lights(desc: &SceneDesc, analysis: &Analysis) -> Vec<String> {
    let mut concentrated = analysis.small_emitters.clone();
    for l in &desc.lights {
        match l {
            LightDesc::Point { .. } => concentrated.push("a point light".into()),
            LightDesc::Spot { .. } => concentrated.push("a spot light".into()),
            LightDesc::Directional { .. } => concentrated.push("a directional light".into()),
            LightDesc::Environment {
                image: Some(image), ..
            } => {
                if let Some(share) = sun_share(image) {
                    concentrated.push(format!(
                        "the environment's sun ({:.0} % of its power from {:.0} % of its directions)",
                        100.0 * share,
                        100.0 * SUN_SOLID_ANGLE
                    ));
                }
            }
            LightDesc::Environment { image: None, .. } => {}
        }
    }
    concentrated
}

/// Analyses the scene and decides what to compute.
pub fn analyze(desc: &SceneDesc) -> Analysis {
    let surfaces = surfaces(desc);
    let reflective: Vec<&Surface> = surfaces
        .iter()
        .filter(|s| matches!(s.class, Class::Diffuse | Class::Specular))
        .collect();
    let specular: Vec<&Surface> = reflective
        .iter()
        .copied()
        .filter(|s| s.class == Class::Specular)
        .collect();
    let diffuse: Vec<&Surface> = reflective
        .iter()
        .copied()
        .filter(|s| s.class == Class::Diffuse)
        .collect();
    let emitters: Vec<&Surface> = surfaces.iter().filter(|s| s.emissive).collect();
    let environment = desc
        .lights
        .iter()
        .any(|l| matches!(l, LightDesc::Environment { .. }));
    let has_light = !emitters.is_empty() || !desc.lights.is_empty();
    let interreflection = reflective.len() >= 2 || reflective.iter().any(|s| !s.convex_or_flat);
    let caustics = !specular.is_empty() && !diffuse.is_empty() && has_light;
    let mut decisions = Vec::new();

    // The light transport.
    let (transport, reason) = if !has_light {
        (
            Transport::Direct,
            "the scene has no light: the image is black whatever is traced".to_string(),
        )
    } else if caustics {
        (
            Transport::Full,
            format!(
                "light reaches diffuse surfaces through specular ones ({}): caustic paths need full path tracing",
                names(&specular)
            ),
        )
    } else if interreflection {
        (
            Transport::Full,
            format!(
                "{} reflective surfaces light each other ({}): indirect light matters",
                reflective.len(),
                names(&reflective)
            ),
        )
    } else if reflective.is_empty() {
        (
            Transport::Direct,
            "nothing reflects light: the camera sees only emitters and the environment, which direct lighting computes exactly".to_string(),
        )
    } else if specular.is_empty() {
        (
            Transport::Direct,
            format!(
                "one reflective surface that cannot see itself ({}), no specular surface: every light path has one bounce, direct lighting is exact and cheaper",
                names(&reflective)
            ),
        )
    } else {
        (
            Transport::Full,
            "specular surfaces seen by the camera: their reflections are followed".to_string(),
        )
    };
    decisions.push(Decision {
        topic: "light transport",
        choice: match transport {
            Transport::Direct => "direct lighting",
            Transport::Full => "every path (auto measures the methods)",
        }
        .into(),
        reason,
    });

    // Passes the literature would add, and whether this scene can use them.
    decisions.push(if caustics {
        Decision {
            topic: "caustic photon map",
            choice: "needed".into(),
            reason: format!(
                "specular surfaces ({}) can focus light onto diffuse ones (photon maps and light tracing find them; path tracing renders caustics with more noise)",
                names(&specular),
            ),
        }
    } else {
        Decision {
            topic: "caustic photon map",
            choice: "skipped".into(),
            reason: if specular.is_empty() {
                "no specular surface can focus light".into()
            } else {
                "no diffuse surface to receive focused light".into()
            },
        }
    });
    let translucent = desc.translucent_materials();
    decisions.push(if translucent.is_empty() {
        Decision {
            topic: "subsurface scattering",
            choice: "skipped".into(),
            reason: "no translucent materials".into(),
        }
    } else {
        Decision {
            topic: "subsurface scattering",
            choice: match desc.integrator.subsurface {
                SubsurfaceMethod::Dipole => "dipole BSSRDF, sampled by probe rays".into(),
                SubsurfaceMethod::Hierarchical => {
                    "point-cloud irradiance pass, dipole summed through an octree".into()
                }
                SubsurfaceMethod::RandomWalk => "random walk inside the objects (reference)".into(),
            },
            reason: format!("translucent materials: {}", translucent.join(", ")),
        }
    });
    if let Some(inv) = surfaces.iter().find(|s| s.class == Class::Invisible) {
        decisions.push(Decision {
            topic: "IOR-1 interfaces",
            choice: "passed straight through".into(),
            reason: format!(
                "{} has IOR 1: it neither bends nor reflects light",
                inv.name
            ),
        });
    }

    // Lights.
    let total_area: f64 = surfaces.iter().map(|s| s.area).sum();
    let small: Vec<&Surface> = emitters
        .iter()
        .copied()
        .filter(|s| s.area < SMALL_EMITTER * total_area)
        .collect();
    if !small.is_empty() {
        decisions.push(Decision {
            topic: "small emitters",
            choice: "sampled by next-event estimation".into(),
            reason: format!(
                "{} cover less than 0.5 % of the scene's surface area: BSDF sampling would rarely hit them",
                names(&small)
            ),
        });
    }
    let camera = Camera::new(&desc.camera, &desc.film);
    let seen: Vec<&Surface> = emitters
        .iter()
        .copied()
        .filter(|s| camera.in_view(s.centre))
        .collect();
    decisions.push(Decision {
        topic: "emitters in view",
        choice: if seen.is_empty() { "none".into() } else { names(&seen) },
        reason: if seen.is_empty() {
            "no emitter lies in the view frustum: the camera sees only reflected light".into()
        } else {
            "emitted radiance reaches the camera directly (counted once, with MIS weight 1 for camera rays)".into()
        },
    });
    decisions.push(Decision {
        topic: "environment light",
        choice: if environment {
            "importance-sampled".into()
        } else {
            "none".into()
        },
        reason: if environment {
            "light arrives from every direction; its distribution is built once".into()
        } else {
            "no environment: rays that leave the scene carry nothing".into()
        },
    });
    // What the scene's files hold that is read but not modelled: the user must see it.
    decisions.extend(desc.warnings.iter().map(|w| Decision {
        topic: "not modelled",
        choice: "ignored".into(),
        reason: w.clone(),
    }));
    Analysis {
        transport,
        caustics,
        small_emitters: small.iter().map(|s| s.name.clone()).collect(),
        decisions,
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn analyze_scene(rel: &str) -> (Analysis, String) {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../scenes")
            .join(rel);
        let mut d = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        d.integrator.method = "auto".into();
        let a = analyze(&d);
        let text = a
            .decisions
            .iter()
            .map(|d| d.to_string())
            .collect::<Vec<_>>()
            .join("\n");
        (a, text)
    }

    fn choice<'a>(a: &'a Analysis, topic: &str) -> &'a str {
        a.decisions
            .iter()
            .find(|d| d.topic == topic)
            .map_or("", |d| d.choice.as_str())
    }

    #[test]
    fn auto_makes_different_reasoned_choices_for_different_scenes() {
        // The Cornell box: diffuse walls light each other; nothing specular.
        let (cb, text) = analyze_scene("cornell-box/scene.json");
        assert_eq!(cb.transport, Transport::Full, "{text}");
        assert!(text.contains("light each other"), "{text}");
        assert_eq!(choice(&cb, "caustic photon map"), "skipped", "{text}");
        assert!(
            choice(&cb, "emitters in view").contains("light.obj"),
            "{text}"
        );
        assert_eq!(choice(&cb, "environment light"), "none");

        // Cornell glass: glass over diffuse blocks, a small bulb: caustics, small emitter.
        let (cg, text) = analyze_scene("cornell-glass/scene.json");
        assert_eq!(cg.transport, Transport::Full, "{text}");
        assert!(text.contains("caustic paths"), "{text}");
        assert_eq!(choice(&cg, "caustic photon map"), "needed", "{text}");
        assert!(text.contains("small emitters"), "{text}");

        // One diffuse plane under a sun, nothing specular: one bounce, direct lighting is exact.
        let (gp, text) = analyze_scene("hard/grazing-plane/scene.json");
        assert_eq!(gp.transport, Transport::Direct, "{text}");
        assert!(text.contains("direct lighting is exact"), "{text}");
        assert_eq!(choice(&gp, "caustic photon map"), "skipped");

        // An IOR-1 sphere under a sky is noticed as invisible.
        let (io, text) = analyze_scene("hard/ior-one/scene.json");
        assert!(text.contains("IOR 1"), "{text}");
        assert_eq!(io.transport, Transport::Direct, "{text}");
    }

    /// Lights that send their power from a point or a small solid angle are named: a sun in
    /// an environment image, a small bulb; the Cornell box's ceiling light is neither.
    #[test]
    fn concentrated_lights_are_found() {
        let concentrated = |rel: &str| {
            let path = Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../scenes")
                .join(rel);
            let d = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
            concentrated_lights(&d, &analyze(&d))
        };
        let ms = concentrated("material-spheres/scene.json");
        assert!(ms.iter().any(|c| c.contains("environment's sun")), "{ms:?}");
        let cg = concentrated("cornell-glass/scene.json");
        assert!(!cg.is_empty());
        let cb = concentrated("cornell-box/scene.json");
        assert!(cb.is_empty(), "{cb:?}");
    }

    /// No translucent material, no point-cloud pass: the decision says so.
    #[test]
    fn a_point_cloud_pass_only_for_translucent_materials() {
        let (cb, text) = analyze_scene("cornell-box/scene.json");
        assert_eq!(choice(&cb, "subsurface scattering"), "skipped", "{text}");
        assert!(text.contains("no translucent materials"), "{text}");
        let (ms, text) = analyze_scene("marble-skin/scene.json");
        assert!(
            choice(&ms, "subsurface scattering").contains("point-cloud irradiance pass"),
            "{text}"
        );
        assert!(
            text.contains("translucent materials: marble, skin"),
            "{text}"
        );
    }

    /// What light transport a scene needs does not depend on the method it sets.
    #[test]
    fn the_transport_a_scene_needs_is_the_same_whatever_method_it_sets() {
        for rel in ["hard/grazing-plane/scene.json", "cornell-box/scene.json"] {
            let path = Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../scenes")
                .join(rel);
            let mut d = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
            let decided = |d: &SceneDesc| {
                let a = analyze(d);
                (a.transport, a.decisions[0].to_string())
            };
            let own = decided(&d);
            d.integrator.method = "auto".into();
            assert_eq!(decided(&d), own, "{rel}");
        }
    }
}
