//! Materials: BSDFs by type, roughness, energy checks, translucent media, named metals.

use super::*;

impl Ctx<'_> {
    pub(super) fn roughness(
        &mut self,
        path: &str,
        alpha: Option<Alpha>,
        distribution: Distribution,
    ) -> Roughness {
        let [alpha_u, alpha_v] = alpha.map(|a| a.expand()).unwrap_or([0.0, 0.0]);
        for a in [alpha_u, alpha_v] {
            self.range(
                &format!("{path}.alpha"),
                a,
                0.0,
                4.0,
                "a microfacet width α in [0, 4]",
            );
        }
        if (alpha_u == 0.0) != (alpha_v == 0.0) {
            self.problem(
                format!("{path}.alpha"),
                "expected both widths zero (smooth) or both positive",
            );
        }
        Roughness {
            distribution,
            alpha_u,
            alpha_v,
        }
    }

    /// Diffuse + specular must not reflect more than arrives (per channel).
    pub(super) fn energy(&mut self, path: &str, diffuse: Vec3, specular: Vec3) {
        let total = diffuse + specular;
        if total.max_element() > 1.0 {
            self.problem(
                format!("{path}.specular"),
                format!("expected diffuse + specular <= 1 per channel (energy conservation), got {total}"),
            );
        }
    }

    /// The material `t`; lengths in it (the subsurface coefficients) converted to scene units.
    pub(super) fn material(
        &mut self,
        path: &str,
        t: &Tagged,
        metres_per_unit: f64,
    ) -> Option<MaterialKind> {
        Some(match t.kind.as_str() {
            "diffuse" => {
                let m: DiffuseMaterial = self.body(path, t)?;
                MaterialKind::Diffuse {
                    albedo: self.albedo(&format!("{path}.albedo"), m.albedo),
                }
            }
            "oren_nayar" => {
                let m: OrenNayarMaterial = self.body(path, t)?;
                let sigma = self.range(
                    &format!("{path}.sigma_deg"),
                    m.sigma_deg,
                    0.0,
                    90.0,
                    "an angle in [0, 90] degrees",
                );
                MaterialKind::OrenNayar {
                    albedo: self.albedo(&format!("{path}.albedo"), m.albedo),
                    sigma: sigma.to_radians(),
                }
            }
            "phong" | "blinn_phong" => {
                let m: PhongMaterial = self.body(path, t)?;
                let diffuse = self.albedo(
                    &format!("{path}.diffuse"),
                    m.diffuse.unwrap_or(NumOrArray::One(0.0)),
                );
                let specular = self.albedo(&format!("{path}.specular"), m.specular);
                self.energy(path, diffuse, specular);
                let exponent = self.range(
                    &format!("{path}.exponent"),
                    m.exponent,
                    0.0,
                    1e6,
                    "an exponent in [0, 1e6]",
                );
                if t.kind == "phong" {
                    MaterialKind::Phong {
                        diffuse,
                        specular,
                        exponent,
                    }
                } else {
                    MaterialKind::BlinnPhong {
                        diffuse,
                        specular,
                        exponent,
                    }
                }
            }
            "ward" => {
                let m: WardMaterial = self.body(path, t)?;
                let diffuse = self.albedo(
                    &format!("{path}.diffuse"),
                    m.diffuse.unwrap_or(NumOrArray::One(0.0)),
                );
                let specular = self.albedo(&format!("{path}.specular"), m.specular);
                self.energy(path, diffuse, specular);
                let alpha_x = self.range(
                    &format!("{path}.alpha_x"),
                    m.alpha_x,
                    1e-4,
                    4.0,
                    "a width in [1e-4, 4]",
                );
                let alpha_y = self.range(
                    &format!("{path}.alpha_y"),
                    m.alpha_y,
                    1e-4,
                    4.0,
                    "a width in [1e-4, 4]",
                );
                MaterialKind::Ward {
                    diffuse,
                    specular,
                    alpha_x,
                    alpha_y,
                }
            }
            "conductor" => {
                let m: ConductorMaterial = self.body(path, t)?;
                let (eta, k) = match (&m.metal, m.eta, m.k) {
                    (Some(name), None, None) => match metal(name) {
                        Some(v) => v,
                        None => {
                            self.problem(
                                format!("{path}.metal"),
                                format!(
                                    "unknown metal \"{name}\"; expected one of: {}",
                                    METALS.map(|m| m.0).join(", ")
                                ),
                            );
                            (Vec3::ONE, Vec3::ZERO)
                        }
                    },
                    (None, Some(eta), Some(k)) => {
                        let eta = self.non_negative3(&format!("{path}.eta"), eta.expand());
                        if eta.min_element() <= 0.0 {
                            self.problem(
                                format!("{path}.eta"),
                                "expected positive indices of refraction",
                            );
                        }
                        (eta, self.non_negative3(&format!("{path}.k"), k.expand()))
                    }
                    _ => {
                        self.problem(
                            path.to_string(),
                            "expected either `metal` or both `eta` and `k`",
                        );
                        (Vec3::ONE, Vec3::ZERO)
                    }
                };
                let specular = self.albedo(
                    &format!("{path}.specular"),
                    m.specular.unwrap_or(NumOrArray::One(1.0)),
                );
                let roughness = self.roughness(path, m.alpha, m.distribution);
                MaterialKind::Conductor {
                    eta,
                    k,
                    specular,
                    roughness,
                }
            }
            "dielectric" => {
                let m: DielectricMaterial = self.body(path, t)?;
                let int = self.range(
                    &format!("{path}.ior"),
                    m.ior,
                    0.01,
                    100.0,
                    "an index of refraction in [0.01, 100]",
                );
                let ext = self.range(
                    &format!("{path}.ext_ior"),
                    m.ext_ior.unwrap_or(1.0),
                    0.01,
                    100.0,
                    "an index of refraction in [0.01, 100]",
                );
                let roughness = self.roughness(path, m.alpha, m.distribution);
                // Per mm → per scene unit.
                let absorption = m.sigma_a_per_mm.map_or(Vec3::ZERO, |a| {
                    self.non_negative3(&format!("{path}.sigma_a_per_mm"), a.expand())
                        * (metres_per_unit * 1000.0) as f32
                });
                if m.thin && absorption.max_element() > 0.0 {
                    self.problem(
                        format!("{path}.sigma_a_per_mm"),
                        "a thin sheet has no interior to absorb in; expected no sigma_a_per_mm \
                         with `thin` (use `tint`)",
                    );
                }
                let tint = match m.tint {
                    Some(t) => self.albedo(&format!("{path}.tint"), t),
                    None => Vec3::ONE,
                };
                MaterialKind::Dielectric {
                    eta: int / ext,
                    roughness,
                    absorption,
                    tint,
                    thin: m.thin,
                }
            }
            "mirror" => {
                let m: MirrorMaterial = self.body(path, t)?;
                MaterialKind::Mirror {
                    reflectance: self.albedo(
                        &format!("{path}.reflectance"),
                        m.reflectance.unwrap_or(NumOrArray::One(1.0)),
                    ),
                }
            }
            "metallic_roughness" => {
                let m: MetallicRoughnessMaterial = self.body(path, t)?;
                let unit = |ctx: &mut Self, field: &str, v: Option<f32>, default: f32| {
                    ctx.range(
                        &format!("{path}.{field}"),
                        v.unwrap_or(default),
                        0.0,
                        1.0,
                        "a number in [0, 1]",
                    )
                };
                MaterialKind::MetallicRoughness {
                    base_color: self.albedo(
                        &format!("{path}.base_color"),
                        m.base_color.unwrap_or(NumOrArray::One(1.0)),
                    ),
                    metallic: unit(self, "metallic", m.metallic, 1.0),
                    roughness: unit(self, "roughness", m.roughness, 1.0),
                    ior: self.range(
                        &format!("{path}.ior"),
                        m.ior.unwrap_or(1.5),
                        1.0,
                        10.0,
                        "an index of refraction in [1, 10]",
                    ),
                    specular_color: self.non_negative3(
                        &format!("{path}.specular_color"),
                        m.specular_color.unwrap_or(NumOrArray::One(1.0)).expand(),
                    ),
                    specular: unit(self, "specular", m.specular, 1.0),
                    textures: Default::default(),
                    transmission: crate::PbrTransmission {
                        specular: unit(self, "transmission", m.transmission, 0.0),
                        diffuse: unit(self, "diffuse_transmission", m.diffuse_transmission, 0.0),
                        diffuse_color: self.albedo(
                            &format!("{path}.diffuse_transmission_color"),
                            m.diffuse_transmission_color.unwrap_or(NumOrArray::One(1.0)),
                        ),
                        thin: m.thin,
                    },
                }
            }
            "subsurface" => {
                let m: SubsurfaceMaterial = self.body(path, t)?;
                self.subsurface(path, &m, metres_per_unit)
            }
            "kubelka_munk" => {
                let m: KubelkaMunkMaterial = self.body(path, t)?;
                if m.layers.is_empty() {
                    self.problem(format!("{path}.layers"), "expected at least one layer");
                }
                let layers = m
                    .layers
                    .iter()
                    .enumerate()
                    .map(|(i, l)| {
                        let at = format!("{path}.layers[{i}]");
                        KmLayer {
                            absorption: self.non_negative3(
                                &format!("{at}.absorption_per_mm"),
                                l.absorption_per_mm.expand(),
                            ),
                            scattering: self.non_negative3(
                                &format!("{at}.scattering_per_mm"),
                                l.scattering_per_mm.expand(),
                            ),
                            thickness: self.positive(&format!("{at}.thickness_mm"), l.thickness_mm),
                        }
                    })
                    .collect();
                MaterialKind::KubelkaMunk {
                    layers,
                    substrate: self.albedo(
                        &format!("{path}.substrate"),
                        m.substrate.unwrap_or(NumOrArray::One(0.0)),
                    ),
                }
            }
            "hanrahan_krueger" => {
                let m: HanrahanKruegerMaterial = self.body(path, t)?;
                MaterialKind::HanrahanKrueger {
                    sigma_s: self.non_negative3(
                        &format!("{path}.sigma_s_per_mm"),
                        m.sigma_s_per_mm.expand(),
                    ),
                    sigma_a: self.non_negative3(
                        &format!("{path}.sigma_a_per_mm"),
                        m.sigma_a_per_mm.expand(),
                    ),
                    thickness: self.positive(&format!("{path}.thickness_mm"), m.thickness_mm),
                    g: self.range(
                        &format!("{path}.g"),
                        m.g.unwrap_or(0.0),
                        -0.99,
                        0.99,
                        "a Henyey–Greenstein asymmetry in [-0.99, 0.99]",
                    ),
                    eta: self.range(
                        &format!("{path}.ior"),
                        m.ior.unwrap_or(1.4),
                        1.0,
                        3.0,
                        "an index of refraction in [1, 3]",
                    ),
                    substrate: self.albedo(
                        &format!("{path}.substrate"),
                        m.substrate.unwrap_or(NumOrArray::One(0.0)),
                    ),
                }
            }
            other => {
                self.unknown_type(
                    path,
                    "material",
                    other,
                    &[
                        "diffuse",
                        "oren_nayar",
                        "phong",
                        "blinn_phong",
                        "ward",
                        "conductor",
                        "dielectric",
                        "mirror",
                        "metallic_roughness",
                        "subsurface",
                        "kubelka_munk",
                        "hanrahan_krueger",
                    ],
                );
                return None;
            }
        })
    }

    /// A translucent material: the coefficients of its preset or its own (per mm), times
    /// `scale`, per scene unit.
    pub(super) fn subsurface(
        &mut self,
        path: &str,
        m: &SubsurfaceMaterial,
        metres_per_unit: f64,
    ) -> MaterialKind {
        let (sigma_s_prime, sigma_a) = match (&m.preset, m.sigma_s_prime_per_mm, m.sigma_a_per_mm) {
            (Some(name), None, None) => match crate::media::measured(name) {
                Some(p) => (Vec3::from(p.sigma_s_prime), Vec3::from(p.sigma_a)),
                None => {
                    let known: Vec<&str> = crate::media::MEASURED.iter().map(|p| p.name).collect();
                    self.problem(
                        format!("{path}.preset"),
                        format!(
                            "unknown medium \"{name}\"; expected one of: {}",
                            known.join(", ")
                        ),
                    );
                    (Vec3::ONE, Vec3::ZERO)
                }
            },
            (None, Some(s), Some(a)) => {
                let s = self.non_negative3(&format!("{path}.sigma_s_prime_per_mm"), s.expand());
                if s.min_element() <= 0.0 {
                    self.problem(
                            format!("{path}.sigma_s_prime_per_mm"),
                            format!("expected a positive scattering coefficient per channel (a medium that does not scatter is a dielectric), got {s}"),
                        );
                }
                (
                    s,
                    self.non_negative3(&format!("{path}.sigma_a_per_mm"), a.expand()),
                )
            }
            _ => {
                self.problem(
                    path.to_string(),
                    "expected either `preset` or both `sigma_s_prime_per_mm` and `sigma_a_per_mm`",
                );
                (Vec3::ONE, Vec3::ZERO)
            }
        };
        let scale = match m.scale {
            Some(s) => self.positive(&format!("{path}.scale"), s),
            None => 1.0,
        };
        let eta = self.range(
            &format!("{path}.ior"),
            m.ior.unwrap_or(crate::media::MEASURED_ETA),
            1.0,
            3.0,
            "an index of refraction in [1, 3] (the dipole's diffuse Fresnel fit holds there)",
        );
        let g = self.range(
            &format!("{path}.g"),
            m.g.unwrap_or(0.0),
            -0.99,
            0.99,
            "a Henyey–Greenstein asymmetry in [-0.99, 0.99]",
        );
        // Per mm → per scene unit.
        let per_unit = (metres_per_unit * 1000.0) as f32 * scale;
        MaterialKind::Subsurface {
            sigma_s_prime: sigma_s_prime * per_unit,
            sigma_a: sigma_a * per_unit,
            eta,
            g,
        }
    }
}

/// Named metals: complex IOR (η, k) at about 650, 550 and 450 nm (R, G, B).
const METALS: [(&str, [f32; 3], [f32; 3]); 4] = [
    ("gold", [0.143, 0.374, 1.442], [3.983, 2.385, 1.603]),
    ("silver", [0.155, 0.117, 0.138], [4.828, 3.122, 2.147]),
    ("copper", [0.200, 0.924, 1.102], [3.912, 2.452, 2.142]),
    ("aluminium", [1.657, 0.880, 0.521], [9.224, 6.270, 4.837]),
];

fn metal(name: &str) -> Option<(Vec3, Vec3)> {
    let name = if name == "aluminum" {
        "aluminium"
    } else {
        name
    };
    METALS
        .iter()
        .find(|m| m.0 == name)
        .map(|m| (Vec3::from(m.1), Vec3::from(m.2)))
}
