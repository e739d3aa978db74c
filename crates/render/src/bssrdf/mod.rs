//! Subsurface scattering: light that enters a translucent object at one point and leaves at
//! another (issue 7).
//!
//! - [`dipole`]: Jensen et al. 2001's diffusion profile Rd(r) and its measured media;
//! - [`profile`]: Rd tabulated per channel for sampling exit radii;
//! - [`hierarchical`]: Jensen & Buhler 2002 — irradiance on a point cloud, summed through an
//!   octree;
//! - [`probe`]: the sampled BSSRDF of the path tracer — exit points found by probe rays along
//!   three axes (pbrt-v3 §15.4, after Mertens et al.'s tangent-plane sampling);
//! - [`single`]: Jensen et al. 2001's single-scattering term, added by both dipole methods;
//! - [`walk`]: the brute-force reference, a volumetric random walk inside the object;
//! - [`random_walk`]: the same walk in a semi-infinite slab, the dipole's own test.
//!
//! A translucent material is a smooth dielectric interface ([`crate::bsdf::SmoothDielectric`])
//! whose transmitted light, instead of refracting, is carried by the BSSRDF
//! S(p_o, ω_o; p_i, ω_i) = (1 − Fr(cos θo)) Rd(|p_o − p_i|) Sw(ω_i): the Fresnel
//! transmittance at entry is the probability of sampling transmission, Rd is the dipole's,
//! and Sw ([`crate::bsdf::SubsurfaceExit`]) is the directional distribution at exit. The
//! dipole methods add the single-scattering term S⁽¹⁾ to this diffusion term, as Jensen et
//! al. 2001 do; the random walk holds every order of scattering by itself.

pub mod dipole;
pub mod hierarchical;
pub mod probe;
pub mod profile;
pub mod random_walk;
pub mod single;
pub mod walk;

use glam::{Vec2, Vec3, Vec3A};

use crate::bsdf::SubsurfaceExit;
use crate::math::Frame;
use crate::scene::Material;
use crate::spectrum::Spectrum;
use dipole::{Dipole, Medium};
use profile::{RadialTable, RdLookup};

/// What a translucent material carries beyond its interface: the medium (per scene unit), its
/// dipoles and sampling tables, and the exit lobe as a material of its own.
#[derive(Debug)]
pub struct Subsurface {
    /// Scattering σs = σs′ / (1 − g) and absorption σa, per scene unit.
    pub sigma_s: Spectrum,
    pub sigma_a: Spectrum,
    /// Henyey–Greenstein asymmetry.
    pub g: f32,
    /// Relative index of refraction (inside / outside).
    pub eta: f32,
    dipoles: [Dipole; 3],
    tables: [RadialTable; 3],
    lookup: RdLookup,
    /// The exit lobe Sw, where the path continues after subsurface transport.
    pub exit: Material,
}

impl Subsurface {
    pub fn new(sigma_s_prime: Vec3, sigma_a: Vec3, eta: f32, g: f32) -> Self {
        let medium = Medium::new(sigma_s_prime, sigma_a, eta);
        let dipoles = [0, 1, 2].map(|c| Dipole::new(&medium, c));
        let exit = SubsurfaceExit::new(eta);
        let tables = dipoles.map(|d| RadialTable::new(&d));
        let r_max = tables.iter().map(RadialTable::r_max).fold(0.0, f32::max);
        Subsurface {
            sigma_s: Vec3A::from(sigma_s_prime) / (1.0 - g),
            sigma_a: Vec3A::from(sigma_a),
            g,
            eta,
            tables,
            lookup: RdLookup::new(&dipoles, r_max),
            dipoles,
            exit: Material::from_bsdf(Box::new(exit)),
        }
    }

    /// Rd(r) per channel: diffuse reflectance per unit area at distance `r` (scene units).
    pub fn rd(&self, r: f32) -> Spectrum {
        let [a, b, c] = self.dipoles.map(|d| d.rd(r as f64) as f32);
        Spectrum::new(a, b, c)
    }

    /// Rd at squared distance `r2` from a table (within 0.5 %; zero past the longest
    /// channel's reach): for sums over many points.
    #[inline]
    pub fn rd_lookup_sq(&self, r2: f32) -> Spectrum {
        Spectrum::from(self.lookup.rd_sq(r2))
    }

    /// The sampling table of channel `c`.
    pub fn table(&self, c: usize) -> &RadialTable {
        &self.tables[c]
    }
}

/// cos θ between the old and new direction, sampled from the Henyey–Greenstein phase function
/// with mean cosine `g` (uniform at g = 0) by inverting its CDF (pbrt-v4 §11.3.1).
pub fn hg_cos(g: f64, u: f64) -> f64 {
    if g.abs() < 1e-3 {
        1.0 - 2.0 * u
    } else {
        let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
        ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
    }
}

/// The Henyey–Greenstein phase function per steradian at cosine `cos` between the directions
/// of travel before and after scattering: (1 − g²) / (4π (1 + g² − 2g cos)^(3/2)).
#[inline]
pub fn hg(cos: f32, g: f32) -> f32 {
    let d = 1.0 + g * g - 2.0 * g * cos;
    (1.0 - g * g) / (4.0 * std::f32::consts::PI * d * d.sqrt())
}

/// A direction scattered from unit `d` by the Henyey–Greenstein phase function.
pub fn sample_hg(d: Vec3A, g: f32, u: Vec2) -> Vec3A {
    let cos = hg_cos(g as f64, u.x as f64) as f32;
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let (s, c) = (2.0 * std::f32::consts::PI * u.y).sin_cos();
    Frame::from_normal(d).to_world(Vec3A::new(sin * c, sin * s, cos))
}
