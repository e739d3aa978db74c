//! The photon tracing pass (Jensen 2001, ch. 5).
//!
//! Photon `i` of a map is a pure function of (seed, map, i): its random numbers come from the
//! scene's sampler keyed by the map and indexed by `i` (a low-discrepancy sequence over the
//! photons with Sobol), so any split of 0..N into index ranges — one task or seven — yields the
//! same photons, and concatenating the ranges in order gives the same map.
//!
//! - A light is chosen in proportion to its power; the photon leaves it through a projection
//!   map toward the objects that can receive it (all objects for point and spot lights in the
//!   global map, the specular ones for the caustic map; area lights shoot global photons
//!   cosine-weighted over their hemisphere, lights at infinity from the disk covering the
//!   targets). The power is Φ_light · covered fraction / (p_light · N).
//! - At every hit on a surface with a non-delta lobe the photon is stored (global map), or,
//!   for the caustic map, only if every bounce before was specular (paths L S+ D), after which
//!   the caustic photon stops.
//! - Russian roulette: the BSDF-sampled throughput w (RGB) survives with probability
//!   q = max(Φ·w) / max(Φ) (capped at 1), and the power becomes Φ·w / q — the max-component
//!   form of Jensen's reflect/absorb choice, so surviving photons keep their power.

use std::ops::Range;

use glam::{UVec2, Vec2, Vec3, Vec3A};
use rayon::prelude::*;

use super::{Photon, PhotonSettings};
use crate::bsdf::TransportMode;
use crate::light::{Aim, Light, ProjectionMap, Target};
use crate::sampler::hash::hash;
use crate::sampler::{PixelSampler, Sampler};
use crate::scene::Scene;
use crate::spectrum::is_black;

/// Which map a pass shoots.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum MapKind {
    Global,
    Caustic,
    /// Every diffuse hit after the first bounce (SPPM: direct light is computed at the visible
    /// points), one pass of `photons` per iteration.
    Indirect,
}

impl MapKind {
    pub fn name(self) -> &'static str {
        match self {
            MapKind::Global => "global",
            MapKind::Caustic => "caustic",
            MapKind::Indirect => "indirect",
        }
    }
}

/// Photons per rayon job when shooting in-process (does not change the map).
const CHUNK: u32 = 4096;

/// How photons leave one light.
#[derive(Debug, Clone)]
enum LightAim {
    Everywhere,
    Projection(ProjectionMap),
    Disk(Target),
    /// Nothing the map wants can be reached from this light.
    Nothing,
}

/// Shoots the photons of one map.
pub struct Shooter<'a> {
    scene: &'a Scene,
    kind: MapKind,
    /// Photons the whole map is shot with (each carries 1/N of the power).
    count: u32,
    max_depth: u32,
    sampler: PixelSampler,
    aims: Vec<LightAim>,
}

/// The sphere around several targets.
fn bounding(targets: &[Target]) -> Option<Target> {
    let (lo, hi) = targets.iter().fold(
        (Vec3A::splat(f32::INFINITY), Vec3A::splat(f32::NEG_INFINITY)),
        |(lo, hi), t| {
            (
                lo.min(t.center - Vec3A::splat(t.radius)),
                hi.max(t.center + Vec3A::splat(t.radius)),
            )
        },
    );
    (lo.x <= hi.x).then(|| {
        let center = 0.5 * (lo + hi);
        let radius = targets
            .iter()
            .map(|t| (t.center - center).length() + t.radius)
            .fold(0.0f32, f32::max);
        Target { center, radius }
    })
}

impl<'a> Shooter<'a> {
    pub fn new(scene: &'a Scene, settings: &PhotonSettings, kind: MapKind) -> Self {
        let count = match kind {
            MapKind::Global | MapKind::Indirect => settings.photons,
            MapKind::Caustic => settings.caustic_photons,
        };
        let targets: Vec<Target> = scene
            .objects
            .iter()
            .filter(|(_, m)| kind != MapKind::Caustic || scene.material(*m).flags.specular)
            .map(|(t, _)| *t)
            .collect();
        let aims = (0..scene.lights.len() as u32)
            .map(|i| Self::aim(scene.lights.get(i), kind, &targets))
            .collect();
        Shooter {
            scene,
            kind,
            count,
            max_depth: settings.max_depth,
            sampler: PixelSampler::new(
                settings.sampler,
                hash(&[settings.seed, 0x9407_0000 + kind as u64]),
            ),
            aims,
        }
    }

    fn aim(light: &Light, kind: MapKind, targets: &[Target]) -> LightAim {
        if targets.is_empty() {
            return LightAim::Nothing;
        }
        match light.bounds() {
            // Area lights light everything around them: aiming global photons would only
            // cut their hemisphere into cells.
            Some(_)
                if kind != MapKind::Caustic
                    && matches!(light, Light::Triangle(_) | Light::Sphere(_)) =>
            {
                LightAim::Everywhere
            }
            Some(b) => {
                let cone = light.cone();
                let map = ProjectionMap::new(b.center, b.radius, targets, |dir, radius| {
                    cone.is_none_or(|(axis, half)| {
                        dir.dot(axis).clamp(-1.0, 1.0).acos() <= half + radius
                    })
                });
                if map.is_empty() {
                    LightAim::Nothing
                } else {
                    LightAim::Projection(map)
                }
            }
            None => bounding(targets).map_or(LightAim::Nothing, LightAim::Disk),
        }
    }

    /// Fraction of the sphere of directions each light's projection map covers (1 where the
    /// light is not aimed by one), for logs.
    pub fn coverage(&self) -> Vec<f32> {
        self.aims
            .iter()
            .map(|a| match a {
                LightAim::Projection(m) => m.covered_fraction(),
                LightAim::Nothing => 0.0,
                _ => 1.0,
            })
            .collect()
    }

    /// The photons stored by photons `range` of the map, in index order.
    pub fn shoot(&self, range: Range<u32>) -> Vec<Photon> {
        let mut out = Vec::new();
        let mut sampler = self.sampler.clone();
        for i in range {
            self.trace(i, &mut sampler, &mut out);
        }
        out
    }

    /// [`Self::shoot`] in chunks on the rayon pool; the same photons in the same order.
    pub fn shoot_parallel(&self, range: Range<u32>) -> Vec<Photon> {
        let chunks: Vec<Range<u32>> = range
            .clone()
            .step_by(CHUNK as usize)
            .map(|s| s..(s.saturating_add(CHUNK)).min(range.end))
            .collect();
        let parts: Vec<Vec<Photon>> = chunks.into_par_iter().map(|r| self.shoot(r)).collect();
        parts.concat()
    }

    /// Traces photon `index`, appending what it stores to `out`.
    fn trace(&self, index: u32, sampler: &mut PixelSampler, out: &mut Vec<Photon>) {
        let scene = self.scene;
        sampler.start_pixel_sample(UVec2::ZERO, index);
        let u = sampler.get_4d();
        let Some((li, pmf)) = scene.lights.choose(u.x) else {
            return;
        };
        let aim = match &self.aims[li as usize] {
            LightAim::Everywhere => Aim::Everywhere,
            LightAim::Projection(m) => Aim::Projection(m),
            LightAim::Disk(t) => Aim::Disk(*t),
            LightAim::Nothing => return,
        };
        let u_dir = sampler.get_2d();
        let Some(e) = scene
            .lights
            .get(li)
            .sample_le(&aim, Vec2::new(u.y, u.z), u_dir, u.w)
        else {
            return;
        };
        let mut power = e.flux / (pmf * self.count as f32);
        let mut ray = e.ray;
        let mut specular_path = true;
        for depth in 0..self.max_depth {
            let Some(si) = scene.intersect(&ray) else {
                return;
            };
            let material = scene.material(si.material);
            let wo = -ray.d;
            if material.flags.smooth {
                let store = match self.kind {
                    MapKind::Global => true,
                    MapKind::Caustic => depth > 0 && specular_path,
                    MapKind::Indirect => depth > 0,
                };
                if store {
                    let n = si.ns_toward(wo);
                    out.push(Photon {
                        p: Vec3::from(si.p),
                        power: Vec3::from(power),
                        wi: Vec3::from(wo),
                        n: Vec3::from(n),
                        material: si.material,
                    });
                }
                if self.kind == MapKind::Caustic {
                    return;
                }
            }
            if material.is_black() {
                return;
            }
            let frame = material.frame(&si, wo);
            let wo_local = frame.to_local(wo);
            let u = sampler.get_4d();
            let Some(bs) = material.bsdf_at(&si).sample(
                wo_local,
                u.x,
                Vec2::new(u.y, u.z),
                TransportMode::Importance,
            ) else {
                return;
            };
            let wi = frame.to_world(bs.wi);
            // Directions on opposite sides for the geometry and the shading frame would leak
            // light through the surface.
            if (wo.dot(si.ng) * wi.dot(si.ng) > 0.0) != (wo_local.z * bs.wi.z > 0.0) {
                return;
            }
            let scattered = power * bs.weight();
            let q = (scattered.max_element() / power.max_element()).min(1.0);
            if q.is_nan() || q <= 0.0 || u.w >= q || is_black(scattered) {
                return;
            }
            power = scattered / q;
            specular_path &= bs.specular;
            ray = si.spawn(wi);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::analyze;
    use crate::photon::PhotonSettings;

    fn scene(name: &str) -> (tessera_scene::SceneDesc, Scene) {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../scenes")
            .join(name)
            .join("scene.json");
        let desc = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let scene = Scene::build(&desc);
        (desc, scene)
    }

    fn settings(desc: &tessera_scene::SceneDesc) -> PhotonSettings {
        PhotonSettings::resolve(desc, &analyze(desc)).0
    }

    #[test]
    fn a_map_is_bit_identical_whether_shot_as_one_task_or_seven() {
        let (desc, scene) = scene("cornell-glass");
        let mut s = settings(&desc);
        s.photons = 7000;
        s.caustic_photons = 7000;
        for kind in [MapKind::Global, MapKind::Caustic] {
            let shooter = Shooter::new(&scene, &s, kind);
            let whole = shooter.shoot(0..7000);
            // Seven uneven tasks, shot by different shooters (as on different workers).
            let bounds = [0, 1, 999, 1000, 3500, 3501, 6000, 7000];
            let mut split = Vec::new();
            for w in bounds.windows(2) {
                split.extend(Shooter::new(&scene, &s, kind).shoot(w[0]..w[1]));
            }
            assert!(!whole.is_empty(), "{kind:?}");
            assert_eq!(whole, split, "{kind:?}");
            assert_eq!(whole, shooter.shoot_parallel(0..7000), "{kind:?}");
            let a = crate::photon::PhotonMap::build(whole, 7000);
            let b = crate::photon::PhotonMap::build(split, 7000);
            assert_eq!(a, b);
            let rho = |m: u32| scene.material(m).bsdf.lambertian();
            let ra = crate::photon::radiance_photons(&a, &rho, &s);
            assert!(kind == MapKind::Caustic || !ra.is_empty());
            assert_eq!(ra, crate::photon::radiance_photons(&b, &rho, &s));
        }
    }

    #[test]
    fn photons_carry_the_power_that_reaches_each_surface() {
        // The white furnace: a white (ρ = 1) unit sphere inside a black sphere of radius 3
        // that emits L = 1 from both sides. The white sphere receives E = πL all over, so the
        // photons stored on it carry 4π·π W in total, and its reflected radiance is ρE/π = 1.
        let (desc, scene) = scene("hard/white-furnace");
        let mut s = settings(&desc);
        s.photons = 400_000;
        let photons = Shooter::new(&scene, &s, MapKind::Global).shoot_parallel(0..s.photons);
        let on_white: Vec<&Photon> = photons.iter().filter(|p| p.p.length() < 1.5).collect();
        // A ninth of the inward half hits the white sphere: (1/3)² for cosine emission from a
        // concentric sphere of radius 3. Relative noise of the total ≈ 1/√n.
        let n = on_white.len() as f32;
        let expected_n = 400_000.0 / 2.0 / 9.0;
        assert!(
            (n / expected_n - 1.0).abs() < 5.0 / expected_n.sqrt(),
            "{n}"
        );
        let total: f32 = on_white.iter().map(|p| p.power.x).sum();
        let want = 4.0 * std::f32::consts::PI * std::f32::consts::PI;
        assert!(
            (total / want - 1.0).abs() < 5.0 / n.sqrt(),
            "{total} vs {want}"
        );
        // (The radiance estimate from these photons is checked on a plane, where it has no
        // curvature bias: photon::tests.)
    }

    #[test]
    fn caustic_photons_are_aimed_at_the_glass_and_land_below_it() {
        let (desc, scene) = scene("cornell-glass");
        let mut s = settings(&desc);
        s.caustic_photons = 20_000;
        let caustic = Shooter::new(&scene, &s, MapKind::Caustic).shoot(0..s.caustic_photons);
        assert!(
            caustic.len() > 5000,
            "the projection map aims caustic photons at the glass: {} of 20000 stored",
            caustic.len()
        );
        // Light through glass lands on the floor and the lower walls, not on the ceiling.
        let low = caustic.iter().filter(|p| p.p.y < 30.0).count();
        assert!(low as f32 > 0.9 * caustic.len() as f32, "{low}");
    }
}
