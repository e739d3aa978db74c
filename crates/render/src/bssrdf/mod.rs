//! Subsurface scattering: light that enters a translucent object at one point and leaves at
//! another (issue 7).
//!
//! - [`dipole`]: Jensen et al. 2001's diffusion profile Rd(r) and its measured media;
//! - [`profile`]: Rd tabulated per channel for sampling exit radii;
//! - [`random_walk`]: a volumetric random walk in a semi-infinite slab, the dipole's own test.
//!
//! These are functions of distance and medium alone; finding entry and exit points in a scene
//! (probe rays, point clouds, the walk inside a mesh) is [`crate::integrator::subsurface`]'s.
//!
//! A translucent material is a smooth dielectric interface ([`crate::bsdf::SmoothDielectric`])
//! whose transmitted light, instead of refracting, is carried by the BSSRDF
//! S(p_o, ω_o; p_i, ω_i) = (1 − Fr(cos θo)) Rd(|p_o − p_i|) Sw(ω_i): the Fresnel
//! transmittance at entry is the probability of sampling transmission, Rd is the dipole's,
//! and Sw ([`crate::bsdf::SubsurfaceExit`]) is the directional distribution at exit. The
//! dipole methods add the single-scattering term S⁽¹⁾ to this diffusion term, as Jensen et
//! al. 2001 do; the random walk holds every order of scattering by itself.

pub mod dipole;
pub mod profile;
pub mod random_walk;

use glam::{Vec3, Vec3A};

use crate::spectrum::Spectrum;
use dipole::{Dipole, Medium};
use profile::{RadialTable, RdLookup};

/// What a translucent material carries beyond its interface: the medium (per scene unit), its
/// dipoles and sampling tables.
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
}

impl Subsurface {
    pub fn new(sigma_s_prime: Vec3, sigma_a: Vec3, eta: f32, g: f32) -> Self {
        let medium = Medium::new(sigma_s_prime, sigma_a, eta);
        let dipoles = [0, 1, 2].map(|c| Dipole::new(&medium, c));
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
