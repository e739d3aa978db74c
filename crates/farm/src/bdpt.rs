//! Bidirectional path tracing and vertex connection and merging on the farm: a frame's samples
//! (VCM's iterations) cut into ranges over the whole film.
//!
//! Light tracing (BDPT's t = 1 strategy) lands on whatever pixel a light subpath's vertex
//! projects to, so a tile cannot be rendered on its own. A BDPT frame's tasks are therefore
//! [`TaskKind::Bdpt`]: samples `sample_start..sample_end` of every pixel (chunk `tile_index`,
//! the tile fields spanning the film). Each returns the film's fixed-point camera-side sums and
//! its fixed-point splats ([`BdptSums`]); the coordinator merges them in chunk order when the
//! frame's last one is accepted. Integer sums do not depend on how the samples were cut or the
//! order they are added in, so the frame is bit for bit `tessera render --integrator bdpt`'s,
//! on any number of workers.
//!
//! A task's result is the whole film's sums: 272 bytes per pixel (17.8 MB at 256²), which is
//! why a frame has few of them (`samples_per_task`, default an eighth of the samples).

use tessera_render::camera::Camera;
use tessera_render::film::Tile;
use tessera_render::integrator::bdpt::{Bdpt, BdptSums};
use tessera_render::integrator::vcm::Vcm;
use tessera_render::{RayStats, SampleRange};
use tessera_scene::{IntegratorKind, SceneDesc};

use crate::codec;
use crate::job::{Prepared, RenderSettings, TaskKind, TaskSpec};

/// Tasks of a frame when the job does not say (`samples_per_task`).
pub const DEFAULT_TASKS: u32 = 8;

/// Whether an integrator's frames are sample ranges over the whole film (BDPT and VCM).
pub fn sample_ranges(kind: IntegratorKind) -> bool {
    matches!(kind, IntegratorKind::Bdpt | IntegratorKind::Vcm)
}

/// Samples (VCM: iterations) `range` of a frame by the scene's BDPT or VCM, on this process's
/// rayon pool.
pub fn render_range(
    prepared: &Prepared,
    camera: &Camera,
    range: SampleRange,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<(BdptSums, RayStats), String> {
    let scene = &prepared.scene;
    match prepared.analysis.integrator {
        IntegratorKind::Vcm => {
            Vcm::new(&prepared.desc, scene).render_range(scene, camera, range, progress)
        }
        IntegratorKind::Bdpt => {
            Bdpt::new(&prepared.desc).render_range(scene, camera, range, progress)
        }
        other => Err(format!(
            "a bdpt/vcm task for a job whose integrator is {other:?}"
        )),
    }
}

/// Checks that a job's BDPT or VCM settings can run on the farm.
pub fn check(desc: &SceneDesc, settings: &RenderSettings) -> Result<(), String> {
    if settings.target_error.is_some() {
        return Err(
            "target_error: bdpt and vcm refine every pixel at once (their splats land anywhere); give spp instead"
                .into(),
        );
    }
    use tessera_scene::LightDesc;
    if desc.lights.iter().any(|l| {
        matches!(
            l,
            LightDesc::Directional { .. } | LightDesc::Environment { .. }
        )
    }) {
        return Err(
            "integrator: bdpt and vcm do not support lights at infinity (environment, directional) yet; use path".into(),
        );
    }
    Ok(())
}

/// The tasks of `frame`: sample ranges of the whole film, in merge order.
pub fn tasks(desc: &SceneDesc, settings: &RenderSettings, frame: u32) -> Vec<TaskSpec> {
    let spp = desc.integrator.spp.max(1);
    let chunk = settings
        .samples_per_task
        .unwrap_or(spp.div_ceil(DEFAULT_TASKS))
        .clamp(1, spp);
    (0..spp)
        .step_by(chunk as usize)
        .enumerate()
        .map(|(i, start)| TaskSpec {
            kind: TaskKind::Bdpt,
            frame,
            tile_index: i as u32,
            x0: 0,
            y0: 0,
            x1: desc.film.width,
            y1: desc.film.height,
            sample_start: start,
            sample_end: (start + chunk).min(spp),
        })
        .collect()
}

/// What the job status says about a BDPT or VCM job's tasks.
pub fn decision(desc: &SceneDesc, settings: &RenderSettings) -> String {
    let name = format!("{:?}", desc.integrator.kind).to_lowercase();
    format!(
        "{name}: light tracing splats anywhere on the film, so each frame is {} tasks of sample ranges over the whole film (not tiles), merged in order as fixed-point sums",
        tasks(desc, settings, 1).len()
    )
}

/// Renders a BDPT or VCM task on this process's rayon pool.
pub fn execute(prepared: &Prepared, spec: &TaskSpec) -> Result<(BdptSums, RayStats), String> {
    if spec.tile() != film(&prepared.desc) {
        return Err(format!(
            "a bdpt task must span the film {:?}, got {:?}",
            film(&prepared.desc),
            spec.tile()
        ));
    }
    render_range(
        prepared,
        &prepared.camera(spec.frame),
        spec.samples(),
        &|_| {},
    )
}

fn film(desc: &SceneDesc) -> Tile {
    Tile {
        x0: 0,
        y0: 0,
        x1: desc.film.width,
        y1: desc.film.height,
    }
}

/// A task's result: the film's sums as a tile's ([`codec`]), then each pixel's splats as
/// three little-endian i64.
pub fn encode_output(sums: &BdptSums, stats: &RayStats) -> Vec<u8> {
    let mut b = codec::encode_sums(&sums.sums, stats);
    b.reserve(sums.splats.len() * 24);
    for px in &sums.splats {
        for v in px {
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    b
}

/// Decodes a task's result and checks it is the one `task` asked for.
pub fn decode_output(bytes: &[u8], task: &TaskSpec) -> Result<(BdptSums, RayStats), String> {
    let pixels = task.tile().pixel_count();
    let head = codec::encoded_len(pixels);
    if bytes.len() != head + pixels * 24 {
        return Err(format!(
            "expected {} bytes of bdpt sums for a {}×{} film, got {}",
            head + pixels * 24,
            task.tile().width(),
            task.tile().height(),
            bytes.len()
        ));
    }
    let out = codec::decode(&bytes[..head], task)?;
    let splats = bytes[head..]
        .chunks_exact(24)
        .map(|px| {
            let v =
                |i: usize| i64::from_le_bytes(px[i * 8..i * 8 + 8].try_into().unwrap_or([0; 8]));
            [v(0), v(1), v(2)]
        })
        .collect();
    let samples = task.sample_end.saturating_sub(task.sample_start);
    Ok((
        BdptSums {
            sums: out.sums,
            splats,
            samples,
        },
        out.stats,
    ))
}

/// Merges a frame's task results (in chunk order; any order gives the same bits).
pub fn merge(outputs: &[(BdptSums, RayStats)], desc: &SceneDesc) -> (BdptSums, RayStats) {
    let mut sums = BdptSums::new(desc.film.width, desc.film.height);
    let mut stats = RayStats::default();
    for (s, st) in outputs {
        sums.merge(s);
        stats.add(st);
    }
    (sums, stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::job::FrameRange;
    use crate::job::tests::scene;

    #[test]
    fn a_frame_as_tasks_round_trips_and_equals_one_render() {
        let mut desc = scene("cornell-glass", 5);
        desc.integrator.kind = tessera_scene::IntegratorKind::Bdpt;
        desc.film.width = 12;
        desc.film.height = 10;
        let settings = RenderSettings {
            samples_per_task: Some(2),
            ..Default::default()
        };
        let specs = tasks(&desc, &settings, 1);
        let ranges: Vec<(u32, u32)> = specs
            .iter()
            .map(|t| (t.sample_start, t.sample_end))
            .collect();
        assert_eq!(ranges, [(0, 2), (2, 4), (4, 5)]);
        let prepared = Prepared::new(desc.clone(), FrameRange::single(1));
        let outputs: Vec<_> = specs
            .iter()
            .map(|t| {
                let (s, st) = execute(&prepared, t).expect("renders");
                let bytes = encode_output(&s, &st);
                let back = decode_output(&bytes, t).expect("decodes");
                assert_eq!(back, (s, st));
                assert!(decode_output(&bytes[1..], t).is_err());
                back
            })
            .collect();
        let (merged, _) = merge(&outputs, &desc);
        let whole = Bdpt::new(&desc)
            .render_range(
                &prepared.scene,
                &prepared.camera(1),
                tessera_render::SampleRange { start: 0, end: 5 },
                &|_| {},
            )
            .expect("renders")
            .0;
        assert_eq!(merged, whole);
        let wrong = TaskSpec { x1: 11, ..specs[0] };
        assert!(
            execute(&prepared, &wrong)
                .unwrap_err()
                .contains("span the film")
        );
    }
}
