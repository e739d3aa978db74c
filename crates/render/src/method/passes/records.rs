//! Ward's irradiance cache as a pass: the records made by final gathering over the photon
//! maps at the candidates of every keyframe's pre-render, one task per tile of candidates,
//! concatenated in (keyframe, tile) order. Frozen before any frame renders (docs/src/design/overview.md: artifacts
//! are frozen). Key: the photon maps' key, the gather settings, the film size and the
//! keyframes' cameras.

use sha2::{Digest, Sha256};
use tessera_scene::SceneDesc;

use super::hex;
use super::photons::PhotonsPass;
use crate::camera::Camera;
use crate::integrator::{PhotonIntegrator, RayStats, keyframes, record_tiles};
use crate::irradiance::{IrradianceCache, Record};
use crate::method::{Pass, TaskCtx, TaskSpec};

const KIND: &str = "records";

#[derive(Debug, Clone)]
pub struct RecordsPass {
    desc: SceneDesc,
    photons: PhotonsPass,
    key: String,
    /// Frames whose cameras make the records.
    pub keyframes: Vec<u32>,
    accuracy: f32,
}

impl RecordsPass {
    /// The cache of a job rendering `frames` with photon maps `photons`; `None` without one.
    pub fn plan(
        desc: &SceneDesc,
        photons: &PhotonsPass,
        frames: std::ops::RangeInclusive<u32>,
    ) -> Option<Self> {
        let s = &photons.settings;
        let ic = s.irradiance_cache?;
        let keyframes = keyframes(frames, ic.keyframe_step);
        let mut h = Sha256::new();
        h.update(b"tessera records v1\0");
        h.update(crate::method::Pass::key(photons));
        h.update(format!(
            "{:?} {} {} {} {} {} {:?} {}x{}",
            s.irradiance_cache,
            s.k,
            s.radius,
            s.gather_rays,
            s.caustic_k,
            s.caustic_radius,
            s.caustic_filter,
            desc.film.width,
            desc.film.height
        ));
        for &f in &keyframes {
            h.update(format!("{f} {:?}", desc.camera_at(f)));
        }
        Some(RecordsPass {
            desc: desc.clone(),
            photons: photons.clone(),
            key: hex(h),
            keyframes,
            accuracy: ic.accuracy,
        })
    }
}

impl Pass for RecordsPass {
    type Partial = Vec<Record>;
    type State = Vec<Record>;
    type Artifact = Vec<Record>;
    type Loaded = IrradianceCache;

    fn name(&self) -> &'static str {
        "irradiance_cache"
    }

    fn key(&self) -> &str {
        &self.key
    }

    /// Every tile of every keyframe's candidate grid; `start` holds the keyframe.
    fn tasks(&self, step: u32) -> Vec<TaskSpec> {
        let d = &self.desc;
        let tiles = record_tiles(&self.photons.settings, d.film.width, d.film.height);
        let mut out = Vec::new();
        for &frame in &self.keyframes {
            for &t in &tiles {
                let i = out.len() as u32;
                out.push(
                    TaskSpec::new(KIND, 0, step, i)
                        .with_rect(t)
                        .with_range(frame, frame),
                );
            }
        }
        out
    }

    fn execute(&self, ctx: &TaskCtx, task: &TaskSpec) -> Result<Vec<Record>, String> {
        let maps = ctx.artifact(&self.photons)?;
        let integ = PhotonIntegrator::new(
            self.photons.settings,
            self.desc.integrator.rr_depth,
            maps,
            None,
        );
        let frame = task.start;
        let camera = Camera::new(&self.desc.camera_at(frame), &self.desc.film);
        let records = integ.record_pass(
            ctx.scene,
            &camera,
            task.tile(),
            frame,
            &mut RayStats::default(),
        );
        ctx.progress(task.pixels());
        Ok(records)
    }

    fn start(&self) -> Self::State {
        Vec::new()
    }

    fn state_bytes(&self, state: &Self::State) -> u64 {
        (state.capacity() * std::mem::size_of::<Record>()) as u64
    }

    /// A task's keyframe pixels make as many records as the cache's error bound asks for:
    /// any count fits; each record must be finite to be looked up.
    fn fits(&self, _: &TaskSpec, p: &Vec<Record>) -> Result<(), String> {
        match p.iter().position(|r| !r.is_finite()) {
            Some(i) => Err(format!("irradiance record {i} has a non-finite value")),
            None => Ok(()),
        }
    }

    fn fold(&self, state: &mut Self::State, _: &TaskSpec, p: Vec<Record>) -> Result<(), String> {
        state.extend(p);
        Ok(())
    }

    fn finish(&self, state: Self::State) -> Result<Vec<Record>, String> {
        Ok(state)
    }

    fn load(&self, records: Vec<Record>) -> Result<IrradianceCache, String> {
        Ok(IrradianceCache::build(records, self.accuracy))
    }

    fn describe(&self, records: &Vec<Record>) -> String {
        format!(
            "irradiance cache: {} records (a = {}) from {} keyframe{}",
            records.len(),
            self.accuracy,
            self.keyframes.len(),
            if self.keyframes.len() == 1 { "" } else { "s" }
        )
    }
}
