//! `bench flythrough`: a camera-only fly-through on a coordinator with local workers, twice:
//!
//! - cached: one job for every frame — the photon maps and the irradiance cache (from
//!   keyframes) are built once, frozen, and read by every frame;
//! - caching disabled: one job per frame with `reuse: false` — each frame builds its own maps
//!   and its own cache from its own camera, as a farm without pass artifacts would.
//!
//! Figures: total wall time of each; the task seconds each frame cost (passes + tiles); and
//! flicker: the frame-to-frame change of the mean radiance at fixed world points (a grid on a
//! wall the camera sees in every frame, each read where it projects in each frame), in units of
//! its noise (the standard error from the frames' own per-pixel variance).

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context;
use glam::{Vec2, Vec3A};
use serde::Serialize;
use tessera_farm::bundle::Bundle;
use tessera_farm::client::Client;
use tessera_farm::job::{FrameRange, RenderSettings};
use tessera_farm::protocol::{JobRequest, JobState, JobStatus};
use tessera_render::Scene;
use tessera_render::camera::Camera;

use super::farm::{local_coordinator, tempfile_dir};

#[derive(clap::Args)]
pub struct FlythroughArgs {
    #[arg(default_value = "scenes/interior-flythrough/scene.json")]
    pub scene: PathBuf,
    /// Local worker processes (one slot each).
    #[arg(long, default_value_t = 2)]
    pub workers: u32,
    /// Frames (default: the whole camera path).
    #[arg(long, value_parser = FrameRange::parse)]
    pub frames: Option<FrameRange>,
    /// Samples per pixel (default: the scene's).
    #[arg(long)]
    pub spp: Option<u32>,
    /// The static region: a parallelogram on a surface, "ox,oy,oz,ux,uy,uz,vx,vy,vz"
    /// (origin + s·u + t·v). A grid of its points seen in every frame is sampled in each
    /// frame where it projects, and compared frame to frame.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "0.5,1.2,4.999,3,0,0,0,1.4,0"
    )]
    pub region: Vec<f32>,
    /// Where report.json and report.md go.
    #[arg(short, long, default_value = "bench-flythrough")]
    pub output: PathBuf,
}

/// One run (cached or not).
#[derive(Debug, Serialize)]
struct Run {
    name: String,
    wall_s: f64,
    /// Task seconds of the passes (photons, records), summed over jobs.
    pass_s: f64,
    /// Task seconds per frame: its tiles plus the passes built for it (the first frame's job,
    /// when cached; each frame's own job, when not).
    frame_s: Vec<f64>,
    /// Mean luminance at the static region's points per frame, and its standard error.
    region_mean: Vec<f64>,
    region_sigma: Vec<f64>,
    /// Points of the region seen in every frame.
    region_pixels: Vec<usize>,
    /// |Δ mean| between consecutive frames over their joint σ.
    flicker_z: Vec<f64>,
}

#[derive(Debug, Serialize)]
struct Report {
    scene: String,
    frames: FrameRange,
    workers: u32,
    runs: Vec<Run>,
}

async fn wait_all(client: &Client, ids: &[i64]) -> anyhow::Result<Vec<JobStatus>> {
    let mut done = Vec::new();
    for &id in ids {
        let s = loop {
            let s = client.job(id).await?;
            if s.state.is_final() {
                break s;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        };
        anyhow::ensure!(s.state == JobState::Done, "job {id} failed: {:?}", s.error);
        done.push(s);
    }
    Ok(done)
}

/// Task seconds of a job: (passes, frame tasks per frame).
async fn task_seconds(
    client: &Client,
    id: i64,
    frames: FrameRange,
) -> anyhow::Result<(f64, Vec<f64>)> {
    let mut passes = 0.0;
    let mut tiles = vec![0.0; frames.len() as usize];
    for t in client.tasks(id).await? {
        let s = t.seconds.unwrap_or(0.0);
        if !t.spec.is_pass() {
            tiles[(t.spec.frame - frames.first) as usize] += s;
        } else {
            passes += s;
        }
    }
    Ok((passes, tiles))
}

pub async fn run(args: FlythroughArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.region.len() == 9,
        "--region: expected nine numbers: origin, edge u and edge v"
    );
    let desc = tessera_scene::load(&args.scene)?;
    let frames = args.frames.unwrap_or(FrameRange {
        first: 1,
        last: desc.frame_count(),
    });
    let dir = tempfile_dir()?;
    let (running, client) = local_coordinator(dir.join("data"), args.workers).await?;
    let (bundle, _, scene_name) = Bundle::pack_scene(&args.scene)?;
    let info = client
        .upload_bundle(bundle.to_tar().map_err(anyhow::Error::msg)?)
        .await?;
    let request = |frames: FrameRange, reuse: bool| JobRequest {
        bundle: info.hash.clone(),
        scene: scene_name.clone(),
        name: None,
        frames: Some(frames),
        settings: RenderSettings {
            spp: args.spp,
            reuse: (!reuse).then_some(false),
            ..Default::default()
        },
        priority: 0,
        require_tags: vec![],
    };

    let mut runs = Vec::new();
    let mut images = Vec::new();
    for cached in [true, false] {
        let t = Instant::now();
        let ids: Vec<i64> = if cached {
            vec![client.submit(&request(frames, true)).await?.id]
        } else {
            let mut ids = Vec::new();
            for f in frames.iter() {
                ids.push(
                    client
                        .submit(&request(FrameRange::single(f), false))
                        .await?
                        .id,
                );
            }
            ids
        };
        let jobs = wait_all(&client, &ids).await?;
        let wall_s = t.elapsed().as_secs_f64();
        let mut pass_s = 0.0;
        let mut frame_s = vec![0.0; frames.len() as usize];
        for job in &jobs {
            let (p, tiles) = task_seconds(&client, job.id, job.frames).await?;
            pass_s += p;
            let first = (job.frames.first - frames.first) as usize;
            frame_s[first] += p;
            for (i, s) in tiles.iter().enumerate() {
                frame_s[first + i] += s;
            }
        }
        let mut exrs = Vec::new();
        for f in frames.iter() {
            let job = jobs
                .iter()
                .find(|j| j.frames.first <= f && f <= j.frames.last)
                .context("a job for every frame")?;
            exrs.push(client.frame_exr(job.id, f).await?);
        }
        let name = if cached {
            "cached (one job, passes built once)"
        } else {
            "caching disabled (a job per frame, reuse off)"
        };
        crate::print(&format!(
            "{name}: {wall_s:.2} s wall for {} frames; passes {pass_s:.2} task-s; frame {} {:.2} task-s, later frames mean {:.2} task-s\n",
            frames.len(),
            frames.first,
            frame_s[0],
            mean(&frame_s[1..])
        ))?;
        runs.push(Run {
            name: name.into(),
            wall_s,
            pass_s,
            frame_s,
            region_mean: Vec::new(),
            region_sigma: Vec::new(),
            region_pixels: Vec::new(),
            flicker_z: Vec::new(),
        });
        images.push(exrs);
    }
    running.stop().await?;

    // Flicker: the static region's mean per frame, from each frame's own EXR.
    let scene = Scene::build(&desc);
    let cameras: Vec<Camera> = frames
        .iter()
        .map(|f| Camera::new(&desc.camera_at(f), &desc.film))
        .collect();
    let (w, h) = (desc.film.width, desc.film.height);
    let v = |i: usize| Vec3A::new(args.region[i], args.region[i + 1], args.region[i + 2]);
    let (origin, eu, ev) = (v(0), v(3), v(6));
    // Grid points seen (not occluded, inside the film away from its edge) in every frame.
    let seen = |camera: &Camera, p: Vec3A| {
        camera.project(p).is_some_and(|r| {
            let inside = r.x >= 2.0 && r.y >= 2.0 && r.x <= w as f32 - 2.0 && r.y <= h as f32 - 2.0;
            let ray = camera.generate_ray(r, Vec2::splat(0.5));
            let dist = (p - ray.o).length();
            inside
                && scene
                    .intersect(&ray)
                    .is_some_and(|si| (si.t - dist).abs() < 1e-3 * dist)
        })
    };
    let points: Vec<Vec3A> = (0..64)
        .flat_map(|i| (0..32).map(move |j| (i, j)))
        .map(|(i, j)| origin + eu * ((i as f32 + 0.5) / 64.0) + ev * ((j as f32 + 0.5) / 32.0))
        .filter(|&p| cameras.iter().all(|c| seen(c, p)))
        .collect();
    anyhow::ensure!(
        !points.is_empty(),
        "--region: no point of it is seen in every frame"
    );
    for (run, exrs) in runs.iter_mut().zip(&images) {
        for (exr, camera) in exrs.iter().zip(&cameras) {
            let names = ["R", "G", "B", "variance.R", "variance.G", "variance.B"];
            let (_, _, c) =
                tessera_scene::image::read_exr_channels(exr, &names).map_err(anyhow::Error::msg)?;
            let lum = |i: usize, o: usize, square: bool| {
                let k = [0.2126f64, 0.7152, 0.0722];
                (0..3)
                    .map(|ch| {
                        let k = if square { k[ch] * k[ch] } else { k[ch] };
                        k * c[o + ch][i] as f64
                    })
                    .sum::<f64>()
            };
            // Bilinear read between pixel centres: value Σ wᵢ yᵢ, variance Σ wᵢ² var yᵢ.
            let (mut sum, mut var) = (0.0, 0.0);
            for &p in &points {
                let r = camera.project(p).unwrap_or_default() - Vec2::splat(0.5);
                let (x0, y0) = (r.x.floor(), r.y.floor());
                let (fx, fy) = ((r.x - x0) as f64, (r.y - y0) as f64);
                for (dx, dy, wgt) in [
                    (0, 0, (1.0 - fx) * (1.0 - fy)),
                    (1, 0, fx * (1.0 - fy)),
                    (0, 1, (1.0 - fx) * fy),
                    (1, 1, fx * fy),
                ] {
                    let x = (x0 as i64 + dx).clamp(0, w as i64 - 1) as usize;
                    let y = (y0 as i64 + dy).clamp(0, h as i64 - 1) as usize;
                    let i = y * w as usize + x;
                    sum += wgt * lum(i, 0, false);
                    var += wgt * wgt * lum(i, 3, true);
                }
            }
            let n = points.len() as f64;
            run.region_mean.push(sum / n);
            run.region_sigma.push(var.sqrt() / n);
            run.region_pixels.push(points.len());
        }
        run.flicker_z = (1..run.region_mean.len())
            .map(|i| {
                let dm = (run.region_mean[i] - run.region_mean[i - 1]).abs();
                let s = (run.region_sigma[i].powi(2) + run.region_sigma[i - 1].powi(2)).sqrt();
                if s > 0.0 { dm / s } else { 0.0 }
            })
            .collect();
    }

    let report = Report {
        scene: args.scene.display().to_string(),
        frames,
        workers: args.workers,
        runs,
    };
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("creating {}", args.output.display()))?;
    std::fs::write(
        args.output.join("report.json"),
        serde_json::to_vec_pretty(&report)?,
    )?;
    let md = markdown(&report);
    std::fs::write(args.output.join("report.md"), &md)?;
    crate::print(&md)?;
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

fn markdown(r: &Report) -> String {
    let mut s = format!(
        "# Fly-through: {} frames {}, {} local workers\n\n| run | wall s | passes task-s | frame {} task-s | frames {}–{} mean task-s | region points | flicker z mean / max | region Δ mean % |\n|---|---:|---:|---:|---:|---:|---:|---:|\n",
        r.scene,
        r.frames,
        r.workers,
        r.frames.first,
        r.frames.first + 1,
        r.frames.last
    );
    for run in &r.runs {
        let rel: Vec<f64> = (1..run.region_mean.len())
            .map(|i| {
                100.0 * (run.region_mean[i] - run.region_mean[i - 1]).abs()
                    / run.region_mean[i - 1].abs().max(1e-12)
            })
            .collect();
        s += &format!(
            "| {} | {:.2} | {:.2} | {:.2} | {:.2} | {} | {:.2} / {:.2} | {:.3} |\n",
            run.name,
            run.wall_s,
            run.pass_s,
            run.frame_s.first().copied().unwrap_or(0.0),
            mean(run.frame_s.get(1..).unwrap_or(&[])),
            run.region_pixels.iter().min().copied().unwrap_or(0),
            mean(&run.flicker_z),
            run.flicker_z.iter().copied().fold(0.0, f64::max),
            mean(&rel)
        );
    }
    s += "\nflicker z: |mean(frame i+1) − mean(frame i)| of the radiance at the static region's points (each read where it projects in that frame) over √(σᵢ² + σᵢ₊₁²), σ the standard error of that mean from the frames' per-pixel variance; z ≈ 1 is noise (neighbouring points share pixels, so σ is an underestimate).\n";
    s
}
