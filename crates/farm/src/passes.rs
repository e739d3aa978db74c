//! Precomputation on the farm: photon maps and irradiance records as tasks, merged by the
//! coordinator into frozen artifacts addressed by a hash of everything that determines them
//! (DESIGN: "passes are tasks too").
//!
//! - Photon passes: index ranges of the global and caustic maps ([`TaskKind::GlobalPhotons`],
//!   [`TaskKind::CausticPhotons`]); photon `i` depends only on (seed, map, i), so the merged
//!   map — the ranges concatenated in order, then balanced — is the one `tessera render` shoots
//!   in one process. Key: geometry, materials, lights, photon settings; never the camera, so
//!   every frame of a camera-only fly-through and every later job of the scene reuses it.
//! - Record passes ([`TaskKind::Records`]): one tile of one keyframe's record-candidate grid
//!   each; merged in (keyframe, tile) order into the irradiance cache. Key: the photon key, the
//!   cache settings, the film size and the keyframes' cameras.
//!
//! Artifacts are built once, then read-only: tile tasks name them by key.

use sha2::{Digest, Sha256};
use tessera_render::camera::Camera;
use tessera_render::integrator::{PhotonIntegrator, keyframes, record_tiles};
use tessera_render::irradiance::{IrradianceCache, Record};
use tessera_render::photon::{
    KdTree, MapKind, Photon, PhotonMap, PhotonMaps, PhotonSettings, RadiancePhoton, Shooter,
};
use tessera_render::scene::Material;
use tessera_render::{RayStats, Tile};
use tessera_scene::{IntegratorKind, LightDesc, SceneDesc};

use crate::job::{FrameRange, Prepared, TaskKind, TaskSpec};

/// Photons per photon-pass task.
pub const PHOTONS_PER_TASK: u32 = 25_000;

/// Most stored photons one photon emitted may leave (one per bounce, bounded by max depth in
/// practice far lower); bounds what a pass result may weigh.
const MAX_STORED_PER_PHOTON: usize = 64;

/// Largest pass result a worker may upload, bytes.
pub const MAX_OUTPUT_BYTES: usize =
    PHOTONS_PER_TASK as usize * MAX_STORED_PER_PHOTON * PHOTON_BYTES + 16;

/// The passes a photon-mapping job needs: their settings, keys and keyframes.
#[derive(Debug, Clone, PartialEq)]
pub struct PassPlan {
    pub settings: PhotonSettings,
    /// Key of the photon-map artifact.
    pub photons_key: String,
    /// Key of the irradiance-cache artifact (`None` without a cache).
    pub records_key: Option<String>,
    /// Frames whose cameras make the records.
    pub keyframes: Vec<u32>,
    /// What was decided, with reasons.
    pub decisions: Vec<String>,
}

/// The passes `desc` (settings applied, `auto` resolved by `analysis`) needs to render
/// `frames`; `None` unless it maps photons.
pub fn plan(
    desc: &SceneDesc,
    analysis: &tessera_render::analysis::Analysis,
    frames: FrameRange,
) -> Option<PassPlan> {
    if analysis.integrator != IntegratorKind::Photon {
        return None;
    }
    let (settings, decisions) = PhotonSettings::resolve(desc, analysis);
    let photons_key = photons_key(desc, &settings);
    let (records_key, keyframes) = match settings.irradiance_cache {
        Some(ic) => {
            let kf = keyframes(frames.first..=frames.last, ic.keyframe_step);
            (Some(records_key(&photons_key, desc, &settings, &kf)), kf)
        }
        None => (None, Vec::new()),
    };
    Some(PassPlan {
        settings,
        photons_key,
        records_key,
        keyframes,
        decisions,
    })
}

impl PassPlan {
    /// The photon-pass tasks: index ranges of the global, then the caustic map.
    pub fn photon_tasks(&self) -> Vec<TaskSpec> {
        let mut out = Vec::new();
        for (kind, count) in [
            (TaskKind::GlobalPhotons, self.settings.photons),
            (TaskKind::CausticPhotons, self.settings.caustic_photons),
        ] {
            let first = out.len() as u32;
            out.extend(TaskSpec::index_ranges(kind, count, PHOTONS_PER_TASK, first));
        }
        out
    }

    /// The record-pass tasks: every tile of every keyframe's candidate grid, in merge order.
    pub fn record_tasks(&self, desc: &SceneDesc) -> Vec<TaskSpec> {
        let tiles = record_tiles(&self.settings, desc.film.width, desc.film.height);
        let mut out = Vec::new();
        for &frame in &self.keyframes {
            for &t in &tiles {
                out.push(TaskSpec {
                    kind: TaskKind::Records,
                    frame,
                    tile_index: out.len() as u32,
                    x0: t.x0,
                    y0: t.y0,
                    x1: t.x1,
                    y1: t.y1,
                    sample_start: 0,
                    sample_end: 0,
                });
            }
        }
        out
    }
}

pub(crate) fn hex(h: Sha256) -> String {
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

fn floats(h: &mut Sha256, v: &[glam::Vec3]) {
    h.update((v.len() as u64).to_le_bytes());
    for p in v {
        for c in p.to_array() {
            h.update(c.to_le_bytes());
        }
    }
}

/// Hash of what determines the photon maps: units, materials, geometry, emission, lights, and
/// the photon settings (counts, seed, sampler, depth). Not the camera, the film or the spp.
/// Floats by their bits; small descriptions by their `Debug` form (Rust prints floats so they
/// round-trip, so the form is exact).
pub fn photons_key(desc: &SceneDesc, settings: &PhotonSettings) -> String {
    let mut h = Sha256::new();
    h.update(b"tessera photons v2\0");
    hash_scene(&mut h, desc);
    let s = settings;
    h.update(format!(
        "{} {} {} {} {:?} {:?}",
        s.photons, s.caustic_photons, s.max_depth, s.seed, s.sampler, desc.integrator.kind
    ));
    hex(h)
}

/// Feeds what light transport in `desc` depends on, apart from the camera and the
/// integrator's settings, to `h`: units, materials, geometry, emission, lights.
pub(crate) fn hash_scene(h: &mut Sha256, desc: &SceneDesc) {
    h.update(desc.metres_per_unit.to_le_bytes());
    for m in &desc.materials {
        h.update(format!("{:?}", m.kind));
    }
    for m in &desc.meshes {
        floats(h, &m.positions);
        match &m.normals {
            Some(n) => floats(h, n),
            None => h.update(b"flat"),
        }
        h.update((m.triangles.len() as u64).to_le_bytes());
        for t in &m.triangles {
            for i in t {
                h.update(i.to_le_bytes());
            }
        }
        h.update(format!("{:?} {:?}", m.material, m.emission));
    }
    for s in &desc.spheres {
        h.update(format!(
            "{:?} {:?} {:?} {:?}",
            s.center, s.radius, s.material, s.emission
        ));
    }
    for l in &desc.lights {
        match l {
            LightDesc::Environment {
                image,
                scale,
                to_world,
            } => {
                h.update(format!("env {scale:?} {to_world:?}"));
                if let Some(img) = image {
                    h.update(img.width.to_le_bytes());
                    h.update(img.height.to_le_bytes());
                    floats(h, &img.texels);
                }
            }
            other => h.update(format!("{other:?}")),
        }
    }
}

/// Hash of what determines the irradiance cache: the photon maps, the gather settings, the
/// film size and the keyframes' cameras.
pub fn records_key(
    photons_key: &str,
    desc: &SceneDesc,
    s: &PhotonSettings,
    keyframes: &[u32],
) -> String {
    let mut h = Sha256::new();
    h.update(b"tessera records v1\0");
    h.update(photons_key);
    h.update(format!(
        "{:?} {} {} {} {} {} {:?} {}x{}",
        s.irradiance_cache,
        s.k,
        s.radius,
        s.gather_rays,
        s.caustic_k,
        s.caustic_radius,
        s.caustic_filter,
        desc.film.width,
        desc.film.height
    ));
    for &f in keyframes {
        h.update(format!("{f} {:?}", desc.camera_at(f)));
    }
    hex(h)
}

/// What a pass task produces.
#[derive(Debug, Clone, PartialEq)]
pub enum PassOutput {
    Photons(Vec<Photon>),
    Records(Vec<Record>),
    /// The irradiance of a range of the subsurface point cloud ([`crate::subsurface`]).
    Irradiance(Vec<tessera_render::spectrum::Spectrum>),
}

/// Runs a pass task: photons from `prepared`'s scene, records with `maps` (the integrator
/// built from the job's photon-map artifact).
pub fn execute(
    prepared: &Prepared,
    maps: Option<&PhotonIntegrator>,
    task: &TaskSpec,
) -> Result<PassOutput, String> {
    if task.kind == TaskKind::SubsurfacePoints {
        return crate::subsurface::execute(prepared, task).map(PassOutput::Irradiance);
    }
    let settings = prepared
        .photon
        .as_ref()
        .ok_or("a pass task for a job that does not map photons")?;
    match task.kind {
        TaskKind::GlobalPhotons | TaskKind::CausticPhotons => {
            let kind = if task.kind == TaskKind::GlobalPhotons {
                MapKind::Global
            } else {
                MapKind::Caustic
            };
            let shooter = Shooter::new(&prepared.scene, settings, kind);
            Ok(PassOutput::Photons(
                shooter.shoot(task.sample_start..task.sample_end),
            ))
        }
        TaskKind::Records => {
            let integ = maps.ok_or("a record task without its photon maps")?;
            let camera = Camera::new(&prepared.desc.camera_at(task.frame), &prepared.desc.film);
            let tile = Tile {
                x0: task.x0,
                y0: task.y0,
                x1: task.x1,
                y1: task.y1,
            };
            Ok(PassOutput::Records(integ.record_pass(
                &prepared.scene,
                &camera,
                tile,
                task.frame,
                &mut RayStats::default(),
            )))
        }
        TaskKind::Tile | TaskKind::Sppm | TaskKind::Bdpt | TaskKind::SubsurfacePoints => Err(
            format!("a {} task is not a photon pass", task.kind.as_str()),
        ),
    }
}

// Binary forms, little-endian. Photons: 12 f32 and a u32 each; radiance photons: 9 f32;
// records: 10 f32.

const PHOTONS_MAGIC: &[u8; 4] = b"TPHO";
const RECORDS_MAGIC: &[u8; 4] = b"TREC";
const MAPS_MAGIC: &[u8; 4] = b"TMAP";

pub(crate) fn put_f32s(b: &mut Vec<u8>, v: &[f32]) {
    for x in v {
        b.extend_from_slice(&x.to_le_bytes());
    }
}

pub(crate) struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
    what: &'static str,
}

impl<'a> Reader<'a> {
    pub(crate) fn new(
        bytes: &'a [u8],
        magic: &[u8; 4],
        what: &'static str,
    ) -> Result<Self, String> {
        if bytes.len() < 4 || &bytes[..4] != magic {
            return Err(format!(
                "expected {what} starting with \"{}\"",
                String::from_utf8_lossy(magic)
            ));
        }
        Ok(Reader { bytes, at: 4, what })
    }
    pub(crate) fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len());
        let Some(end) = end else {
            return Err(format!("{} cut short at byte {}", self.what, self.at));
        };
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    pub(crate) fn u64(&mut self) -> Result<u64, String> {
        let s = self.take(8)?;
        Ok(u64::from_le_bytes(s.try_into().map_err(|_| "short")?))
    }
    pub(crate) fn u32(&mut self) -> Result<u32, String> {
        let s = self.take(4)?;
        Ok(u32::from_le_bytes(s.try_into().map_err(|_| "short")?))
    }
    pub(crate) fn f64s<const N: usize>(&mut self) -> Result<[f64; N], String> {
        let s = self.take(8 * N)?;
        let mut out = [0.0; N];
        for (i, o) in out.iter_mut().enumerate() {
            let mut b = [0u8; 8];
            b.copy_from_slice(&s[8 * i..8 * i + 8]);
            *o = f64::from_le_bytes(b);
        }
        Ok(out)
    }
    pub(crate) fn f32s<const N: usize>(&mut self) -> Result<[f32; N], String> {
        let s = self.take(4 * N)?;
        let mut out = [0.0; N];
        for (i, o) in out.iter_mut().enumerate() {
            *o = f32::from_le_bytes([s[4 * i], s[4 * i + 1], s[4 * i + 2], s[4 * i + 3]]);
        }
        Ok(out)
    }
    /// A count of items of `size` bytes each, checked against what is left.
    pub(crate) fn count(&mut self, size: usize) -> Result<usize, String> {
        let n = self.u64()? as usize;
        if n.checked_mul(size)
            .is_none_or(|b| b > self.bytes.len() - self.at)
        {
            return Err(format!(
                "{}: {n} items do not fit in the bytes left",
                self.what
            ));
        }
        Ok(n)
    }
    pub(crate) fn end(&self) -> Result<(), String> {
        if self.at == self.bytes.len() {
            Ok(())
        } else {
            Err(format!(
                "{}: {} bytes left over",
                self.what,
                self.bytes.len() - self.at
            ))
        }
    }
}

const PHOTON_BYTES: usize = 52;

fn put_photons(b: &mut Vec<u8>, photons: &[Photon]) {
    b.extend_from_slice(&(photons.len() as u64).to_le_bytes());
    for p in photons {
        put_f32s(b, &p.p.to_array());
        put_f32s(b, &p.power.to_array());
        put_f32s(b, &p.wi.to_array());
        put_f32s(b, &p.n.to_array());
        b.extend_from_slice(&p.material.to_le_bytes());
    }
}

fn read_photons(r: &mut Reader) -> Result<Vec<Photon>, String> {
    let n = r.count(PHOTON_BYTES)?;
    (0..n)
        .map(|_| {
            let v = r.f32s::<12>()?;
            let m = r.take(4)?;
            let v3 = |i: usize| glam::Vec3::new(v[i], v[i + 1], v[i + 2]);
            Ok(Photon {
                p: v3(0),
                power: v3(3),
                wi: v3(6),
                n: v3(9),
                material: u32::from_le_bytes([m[0], m[1], m[2], m[3]]),
            })
        })
        .collect()
}

fn put_radiance(b: &mut Vec<u8>, tree: &KdTree<RadiancePhoton>) {
    b.extend_from_slice(&(tree.len() as u64).to_le_bytes());
    for p in tree.photons() {
        put_f32s(b, &p.p.to_array());
        put_f32s(b, &p.n.to_array());
        put_f32s(b, &p.lo.to_array());
    }
    b.extend_from_slice(tree.axes());
}

fn read_radiance(r: &mut Reader) -> Result<KdTree<RadiancePhoton>, String> {
    let n = r.count(37)?;
    let points = (0..n)
        .map(|_| {
            let v = r.f32s::<9>()?;
            let v3 = |i: usize| glam::Vec3::new(v[i], v[i + 1], v[i + 2]);
            Ok(RadiancePhoton {
                p: v3(0),
                n: v3(3),
                lo: v3(6),
            })
        })
        .collect::<Result<Vec<_>, String>>()?;
    let axes = r.take(n)?.to_vec();
    KdTree::from_parts(points, axes)
}

fn put_records(b: &mut Vec<u8>, records: &[Record]) {
    b.extend_from_slice(&(records.len() as u64).to_le_bytes());
    for r in records {
        put_f32s(b, &r.p.to_array());
        put_f32s(b, &r.n.to_array());
        put_f32s(b, &r.e.to_array());
        put_f32s(b, &[r.r]);
    }
}

fn read_records(r: &mut Reader) -> Result<Vec<Record>, String> {
    let n = r.count(40)?;
    (0..n)
        .map(|_| {
            let v = r.f32s::<10>()?;
            Ok(Record {
                p: glam::Vec3::new(v[0], v[1], v[2]),
                n: glam::Vec3::new(v[3], v[4], v[5]),
                e: glam::Vec3::new(v[6], v[7], v[8]),
                r: v[9],
            })
        })
        .collect()
}

pub fn encode_output(out: &PassOutput) -> Vec<u8> {
    let mut b = Vec::new();
    match out {
        PassOutput::Photons(p) => {
            b.extend_from_slice(PHOTONS_MAGIC);
            put_photons(&mut b, p);
        }
        PassOutput::Records(r) => {
            b.extend_from_slice(RECORDS_MAGIC);
            put_records(&mut b, r);
        }
        PassOutput::Irradiance(e) => return crate::subsurface::encode(e),
    }
    b
}

/// Decodes a pass task's output and checks it is of the kind `task` asked for.
pub fn decode_output(bytes: &[u8], task: &TaskSpec) -> Result<PassOutput, String> {
    match task.kind {
        TaskKind::GlobalPhotons | TaskKind::CausticPhotons => {
            let mut r = Reader::new(bytes, PHOTONS_MAGIC, "photons")?;
            let p = read_photons(&mut r)?;
            r.end()?;
            let shot = task.sample_end.saturating_sub(task.sample_start) as usize;
            if p.len() > shot * MAX_STORED_PER_PHOTON {
                return Err(format!("{} photons stored from {shot} shot", p.len()));
            }
            Ok(PassOutput::Photons(p))
        }
        TaskKind::Records => {
            let mut r = Reader::new(bytes, RECORDS_MAGIC, "records")?;
            let rec = read_records(&mut r)?;
            r.end()?;
            Ok(PassOutput::Records(rec))
        }
        TaskKind::SubsurfacePoints => {
            let n = task.sample_end.saturating_sub(task.sample_start) as usize;
            crate::subsurface::decode(bytes, Some(n)).map(PassOutput::Irradiance)
        }
        TaskKind::Tile | TaskKind::Sppm | TaskKind::Bdpt => {
            Err(format!("a {} task has no pass output", task.kind.as_str()))
        }
    }
}

/// Merges photon-pass outputs, given in task order, into the maps artifact: each map's photons
/// concatenated by index range and balanced, with its emitted count, and the radiance photons
/// (materials' Lambertian reflectances from `desc`).
pub fn merge_photons<'a>(
    desc: &SceneDesc,
    settings: &PhotonSettings,
    outputs: impl IntoIterator<Item = (TaskKind, &'a [Photon])>,
) -> PhotonMaps {
    let (mut global, mut caustic) = (Vec::new(), Vec::new());
    for (kind, photons) in outputs {
        match kind {
            TaskKind::GlobalPhotons => global.extend_from_slice(photons),
            _ => caustic.extend_from_slice(photons),
        }
    }
    let rho: Vec<_> = desc
        .materials
        .iter()
        .map(|m| Material::from_desc(&m.kind).bsdf.lambertian())
        .collect();
    PhotonMaps::build(global, caustic, settings, &|m| {
        rho.get(m as usize).copied().flatten()
    })
}

/// The maps artifact: the balanced trees as stored, so readers need not balance again.
pub fn encode_maps(maps: &PhotonMaps) -> Vec<u8> {
    let mut b = Vec::from(*MAPS_MAGIC);
    for m in [&maps.global, &maps.caustic] {
        b.extend_from_slice(&(m.emitted as u64).to_le_bytes());
        put_photons(&mut b, m.tree.photons());
        b.extend_from_slice(m.tree.axes());
    }
    put_radiance(&mut b, &maps.radiance);
    b
}

pub fn decode_maps(bytes: &[u8]) -> Result<PhotonMaps, String> {
    let mut r = Reader::new(bytes, MAPS_MAGIC, "photon maps")?;
    let map = |r: &mut Reader| -> Result<PhotonMap, String> {
        let emitted = u32::try_from(r.u64()?).map_err(|_| "emitted count out of range")?;
        let photons = read_photons(r)?;
        let axes = r.take(photons.len())?.to_vec();
        let tree = KdTree::from_parts(photons, axes)?;
        Ok(PhotonMap { tree, emitted })
    };
    let global = map(&mut r)?;
    let caustic = map(&mut r)?;
    let radiance = read_radiance(&mut r)?;
    r.end()?;
    Ok(PhotonMaps {
        global,
        caustic,
        radiance,
    })
}

/// The records artifact: records in merge order.
pub fn encode_records(records: &[Record]) -> Vec<u8> {
    let mut b = Vec::from(*RECORDS_MAGIC);
    put_records(&mut b, records);
    b
}

pub fn decode_records(bytes: &[u8]) -> Result<Vec<Record>, String> {
    let mut r = Reader::new(bytes, RECORDS_MAGIC, "irradiance records")?;
    let rec = read_records(&mut r)?;
    r.end()?;
    Ok(rec)
}

/// The photon-mapping integrator from a job's artifacts (the cache only when given).
pub fn integrator(
    prepared: &Prepared,
    maps: std::sync::Arc<PhotonMaps>,
    records: Option<Vec<Record>>,
) -> Result<PhotonIntegrator, String> {
    let settings = prepared
        .photon
        .ok_or("photon maps for a job that does not map photons")?;
    let cache = match (records, settings.irradiance_cache) {
        (Some(r), Some(ic)) => Some(std::sync::Arc::new(IrradianceCache::build(r, ic.accuracy))),
        _ => None,
    };
    Ok(PhotonIntegrator::new(
        settings,
        prepared.desc.integrator.rr_depth,
        maps,
        cache,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::job::{self, RenderSettings, TaskOutput, stitch};

    /// The Cornell glass at 24×20, photon mapping with small passes.
    fn glass() -> SceneDesc {
        let mut d = job::tests::scene("cornell-glass", 2);
        d.integrator.kind = IntegratorKind::Photon;
        d.integrator.photon.photons = Some(60_000);
        d.integrator.photon.caustic_photons = Some(30_000);
        d.integrator.photon.gather_rays = Some(4);
        d
    }

    #[test]
    fn passes_as_tasks_make_the_frame_render_makes_in_one_process() {
        let desc = glass();
        let frames = FrameRange::single(1);
        let local = Prepared::new(desc.clone(), frames);
        let worker = Prepared::scene_only(desc.clone());
        let plan = plan(&desc, &worker.analysis, frames).expect("photon plan");
        // Photon tasks, each encoded and decoded as on the wire, merged in order.
        let photon_tasks = plan.photon_tasks();
        assert!(photon_tasks.len() >= 4);
        let outs: Vec<(TaskKind, Vec<Photon>)> = photon_tasks
            .iter()
            .map(|t| {
                let out = execute(&worker, None, t).expect("photons");
                match decode_output(&encode_output(&out), t).expect("decode") {
                    PassOutput::Photons(p) => (t.kind, p),
                    _ => panic!("photons expected"),
                }
            })
            .collect();
        let maps = merge_photons(
            &desc,
            &plan.settings,
            outs.iter().map(|(k, p)| (*k, p.as_slice())),
        );
        let maps = decode_maps(&encode_maps(&maps)).expect("maps");
        let maps = std::sync::Arc::new(maps);
        let stage1 = integrator(&worker, maps.clone(), None).expect("integrator");
        let mut records = Vec::new();
        for t in plan.record_tasks(&desc) {
            match execute(&worker, Some(&stage1), &t).expect("records") {
                PassOutput::Records(r) => records.extend(r),
                _ => panic!("records expected"),
            }
        }
        let records = decode_records(&encode_records(&records)).expect("records");
        assert!(!records.is_empty());
        let full = integrator(&worker, maps, Some(records)).expect("integrator");
        let tasks = job::plan_frame(&desc, &RenderSettings::default(), 1);
        let camera = worker.camera(1);
        let farm: Vec<TaskOutput> = tasks
            .iter()
            .map(|t| worker.execute_using(&full, &camera, t))
            .collect();
        let alone: Vec<TaskOutput> = tasks.iter().map(|t| local.execute(t)).collect();
        let (w, h) = (desc.film.width, desc.film.height);
        assert_eq!(stitch(w, h, &farm), stitch(w, h, &alone));
    }

    #[test]
    fn keys_ignore_the_camera_and_see_a_changed_material() {
        let desc = glass();
        let a = tessera_render::analysis::analyze(&desc);
        let key = |d: &SceneDesc, frames: FrameRange| {
            let p = plan(d, &a, frames).expect("plan");
            (p.photons_key, p.records_key)
        };
        let (p0, r0) = key(&desc, FrameRange::single(1));
        let mut moved = desc.clone();
        moved.camera.position.x += 5.0;
        let (p1, r1) = key(&moved, FrameRange::single(1));
        assert_eq!(p0, p1, "the camera does not change the photon maps");
        assert_ne!(r0, r1, "it changes the irradiance records");
        let mut repainted = desc.clone();
        repainted.materials[0].kind = tessera_scene::MaterialKind::Diffuse {
            albedo: glam::Vec3::splat(0.5),
        };
        let (p2, r2) = key(&repainted, FrameRange::single(1));
        assert_ne!(p0, p2);
        assert_ne!(r0, r2);
        let mut more = desc.clone();
        more.integrator.spp = 99;
        assert_eq!(
            key(&more, FrameRange::single(1)).0,
            p0,
            "spp is not a pass setting"
        );
    }

    #[test]
    fn bad_pass_outputs_are_rejected() {
        let t = TaskSpec {
            kind: TaskKind::GlobalPhotons,
            frame: 0,
            tile_index: 0,
            x0: 0,
            y0: 0,
            x1: 0,
            y1: 0,
            sample_start: 0,
            sample_end: 10,
        };
        assert!(decode_output(b"nope", &t).is_err());
        let mut b = encode_output(&PassOutput::Photons(vec![]));
        b.push(0);
        assert!(decode_output(&b, &t).is_err());
        let mut b = Vec::from(*PHOTONS_MAGIC);
        b.extend_from_slice(&u64::MAX.to_le_bytes());
        assert!(decode_output(&b, &t).is_err());
        assert!(decode_maps(b"TMAP").is_err());
        let rec = TaskSpec {
            kind: TaskKind::Records,
            ..t
        };
        assert!(decode_output(&encode_output(&PassOutput::Photons(vec![])), &rec).is_err());
    }
}
