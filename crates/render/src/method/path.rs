//! Path tracing with next-event estimation, MIS and Russian roulette (pbrt-v4 §13.4), and
//! direct lighting (the same estimator stopped after the first diffuse or glossy vertex), as
//! frame methods: frames of independent tiles. Translucent materials are rendered by the scene's
//! subsurface method; the hierarchical one adds its point-cloud pass.

use std::time::Duration;

use super::info::MethodInfo;
use super::passes::SubsurfacePass;
use super::tiles::{TileFrame, TilePartial, Tiles, execute_tile};
use super::{DynPass, Job, Method, Next, Plan, Step, TaskCtx, TaskSpec, aov, tiles};
use crate::camera::Camera;
use crate::film::Image;
use crate::integrator::PathIntegrator;

pub static PATH: MethodInfo = MethodInfo {
    name: "path",
    summary: "unidirectional path tracing with next-event estimation, MIS and Russian roulette",
    spp: "samples per pixel",
    params: &["subsurface", "sampler"],
    translucent: true,
    plan: |job| Ok(Box::new(PathMethod::plan(job, "path")?) as Box<dyn Plan>),
};

pub static DIRECT: MethodInfo = MethodInfo {
    name: "direct",
    summary: "emitted and directly reflected light only (specular chains are followed)",
    spp: "samples per pixel",
    params: &["subsurface", "sampler"],
    translucent: true,
    plan: |job| Ok(Box::new(PathMethod::plan(job, "direct")?) as Box<dyn Plan>),
};

pub struct PathMethod {
    name: &'static str,
    desc: tessera_scene::SceneDesc,
    tiles: Tiles,
    integrator: PathIntegrator,
    clouds: Option<SubsurfacePass>,
}

impl PathMethod {
    fn plan(job: &Job, name: &'static str) -> Result<Self, String> {
        let i = &job.desc.integrator;
        let integrator = if name == "direct" {
            PathIntegrator::direct_lighting(i.max_depth)
        } else {
            PathIntegrator::new(i.max_depth, i.rr_depth)
        }
        .with_subsurface(i.subsurface);
        Ok(PathMethod {
            name,
            desc: job.desc.clone(),
            tiles: Tiles::new(job)?,
            integrator,
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
