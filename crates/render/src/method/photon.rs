//! Photon mapping with final gathering (Jensen 2001, ch. 9) and Ward's irradiance cache as a
//! frame method: the photon maps and the irradiance cache are passes (built once, read by
//! every frame and every later job with the same keys), then frames of independent tiles.

use std::time::Duration;
use tessera_scene::setting;

use super::info::{MethodInfo, Model, PilotInfo, Sight, Transport};
use super::passes::{PhotonsPass, RecordsPass};
use super::tiles::{TileFrame, TilePartial, Tiles, execute_tile};
use super::{DynPass, Job, Method, Next, Plan, Step, TaskCtx, TaskSpec, aov, tiles};
use crate::analysis::analyze;
use crate::camera::Camera;
use crate::film::Image;
use crate::integrator::PhotonIntegrator;
use crate::photon::PhotonSettings;
use tessera_scene::SceneDesc;

pub static PHOTON: MethodInfo = MethodInfo {
    name: "photon",
    summary: "photon mapping (Jensen): global and caustic maps, final gathering through Ward's irradiance cache",
    spp: "samples per pixel",
    settings: &[
        &setting::SAMPLER,
        &setting::PHOTONS,
        &setting::CAUSTIC_PHOTONS,
        &setting::PHOTON_K,
        &setting::CAUSTIC_K,
        &setting::RADIUS,
        &setting::CAUSTIC_RADIUS,
        &setting::GATHER_RAYS,
        &setting::CAUSTIC_FILTER,
        &setting::IRRADIANCE_CACHE,
        &setting::IC_ACCURACY,
        &setting::IC_SPACING,
        &setting::IC_KEYFRAME_STEP,
        &setting::IC_GATHER_RAYS,
    ],
    translucent: false,
    refuses: None,
    transport: Transport::Full,
    pilot: Some(PilotInfo {
        order: 4,
        model: Model::Biased,
        k: 4,
        sight: Sight::All,
        photon_map: true,
        probe: None,
    }),
    per_ray: Some(|desc, scene| {
        let (p, why) = PhotonIntegrator::prepare(desc, scene, &analyze(desc), 1..=1);
        (Box::new(p), why)
    }),
    payloads: |p| {
        p.method::<PhotonMethod>()
            .pass::<PhotonsPass>("photons")
            .pass::<RecordsPass>("records");
    },
    plan: |job| Ok(Box::new(PhotonMethod::plan(job)?) as Box<dyn Plan>),
};

pub struct PhotonMethod {
    desc: SceneDesc,
    tiles: Tiles,
    photons: PhotonsPass,
    records: Option<RecordsPass>,
    decisions: Vec<String>,
}

impl PhotonMethod {
    fn plan(job: &Job) -> Result<Self, String> {
        let (settings, decisions) = PhotonSettings::resolve(&job.desc, &analyze(&job.desc));
        let photons = PhotonsPass::new(&job.desc, settings);
        let cache = SceneDesc {
            film: job.cache_film.unwrap_or(job.desc.film),
            ..job.desc.clone()
        };
        let records = RecordsPass::plan(&cache, &photons, job.frames.clone());
        Ok(PhotonMethod {
            desc: job.desc.clone(),
            tiles: Tiles::new(job)?,
            photons,
            records,
            decisions,
        })
    }

    fn integrator(&self, ctx: &TaskCtx) -> Result<PhotonIntegrator, String> {
        let maps = ctx.artifact(&self.photons)?;
        let cache = match &self.records {
            Some(r) => Some(ctx.artifact(r)?),
            None => None,
        };
        Ok(PhotonIntegrator::new(
            self.photons.settings,
            self.desc.integrator.rr_depth,
            maps,
            cache,
        ))
    }
}

impl Method for PhotonMethod {
    type Partial = TilePartial;
    type Frame = TileFrame;

    fn name(&self) -> &'static str {
        "photon"
    }

    fn decisions(&self) -> Vec<String> {
        let mut out = self.decisions.clone();
        out.push(match &self.records {
            Some(r) => format!(
                "irradiance cache: built from keyframes {:?}, frozen before any frame renders",
                r.keyframes
            ),
            None => "irradiance cache: off — final gathering at every camera sample".into(),
        });
        out
    }

    fn passes(&self) -> Vec<&dyn DynPass> {
        let mut out: Vec<&dyn DynPass> = vec![&self.photons];
        if let Some(r) = &self.records {
            out.push(r);
        }
        out
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
            tiles::KIND => execute_tile(ctx.scene, &camera, &self.integrator(ctx)?, task),
            other => return Err(format!("photon has no {other} tasks")),
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
