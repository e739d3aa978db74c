//! Emitters and lights: radiance, intensity or power at a colour temperature, converted to SI once; environment images.

use super::*;

/// Brightness of an emitter as given in the file, before unit conversion.
pub(super) struct Strength<'a> {
    /// The direct value (radiance, intensity or irradiance) and its field name.
    value: Option<NumOrArray<3>>,
    field: &'static str,
    power: Option<&'a PowerFile>,
    color: Option<Color>,
    temperature_k: Option<f32>,
}

impl Ctx<'_> {
    pub(super) fn emission(
        &mut self,
        path: &str,
        e: &EmissionFile,
        area_m2: f64,
    ) -> Option<EmissionDesc> {
        if area_m2 <= 0.0 && e.power.is_some() {
            self.problem(
                format!("{path}.power"),
                "expected an emitter with a positive area to spread the power over",
            );
            return None;
        }
        let sides = if e.two_sided { 2.0 } else { 1.0 };
        let strength = Strength {
            value: e.radiance,
            field: "radiance",
            power: e.power.as_ref(),
            color: e.color,
            temperature_k: e.temperature_k,
        };
        // Φ = π A L for a Lambertian emitter, per side.
        let radiance =
            self.strength(path, strength, Some(std::f64::consts::PI * area_m2 * sides))?;
        Some(EmissionDesc {
            radiance,
            two_sided: e.two_sided,
            texture: None,
        })
    }

    /// Resolves an emitter's brightness and colour to an RGB value in luminous-equivalent
    /// W-based units. `power_divisor` converts a power Φ (W) to the value (Φ / divisor);
    /// `None` if a power cannot be given for this kind of emitter.
    pub(super) fn strength(
        &mut self,
        path: &str,
        s: Strength,
        power_divisor: Option<f64>,
    ) -> Option<Vec3> {
        let field = s.field;
        let chroma = match (s.color, s.temperature_k) {
            (Some(_), Some(_)) => {
                self.problem(
                    format!("{path}.color"),
                    "expected `color` or `temperature_k`, not both",
                );
                return None;
            }
            (None, Some(t)) => {
                let t = self.range(
                    &format!("{path}.temperature_k"),
                    t,
                    500.0,
                    50_000.0,
                    "a colour temperature in [500, 50000] K",
                );
                photometry::blackbody_rgb(t as f64)
            }
            (Some(c), None) => {
                let c = self.non_negative3(&format!("{path}.color"), c.expand());
                let y = photometry::luminance(c);
                if y <= 0.0 {
                    self.problem(
                        format!("{path}.color"),
                        "expected a colour with positive luminance",
                    );
                    return None;
                }
                c / y
            }
            (None, None) => Vec3::ONE,
        };
        match (s.value, s.power) {
            (Some(NumOrArray::Many(rgb)), None) => {
                if s.color.is_some() || s.temperature_k.is_some() {
                    self.problem(format!("{path}.{field}"), format!("expected one number when `color` or `temperature_k` is given; an RGB {field} already has a colour"));
                }
                Some(self.non_negative3(&format!("{path}.{field}"), rgb))
            }
            (Some(NumOrArray::One(v)), None) => {
                let v = self.range(
                    &format!("{path}.{field}"),
                    v,
                    0.0,
                    f32::MAX,
                    "a finite, non-negative number",
                );
                Some(chroma * v)
            }
            (None, Some(p)) => {
                let Some(divisor) = power_divisor else {
                    self.problem(
                        format!("{path}.power"),
                        "this kind of light cannot be given a power",
                    );
                    return None;
                };
                let watts = self.power(&format!("{path}.power"), p, s.temperature_k)?;
                Some(chroma * (watts / divisor) as f32)
            }
            (Some(_), Some(_)) => {
                self.problem(
                    path.to_string(),
                    format!("expected `{field}` or `power`, not both"),
                );
                None
            }
            (None, None) => {
                self.problem(
                    path.to_string(),
                    format!("missing: expected `{field}` or `power`"),
                );
                None
            }
        }
    }

    /// A power specification in luminous-equivalent watts (lumens / 683).
    pub(super) fn power(
        &mut self,
        path: &str,
        p: &PowerFile,
        temperature_k: Option<f32>,
    ) -> Option<f64> {
        let lumens = match (p.lumens, p.watts, p.efficacy_lm_per_w) {
            (Some(lm), None, None) => self.positive(&format!("{path}.lumens"), lm) as f64,
            (None, Some(w), Some(eff)) => {
                self.positive(&format!("{path}.watts"), w) as f64
                    * self.positive(&format!("{path}.efficacy_lm_per_w"), eff) as f64
            }
            (None, Some(w), None) => match temperature_k {
                Some(t) => {
                    self.positive(&format!("{path}.watts"), w) as f64
                        * photometry::blackbody_efficacy(t.clamp(500.0, 50_000.0) as f64)
                }
                None => {
                    self.problem(
                        format!("{path}.efficacy_lm_per_w"),
                        "missing: radiant watts need a spectrum; give `temperature_k` (black body), or the lamp's efficacy in lm/W",
                    );
                    return None;
                }
            },
            _ => {
                self.problem(
                    path.to_string(),
                    "expected `lumens`, or `watts` (optionally with `efficacy_lm_per_w`)",
                );
                return None;
            }
        };
        Some(lumens / K_M)
    }

    pub(super) fn light(
        &mut self,
        path: &str,
        t: &Tagged,
        metres_per_unit: f64,
    ) -> Option<LightDesc> {
        let m2 = (metres_per_unit * metres_per_unit) as f32;
        Some(match t.kind.as_str() {
            "point" => {
                let l: PointLight = self.body(path, t)?;
                let position = self.finite3(&format!("{path}.position"), l.position);
                let s = Strength {
                    value: l.intensity,
                    field: "intensity",
                    power: l.power.as_ref(),
                    color: l.color,
                    temperature_k: l.temperature_k,
                };
                let intensity = self.strength(path, s, Some(4.0 * std::f64::consts::PI))?;
                LightDesc::Point {
                    position,
                    intensity: intensity / m2,
                }
            }
            "spot" => {
                let l: SpotLight = self.body(path, t)?;
                let position = self.finite3(&format!("{path}.position"), l.position);
                let target = self.finite3(&format!("{path}.look_at"), l.look_at);
                let direction = (target - position).normalize_or_zero();
                if direction == Vec3::ZERO {
                    self.problem(
                        format!("{path}.look_at"),
                        "expected a point different from the light's position",
                    );
                }
                let cone = self.range(
                    &format!("{path}.cone_angle_deg"),
                    l.cone_angle_deg,
                    0.01,
                    180.0,
                    "a half-angle in (0, 180] degrees",
                );
                let start = l.falloff_start_deg.unwrap_or(cone);
                let start = self.range(
                    &format!("{path}.falloff_start_deg"),
                    start,
                    0.0,
                    cone,
                    "a half-angle from 0 up to cone_angle_deg",
                );
                let (cos_start, cos_cone) = (start.to_radians().cos(), cone.to_radians().cos());
                // Power of a spot with a smooth fall-off (pbrt-v4, SpotLight::Phi):
                // Φ = 2π I (1 − (cos θ_start + cos θ_cone) / 2).
                let solid =
                    2.0 * std::f64::consts::PI * (1.0 - 0.5 * (cos_start as f64 + cos_cone as f64));
                let s = Strength {
                    value: l.intensity,
                    field: "intensity",
                    power: l.power.as_ref(),
                    color: l.color,
                    temperature_k: l.temperature_k,
                };
                let intensity = self.strength(path, s, Some(solid))?;
                LightDesc::Spot {
                    position,
                    direction,
                    intensity: intensity / m2,
                    cos_falloff_start: cos_start,
                    cos_cone,
                }
            }
            "directional" => {
                let l: DirectionalLight = self.body(path, t)?;
                let direction = self
                    .finite3(&format!("{path}.direction"), l.direction)
                    .normalize_or_zero();
                if direction == Vec3::ZERO {
                    self.problem(format!("{path}.direction"), "expected a non-zero direction");
                }
                let value = match (l.irradiance, l.illuminance_lux) {
                    (Some(_), Some(_)) => {
                        self.problem(
                            path.to_string(),
                            "expected `irradiance` or `illuminance_lux`, not both",
                        );
                        return None;
                    }
                    (None, Some(lux)) => Some(NumOrArray::One(
                        self.positive(&format!("{path}.illuminance_lux"), lux) / K_M as f32,
                    )),
                    (v, None) => v,
                };
                let s = Strength {
                    value,
                    field: "irradiance",
                    power: None,
                    color: l.color,
                    temperature_k: l.temperature_k,
                };
                LightDesc::Directional {
                    direction,
                    irradiance: self.strength(path, s, None)?,
                }
            }
            "environment" => {
                let l: EnvironmentLight = self.body(path, t)?;
                let m = self.transform(path, &l.transform);
                if transform::uniform_scale(&m).is_none_or(|s| (s - 1.0).abs() > 1e-4)
                    || m.translation != glam::Vec3A::ZERO
                {
                    self.problem(
                        format!("{path}.transform"),
                        "expected rotations only for an environment",
                    );
                }
                let scale = self.non_negative3(
                    &format!("{path}.radiance"),
                    l.radiance.unwrap_or(NumOrArray::One(1.0)).expand(),
                );
                let image = match &l.file {
                    None => None,
                    Some(f) => Some(self.env_image(&format!("{path}.file"), f)?),
                };
                LightDesc::Environment {
                    image,
                    scale,
                    to_world: Mat3::from(m.matrix3),
                }
            }
            other => {
                self.unknown_type(
                    path,
                    "light",
                    other,
                    &["point", "spot", "directional", "environment"],
                );
                return None;
            }
        })
    }

    /// The scene's top-level `environment`.
    pub(super) fn environment(&mut self, e: &EnvironmentFile) -> Option<LightDesc> {
        let strength = e.strength.unwrap_or(1.0);
        if !(strength >= 0.0 && strength.is_finite()) {
            self.problem(
                "environment.strength",
                format!("expected a finite, non-negative number, got {strength}"),
            );
            return None;
        }
        let rotation = e.rotation_deg.unwrap_or(0.0);
        if !rotation.is_finite() {
            self.problem(
                "environment.rotation_deg",
                "expected a finite number of degrees",
            );
            return None;
        }
        let image = match &e.image {
            None => None,
            Some(f) => Some(self.env_image("environment.image", f)?),
        };
        Some(LightDesc::Environment {
            image,
            scale: Vec3::splat(strength),
            to_world: Mat3::from_rotation_y(rotation.to_radians()),
        })
    }

    pub(super) fn env_image(&mut self, path: &str, file: &str) -> Option<EnvImage> {
        let rel = confine(file).map_err(|msg| self.problem(path, msg)).ok()?;
        let shown = self.source.display_path(&rel);
        let bytes = match self.source.read(&rel) {
            Ok(b) => b,
            Err(e) => {
                self.problem(
                    path,
                    format!("cannot read environment image {}: {e}", shown.display()),
                );
                return None;
            }
        };
        let img = match crate::image::read_exr_rgb(&bytes) {
            Ok(img) => img,
            Err(msg) => {
                self.problems.push(Problem {
                    file: shown,
                    path: String::new(),
                    message: format!("{msg} (referenced by {path})"),
                });
                return None;
            }
        };
        if let Some(i) = img
            .pixels
            .iter()
            .position(|p| !(p.is_finite() && p.min_element() >= 0.0))
        {
            let (x, y) = (i as u32 % img.width, i as u32 / img.width);
            self.problems.push(Problem {
                file: shown,
                path: format!("pixel ({x}, {y})"),
                message: format!(
                    "expected finite, non-negative radiance, got {}",
                    img.pixels[i]
                ),
            });
            return None;
        }
        if img.width < 2 || img.height < 1 {
            self.problem(
                path,
                "expected a latitude-longitude image at least 2 pixels wide",
            );
            return None;
        }
        Some(EnvImage {
            width: img.width,
            height: img.height,
            texels: img.pixels,
        })
    }
}
