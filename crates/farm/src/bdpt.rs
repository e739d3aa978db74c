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
//!
//! The Metropolis renderers (PSSMLT, MLT) go the same way: their chains wander over the whole
//! film, and a frame is [`GROUPS`] tasks, one per group of chains (`tile_index` = the group,
//! the sample range its share of the direct-light samples; see
//! [`tessera_render::integrator::metropolis`]). Their results add the chains' fixed-point
//! splats and the group's brightness samples (296 bytes per pixel).

use tessera_render::camera::Camera;
use tessera_render::film::Tile;
use tessera_render::integrator::bdpt::{Bdpt, BdptSums};
use tessera_render::integrator::metropolis::{GROUPS, Metropolis, share};
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

/// Whether an integrator's frames are farm tasks over the whole film, merged as [`BdptSums`]:
/// BDPT's and VCM's sample ranges, the Metropolis renderers' chain groups.
pub fn film_tasks(kind: IntegratorKind) -> bool {
    sample_ranges(kind) || matches!(kind, IntegratorKind::Pssmlt | IntegratorKind::Mlt)
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

/// Checks that a job's BDPT, VCM or Metropolis settings can run on the farm.
pub fn check(desc: &SceneDesc, settings: &RenderSettings) -> Result<(), String> {
    let name = format!("{:?}", desc.integrator.kind).to_lowercase();
    if settings.target_error.is_some() {
        return Err(format!(
            "target_error: {name} refines every pixel at once (its splats land anywhere); give spp instead"
        ));
    }
    if desc.integrator.kind == IntegratorKind::Mlt {
        use tessera_scene::LightDesc;
        if desc.lights.iter().any(|l| {
            matches!(
                l,
                LightDesc::Directional { .. } | LightDesc::Environment { .. }
            )
        }) {
            return Err("integrator: mlt does not support lights at infinity (environment, directional); use pssmlt or bdpt".into());
        }
        if matches!(desc.camera.lens, tessera_scene::Lens::Thin { aperture_radius, .. } if aperture_radius > 0.0)
        {
            return Err("integrator: mlt supports pinhole cameras only; use pssmlt or bdpt".into());
        }
    }
    Ok(())
}

/// The tasks of `frame`: sample ranges of the whole film (Metropolis: chain groups), in
/// merge order.
pub fn tasks(desc: &SceneDesc, settings: &RenderSettings, frame: u32) -> Vec<TaskSpec> {
    let spp = desc.integrator.spp.max(1);
    let whole = |tile_index: u32, sample_start: u32, sample_end: u32| TaskSpec {
        kind: TaskKind::Bdpt,
        frame,
        tile_index,
        x0: 0,
        y0: 0,
        x1: desc.film.width,
        y1: desc.film.height,
        sample_start,
        sample_end,
    };
    if !sample_ranges(desc.integrator.kind) {
        return (0..GROUPS)
            .map(|g| {
                let s = share(spp as u64, g);
                whole(g, s.start as u32, s.end as u32)
            })
            .collect();
    }
    let chunk = settings
        .samples_per_task
        .unwrap_or(spp.div_ceil(DEFAULT_TASKS))
        .clamp(1, spp);
    (0..spp)
        .step_by(chunk as usize)
        .enumerate()
        .map(|(i, start)| whole(i as u32, start, (start + chunk).min(spp)))
        .collect()
}

/// What the job status says about a BDPT, VCM or Metropolis job's tasks.
pub fn decision(desc: &SceneDesc, settings: &RenderSettings) -> String {
    let name = format!("{:?}", desc.integrator.kind).to_lowercase();
    if !sample_ranges(desc.integrator.kind) {
        return format!(
            "{name}: Markov chains wander over the whole film, so each frame is {GROUPS} tasks, each a group of chains (with its share of the direct light, brightness samples and bootstrap paths), merged as fixed-point sums"
        );
    }
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
    let camera = prepared.camera(spec.frame);
    match Metropolis::new(prepared.analysis.integrator, &prepared.desc) {
        Some(m) => {
            let g = spec.tile_index;
            let (sums, stats) = m.render_groups(
                &prepared.scene,
                &camera,
                prepared.desc.integrator.spp.max(1),
                g..g + 1,
                &|_| {},
            )?;
            if sums.sums.samples != spec.samples() {
                return Err(format!(
                    "group {g}'s direct-light samples are {:?}, the task says {:?}",
                    sums.sums.samples,
                    spec.samples()
                ));
            }
            Ok((sums, stats))
        }
        None => render_range(prepared, &camera, spec.samples(), &|_| {}),
    }
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
/// three little-endian i64; for the Metropolis renderers then each pixel's chain splats the
/// same way and the brightness sum (i128) and count (u64).
pub fn encode_output(sums: &BdptSums, stats: &RayStats) -> Vec<u8> {
    let mut b = codec::encode_sums(&sums.sums, stats);
    let chains = !sums.chain.is_empty();
    b.reserve(sums.splats.len() * if chains { 48 } else { 24 } + 24);
    let mut put = |splats: &[[i64; 3]]| {
        for px in splats {
            for v in px {
                b.extend_from_slice(&v.to_le_bytes());
            }
        }
    };
    put(&sums.splats);
    if chains {
        put(&sums.chain);
        b.extend_from_slice(&sums.brightness.0.to_le_bytes());
        b.extend_from_slice(&sums.brightness.1.to_le_bytes());
    }
    b
}

/// Decodes a task's result and checks it is the one `task` asked for.
pub fn decode_output(bytes: &[u8], task: &TaskSpec) -> Result<(BdptSums, RayStats), String> {
    let pixels = task.tile().pixel_count();
    let head = codec::encoded_len(pixels);
    let (plain, chains) = (head + pixels * 24, head + pixels * 48 + 24);
    if bytes.len() != plain && bytes.len() != chains {
        return Err(format!(
            "expected {plain} bytes of bdpt sums for a {}×{} film ({chains} with Metropolis chains), got {}",
            task.tile().width(),
            task.tile().height(),
            bytes.len()
        ));
    }
    let out = codec::decode(&bytes[..head], task)?;
    let splats = |bytes: &[u8]| -> Vec<[i64; 3]> {
        bytes
            .chunks_exact(24)
            .map(|px| {
                let v = |i: usize| {
                    i64::from_le_bytes(px[i * 8..i * 8 + 8].try_into().unwrap_or([0; 8]))
                };
                [v(0), v(1), v(2)]
            })
            .collect()
    };
    let mut sums = BdptSums::new(task.tile().width(), task.tile().height());
    sums.sums = out.sums;
    sums.samples = task.sample_end.saturating_sub(task.sample_start);
    sums.splats = splats(&bytes[head..head + pixels * 24]);
    if bytes.len() == chains {
        let rest = &bytes[head + pixels * 24..];
        sums.chain = splats(&rest[..pixels * 24]);
        let tail = &rest[pixels * 24..];
        sums.brightness = (
            i128::from_le_bytes(tail[..16].try_into().unwrap_or([0; 16])),
            u64::from_le_bytes(tail[16..24].try_into().unwrap_or([0; 8])),
        );
    }
    Ok((sums, out.stats))
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

    #[test]
    fn metropolis_frames_as_group_tasks_round_trip_and_equal_one_render() {
        for kind in [IntegratorKind::Pssmlt, IntegratorKind::Mlt] {
            let mut desc = scene("cornell-glass", 3);
            desc.integrator.kind = kind;
            desc.film.width = 12;
            desc.film.height = 10;
            let specs = tasks(&desc, &RenderSettings::default(), 1);
            assert_eq!(specs.len(), GROUPS as usize);
            // 3 direct-light samples over 8 groups: most have none.
            let direct: u32 = specs.iter().map(|t| t.sample_end - t.sample_start).sum();
            assert_eq!(direct, 3);
            let prepared = Prepared::new(desc.clone(), FrameRange::single(1));
            let outputs: Vec<_> = specs
                .iter()
                .map(|t| {
                    let (s, st) = execute(&prepared, t).expect("renders");
                    assert_eq!(s.chain.len(), 120, "{kind:?}: chain splats");
                    let bytes = encode_output(&s, &st);
                    let back = decode_output(&bytes, t).expect("decodes");
                    assert_eq!(back, (s, st));
                    back
                })
                .collect();
            let (merged, _) = merge(&outputs, &desc);
            let m = Metropolis::new(kind, &desc).expect("metropolis");
            let whole = m
                .render_groups(&prepared.scene, &prepared.camera(1), 3, 0..GROUPS, &|_| {})
                .expect("renders")
                .0;
            assert_eq!(merged, whole, "{kind:?}");
            assert!(merged.b() > 0.0);
        }
    }
}
