//! Path tracing with next-event estimation, MIS and Russian roulette (pbrt-v4 §13.4), and
//! direct lighting (the same estimator stopped after the first diffuse or glossy vertex), as
//! frame methods: frames of independent tiles. Translucent materials are rendered by the scene's
//! subsurface method; the hierarchical one adds its point-cloud pass.

use std::time::Duration;
use tessera_scene::setting;

use std::sync::Arc;

use tessera_scene::{IntegratorDesc, SceneDesc};

use super::info::{MethodInfo, Model, PilotInfo, Sight, Transport};
use super::passes::SubsurfacePass;
use super::tiles::{TileFrame, TilePartial, Tiles, execute_tile};
use super::{DynPass, Job, Method, Next, Plan, Step, TaskCtx, TaskSpec, aov, tiles};
use crate::camera::Camera;
use crate::film::Image;
use crate::integrator::{Integrator, PathIntegrator, needs_point_clouds, subsurface_pass};
use crate::scene::Scene;

pub static PATH: MethodInfo = MethodInfo {
    name: "path",
    summary: "unidirectional path tracing with next-event estimation, MIS and Russian roulette",
    spp: "samples per pixel",
    settings: &[&setting::SUBSURFACE, &setting::SAMPLER],
    translucent: true,
    refuses: None,
    transport: Transport::Full,
    pilot: Some(PilotInfo {
        order: 0,
        model: Model::Unbiased,
        k: 16,
        sight: Sight::CameraOnly,
        photon_map: false,
        probe: None,
    }),
    per_ray: Some(|desc, scene| per_ray(Transport::Full, desc, scene)),
    payloads: |p| {
        p.method::<PathMethod>()
            .pass::<SubsurfacePass>("subsurface");
    },
    plan: |job| Ok(Box::new(PathMethod::plan(job, &PATH)?) as Box<dyn Plan>),
};

pub static DIRECT: MethodInfo = MethodInfo {
    name: "direct",
    summary: "emitted and directly reflected light only (specular chains are followed)",
    spp: "samples per pixel",
    settings: &[&setting::SUBSURFACE, &setting::SAMPLER],
    translucent: true,
    refuses: None,
    transport: Transport::Direct,
    // Chosen without a pilot where it is exact, never measured.
    pilot: None,
    per_ray: Some(|desc, scene| per_ray(Transport::Direct, desc, scene)),
    payloads: |p| {
        p.method::<PathMethod>()
            .pass::<SubsurfacePass>("subsurface");
    },
    plan: |job| Ok(Box::new(PathMethod::plan(job, &DIRECT)?) as Box<dyn Plan>),
};

/// The path tracer, or the direct-lighting estimator for [`Transport::Direct`].
pub fn estimator(transport: Transport, i: &IntegratorDesc) -> PathIntegrator {
    match transport {
        Transport::Full => PathIntegrator::new(i.max_depth, i.rr_depth),
        Transport::Direct => PathIntegrator::direct_lighting(i.max_depth),
    }
    .with_subsurface(i.subsurface)
}

/// The estimator of `transport`, with the hierarchical method's point-cloud pass run
/// in-process where the scene takes it.
fn per_ray(
    transport: Transport,
    desc: &SceneDesc,
    scene: &Scene,
) -> (Box<dyn Integrator>, Vec<String>) {
    let path = estimator(transport, &desc.integrator);
    if !needs_point_clouds(desc) {
        return (Box::new(path), Vec::new());
    }
    let clouds = subsurface_pass(desc, scene);
    let passes = clouds.summary.clone();
    (Box::new(path.with_clouds(Arc::new(clouds))), passes)
}

pub struct PathMethod {
    name: &'static str,
    desc: SceneDesc,
    tiles: Tiles,
    integrator: PathIntegrator,
    clouds: Option<SubsurfacePass>,
}

impl PathMethod {
    fn plan(job: &Job, info: &'static MethodInfo) -> Result<Self, String> {
        Ok(PathMethod {
            name: info.name,
            desc: job.desc.clone(),
            tiles: Tiles::new(job)?,
            integrator: estimator(info.transport, &job.desc.integrator),
            clouds: SubsurfacePass::plan(&job.desc),
        })
    }
}

impl Method for PathMethod {
    type Partial = TilePartial;
    type Frame = TileFrame;

    fn name(&self) -> &'static str {
        self.name
    }

    fn decisions(&self) -> Vec<String> {
        let mut out = Vec::new();
        if let Some(c) = &self.clouds {
            out.push(format!(
                "subsurface: hierarchical — a point-cloud pass of {} points before the frames",
                c.points()
            ));
        }
        out
    }

    fn passes(&self) -> Vec<&dyn DynPass> {
        self.clouds.iter().map(|c| c as &dyn DynPass).collect()
    }

    fn start(&self, frame: u32) -> Result<Step, String> {
        Ok(self.tiles.start(frame))
    }

    fn more(&self, frame: u32, state: &mut TileFrame, spp: u32) -> Option<Step> {
        self.tiles.more(frame, state, spp)
    }

    fn frame_bytes(&self) -> u64 {
        self.tiles.frame_bytes()
    }

    fn new_frame(&self, _frame: u32) -> TileFrame {
        self.tiles.new_frame()
    }

    fn execute(&self, ctx: &TaskCtx, task: &TaskSpec) -> Result<TilePartial, String> {
        let camera = Camera::new(&self.desc.camera_at(task.frame), &self.desc.film);
        let partial = match task.kind.as_str() {
            aov::KIND => TilePartial::Aov(aov::execute(
                ctx.scene,
                &camera,
                task.tile(),
                task.samples(),
            )),
            tiles::KIND => match &self.clouds {
                Some(pass) => {
                    let clouds = ctx.artifact(pass)?;
                    let integ = self.integrator.clone().with_clouds(clouds);
                    execute_tile(ctx.scene, &camera, &integ, task)
                }
                None => execute_tile(ctx.scene, &camera, &self.integrator, task),
            },
            other => return Err(format!("{} has no {other} tasks", self.name)),
        };
        ctx.progress(task.pixels() * task.samples().len() as u64);
        Ok(partial)
    }

    fn fits(&self, task: &TaskSpec, p: &TilePartial) -> Result<(), String> {
        self.tiles.fits(task, p)
    }

    fn fold(&self, state: &mut TileFrame, task: &TaskSpec, p: TilePartial) -> Result<(), String> {
        self.tiles.fold(state, task, p)
    }

    fn advance(
        &self,
        frame: u32,
        state: &mut TileFrame,
        elapsed: Duration,
    ) -> Result<Next, String> {
        Ok(self.tiles.advance(frame, state, elapsed))
    }

    fn preview(&self, _frame: u32, state: &TileFrame) -> Image {
        self.tiles.image(state)
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    /// No translucent material, no point-cloud pass, even where the scene asks for the
    /// hierarchical method.
    #[test]
    fn a_point_cloud_pass_only_for_translucent_materials() {
        let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
        let load =
            |rel: &str| tessera_scene::load(&scenes.join(rel)).unwrap_or_else(|e| panic!("{e}"));
        let mut d = load("cornell-box/scene.json");
        d.integrator.method = "path".into();
        d.integrator.subsurface = tessera_scene::SubsurfaceMethod::Hierarchical;
        let (_, passes) = super::per_ray(super::Transport::Full, &d, &crate::Scene::build(&d));
        assert!(passes.is_empty(), "{passes:?}");
    }
}
