//! Measured scattering media, for translucent (`subsurface`) materials by name.

/// A homogeneous medium measured by Jensen, Marschner, Levoy & Hanrahan 2001 ("A Practical
/// Model for Subsurface Light Transport", Figure 5): reduced scattering σs′ and absorption σa
/// in mm⁻¹ per RGB channel; the paper uses η = 1.3 for all of them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasuredMedium {
    pub name: &'static str,
    pub sigma_s_prime: [f32; 3],
    pub sigma_a: [f32; 3],
}

/// The relative index of refraction the paper gives its measured media.
pub const MEASURED_ETA: f32 = 1.3;

const fn m(name: &'static str, sigma_s_prime: [f32; 3], sigma_a: [f32; 3]) -> MeasuredMedium {
    MeasuredMedium {
        name,
        sigma_s_prime,
        sigma_a,
    }
}

/// The paper's Figure 5, in its order.
pub const MEASURED: &[MeasuredMedium] = &[
    m("apple", [2.29, 2.39, 1.97], [0.0030, 0.0034, 0.046]),
    m("chicken1", [0.15, 0.21, 0.38], [0.015, 0.077, 0.19]),
    m("chicken2", [0.19, 0.25, 0.32], [0.018, 0.088, 0.20]),
    m("cream", [7.38, 5.47, 3.15], [0.0002, 0.0028, 0.0163]),
    m("ketchup", [0.18, 0.07, 0.03], [0.061, 0.97, 1.45]),
    m("marble", [2.19, 2.62, 3.00], [0.0021, 0.0041, 0.0071]),
    m("potato", [0.68, 0.70, 0.55], [0.0024, 0.0090, 0.12]),
    m("skim-milk", [0.70, 1.22, 1.90], [0.0014, 0.0025, 0.0142]),
    m("skin1", [0.74, 0.88, 1.01], [0.032, 0.17, 0.48]),
    m("skin2", [1.09, 1.59, 1.79], [0.013, 0.070, 0.145]),
    m("spectralon", [11.6, 20.4, 14.9], [0.0, 0.0, 0.0]),
    m("whole-milk", [2.55, 3.21, 3.77], [0.0011, 0.0024, 0.014]),
];

/// The measured medium named `name`, ignoring case, dashes, underscores and spaces
/// ("Skim milk", "skim_milk" and "skimmilk" alike).
pub fn measured(name: &str) -> Option<&'static MeasuredMedium> {
    let key = |s: &str| s.to_ascii_lowercase().replace(['-', '_', ' '], "");
    MEASURED.iter().find(|m| key(m.name) == key(name))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn media_are_found_by_any_spelling_of_their_name() {
        assert_eq!(measured("skimmilk").map(|m| m.name), Some("skim-milk"));
        assert_eq!(measured("Whole milk").map(|m| m.name), Some("whole-milk"));
        assert_eq!(measured("SKIN_1").map(|m| m.name), Some("skin1"));
        assert!(measured("jade").is_none());
    }
}
