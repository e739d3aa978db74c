//! SPPM on the farm: a frame's iterations one after another, each iteration's photons as
//! parallel tasks.
//!
//! Hachisuka & Jensen's per-pixel radii make iteration t+1 depend on iteration t, so a frame's
//! iterations run in sequence; within one, the photon chunks of
//! [`sppm::PHOTONS_PER_CHUNK`] are tasks:
//! - a [`TaskKind::Sppm`] task (frame f, iteration t = `sample_start`, photons `x0..x1` of the
//!   iteration) traces every pixel's camera path of iteration t (a worker does this once per
//!   iteration and keeps it for its other chunks), shoots its chunk, gathers it at the visible
//!   points within the radii left by iteration t−1 (from the coordinator: `GET
//!   /v1/jobs/{id}/frames/{f}/sppm/{t}/radii`), and returns (M, Φ) of the pixels it reached;
//!   chunk 0 also returns every pixel's direct light and film-filter weight, and the camera
//!   paths' counters;
//! - when an iteration's tasks are all done, the coordinator folds them in chunk order into the
//!   frame's [`SppmState`] (f64, a file beside the job, replaced by rename), writes the radii
//!   for the next iteration and queues it; after the last it writes the frame.
//!
//! The sums, their order and the state are those of [`sppm::render`] in one process, so the
//! farm's frame is byte for byte `tessera render --integrator sppm`'s.

use tessera_render::RayStats;
use tessera_render::integrator::sppm::{
    self, CameraPass, PixelSum, Sppm, SppmSettings, SppmState, VisiblePoints,
};
use tessera_render::photon::PhotonSettings;
use tessera_render::spectrum::Spectrum;
use tessera_scene::SceneDesc;

use crate::job::{Prepared, RenderSettings, TaskKind, TaskSpec};
use crate::passes::{Reader, put_f32s};

/// Photon indices are `u32`: every iteration's photons must have one.
const MAX_PHOTON_INDEX: u64 = u32::MAX as u64;

/// Checks that a job's SPPM settings can run on the farm.
pub fn check(desc: &SceneDesc, settings: &RenderSettings) -> Result<(), String> {
    if settings.target_error.is_some() {
        return Err(
            "target_error: sppm refines every pixel each iteration; give spp (its iterations) instead"
                .into(),
        );
    }
    let photons = sppm::photons_per_iteration(desc);
    if photons == 0 {
        return Err(
            "integrator.photon_map.photons: sppm needs at least 1 photon per iteration".into(),
        );
    }
    let total = desc.integrator.spp as u64 * photons as u64;
    if total > MAX_PHOTON_INDEX {
        return Err(format!(
            "spp: sppm's iterations × photons per iteration must stay below 2^32 (photon indices), got {} × {photons}",
            desc.integrator.spp
        ));
    }
    Ok(())
}

/// The settings of a job's (settings-applied) scene.
pub fn settings(desc: &SceneDesc) -> (PhotonSettings, SppmSettings) {
    SppmSettings::resolve(desc, &tessera_render::analysis::analyze(desc))
}

/// The tasks of iteration `t` of `frame`: one per photon chunk, in fold order.
pub fn iteration_tasks(desc: &SceneDesc, frame: u32, t: u32) -> Vec<TaskSpec> {
    sppm::chunks(sppm::photons_per_iteration(desc))
        .into_iter()
        .enumerate()
        .map(|(i, c)| TaskSpec {
            kind: TaskKind::Sppm,
            frame,
            tile_index: i as u32,
            x0: c.start,
            y0: 0,
            x1: c.end,
            y1: 0,
            sample_start: t,
            sample_end: t + 1,
        })
        .collect()
}

/// The image metadata SPPM adds (the same in `tessera render`).
pub fn metadata(s: &SppmSettings) -> Vec<(String, String)> {
    vec![("sppm".to_string(), s.describe())]
}

/// The SPPM of a prepared scene (its settings were resolved when it was built).
fn sppm_of(prepared: &Prepared) -> Result<Sppm<'_>, String> {
    let (photon, s) = prepared
        .sppm
        .as_ref()
        .ok_or("an sppm task for a job whose integrator is not sppm")?;
    Ok(Sppm::new(&prepared.scene, photon, *s))
}

/// Every pixel's camera path of iteration `t` of `frame`, on this thread.
pub fn visible_points(prepared: &Prepared, frame: u32, t: u32) -> Result<VisiblePoints, String> {
    let camera = prepared.camera(frame);
    let pixels = prepared.desc.film.width * prepared.desc.film.height;
    Ok(sppm_of(prepared)?.visible_points(&camera, t, 0..pixels))
}

/// What an SPPM task returns.
#[derive(Debug, Clone, PartialEq)]
pub struct Output {
    /// (pixel, M, Φ) of the pixels the chunk reached, in pixel order.
    pub sums: Vec<PixelSum>,
    /// Chunk 0 only: every pixel's emitted and direct light and filter weight, and the
    /// camera paths' counters.
    pub camera: Option<CameraPass>,
}

/// Runs an SPPM task on this thread with the iteration's visible points and squared radii.
pub fn execute(
    prepared: &Prepared,
    vps: &VisiblePoints,
    r2: &[f32],
    task: &TaskSpec,
) -> Result<Output, String> {
    if task.kind != TaskKind::Sppm {
        return Err(format!("a {} task is not an sppm task", task.kind.as_str()));
    }
    let pixels = prepared.desc.film.width * prepared.desc.film.height;
    if r2.len() != pixels as usize || vps.camera.ld.len() != pixels as usize {
        return Err(format!(
            "sppm task: radii and visible points for {} and {} pixels, the film has {pixels}",
            r2.len(),
            vps.camera.ld.len()
        ));
    }
    let sppm = sppm_of(prepared)?;
    let photons = sppm.shoot(task.sample_start, task.x0..task.x1, false);
    Ok(Output {
        sums: sppm.gather(vps, r2, &photons, 0..pixels),
        camera: (task.x0 == 0).then(|| vps.camera.clone()),
    })
}

const OUTPUT_MAGIC: &[u8; 4] = b"TSPM";
const STATE_MAGIC: &[u8; 4] = b"TSST";
const RADII_MAGIC: &[u8; 4] = b"TSPR";

fn put_stats(b: &mut Vec<u8>, s: &RayStats) {
    for v in [s.rays, s.samples, s.nonfinite] {
        b.extend_from_slice(&v.to_le_bytes());
    }
}

fn read_stats(r: &mut Reader) -> Result<RayStats, String> {
    Ok(RayStats {
        rays: r.u64()?,
        samples: r.u64()?,
        nonfinite: r.u64()?,
    })
}

fn put_f64s(b: &mut Vec<u8>, v: &[f64]) {
    for x in v {
        b.extend_from_slice(&x.to_le_bytes());
    }
}

/// Little-endian: count, then (pixel u32, M u32, Φ 3×f64) each; a flag, then for chunk 0 the
/// direct light and filter weight (4×f32 per pixel) and the counters.
pub fn encode_output(out: &Output) -> Vec<u8> {
    let mut b = Vec::from(*OUTPUT_MAGIC);
    b.extend_from_slice(&(out.sums.len() as u64).to_le_bytes());
    for s in &out.sums {
        b.extend_from_slice(&s.pixel.to_le_bytes());
        b.extend_from_slice(&s.m.to_le_bytes());
        put_f64s(&mut b, &s.phi);
    }
    match &out.camera {
        Some(c) => {
            b.push(1);
            b.extend_from_slice(&(c.ld.len() as u64).to_le_bytes());
            for (l, w) in c.ld.iter().zip(&c.w) {
                put_f32s(&mut b, &l.to_array());
                put_f32s(&mut b, &[*w]);
            }
            put_stats(&mut b, &c.stats);
        }
        None => b.push(0),
    }
    b
}

/// Decodes an SPPM task's output for a film of `pixels` pixels, checking that its pixels are
/// on the film and in order, and that it has the direct light exactly when it is chunk 0.
pub fn decode_output(bytes: &[u8], task: &TaskSpec, pixels: u32) -> Result<Output, String> {
    let mut r = Reader::new(bytes, OUTPUT_MAGIC, "sppm sums")?;
    let n = r.count(32)?;
    let mut sums = Vec::with_capacity(n);
    for _ in 0..n {
        let pixel = r.u32()?;
        let m = r.u32()?;
        let phi = r.f64s::<3>()?;
        if pixel >= pixels || sums.last().is_some_and(|p: &PixelSum| p.pixel >= pixel) {
            return Err(format!(
                "sppm sums: pixel {pixel} out of order or off the {pixels}-pixel film"
            ));
        }
        sums.push(PixelSum { pixel, m, phi });
    }
    let camera = match r.take(1)?[0] {
        0 => None,
        1 => {
            let n = r.count(16)?;
            if n != pixels as usize {
                return Err(format!(
                    "sppm direct light: {n} pixels, the film has {pixels}"
                ));
            }
            let (mut ld, mut w) = (Vec::with_capacity(n), Vec::with_capacity(n));
            for _ in 0..n {
                let v = r.f32s::<4>()?;
                ld.push(Spectrum::new(v[0], v[1], v[2]));
                w.push(v[3]);
            }
            let stats = read_stats(&mut r)?;
            Some(CameraPass { ld, w, stats })
        }
        f => return Err(format!("sppm sums: bad direct-light flag {f}")),
    };
    r.end()?;
    if camera.is_some() != (task.x0 == 0) {
        return Err("sppm sums: the direct light comes with chunk 0, and only with it".into());
    }
    Ok(Output { sums, camera })
}

/// A frame's SPPM state between iterations, with the counters so far.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameState {
    pub state: SppmState,
    pub stats: RayStats,
}

impl FrameState {
    pub fn new(desc: &SceneDesc, s: &SppmSettings) -> Self {
        FrameState {
            state: SppmState::new(desc.film.width, desc.film.height, s.initial_radius),
            stats: RayStats::default(),
        }
    }

    /// Folds one iteration's outputs, given in chunk order, in.
    pub fn fold(&mut self, outputs: &[Output], alpha: f32) -> Result<(), String> {
        let Some(camera) = outputs.first().and_then(|o| o.camera.as_ref()) else {
            return Err("an sppm iteration without its chunk 0".into());
        };
        self.state
            .add_iteration(camera, outputs.iter().map(|o| o.sums.as_slice()), alpha);
        self.stats.add(&camera.stats);
        Ok(())
    }
}

/// Little-endian: width, height, iterations (u32), the counters (3×u64), then per pixel
/// L_d, τ (3×f64 each), W, N, r (f64).
pub fn encode_state(f: &FrameState) -> Vec<u8> {
    let s = &f.state;
    let mut b = Vec::from(*STATE_MAGIC);
    for v in [s.width, s.height, s.iterations] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    put_stats(&mut b, &f.stats);
    for i in 0..s.r.len() {
        put_f64s(&mut b, &s.ld[i].to_array());
        put_f64s(&mut b, &s.tau[i].to_array());
        put_f64s(&mut b, &[s.w[i], s.n[i], s.r[i]]);
    }
    b
}

pub fn decode_state(bytes: &[u8]) -> Result<FrameState, String> {
    let mut r = Reader::new(bytes, STATE_MAGIC, "sppm state")?;
    let (width, height, iterations) = (r.u32()?, r.u32()?, r.u32()?);
    let stats = read_stats(&mut r)?;
    let len = width as usize * height as usize;
    let mut state = SppmState::new(width, height, 0.0);
    state.iterations = iterations;
    for i in 0..len {
        let v = r.f64s::<9>()?;
        state.ld[i] = glam::DVec3::new(v[0], v[1], v[2]);
        state.tau[i] = glam::DVec3::new(v[3], v[4], v[5]);
        state.w[i] = v[6];
        state.n[i] = v[7];
        state.r[i] = v[8];
    }
    r.end()?;
    Ok(FrameState { state, stats })
}

/// The squared radii a frame's next iteration gathers within, one f32 per pixel.
pub fn encode_radii(r2: &[f32]) -> Vec<u8> {
    let mut b = Vec::from(*RADII_MAGIC);
    b.extend_from_slice(&(r2.len() as u64).to_le_bytes());
    put_f32s(&mut b, r2);
    b
}

pub fn decode_radii(bytes: &[u8], pixels: u32) -> Result<Vec<f32>, String> {
    let mut r = Reader::new(bytes, RADII_MAGIC, "sppm radii")?;
    let n = r.count(4)?;
    if n != pixels as usize {
        return Err(format!("sppm radii: {n} pixels, the film has {pixels}"));
    }
    let r2 = (0..n)
        .map(|_| r.f32s::<1>().map(|v| v[0]))
        .collect::<Result<Vec<_>, _>>()?;
    r.end()?;
    Ok(r2)
}

/// The squared radii of iteration 0 (every pixel at the initial radius): no download needed.
pub fn initial_radii(prepared: &Prepared) -> Result<Vec<f32>, String> {
    let pixels = prepared.desc.film.width as usize * prepared.desc.film.height as usize;
    let (_, s) = prepared
        .sppm
        .as_ref()
        .ok_or("an sppm task for a job whose integrator is not sppm")?;
    Ok(vec![sppm::radius2(s.initial_radius as f64); pixels])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Cornell glass at 24×20, SPPM with 3 chunks per iteration.
    fn glass() -> SceneDesc {
        let mut d = crate::job::tests::scene("cornell-glass", 3);
        d.integrator.kind = tessera_scene::IntegratorKind::Sppm;
        d.integrator.photon.photons = Some(60_000);
        d
    }

    /// Tasks run as a worker runs them (visible points once per iteration), through the wire
    /// format, folded as the coordinator folds them (state and radii through their files):
    /// the frame `sppm::render` makes in one process, bit for bit.
    #[test]
    fn iterations_as_tasks_make_the_frame_render_makes_in_one_process() {
        let desc = glass();
        let worker = Prepared::scene_only(desc.clone());
        let (photon, s) = settings(&desc);
        let pixels = desc.film.width * desc.film.height;
        let mut frame = FrameState::new(&desc, &s);
        let mut r2 = initial_radii(&worker).expect("sppm");
        for t in 0..s.iterations {
            let tasks = iteration_tasks(&desc, 1, t);
            assert_eq!(tasks.len(), 3);
            let vps = visible_points(&worker, 1, t).expect("sppm");
            let outs: Vec<Output> = tasks
                .iter()
                .map(|task| {
                    let out = execute(&worker, &vps, &r2, task).expect("runs");
                    decode_output(&encode_output(&out), task, pixels).expect("decodes")
                })
                .collect();
            assert!(
                outs.iter().all(|o| !o.sums.is_empty()),
                "every chunk reaches some pixel"
            );
            frame = decode_state(&encode_state(&frame)).expect("state");
            frame.fold(&outs, s.alpha).expect("folds");
            r2 = decode_radii(&encode_radii(&frame.state.radii2()), pixels).expect("radii");
        }
        let camera = crate::job::camera(&desc, 1);
        let (alone, stats) = sppm::render(&worker.scene, &camera, &photon, &s, &|_| {});
        assert_eq!(frame.state.image(camera.exposure).pixels, alone.pixels);
        assert_eq!(frame.stats, stats);
    }

    #[test]
    fn bad_outputs_and_settings_are_rejected() {
        let desc = glass();
        let tasks = iteration_tasks(&desc, 1, 0);
        let out = Output {
            sums: vec![
                PixelSum {
                    pixel: 5,
                    m: 1,
                    phi: [1.0; 3],
                },
                PixelSum {
                    pixel: 3,
                    m: 1,
                    phi: [1.0; 3],
                },
            ],
            camera: None,
        };
        let e = decode_output(&encode_output(&out), &tasks[1], 480).expect_err("out of order");
        assert!(e.contains("out of order"), "{e}");
        let ok = Output {
            sums: vec![],
            camera: None,
        };
        assert!(decode_output(&encode_output(&ok), &tasks[1], 480).is_ok());
        let e = decode_output(&encode_output(&ok), &tasks[0], 480).expect_err("no direct");
        assert!(e.contains("chunk 0"), "{e}");
        let off = Output {
            sums: vec![PixelSum {
                pixel: 480,
                m: 1,
                phi: [0.0; 3],
            }],
            camera: None,
        };
        assert!(decode_output(&encode_output(&off), &tasks[1], 480).is_err());
        assert!(decode_radii(&encode_radii(&[1.0; 4]), 5).is_err());
        assert!(decode_state(b"TSST").is_err());

        let mut many = desc.clone();
        many.integrator.spp = 100_000;
        let e = check(&many, &RenderSettings::default()).expect_err("too many photons");
        assert!(e.contains("2^32"), "{e}");
        let adaptive = RenderSettings {
            target_error: Some(0.01),
            ..RenderSettings::default()
        };
        assert!(check(&desc, &adaptive).is_err());
    }
}
