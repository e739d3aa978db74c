//! Jensen & Buhler's point-cloud pass for translucent materials rendered by the hierarchical
//! method: points on every translucent surface (placed from the scene description alone, so
//! every process places the same ones), their irradiance path traced in index ranges, folded
//! into the cloud's octrees. Key: geometry, materials, lights and the irradiance paths'
//! settings — never the camera.

use sha2::{Digest, Sha256};
use tessera_scene::{SceneDesc, SubsurfaceMethod};

use super::{hash_scene, hex, index_ranges};
use crate::integrator::PathIntegrator;
use crate::integrator::subsurface::hierarchical::{IRRADIANCE_SAMPLES, Placement, PointClouds};
use crate::method::{Pass, TaskCtx, TaskSpec};
use crate::spectrum::Spectrum;

/// Points per task.
const POINTS_PER_TASK: u32 = 8192;
const KIND: &str = "subsurface_points";

#[derive(Debug, Clone)]
pub struct SubsurfacePass {
    desc: SceneDesc,
    key: String,
    points: u32,
}

impl SubsurfacePass {
    /// The pass `desc` needs: `None` unless it renders translucent materials by the
    /// hierarchical method.
    pub fn plan(desc: &SceneDesc) -> Option<Self> {
        if desc.integrator.subsurface != SubsurfaceMethod::Hierarchical
            || desc.translucent_materials().is_empty()
        {
            return None;
        }
        let mut h = Sha256::new();
        h.update(b"tessera subsurface v1\0");
        hash_scene(&mut h, desc);
        let i = &desc.integrator;
        h.update(format!(
            "{} {} {} {}",
            i.max_depth, i.rr_depth, i.seed, IRRADIANCE_SAMPLES
        ));
        Some(SubsurfacePass {
            desc: desc.clone(),
            key: hex(h),
            points: u32::try_from(Placement::new(desc).len()).unwrap_or(u32::MAX),
        })
    }

    pub fn points(&self) -> u32 {
        self.points
    }
}

impl Pass for SubsurfacePass {
    /// Irradiance of each point of the task's range, W/m² (RGB).
    type Partial = Vec<[f32; 3]>;
    type State = Vec<[f32; 3]>;
    type Artifact = Vec<[f32; 3]>;
    type Loaded = PointClouds;

    fn name(&self) -> &'static str {
        "subsurface"
    }

    fn key(&self) -> &str {
        &self.key
    }

    fn tasks(&self, step: u32) -> Vec<TaskSpec> {
        index_ranges(KIND, step, self.points, POINTS_PER_TASK, 0)
    }

    fn execute(&self, ctx: &TaskCtx, task: &TaskSpec) -> Result<Self::Partial, String> {
        let placement = ctx.memo("placement", || Ok(Placement::new(&self.desc)))?;
        let range = task.start as usize..task.end as usize;
        if range.end > placement.len() || range.start > range.end {
            return Err(format!(
                "points {}..{} of a cloud of {}",
                range.start,
                range.end,
                placement.len()
            ));
        }
        let i = &self.desc.integrator;
        let tracer = PathIntegrator::new(i.max_depth, i.rr_depth);
        let e = placement.irradiance(&self.desc, ctx.scene, range, &|si, sub, s, stats| {
            tracer.exit_irradiance(ctx.scene, si, sub, s, stats)
        });
        ctx.progress(task.end as u64 - task.start as u64);
        Ok(e.iter().map(|v| v.to_array()).collect())
    }

    fn state_bytes(&self, state: &Self::State) -> u64 {
        (state.capacity() * std::mem::size_of::<[f32; 3]>()) as u64
    }

    fn start(&self) -> Self::State {
        Vec::with_capacity(self.points as usize)
    }

    fn fits(&self, task: &TaskSpec, p: &Self::Partial) -> Result<(), String> {
        if p.len() != task.end.saturating_sub(task.start) as usize {
            return Err(format!(
                "irradiance of {} points for points {}..{}",
                p.len(),
                task.start,
                task.end
            ));
        }
        Ok(())
    }

    fn fold(
        &self,
        state: &mut Self::State,
        task: &TaskSpec,
        p: Self::Partial,
    ) -> Result<(), String> {
        if state.len() != task.start as usize || p.len() != (task.end - task.start) as usize {
            return Err(format!(
                "irradiance of {} points for points {}..{} after {}",
                p.len(),
                task.start,
                task.end,
                state.len()
            ));
        }
        state.extend(p);
        Ok(())
    }

    fn finish(&self, state: Self::State) -> Result<Self::Artifact, String> {
        if state.len() != self.points as usize {
            return Err(format!(
                "{} of the cloud's {} points have their irradiance",
                state.len(),
                self.points
            ));
        }
        Ok(state)
    }

    fn load(&self, e: Self::Artifact) -> Result<PointClouds, String> {
        let e: Vec<Spectrum> = e.into_iter().map(Spectrum::from).collect();
        Placement::new(&self.desc).with_irradiance(&self.desc, &e)
    }

    fn describe(&self, e: &Self::Artifact) -> String {
        format!(
            "subsurface point cloud: {} points, {} irradiance paths each",
            e.len(),
            IRRADIANCE_SAMPLES
        )
    }
}
