//! Jensen's photon maps as a pass: index ranges of the global, then the caustic map, each
//! photon a function of (seed, map, index) alone, so the ranges concatenated in order and
//! balanced are the maps one process would shoot. Key: geometry, materials, lights and the
//! photon settings — never the camera, the film or the samples.

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use tessera_scene::SceneDesc;

use super::{hash_scene, hex, index_ranges};
use crate::method::{Pass, TaskCtx, TaskSpec};
use crate::photon::{
    KdTree, MapKind, Photon, PhotonMap, PhotonMaps, PhotonSettings, RadiancePhoton, Shooter,
    radiance_photons,
};
use crate::scene::Material;
use crate::spectrum::Spectrum;

/// Photons per task.
const PHOTONS_PER_TASK: u32 = 25_000;
/// The share of the global map whose finish [`PhotonsPass::finish_estimate`] times.
const FINISH_SAMPLE: f64 = 1.0 / 32.0;
const GLOBAL: &str = "global_photons";
const CAUSTIC: &str = "caustic_photons";

#[derive(Debug, Clone)]
pub struct PhotonsPass {
    desc: SceneDesc,
    pub settings: PhotonSettings,
    key: String,
}

/// A map as stored: the balanced tree's photons and split axes, and the photons emitted.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapParts {
    pub emitted: u32,
    pub photons: Vec<Photon>,
    pub axes: Vec<u8>,
}

/// The maps as stored, trees balanced, so readers need not balance again.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MapsArtifact {
    pub global: MapParts,
    pub caustic: MapParts,
    pub radiance: Vec<RadiancePhoton>,
    pub radiance_axes: Vec<u8>,
}

impl PhotonsPass {
    pub fn new(desc: &SceneDesc, settings: PhotonSettings) -> Self {
        let mut h = Sha256::new();
        h.update(b"tessera photons v2\0");
        hash_scene(&mut h, desc);
        let s = &settings;
        h.update(format!(
            "{} {} {} {} {:?} {}",
            s.photons, s.caustic_photons, s.max_depth, s.seed, s.sampler, desc.integrator.method
        ));
        PhotonsPass {
            desc: desc.clone(),
            settings,
            key: hex(h),
        }
    }
}

/// A sample of a global map to come, for timing its finish.
struct FinishSample {
    /// Every m-th photon of those shot so far.
    photons: Vec<Photon>,
    /// The settings with the search radius widened by the inverse square root of
    /// `fraction`, so that a search holds as many photons as in the whole map.
    settings: PhotonSettings,
    /// The sample's share of the whole map.
    fraction: f64,
    /// Photons the whole map is expected to store.
    total: f64,
}

impl PhotonsPass {
    /// A sample of about [`FINISH_SAMPLE`] of the global map, from `global`, the photons that
    /// the share `share` of the pass's tasks stored (global tasks come first); `None` before
    /// any.
    fn finish_sample(&self, global: &[Photon], share: f64) -> Option<FinishSample> {
        let s = &self.settings;
        let emitted = (share * (s.photons as f64 + s.caustic_photons as f64)).min(s.photons as f64);
        if global.is_empty() || emitted <= 0.0 {
            return None;
        }
        let total = global.len() as f64 * s.photons as f64 / emitted;
        let step = ((global.len() as f64 / (FINISH_SAMPLE * total)).round() as usize).max(1);
        let photons: Vec<Photon> = global.iter().step_by(step).copied().collect();
        let fraction = photons.len() as f64 / total;
        let settings = PhotonSettings {
            photons: ((s.photons as f64 * fraction).ceil() as u32).max(1),
            radius: s.radius * (1.0 / fraction).sqrt() as f32,
            ..*s
        };
        Some(FinishSample {
            photons,
            settings,
            fraction,
            total,
        })
    }

    /// Each material's Lambertian reflectance, where it has one (for the radiance photons).
    fn rho(&self) -> Vec<Option<Spectrum>> {
        self.desc
            .materials
            .iter()
            .map(|m| Material::from_desc(&m.kind).bsdf.lambertian())
            .collect()
    }
}

fn parts(m: &PhotonMap) -> MapParts {
    MapParts {
        emitted: m.emitted,
        photons: m.tree.photons().to_vec(),
        axes: m.tree.axes().to_vec(),
    }
}

fn map(p: MapParts) -> Result<PhotonMap, String> {
    Ok(PhotonMap {
        tree: KdTree::from_parts(p.photons, p.axes)?,
        emitted: p.emitted,
    })
}

impl Pass for PhotonsPass {
    type Partial = Vec<Photon>;
    /// The global map's photons and the caustic map's, in index order.
    type State = (Vec<Photon>, Vec<Photon>);
    type Artifact = MapsArtifact;
    type Loaded = PhotonMaps;

    fn name(&self) -> &'static str {
        "photons"
    }

    fn key(&self) -> &str {
        &self.key
    }

    fn tasks(&self, step: u32) -> Vec<TaskSpec> {
        let mut out = index_ranges(GLOBAL, step, self.settings.photons, PHOTONS_PER_TASK, 0);
        let first = out.len() as u32;
        out.extend(index_ranges(
            CAUSTIC,
            step,
            self.settings.caustic_photons,
            PHOTONS_PER_TASK,
            first,
        ));
        out
    }

    fn execute(&self, ctx: &TaskCtx, task: &TaskSpec) -> Result<Vec<Photon>, String> {
        let kind = match task.kind.as_str() {
            GLOBAL => MapKind::Global,
            CAUSTIC => MapKind::Caustic,
            other => return Err(format!("a {other} task is not one of the photon pass's")),
        };
        let photons = Shooter::new(ctx.scene, &self.settings, kind).shoot(task.start..task.end);
        ctx.progress(task.end as u64 - task.start as u64);
        Ok(photons)
    }

    fn start(&self) -> Self::State {
        (Vec::new(), Vec::new())
    }

    fn state_bytes(&self, (global, caustic): &Self::State) -> u64 {
        ((global.capacity() + caustic.capacity()) * std::mem::size_of::<Photon>()) as u64
    }

    /// One stored photon per bounce at most, bounded by the depth.
    fn fits(&self, task: &TaskSpec, p: &Vec<Photon>) -> Result<(), String> {
        let shot = task.end.saturating_sub(task.start) as usize;
        if p.len() > shot * (self.settings.max_depth as usize + 1) {
            return Err(format!("{} photons stored from {shot} shot", p.len()));
        }
        Ok(())
    }

    fn fold(&self, state: &mut Self::State, task: &TaskSpec, p: Vec<Photon>) -> Result<(), String> {
        Pass::fits(self, task, &p)?;
        match task.kind.as_str() {
            GLOBAL => state.0.extend(p),
            _ => state.1.extend(p),
        }
        Ok(())
    }

    fn finish(&self, (global, caustic): Self::State) -> Result<MapsArtifact, String> {
        let rho = self.rho();
        let maps = PhotonMaps::build(global, caustic, &self.settings, &|m| {
            rho.get(m as usize).copied().flatten()
        });
        Ok(MapsArtifact {
            global: parts(&maps.global),
            caustic: parts(&maps.caustic),
            radiance: maps.radiance.photons().to_vec(),
            radiance_axes: maps.radiance.axes().to_vec(),
        })
    }

    /// The finish (balancing the trees, the radiance photons' searches) of a sample of the
    /// global photons shot so far ([`PhotonsPass::finish_sample`]), timed and scaled to the
    /// whole map: balancing grows as n log n; each radiance photon is a search for the k
    /// nearest photons within a radius that holds about k (the sample's is widened to), whose
    /// cost grows with k, not with the map, so their time grows as n. The caustic map
    /// (balanced only) is left out: a lower bound.
    fn finish_estimate(&self, (global, _): &Self::State, share: f64) -> Option<f64> {
        let sample = self.finish_sample(global, share)?;
        let rho = self.rho();
        // Timed on one thread (a sample's few milliseconds split over a pool measure its
        // threads waking more than its work), then shared among the pool's threads as the
        // finish shares it.
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .ok()?;
        let (balanced, searched) = one.install(|| {
            let start = std::time::Instant::now();
            let map = PhotonMap::build(sample.photons, sample.settings.photons);
            let balanced = start.elapsed().as_secs_f64();
            let radiance = radiance_photons(
                &map,
                &|m| rho.get(m as usize).copied().flatten(),
                &sample.settings,
            );
            let searched = start.elapsed().as_secs_f64() - balanced;
            drop((map, radiance));
            (balanced, searched)
        });
        let threads = rayon::current_num_threads() as f64;
        let (balanced, searched) = (balanced / threads, searched / threads);
        let n = (sample.fraction * sample.total).max(2.0);
        let balance = balanced / sample.fraction * sample.total.max(2.0).ln() / n.ln();
        Some(balance + searched / sample.fraction)
    }

    fn load(&self, a: MapsArtifact) -> Result<PhotonMaps, String> {
        Ok(PhotonMaps {
            global: map(a.global)?,
            caustic: map(a.caustic)?,
            radiance: KdTree::from_parts(a.radiance, a.radiance_axes)?,
        })
    }

    fn describe(&self, a: &MapsArtifact) -> String {
        format!(
            "photon maps: {} global photons stored of {} shot, {} caustic of {}",
            a.global.photons.len(),
            a.global.emitted,
            a.caustic.photons.len(),
            a.caustic.emitted
        )
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3A;

    use super::*;
    use crate::analysis::analyze;
    use crate::photon::{KdTree, Shooter};
    use crate::scene::Scene;

    /// The finish is timed on a sample of the first tasks' photons searched in widened radii:
    /// it predicts the whole map's size, and each of its searches holds about as many photons
    /// as one in the whole map (so costs as much).
    #[test]
    fn the_finish_sample_searches_as_many_photons_as_the_whole_map() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../scenes/cornell-box/scene.json");
        let mut desc = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        desc.integrator.method = "photon".into();
        let mut scene = Scene::build(&desc);
        scene.set_settings(&desc);
        let (settings, _) = PhotonSettings::resolve(&desc, &analyze(&desc));
        let pass = PhotonsPass::new(&desc, settings);
        let shoot = |n: u32| Shooter::new(&scene, &settings, MapKind::Global).shoot(0..n);
        let all = shoot(settings.photons);
        let quarter = settings.photons / 4;
        let first = shoot(quarter);
        let share = quarter as f64 / (settings.photons + settings.caustic_photons) as f64;
        let sample = pass
            .finish_sample(&first, share)
            .expect("photons were stored");
        let ratio = sample.total / all.len() as f64;
        assert!(
            (0.95..1.05).contains(&ratio),
            "total {} of {}",
            sample.total,
            all.len()
        );
        let ratio = sample.photons.len() as f64 / (FINISH_SAMPLE * all.len() as f64);
        assert!(
            (0.8..1.25).contains(&ratio),
            "{} sampled",
            sample.photons.len()
        );

        let count = |tree: &KdTree<Photon>, q: &Photon, r: f32| {
            let mut n = 0u64;
            tree.within(q.p.into(), Vec3A::from(q.n), 0.0, r * r, &mut |_, _| n += 1);
            n
        };
        let (whole, part) = (KdTree::build(all.clone()), KdTree::build(sample.photons));
        let (mut in_whole, mut in_part) = (0u64, 0u64);
        for q in all.iter().step_by(97) {
            in_whole += count(&whole, q, settings.radius);
            in_part += count(&part, q, sample.settings.radius);
        }
        let ratio = in_part as f64 / in_whole as f64;
        assert!(
            (0.8..1.25).contains(&ratio),
            "photons within the widened radius {in_part}, within the radius in the whole map {in_whole}"
        );
    }
}
