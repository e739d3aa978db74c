//! The hierarchical method's point-cloud pass on the farm (issue 7; DESIGN: "passes are tasks
//! too"). The points depend on the scene description alone ([`Placement`]), so the coordinator
//! counts them and every process places the same ones; a pass task computes the irradiance of
//! an index range of them ([`TaskKind::SubsurfacePoints`], each point by its own sampler
//! stream), the coordinator concatenates the ranges into the artifact, and tile tasks build the
//! octrees from it. Key: geometry, materials, lights and the irradiance paths' settings — never
//! the camera, so every frame of a fly-through and every later job of the scene reuses it.

use sha2::{Digest, Sha256};
use tessera_render::Integrator;
use tessera_render::bssrdf::hierarchical::{IRRADIANCE_SAMPLES, Placement};
use tessera_render::integrator::{needs_point_clouds, subsurface_irradiance, with_point_clouds};
use tessera_render::spectrum::Spectrum;
use tessera_scene::SceneDesc;

use crate::job::{Prepared, TaskKind, TaskSpec};
use crate::passes::{Reader, hash_scene, hex, put_f32s};

/// Points per pass task (about 0.1 s of a core on the translucent scene).
pub const POINTS_PER_TASK: u32 = 8192;

const IRRADIANCE_MAGIC: &[u8; 4] = b"TSSI";

/// The point-cloud pass a job needs.
#[derive(Debug, Clone, PartialEq)]
pub struct SubsurfacePlan {
    /// Key of the artifact: the irradiance of every point, in index order.
    pub key: String,
    pub points: u32,
}

/// The pass `desc` (settings applied) needs: `None` unless it renders translucent materials by
/// the hierarchical method.
pub fn plan(desc: &SceneDesc) -> Option<SubsurfacePlan> {
    if !needs_point_clouds(desc) {
        return None;
    }
    let points = u32::try_from(Placement::new(desc).len()).unwrap_or(u32::MAX);
    Some(SubsurfacePlan {
        key: key(desc),
        points,
    })
}

/// Hash of what determines the cloud's irradiance: the scene as the photon maps see it, and
/// the depth, Russian roulette, seed and paths per point of the irradiance paths.
pub fn key(desc: &SceneDesc) -> String {
    let mut h = Sha256::new();
    h.update(b"tessera subsurface v1\0");
    hash_scene(&mut h, desc);
    let i = &desc.integrator;
    h.update(format!(
        "{} {} {} {}",
        i.max_depth, i.rr_depth, i.seed, IRRADIANCE_SAMPLES
    ));
    hex(h)
}

impl SubsurfacePlan {
    /// Index ranges of [`POINTS_PER_TASK`] points, in merge order.
    pub fn tasks(&self) -> Vec<TaskSpec> {
        TaskSpec::index_ranges(TaskKind::SubsurfacePoints, self.points, POINTS_PER_TASK, 0)
            .collect()
    }
}

/// The irradiance of the points of `task`'s range.
pub fn execute(prepared: &Prepared, task: &TaskSpec) -> Result<Vec<Spectrum>, String> {
    let placement = Placement::new(&prepared.desc);
    let range = task.sample_start as usize..task.sample_end as usize;
    if range.end > placement.len() || range.start > range.end {
        return Err(format!(
            "points {}..{} of a cloud of {}",
            range.start,
            range.end,
            placement.len()
        ));
    }
    Ok(subsurface_irradiance(
        &prepared.desc,
        &prepared.scene,
        &placement,
        range,
    ))
}

/// Irradiance values as bytes (a task's output, and the merged artifact).
pub fn encode(e: &[Spectrum]) -> Vec<u8> {
    let mut b = Vec::from(*IRRADIANCE_MAGIC);
    b.extend_from_slice(&(e.len() as u64).to_le_bytes());
    for v in e {
        put_f32s(&mut b, &v.to_array());
    }
    b
}

/// Decodes irradiance values; `expected` is their count when known (a task's range).
pub fn decode(bytes: &[u8], expected: Option<usize>) -> Result<Vec<Spectrum>, String> {
    let mut r = Reader::new(bytes, IRRADIANCE_MAGIC, "point-cloud irradiance")?;
    let n = r.count(12)?;
    if let Some(want) = expected.filter(|&w| w != n) {
        return Err(format!("{n} irradiance values for {want} points"));
    }
    let e = (0..n)
        .map(|_| r.f32s::<3>().map(Spectrum::from))
        .collect::<Result<Vec<_>, _>>()?;
    r.end()?;
    Ok(e)
}

/// The tile integrator of a job whose point cloud arrives as an artifact.
pub fn integrator(prepared: &Prepared, artifact: &[u8]) -> Result<Box<dyn Integrator>, String> {
    let e = decode(artifact, None)?;
    let clouds = Placement::new(&prepared.desc).with_irradiance(&prepared.desc, &e)?;
    Ok(with_point_clouds(
        &prepared.desc,
        &prepared.analysis,
        clouds,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::job::{self, FrameRange, RenderSettings, TaskOutput, stitch};
    use tessera_scene::SubsurfaceMethod;

    /// Marble and skin at 24×20, 2 spp, by the hierarchical method.
    fn marble_skin() -> SceneDesc {
        let mut d = job::tests::scene("marble-skin", 2);
        d.integrator.subsurface = SubsurfaceMethod::Hierarchical;
        d
    }

    #[test]
    fn the_pass_as_tasks_makes_the_frame_render_makes_in_one_process() {
        let desc = marble_skin();
        let local = Prepared::new(desc.clone(), FrameRange::single(1));
        let worker = Prepared::scene_only(desc.clone());
        assert!(
            worker.integrator().is_none(),
            "a worker's tile integrator waits for the artifact"
        );
        let plan = plan(&desc).expect("a point-cloud pass");
        let tasks = plan.tasks();
        assert!(tasks.len() >= 3, "{} tasks", tasks.len());
        // Each task's output through the wire form, concatenated in order.
        let mut e = Vec::new();
        for t in &tasks {
            let out = crate::passes::execute(&worker, None, t).expect("irradiance");
            let bytes = crate::passes::encode_output(&out);
            match crate::passes::decode_output(&bytes, t).expect("decode") {
                crate::passes::PassOutput::Irradiance(v) => e.extend(v),
                _ => panic!("irradiance expected"),
            }
        }
        assert_eq!(e.len(), plan.points as usize);
        let full = integrator(&worker, &encode(&e)).expect("integrator");
        let frame = job::plan_frame(&desc, &RenderSettings::default(), 1);
        let camera = worker.camera(1);
        let farm: Vec<TaskOutput> = frame
            .iter()
            .map(|t| worker.execute_using(full.as_ref(), &camera, t))
            .collect();
        let alone: Vec<TaskOutput> = frame.iter().map(|t| local.execute(t)).collect();
        let (w, h) = (desc.film.width, desc.film.height);
        assert_eq!(stitch(w, h, &farm), stitch(w, h, &alone));
    }

    #[test]
    fn only_hierarchical_translucent_scenes_plan_it_and_its_key_ignores_the_camera() {
        let desc = marble_skin();
        let key = plan(&desc).expect("plan").key;
        let mut moved = desc.clone();
        moved.camera.position.x += 5.0;
        moved.integrator.spp = 99;
        assert_eq!(plan(&moved).expect("plan").key, key);
        let mut deeper = desc.clone();
        deeper.integrator.max_depth += 1;
        assert_ne!(plan(&deeper).expect("plan").key, key);
        let mut repainted = desc.clone();
        repainted.materials[0].kind = tessera_scene::MaterialKind::Diffuse {
            albedo: glam::Vec3::splat(0.5),
        };
        assert_ne!(plan(&repainted).expect("plan").key, key);
        let mut sampled = desc.clone();
        sampled.integrator.subsurface = SubsurfaceMethod::Dipole;
        assert_eq!(plan(&sampled), None);
        assert_eq!(plan(&job::tests::cornell()), None);
    }

    #[test]
    fn bad_irradiance_is_rejected() {
        let e = vec![Spectrum::ONE; 3];
        assert_eq!(decode(&encode(&e), Some(3)), Ok(e.clone()));
        assert!(decode(&encode(&e), Some(4)).is_err());
        assert!(decode(b"TSSI", None).is_err());
        let mut long = encode(&e);
        long.push(0);
        assert!(decode(&long, None).is_err());
        // An artifact of another cloud's size.
        let worker = Prepared::scene_only(marble_skin());
        assert!(integrator(&worker, &encode(&e)).is_err());
    }
}
