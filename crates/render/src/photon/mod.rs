//! Photon maps (Jensen, "A Practical Guide to Global Illumination using Photon Maps", 2000;
//! "Realistic Image Synthesis Using Photon Mapping", 2001).
//!
//! - [`shoot`]: the photon tracing pass, photon by photon, each a pure function of (seed, map,
//!   photon index), so a map is the same however its index range is split into farm tasks.
//! - [`PhotonMap`]: the photons of one map in a balanced kd-tree, and the radiance estimate
//!   L(x, ωo) ≈ Σ f(x, ωp, ωo) ΔΦp · w(dp) / (π r²) over the k nearest photons within a
//!   disc-flattened search of radius ≤ r_max.
//! - [`PhotonSettings`]: Mental Ray's knobs (photon count, accuracy k, radius), resolved from
//!   the scene where the scene leaves them out.

pub mod hashgrid;
pub mod kdtree;
pub mod shoot;

use glam::{Vec3, Vec3A};
use rayon::prelude::*;
use tessera_scene::{PhotonFilter, SamplerType, SceneDesc};

use crate::analysis::Analysis;
use crate::bsdf::TransportMode;
use crate::math::{INV_PI, PI};
use crate::scene::{Material, Scene, SurfaceInteraction};
use crate::spectrum::Spectrum;

pub use kdtree::{KdTree, Knn, Photon, Positioned};
pub use shoot::{MapKind, Shooter};

/// The search ellipsoid is this thin along the surface normal, relative to its radius: the
/// distance is |Δ|² + FLATTEN·(Δ·n)² with FLATTEN = 1/t² − 1 for t = 1/5 (Jensen 2001 §7.1:
/// compressing the sphere into a disc keeps photons of a nearby, differently oriented surface
/// out of the estimate).
pub const FLATTEN: f32 = 24.0;

/// Default photons emitted for the global map, and for the caustic map where it has work.
pub const DEFAULT_PHOTONS: u32 = 200_000;
pub const DEFAULT_CAUSTIC_PHOTONS: u32 = 200_000;
/// Default nearest photons per estimate ("accuracy"): global, caustic.
pub const DEFAULT_K: u32 = 64;
pub const DEFAULT_CAUSTIC_K: u32 = 64;
/// Default final-gather rays per camera sample (without an irradiance cache) and per record.
pub const DEFAULT_GATHER_RAYS: u32 = 32;
pub const DEFAULT_RECORD_RAYS: u32 = 256;
/// Photons stored per photon emitted in a closed room of albedo ≈ 0.5: 1/(1 − ρ).
const STORED_PER_EMITTED: f32 = 2.0;

/// Pixels between irradiance-cache candidates when a scene does not say.
const DEFAULT_SPACING: u32 = 4;

/// Photon-mapping settings with every knob decided: what determines the maps and the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhotonSettings {
    /// Photons emitted for the global map.
    pub photons: u32,
    /// Photons emitted for the caustic map (0: none).
    pub caustic_photons: u32,
    pub k: u32,
    pub caustic_k: u32,
    /// Largest search radii, scene units.
    pub radius: f32,
    pub caustic_radius: f32,
    /// Final-gather rays per gather point.
    pub gather_rays: u32,
    pub caustic_filter: PhotonFilter,
    pub irradiance_cache: Option<CacheSettings>,
    pub max_depth: u32,
    pub seed: u64,
    pub sampler: SamplerType,
}

/// Irradiance-cache settings with every knob decided.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CacheSettings {
    /// Ward's a.
    pub accuracy: f32,
    /// Pre-render pixels between record candidates.
    pub spacing: u32,
    pub keyframe_step: u32,
    /// Hemisphere rays per record.
    pub gather_rays: u32,
}

/// The radius within which `k` of `stored` photons spread evenly over `area` are expected,
/// doubled: a search limit that lets the k-nearest adapt without reaching across the room.
fn expected_radius(k: u32, stored: f32, area: f32) -> f32 {
    2.0 * (k as f32 * area / (PI * stored.max(1.0))).sqrt()
}

impl PhotonSettings {
    /// Resolves the scene's knobs: counts and k from the defaults, a caustic map only where
    /// `analysis` found caustic paths, radii from the scene's surface area and photon counts.
    /// Returns the settings and what was decided, with reasons.
    /// A function of the description alone (no BVH), so a coordinator can plan and hash
    /// passes without building the scene.
    pub fn resolve(desc: &SceneDesc, analysis: &Analysis) -> (Self, Vec<String>) {
        let d = &desc.integrator.photon;
        let mut why = Vec::new();
        let photons = d.photons.unwrap_or(DEFAULT_PHOTONS);
        let specular: Vec<bool> = desc
            .materials
            .iter()
            .map(|m| crate::bsdf::from_desc(&m.kind).flags().specular)
            .collect();
        let is_specular = |m: u32| specular.get(m as usize).copied().unwrap_or(false);
        let has_caustic_targets = desc.meshes.iter().any(|m| is_specular(m.material))
            || desc.spheres.iter().any(|s| is_specular(s.material));
        let caustic_photons = match d.caustic_photons {
            Some(n) => n,
            None if analysis.caustics && has_caustic_targets => DEFAULT_CAUSTIC_PHOTONS,
            None => 0,
        };
        if caustic_photons == 0 {
            why.push(if d.caustic_photons == Some(0) {
                "caustic photon map: none (caustic_photons = 0)".to_string()
            } else {
                "caustic photon map: none — no specular surface can focus light onto a diffuse one"
                    .to_string()
            });
        }
        let k = d.k.unwrap_or(DEFAULT_K);
        let caustic_k = d.caustic_k.unwrap_or(DEFAULT_CAUSTIC_K);
        let area = (desc.meshes.iter().map(|m| m.area()).sum::<f64>()
            + desc.spheres.iter().map(|s| s.area()).sum::<f64>())
        .max(f64::MIN_POSITIVE) as f32;
        let radius = d.radius.unwrap_or_else(|| {
            let r = expected_radius(k, photons as f32 * STORED_PER_EMITTED, area);
            why.push(format!(
                "photon search radius: {r:.4} scene units — twice the radius holding {k} of {photons}×{STORED_PER_EMITTED} photons spread over the scene's {area:.3} units²"
            ));
            r
        });
        // Caustic photons gather where they are focused; the limit is the global one scaled to
        // the caustic count.
        let caustic_radius = d.caustic_radius.unwrap_or_else(|| {
            expected_radius(caustic_k, caustic_photons.max(1) as f32, area).min(radius)
        });
        let irradiance_cache = d.irradiance_cache.map(|c| CacheSettings {
            accuracy: c.accuracy.unwrap_or(0.2),
            spacing: c.spacing.unwrap_or(DEFAULT_SPACING),
            keyframe_step: c.keyframe_step.unwrap_or(4),
            gather_rays: c.gather_rays.unwrap_or(DEFAULT_RECORD_RAYS),
        });
        let settings = PhotonSettings {
            photons,
            caustic_photons,
            k,
            caustic_k,
            radius,
            caustic_radius,
            gather_rays: d.gather_rays.unwrap_or(DEFAULT_GATHER_RAYS),
            caustic_filter: d.caustic_filter,
            irradiance_cache,
            max_depth: desc.integrator.max_depth,
            seed: desc.integrator.seed,
            sampler: desc.integrator.sampler,
        };
        (settings, why)
    }
}

/// One photon map: photons in a kd-tree, and how many were emitted to make it.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PhotonMap {
    pub tree: KdTree,
    pub emitted: u32,
}

impl PhotonMap {
    /// The map of photons shot with indices 0..`emitted`, given in index order.
    pub fn build(photons: Vec<Photon>, emitted: u32) -> Self {
        PhotonMap {
            tree: KdTree::build(photons),
            emitted,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.tree.is_empty()
    }

    /// Reflected radiance toward `wo` at `si` (material `material`) from the `k` nearest
    /// photons within `max_radius`, weighted by `filter` (Jensen 2001 eq. 7.6 and §7.2). The
    /// area is that of the disc of the k-th photon, or of the whole search if fewer were found.
    pub fn radiance(
        &self,
        si: &SurfaceInteraction,
        material: &Material,
        wo: Vec3A,
        k: u32,
        max_radius: f32,
        filter: PhotonFilter,
    ) -> Spectrum {
        if self.tree.is_empty() {
            return Spectrum::ZERO;
        }
        let mut knn = Knn::<{ kdtree::MAX_K }>::new(k as usize, max_radius * max_radius);
        self.tree.nearest(si.p, si.ns, FLATTEN, &mut knn);
        if knn.found().is_empty() {
            return Spectrum::ZERO;
        }
        // The disc: the k-th photon's distance, or the search limit if fewer were found.
        let r2 = knn.max_d2;
        let frame = material.frame(si, wo);
        let wo_local = frame.to_local(wo);
        let bsdf = material.bsdf_at(si);
        let r = r2.sqrt();
        let mut sum = Spectrum::ZERO;
        for &(d2, i) in knn.found() {
            let ph = self.tree.get(i);
            let wi = Vec3A::from(ph.wi);
            let f = bsdf.eval(wo_local, frame.to_local(wi), TransportMode::Radiance);
            let w = match filter {
                PhotonFilter::Box => 1.0,
                PhotonFilter::Cone => 1.0 - d2.sqrt() / r,
                PhotonFilter::Gaussian => gaussian_weight(d2, r2),
            };
            sum += f * Vec3A::from(ph.power) * w;
        }
        // Each filter divided by its integral over the disc, so a uniform density is read
        // back exactly.
        let norm = INV_PI
            / r2
            / match filter {
                PhotonFilter::Box => 1.0,
                // ∫ (1 − d/r) dA = πr²/3.
                PhotonFilter::Cone => 1.0 / 3.0,
                PhotonFilter::Gaussian => GAUSSIAN_INTEGRAL,
            };
        sum * norm
    }
}

const GAUSS_ALPHA: f32 = 0.918;
const GAUSS_BETA: f32 = 1.953;

/// Pavicic's Gaussian (Jensen 2001 eq. 7.9): α[1 − (1 − e^(−β d²/2r²)) / (1 − e^(−β))],
/// α = 0.918, β = 1.953.
fn gaussian_weight(d2: f32, r2: f32) -> f32 {
    GAUSS_ALPHA
        * (1.0 - (1.0 - (-GAUSS_BETA * d2 / (2.0 * r2)).exp()) / (1.0 - (-GAUSS_BETA).exp()))
}

/// ∫ gaussian_weight dA over the disc of radius r, in units of πr²: with s = d²/r²,
/// α[1 − (1 − (2/β)(1 − e^(−β/2))) / (1 − e^(−β))] ≈ 0.531. Jensen's formula as printed is
/// not normalised to the disc (it would read a uniform density back 47 % low); we divide by
/// this.
const GAUSSIAN_INTEGRAL: f32 = {
    // e^(−β/2) and e^(−β) for β = 1.953, to f32 precision (const fn has no exp).
    let e_half = 0.376_627_f32;
    let e_full = 0.141_847_9_f32;
    GAUSS_ALPHA * (1.0 - (1.0 - (2.0 / GAUSS_BETA) * (1.0 - e_half)) / (1.0 - e_full))
};

/// Outgoing radiance precomputed at a global photon on a Lambertian surface (Christensen,
/// "Faster Photon Map Global Illumination", 1999): final gathering reads the nearest one
/// instead of making a k-nearest density estimate per gather ray.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[repr(C)]
pub struct RadiancePhoton {
    pub p: Vec3,
    /// Unit normal, on the lit side.
    pub n: Vec3,
    /// Radiance leaving the surface, ρ/π · E (W sr⁻¹ m⁻², RGB).
    pub lo: Vec3,
}

impl Positioned for RadiancePhoton {
    #[inline]
    fn position(&self) -> Vec3 {
        self.p
    }
}

/// Every this-many-th global photon (in the balanced order) gets a radiance photon.
pub const RADIANCE_STRIDE: usize = 4;

/// A radiance photon serves a gather point whose normal is within this cosine of its own.
const RADIANCE_NORMAL_COS: f32 = 0.7;

/// Radiance photons over `global`: at every [`RADIANCE_STRIDE`]-th photon resting on a
/// material `rho` calls Lambertian, E from its k nearest photons arriving on its side (same
/// search as [`PhotonMap::radiance`]) and Lo = ρE/π. In parallel, in order: deterministic.
pub fn radiance_photons(
    global: &PhotonMap,
    rho: &(dyn Fn(u32) -> Option<Spectrum> + Sync),
    s: &PhotonSettings,
) -> KdTree<RadiancePhoton> {
    let photons = global.tree.photons();
    let out: Vec<RadiancePhoton> = (0..photons.len())
        .into_par_iter()
        .step_by(RADIANCE_STRIDE)
        .filter_map(|i| {
            let ph = &photons[i];
            let rho = rho(ph.material)?;
            let n = Vec3A::from(ph.n);
            let mut knn = Knn::<{ kdtree::MAX_K }>::new(s.k as usize, s.radius * s.radius);
            global.tree.nearest(ph.p.into(), n, FLATTEN, &mut knn);
            let r2 = knn.max_d2;
            let mut flux = Spectrum::ZERO;
            for &(_, j) in knn.found() {
                let q = global.tree.get(j);
                if Vec3A::from(q.wi).dot(n) > 0.0 {
                    flux += Vec3A::from(q.power);
                }
            }
            let e = flux * (INV_PI / r2);
            Some(RadiancePhoton {
                p: ph.p,
                n: ph.n,
                lo: Vec3::from(rho * e * INV_PI),
            })
        })
        .collect();
    KdTree::build(out)
}

/// The global and caustic maps of a scene, and the radiance photons over the global one.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PhotonMaps {
    pub global: PhotonMap,
    pub caustic: PhotonMap,
    pub radiance: KdTree<RadiancePhoton>,
}

impl PhotonMaps {
    /// The maps of the photons of each, given in index order (as [`Shooter::shoot`] ranges
    /// concatenate), and their radiance photons; `rho` gives a material's Lambertian
    /// reflectance.
    pub fn build(
        global: Vec<Photon>,
        caustic: Vec<Photon>,
        settings: &PhotonSettings,
        rho: &(dyn Fn(u32) -> Option<Spectrum> + Sync),
    ) -> PhotonMaps {
        let global = PhotonMap::build(global, settings.photons);
        let radiance = radiance_photons(&global, rho, settings);
        PhotonMaps {
            global,
            caustic: PhotonMap::build(caustic, settings.caustic_photons),
            radiance,
        }
    }

    /// Shoots both maps in-process, in chunks on the rayon pool: the same photons a farm's
    /// pass tasks would shoot, concatenated in index order.
    pub fn shoot(scene: &Scene, settings: &PhotonSettings) -> PhotonMaps {
        let shoot = |kind: MapKind, count: u32| {
            Shooter::new(scene, settings, kind).shoot_parallel(0..count)
        };
        PhotonMaps::build(
            shoot(MapKind::Global, settings.photons),
            shoot(MapKind::Caustic, settings.caustic_photons),
            settings,
            &|m| scene.material(m).bsdf.lambertian(),
        )
    }

    /// Radiance leaving `si` toward `wo`, as a final-gather ray reads it: the nearest radiance
    /// photon facing the same way where the surface is Lambertian (and one is near), else the
    /// global map's estimate with the BSDF.
    pub fn gather_radiance(
        &self,
        si: &SurfaceInteraction,
        material: &Material,
        wo: Vec3A,
        s: &PhotonSettings,
    ) -> Spectrum {
        if material.bsdf.lambertian().is_some() && !self.radiance.is_empty() {
            let n = si.ns_toward(wo);
            let mut knn = Knn::<8>::new(8, s.radius * s.radius);
            self.radiance.nearest(si.p, n, FLATTEN, &mut knn);
            let best = knn
                .found()
                .iter()
                .filter(|&&(_, i)| Vec3A::from(self.radiance.get(i).n).dot(n) > RADIANCE_NORMAL_COS)
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            if let Some(&(_, i)) = best {
                return Vec3A::from(self.radiance.get(i).lo);
            }
        }
        self.global
            .radiance(si, material, wo, s.k, s.radius, PhotonFilter::Box)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filters_integrate_to_the_disc_area() {
        // ∫ w(d) dA over the unit disc, by the midpoint rule in d: box π, cone π/3, Gaussian ≈ π.
        let n = 100_000;
        let (mut cone, mut gauss) = (0.0f64, 0.0f64);
        for i in 0..n {
            let d = (i as f64 + 0.5) / n as f64;
            let ring = 2.0 * std::f64::consts::PI * d / n as f64;
            cone += (1.0 - d) * ring;
            gauss += gaussian_weight((d * d) as f32, 1.0) as f64 * ring;
        }
        let pi = std::f64::consts::PI;
        assert!((cone - pi / 3.0).abs() < 1e-6, "{cone}");
        assert!(
            (gauss / pi - GAUSSIAN_INTEGRAL as f64).abs() < 1e-5,
            "{}",
            gauss / pi
        );
        assert!(((-GAUSS_BETA / 2.0).exp() - 0.376_627).abs() < 1e-6);
        assert!(((-GAUSS_BETA).exp() - 0.141_847_9).abs() < 1e-6);
    }

    /// Photons on a jittered grid over the plane z = 0, E W/m² in all, arriving from +z.
    fn plane(e: f32, spacing: f32, half: i32) -> Vec<Photon> {
        let mut out = Vec::new();
        for i in -half..half {
            for j in -half..half {
                let h = crate::sampler::hash::hash(&[i as u64, j as u64]);
                let jx = crate::sampler::hash::u32_to_unit(h as u32) - 0.5;
                let jy = crate::sampler::hash::u32_to_unit((h >> 32) as u32) - 0.5;
                out.push(Photon {
                    p: glam::Vec3::new((i as f32 + jx) * spacing, (j as f32 + jy) * spacing, 0.0),
                    power: glam::Vec3::splat(e * spacing * spacing),
                    wi: glam::Vec3::new(0.3, 0.0, 1.0).normalize(),
                    n: glam::Vec3::Z,
                    material: 0,
                });
            }
        }
        out
    }

    #[test]
    fn every_filter_reads_a_uniform_irradiance_back() {
        // E = 2 W/m² on a white Lambertian plane: L = ρE/π = 2/π. With k photons the estimate
        // is a ratio of sums over ~k photons; on a jittered grid its error is a boundary
        // effect of order 1/√k, which over 100 points averages well below 2 %.
        let map = PhotonMap::build(plane(2.0, 0.01, 100), 40_000);
        let white = crate::scene::Material::from_desc(&tessera_scene::MaterialKind::Diffuse {
            albedo: glam::Vec3::ONE,
        });
        for filter in [
            PhotonFilter::Box,
            PhotonFilter::Cone,
            PhotonFilter::Gaussian,
        ] {
            let mut sum = 0.0;
            for i in 0..100 {
                let h = crate::sampler::hash::hash(&[i, 5]);
                let x = (crate::sampler::hash::u32_to_unit(h as u32) - 0.5) * 1.0;
                let y = (crate::sampler::hash::u32_to_unit((h >> 32) as u32) - 0.5) * 1.0;
                let p = Vec3A::new(x, y, 0.0);
                let si = SurfaceInteraction {
                    p,
                    p_error: Vec3A::ZERO,
                    t: 1.0,
                    ng: Vec3A::Z,
                    ns: Vec3A::Z,
                    material: 0,
                    light: crate::scene::NO_LIGHT,
                    uv: [glam::Vec2::ZERO; 2],
                    uv_width: [0.0; 2],
                    interior: 0.0,
                };
                sum += map.radiance(&si, &white, Vec3A::Z, 200, 1.0, filter).x;
            }
            let mean = sum / 100.0;
            let want = 2.0 * INV_PI;
            assert!(
                (mean / want - 1.0).abs() < 0.02,
                "{filter:?}: {mean} vs {want}"
            );
        }
    }
}
