//! A method added from outside the core, with nothing else edited: registered from this file
//! only, it is listed, planned, rendered in-process, measured by `auto`'s pilot and run
//! through the farm (a coordinator and a real worker in this process) as the built-in ones are.
//!
//! The method, `whole-frame`, is the path tracer's per-ray estimator with each frame one task:
//! a real estimator of the same image, so its mean is checked against the built-in `path`'s.

mod common;

use std::path::Path;
use std::time::Duration;

use common::{coordinator_in, cornell, local_frame, local_render, run_to_the_end, submit};
use tessera_farm::job::RenderSettings;
use tessera_farm::protocol::JobState;
use tessera_render::camera::Camera;
use tessera_render::film::{Image, SampleRange, Tile};
use tessera_render::integrator::PathIntegrator;
use tessera_render::method::auto::pilot::{self, Goal};
use tessera_render::method::{
    Finished, Job, Method, MethodInfo, Model, Next, PilotInfo, Plan, Sight, Step, TaskCtx,
    TaskSpec, Transport,
};
use tessera_scene::SceneDesc;

const NAME: &str = "whole-frame";
const KIND: &str = "frame";

static WHOLE_FRAME: MethodInfo = MethodInfo {
    name: NAME,
    summary: "the path tracer's estimator, each frame one task (a test's method)",
    spp: "samples per pixel",
    settings: &[],
    translucent: false,
    refuses: None,
    transport: Transport::Full,
    // Measured among the first, whatever the pilot spends: it traces from the camera only.
    pilot: Some(PilotInfo {
        order: 0,
        model: Model::Unbiased,
        k: 4,
        sight: Sight::CameraOnly,
        photon_map: false,
        probe: None,
    }),
    per_ray: None,
    payloads: |p| {
        p.method::<WholeFrame>();
    },
    plan: |job| Ok(Box::new(WholeFrame::plan(job)) as Box<dyn Plan>),
};

struct WholeFrame {
    desc: SceneDesc,
    integrator: PathIntegrator,
}

/// Every pixel's mean and the variance of that mean, row-major.
type Pixels = Vec<([f32; 3], [f32; 3])>;

impl WholeFrame {
    fn plan(job: &Job) -> Self {
        let i = &job.desc.integrator;
        WholeFrame {
            desc: job.desc.clone(),
            integrator: PathIntegrator::new(i.max_depth, i.rr_depth),
        }
    }

    fn film(&self) -> Tile {
        Tile {
            x0: 0,
            y0: 0,
            x1: self.desc.film.width,
            y1: self.desc.film.height,
        }
    }

    fn image(&self, pixels: &Pixels) -> Image {
        let mut image = Image::new(self.desc.film.width, self.desc.film.height);
        for (p, (rgb, variance)) in image.pixels.iter_mut().zip(pixels) {
            p.rgb = *rgb;
            p.variance = *variance;
        }
        image
    }
}

impl Method for WholeFrame {
    type Partial = Pixels;
    type Frame = Pixels;

    fn name(&self) -> &'static str {
        NAME
    }
    fn decisions(&self) -> Vec<String> {
        vec![format!("{NAME}: one task per frame")]
    }
    fn start(&self, frame: u32) -> Result<Step, String> {
        let spp = self.desc.integrator.spp.max(1);
        Ok(Step::tasks(vec![
            TaskSpec::new(KIND, frame, 0, 0)
                .with_rect(self.film())
                .with_range(0, spp),
        ]))
    }
    fn new_frame(&self, _frame: u32) -> Pixels {
        Vec::new()
    }
    fn frame_bytes(&self) -> u64 {
        self.film().pixel_count() as u64 * 24
    }
    fn execute(&self, ctx: &TaskCtx, task: &TaskSpec) -> Result<Pixels, String> {
        if task.kind != KIND {
            return Err(format!("{NAME} has no {} tasks", task.kind));
        }
        let camera = Camera::new(&self.desc.camera_at(task.frame), &self.desc.film);
        let range: SampleRange = task.samples();
        let (sums, _) = tessera_render::render::render_tile(
            ctx.scene,
            &camera,
            &self.integrator,
            task.tile(),
            range,
        );
        let image = Image::from_tiles(self.desc.film.width, self.desc.film.height, &[sums]);
        ctx.progress(task.pixels() * range.len() as u64);
        Ok(image.pixels.iter().map(|p| (p.rgb, p.variance)).collect())
    }
    fn fits(&self, task: &TaskSpec, p: &Pixels) -> Result<(), String> {
        let want = task.pixels() as usize;
        if p.len() != want {
            return Err(format!("expected {want} pixels, got {}", p.len()));
        }
        Ok(())
    }
    fn fold(&self, state: &mut Pixels, _: &TaskSpec, p: Pixels) -> Result<(), String> {
        *state = p;
        Ok(())
    }
    fn advance(&self, _frame: u32, state: &mut Pixels, _: Duration) -> Result<Next, String> {
        Ok(Next::Done(Finished {
            image: self.image(state),
            stats: Default::default(),
            metadata: Vec::new(),
            estimated_rel_mse: None,
            pixels_s: None,
            fixed_s: 0.0,
        }))
    }
    fn preview(&self, _frame: u32, state: &Pixels) -> Image {
        self.image(state)
    }
}

fn register() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| tessera_render::method::register(&WHOLE_FRAME).expect("registers"));
}

fn settings(method: &str) -> RenderSettings {
    RenderSettings {
        integrator: Some(method.into()),
        size: Some([48, 36]),
        spp: Some(16),
        ..Default::default()
    }
}

/// The image's mean radiance (all channels) and that mean's standard deviation, from the
/// pixels' variances (independent pixels).
fn mean_and_sigma(image: &Image) -> (f64, f64) {
    let n = (image.pixels.len() * 3) as f64;
    let sum: f64 = image.pixels.iter().flat_map(|p| p.rgb).map(f64::from).sum();
    let var: f64 = image
        .pixels
        .iter()
        .flat_map(|p| p.variance)
        .map(f64::from)
        .sum();
    (sum / n, var.sqrt() / n)
}

#[test]
fn a_registered_method_is_listed_planned_rendered_and_refused_where_it_cannot_render() {
    register();
    assert!(tessera_render::method::names().contains(&NAME));
    assert_eq!(
        tessera_render::method::lookup(NAME).map(|m| m.name),
        Ok(NAME)
    );
    let taken = tessera_render::method::register(&WHOLE_FRAME).expect_err("taken");
    assert!(taken.contains("taken"), "{taken}");

    let (_, plan, ours) = local_render(&settings(NAME));
    assert_eq!(plan.method(), NAME);
    let (_, _, path) = local_render(&settings("path"));
    let (a, sa) = mean_and_sigma(&ours.image);
    let (b, sb) = mean_and_sigma(&path.image);
    // The same estimator with the same samples per pixel, tiles cut otherwise: equal means
    // within their noise.
    let sigma = (sa * sa + sb * sb).sqrt();
    assert!(a > 0.0 && sigma > 0.0, "mean {a}, σ {sigma}");
    assert!(
        (a - b).abs() < 4.0 * sigma,
        "{NAME} {a} against path {b}, σ {sigma}"
    );

    // It says it renders no translucent material: a scene with one is refused for it, before
    // planning, by the core's one rule.
    let mut desc = tessera_scene::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/marble-skin/scene.json"),
    )
    .expect("scene");
    desc.integrator.method = NAME.into();
    let err = tessera_render::method::plan(&Job::new(desc, 1))
        .err()
        .expect("refused");
    assert!(err.contains(NAME) && err.contains("translucent"), "{err}");
}

/// `auto`'s pilot measures it among its first candidates, with the built-in ones.
#[test]
fn auto_measures_a_registered_method() {
    register();
    let mut desc = tessera_scene::load(&cornell()).expect("scene");
    (desc.film.width, desc.film.height) = (48, 36);
    desc.integrator.spp = 16;
    let mut scene = tessera_render::Scene::build(&desc);
    let selection =
        pilot::select(&desc, &mut scene, 1, Goal::Error(1e-3), 2).expect("the pilot runs");
    eprintln!("{}", selection.choice.report.join("\n"));
    let measured: Vec<&str> = selection
        .measurements
        .iter()
        .map(|m| m.label.as_str())
        .collect();
    assert!(
        measured.contains(&NAME),
        "{measured:?} {:#?}",
        selection.choice.report
    );
    assert!(measured.contains(&"path"), "{measured:?}");
    let ours = selection
        .measurements
        .iter()
        .find(|m| m.label == NAME)
        .expect("measured");
    assert!(ours.rel_var > 0.0 && ours.sample_s > 0.0, "{ours:?}");
    assert!(
        selection.choice.report.iter().any(|l| l.contains(NAME)),
        "{:#?}",
        selection.choice.report
    );
}

/// A coordinator and a real worker in this process render a job of the registered method:
/// the frame is the one this process renders, byte for byte.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_farm_runs_a_registered_method() {
    register();
    let dir = tempfile::tempdir().expect("temp dir");
    let (running, url, client) = coordinator_in(dir.path()).await;

    let listed: Vec<String> = client
        .methods()
        .await
        .expect("methods")
        .into_iter()
        .map(|m| m.name)
        .collect();
    assert!(listed.iter().any(|n| n == NAME), "{listed:?}");

    let settings = settings(NAME);
    let job = submit(&client, &cornell(), settings.clone()).await;
    let status = run_to_the_end(&url, &client, job.id, 2).await;
    assert_eq!(status.state, JobState::Done, "{:?}", status.error);
    let farm = client.frame_exr(job.id, 1).await.expect("frame");
    assert!(
        farm == local_frame(&settings, dir.path()),
        "the farm's frame is not the one this process renders"
    );
    running.stop().await.expect("stop");
}
