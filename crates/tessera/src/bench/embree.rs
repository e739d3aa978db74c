//! Embree 3 (Debian's libembree-dev) through its C API, for `tessera bench rays` only: a
//! triangle scene, closest-hit and occlusion queries one ray at a time (`rtcIntersect1`,
//! `rtcOccluded1`), as our BVH answers them, and in packets of eight (`rtcIntersect8`,
//! `rtcOccluded8`: how much tracing several rays per instruction stream gains on the same
//! rays). Built with `--features embree`; nothing else depends on it.
//!
//! Declarations follow embree3/rtcore_*.h of Embree 3.13 (RTC_MAX_INSTANCE_LEVEL_COUNT 1,
//! RTC_MIN_WIDTH 0).

use std::ffi::c_void;
use std::os::raw::c_char;

use anyhow::bail;
use glam::Vec3A;
use tessera_render::ray::Ray;

type Device = *mut c_void;
type RtcScene = *mut c_void;
type Geometry = *mut c_void;

const GEOMETRY_TYPE_TRIANGLE: u32 = 0;
const BUFFER_TYPE_INDEX: u32 = 0;
const BUFFER_TYPE_VERTEX: u32 = 1;
const FORMAT_UINT3: u32 = 0x5003;
const FORMAT_FLOAT3: u32 = 0x9003;
const INVALID_GEOMETRY_ID: u32 = u32::MAX;

#[repr(C)]
struct IntersectContext {
    flags: u32,
    filter: *const c_void,
    inst_id: [u32; 1],
}

#[repr(C, align(16))]
#[derive(Clone, Copy)]
struct RtcRay {
    org: [f32; 3],
    tnear: f32,
    dir: [f32; 3],
    time: f32,
    tfar: f32,
    mask: u32,
    id: u32,
    flags: u32,
}

#[repr(C, align(16))]
#[derive(Clone, Copy)]
struct RtcHit {
    ng: [f32; 3],
    u: f32,
    v: f32,
    prim_id: u32,
    geom_id: u32,
    inst_id: [u32; 1],
}

#[repr(C)]
struct RayHit {
    ray: RtcRay,
    hit: RtcHit,
}

/// Eight rays, structure of arrays (`RTCRay8`).
#[repr(C, align(32))]
#[derive(Clone, Copy)]
struct RtcRay8 {
    org: [[f32; 8]; 3],
    tnear: [f32; 8],
    dir: [[f32; 8]; 3],
    time: [f32; 8],
    tfar: [f32; 8],
    mask: [u32; 8],
    id: [u32; 8],
    flags: [u32; 8],
}

/// Their hits (`RTCHit8`).
#[repr(C, align(32))]
#[derive(Clone, Copy)]
struct RtcHit8 {
    ng: [[f32; 8]; 3],
    u: [f32; 8],
    v: [f32; 8],
    prim_id: [u32; 8],
    geom_id: [u32; 8],
    inst_id: [[u32; 8]; 1],
}

#[repr(C, align(32))]
struct RayHit8 {
    ray: RtcRay8,
    hit: RtcHit8,
}

/// A packet's lanes: −1 where a ray is, 0 where none is.
#[repr(C, align(32))]
struct Valid8([i32; 8]);

#[link(name = "embree3")]
unsafe extern "C" {
    fn rtcNewDevice(config: *const c_char) -> Device;
    fn rtcReleaseDevice(device: Device);
    fn rtcGetDeviceError(device: Device) -> u32;
    fn rtcNewScene(device: Device) -> RtcScene;
    fn rtcReleaseScene(scene: RtcScene);
    fn rtcNewGeometry(device: Device, kind: u32) -> Geometry;
    fn rtcSetNewGeometryBuffer(
        geometry: Geometry,
        kind: u32,
        slot: u32,
        format: u32,
        byte_stride: usize,
        count: usize,
    ) -> *mut c_void;
    fn rtcCommitGeometry(geometry: Geometry);
    fn rtcAttachGeometry(scene: RtcScene, geometry: Geometry) -> u32;
    fn rtcReleaseGeometry(geometry: Geometry);
    fn rtcCommitScene(scene: RtcScene);
    fn rtcIntersect1(scene: RtcScene, context: *mut IntersectContext, rayhit: *mut RayHit);
    fn rtcOccluded1(scene: RtcScene, context: *mut IntersectContext, ray: *mut RtcRay);
    fn rtcIntersect8(
        valid: *const Valid8,
        scene: RtcScene,
        context: *mut IntersectContext,
        rayhit: *mut RayHit8,
    );
    fn rtcOccluded8(
        valid: *const Valid8,
        scene: RtcScene,
        context: *mut IntersectContext,
        ray: *mut RtcRay8,
    );
}

/// `RTC_INTERSECT_CONTEXT_FLAG_COHERENT`: the packet's rays are told to be coherent.
const CONTEXT_FLAG_COHERENT: u32 = 1;

/// An Embree device and a committed scene of one triangle mesh.
pub struct Scene {
    device: Device,
    scene: RtcScene,
}

impl Scene {
    pub fn new(triangles: &[[Vec3A; 3]]) -> anyhow::Result<Scene> {
        // SAFETY: the calls follow Embree's API; the buffers it returns are sized for the
        // counts given and written within them before the geometry is committed.
        unsafe {
            let device = rtcNewDevice(std::ptr::null());
            if device.is_null() {
                bail!(
                    "Embree: rtcNewDevice failed (error {})",
                    rtcGetDeviceError(device)
                );
            }
            let scene = rtcNewScene(device);
            let geometry = rtcNewGeometry(device, GEOMETRY_TYPE_TRIANGLE);
            let n = triangles.len();
            let vertices =
                rtcSetNewGeometryBuffer(geometry, BUFFER_TYPE_VERTEX, 0, FORMAT_FLOAT3, 12, 3 * n)
                    as *mut [f32; 3];
            let indices =
                rtcSetNewGeometryBuffer(geometry, BUFFER_TYPE_INDEX, 0, FORMAT_UINT3, 12, n)
                    as *mut [u32; 3];
            if vertices.is_null() || indices.is_null() {
                bail!(
                    "Embree: no buffers for {n} triangles (error {})",
                    rtcGetDeviceError(device)
                );
            }
            for (i, t) in triangles.iter().enumerate() {
                for (k, v) in t.iter().enumerate() {
                    *vertices.add(3 * i + k) = v.to_array();
                }
                let first = 3 * i as u32;
                *indices.add(i) = [first, first + 1, first + 2];
            }
            rtcCommitGeometry(geometry);
            rtcAttachGeometry(scene, geometry);
            rtcReleaseGeometry(geometry);
            rtcCommitScene(scene);
            let error = rtcGetDeviceError(device);
            if error != 0 {
                bail!("Embree: building the scene failed (error {error})");
            }
            Ok(Scene { device, scene })
        }
    }

    fn ray(r: &Ray) -> RtcRay {
        RtcRay {
            org: r.o.to_array(),
            tnear: 0.0,
            dir: r.d.to_array(),
            time: 0.0,
            tfar: f32::INFINITY,
            mask: u32::MAX,
            id: 0,
            flags: 0,
        }
    }

    /// A query's context; `coherent` tells Embree a packet's rays are.
    fn context(coherent: bool) -> IntersectContext {
        IntersectContext {
            flags: if coherent { CONTEXT_FLAG_COHERENT } else { 0 },
            filter: std::ptr::null(),
            inst_id: [INVALID_GEOMETRY_ID],
        }
    }

    /// Whether the ray hits a triangle (the closest hit is searched for).
    pub fn intersect(&self, r: &Ray) -> bool {
        let mut rh = RayHit {
            ray: Self::ray(r),
            hit: RtcHit {
                ng: [0.0; 3],
                u: 0.0,
                v: 0.0,
                prim_id: INVALID_GEOMETRY_ID,
                geom_id: INVALID_GEOMETRY_ID,
                inst_id: [INVALID_GEOMETRY_ID],
            },
        };
        let mut context = Self::context(false);
        // SAFETY: a committed scene, an initialised context and ray.
        unsafe { rtcIntersect1(self.scene, &mut context, &mut rh) };
        rh.hit.geom_id != INVALID_GEOMETRY_ID
    }

    /// Whether anything blocks the ray (Embree sets tfar to −∞ then).
    pub fn occluded(&self, r: &Ray) -> bool {
        let mut ray = Self::ray(r);
        let mut context = Self::context(false);
        // SAFETY: as above.
        unsafe { rtcOccluded1(self.scene, &mut context, &mut ray) };
        ray.tfar == f32::NEG_INFINITY
    }
}

impl Scene {
    /// Up to eight rays as a packet: its lanes and the valid mask.
    fn packet(rays: &[Ray]) -> (RtcRay8, Valid8) {
        let mut p = RtcRay8 {
            org: [[0.0; 8]; 3],
            tnear: [0.0; 8],
            dir: [[1.0; 8]; 3],
            time: [0.0; 8],
            tfar: [f32::INFINITY; 8],
            mask: [u32::MAX; 8],
            id: [0; 8],
            flags: [0; 8],
        };
        let mut valid = Valid8([0; 8]);
        for (lane, r) in rays.iter().take(8).enumerate() {
            for axis in 0..3 {
                p.org[axis][lane] = r.o[axis];
                p.dir[axis][lane] = r.d[axis];
            }
            valid.0[lane] = -1;
        }
        (p, valid)
    }

    /// How many of up to eight rays hit a triangle, traced as one packet (`coherent`: the
    /// context says they are).
    pub fn intersect8(&self, rays: &[Ray], coherent: bool) -> usize {
        let (ray, valid) = Self::packet(rays);
        let mut rh = RayHit8 {
            ray,
            hit: RtcHit8 {
                ng: [[0.0; 8]; 3],
                u: [0.0; 8],
                v: [0.0; 8],
                prim_id: [INVALID_GEOMETRY_ID; 8],
                geom_id: [INVALID_GEOMETRY_ID; 8],
                inst_id: [[INVALID_GEOMETRY_ID; 8]; 1],
            },
        };
        let mut context = Self::context(coherent);
        // SAFETY: a committed scene, an initialised context, and a 32-byte aligned packet
        // and mask of eight lanes, as rtcIntersect8 requires.
        unsafe { rtcIntersect8(&valid, self.scene, &mut context, &mut rh) };
        (0..rays.len().min(8))
            .filter(|&lane| rh.hit.geom_id[lane] != INVALID_GEOMETRY_ID)
            .count()
    }

    /// How many of up to eight rays are blocked, traced as one packet.
    pub fn occluded8(&self, rays: &[Ray], coherent: bool) -> usize {
        let (mut ray, valid) = Self::packet(rays);
        let mut context = Self::context(coherent);
        // SAFETY: as in `intersect8`.
        unsafe { rtcOccluded8(&valid, self.scene, &mut context, &mut ray) };
        (0..rays.len().min(8))
            .filter(|&lane| ray.tfar[lane] == f32::NEG_INFINITY)
            .count()
    }
}

impl Drop for Scene {
    fn drop(&mut self) {
        // SAFETY: both were created in `new` and are released once.
        unsafe {
            rtcReleaseScene(self.scene);
            rtcReleaseDevice(self.device);
        }
    }
}
