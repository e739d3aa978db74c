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
};
use crate::scene::Material;

/// Photons per task.
const PHOTONS_PER_TASK: u32 = 25_000;
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

    fn fold(&self, state: &mut Self::State, task: &TaskSpec, p: Vec<Photon>) -> Result<(), String> {
        // One stored photon per bounce at most, bounded by the depth.
        let shot = (task.end - task.start) as usize;
        if p.len() > shot * (self.settings.max_depth as usize + 1) {
            return Err(format!("{} photons stored from {shot} shot", p.len()));
        }
        match task.kind.as_str() {
            GLOBAL => state.0.extend(p),
            _ => state.1.extend(p),
        }
        Ok(())
    }

    fn finish(&self, (global, caustic): Self::State) -> Result<MapsArtifact, String> {
        let rho: Vec<_> = self
            .desc
            .materials
            .iter()
            .map(|m| Material::from_desc(&m.kind).bsdf.lambertian())
            .collect();
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
