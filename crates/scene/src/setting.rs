//! The settings under `integrator` that rendering methods read besides `spp`, `max_depth`,
//! `rr_depth` and `seed`, with the values each admits: one list, which the scene format checks
//! values against and each method's description names (`tessera methods`, `GET /v1/methods`).

/// Longest camera path, in frames.
pub const MAX_FRAMES: u32 = 1_000_000;
/// Most photons one map may be shot with (each stored photon takes 40 bytes; a photon is
/// stored about twice in a closed room).
pub const MAX_PHOTONS: u32 = 100_000_000;
/// Most photons in one radiance estimate (the search keeps them on the stack).
pub const MAX_PHOTON_K: u32 = 1024;
/// Most final-gather rays per gather point.
pub const MAX_GATHER_RAYS: u32 = 65_536;

/// One setting: its path under `integrator`, its values, what it does.
#[derive(Debug, PartialEq)]
pub struct Setting {
    /// Its path under `integrator` (`photon_map.alpha`).
    pub name: &'static str,
    pub kind: Kind,
    /// What it sets, and what is chosen where the scene leaves it out.
    pub doc: &'static str,
}

/// The values a setting admits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind {
    /// A whole number in [min, max].
    Count { min: u32, max: u32 },
    /// A positive finite length, in scene units.
    Length,
    /// A number in the open interval (0, 1).
    Fraction,
    /// A number in [min, max].
    Number { min: f32, max: f32 },
    /// One of these words.
    Word(&'static [&'static str]),
    /// An object of settings of its own, or `{"enabled": false}`.
    Group,
}

impl Kind {
    /// The values, as users read them: `1 to 1024`, `one of box, cone, gaussian`.
    pub fn describe(&self) -> String {
        match *self {
            Kind::Count { min, max } => format!("a whole number, {min} to {max}"),
            Kind::Length => "a positive length (scene units)".into(),
            Kind::Fraction => "a fraction in (0, 1)".into(),
            Kind::Number { min, max } => format!("a number in [{min}, {max}]"),
            Kind::Word(words) => format!("one of {}", words.join(", ")),
            Kind::Group => "an object of settings".into(),
        }
    }

    /// Checks a number against the values; the error says what was expected and what came.
    /// Words and groups are the file format's to check (they are parsed as such).
    pub fn check(&self, v: f64) -> Result<(), String> {
        let ok = match *self {
            Kind::Count { min, max } => v >= f64::from(min) && v <= f64::from(max),
            Kind::Length => v > 0.0 && v.is_finite(),
            Kind::Fraction => v > 0.0 && v < 1.0,
            Kind::Number { min, max } => v >= f64::from(min) && v <= f64::from(max),
            Kind::Word(_) | Kind::Group => true,
        };
        match ok {
            true => Ok(()),
            false => Err(format!("expected {}, got {v}", self.describe())),
        }
    }
}

const fn setting(name: &'static str, kind: Kind, doc: &'static str) -> Setting {
    Setting { name, kind, doc }
}

pub static SAMPLER: Setting = setting(
    "sampler",
    Kind::Word(&["sobol", "independent"]),
    "the sample sequence: Owen-scrambled Sobol (default) or independent random numbers",
);
pub static SUBSURFACE: Setting = setting(
    "subsurface",
    Kind::Word(&["dipole", "hierarchical", "random_walk"]),
    "how translucent materials are rendered: the dipole BSSRDF (default), Jensen–Buhler's hierarchical dipole, or a volumetric random walk",
);
pub static PHOTONS: Setting = setting(
    "photon_map.photons",
    Kind::Count {
        min: 1,
        max: MAX_PHOTONS,
    },
    "photons emitted for the global map (SPPM: per iteration); default chosen from the scene",
);
pub static CAUSTIC_PHOTONS: Setting = setting(
    "photon_map.caustic_photons",
    Kind::Count {
        min: 0,
        max: MAX_PHOTONS,
    },
    "photons emitted for the caustic map (0: none); default chosen from the scene",
);
pub static PHOTON_K: Setting = setting(
    "photon_map.k",
    Kind::Count {
        min: 1,
        max: MAX_PHOTON_K,
    },
    "nearest photons per global radiance estimate",
);
pub static CAUSTIC_K: Setting = setting(
    "photon_map.caustic_k",
    Kind::Count {
        min: 1,
        max: MAX_PHOTON_K,
    },
    "nearest photons per caustic estimate",
);
pub static RADIUS: Setting = setting(
    "photon_map.radius",
    Kind::Length,
    "largest search radius of a global estimate (SPPM: the initial radius)",
);
pub static CAUSTIC_RADIUS: Setting = setting(
    "photon_map.caustic_radius",
    Kind::Length,
    "largest search radius of a caustic estimate",
);
pub static GATHER_RAYS: Setting = setting(
    "photon_map.gather_rays",
    Kind::Count {
        min: 1,
        max: MAX_GATHER_RAYS,
    },
    "final-gather rays per gather point",
);
pub static CAUSTIC_FILTER: Setting = setting(
    "photon_map.caustic_filter",
    Kind::Word(&["box", "cone", "gaussian"]),
    "how caustic photons are weighted by distance (default cone)",
);
pub static ALPHA: Setting = setting(
    "photon_map.alpha",
    Kind::Fraction,
    "SPPM's fraction of new photons kept per iteration (default 2/3)",
);
pub static IRRADIANCE_CACHE: Setting = setting(
    "photon_map.irradiance_cache",
    Kind::Group,
    "Ward's irradiance cache for the indirect diffuse term (on by default)",
);
pub static IC_ACCURACY: Setting = setting(
    "photon_map.irradiance_cache.accuracy",
    Kind::Number {
        min: 1e-3,
        max: 10.0,
    },
    "Ward's accuracy a: a record serves points where its error weight exceeds 1/a",
);
pub static IC_SPACING: Setting = setting(
    "photon_map.irradiance_cache.spacing",
    Kind::Count { min: 1, max: 1024 },
    "record candidates every this many pixels of the pre-render",
);
pub static IC_KEYFRAME_STEP: Setting = setting(
    "photon_map.irradiance_cache.keyframe_step",
    Kind::Count {
        min: 1,
        max: MAX_FRAMES,
    },
    "a fly-through's records come from every this-many-th frame's camera",
);
pub static IC_GATHER_RAYS: Setting = setting(
    "photon_map.irradiance_cache.gather_rays",
    Kind::Count {
        min: 1,
        max: MAX_GATHER_RAYS,
    },
    "hemisphere rays per record",
);

/// Every setting, in the order of the file format.
pub static ALL: &[&Setting] = &[
    &SAMPLER,
    &SUBSURFACE,
    &PHOTONS,
    &CAUSTIC_PHOTONS,
    &PHOTON_K,
    &CAUSTIC_K,
    &RADIUS,
    &CAUSTIC_RADIUS,
    &GATHER_RAYS,
    &CAUSTIC_FILTER,
    &ALPHA,
    &IRRADIANCE_CACHE,
    &IC_ACCURACY,
    &IC_SPACING,
    &IC_KEYFRAME_STEP,
    &IC_GATHER_RAYS,
];

#[cfg(test)]
mod tests {
    use serde_json::{Value, json};

    use super::*;

    /// The scene's `integrator` with `value` at the setting's path.
    fn integrator_with(name: &str, value: Value) -> Value {
        let mut v = value;
        for part in name.rsplit('.') {
            v = json!({ part: v });
        }
        v
    }

    /// Loads the Cornell box with `integrator` merged into its own; the settings it then
    /// says the scene gave.
    fn load(integrator: Value) -> Result<Vec<&'static Setting>, String> {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-box");
        let text = std::fs::read_to_string(dir.join("scene.json")).unwrap();
        let mut scene: Value = serde_json::from_str(&text).unwrap();
        fn merge(a: &mut Value, b: Value) {
            match (a, b) {
                (Value::Object(a), Value::Object(b)) => {
                    for (k, v) in b {
                        merge(a.entry(k).or_insert(Value::Null), v);
                    }
                }
                (a, b) => *a = b,
            }
        }
        merge(&mut scene["integrator"], integrator);
        let tmp = tempfile::tempdir().unwrap();
        for entry in std::fs::read_dir(&dir).unwrap() {
            let entry = entry.unwrap();
            std::fs::copy(entry.path(), tmp.path().join(entry.file_name())).unwrap();
        }
        std::fs::write(tmp.path().join("scene.json"), scene.to_string()).unwrap();
        crate::load(&tmp.path().join("scene.json"))
            .map(|d| d.integrator.given)
            .map_err(|e| e.to_string())
    }

    /// What each setting says it admits is what the scene format admits: its bounds load, a
    /// step past them is refused naming the setting, and each word is one the format parses.
    /// A scene that gives one setting is said to give it (and the group it is in), no other.
    #[test]
    fn the_declared_values_are_the_ones_the_scene_format_checks() {
        for s in ALL {
            let field = format!("integrator.{}", s.name);
            let refused = |v: Value| {
                let err = load(integrator_with(s.name, v.clone()))
                    .expect_err(&format!("{field} = {v} loaded"));
                assert!(err.contains(&field), "{field} = {v}: {err}");
            };
            let within: Vec<&Setting> = ALL
                .iter()
                .copied()
                .filter(|t| *t == *s || s.name.starts_with(&format!("{}.", t.name)))
                .collect();
            let loads = |v: Value| {
                let given = load(integrator_with(s.name, v.clone()))
                    .unwrap_or_else(|e| panic!("{field} = {v}: {e}"));
                let names = |l: &[&Setting]| l.iter().map(|t| t.name).collect::<Vec<_>>();
                assert_eq!(names(&given), names(&within), "{field} = {v}");
            };
            match s.kind {
                Kind::Count { min, max } => {
                    loads(json!(min));
                    loads(json!(max));
                    if min > 0 {
                        refused(json!(min - 1));
                    }
                    refused(json!(u64::from(max) + 1));
                }
                Kind::Length => {
                    loads(json!(0.5));
                    refused(json!(0.0));
                    refused(json!(-1.0));
                }
                Kind::Fraction => {
                    loads(json!(0.5));
                    refused(json!(0.0));
                    refused(json!(1.0));
                }
                Kind::Number { min, max } => {
                    loads(json!(min));
                    loads(json!(max));
                    refused(json!(max * 1.5));
                    refused(json!(min * 0.5));
                }
                Kind::Word(words) => {
                    for w in words {
                        loads(json!(w));
                    }
                    refused(json!("no-such-word"));
                }
                Kind::Group => {
                    loads(json!({}));
                    loads(json!({"enabled": false}));
                    refused(json!({"no_such_field": 1}));
                }
            }
            assert!(
                matches!(s.kind.check(f64::NAN), Err(_))
                    || matches!(s.kind, Kind::Word(_) | Kind::Group)
            );
        }
    }
}
