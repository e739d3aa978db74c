//! View-independent precomputation as passes (docs/src/design/overview.md: "passes are tasks too"): each builds an
//! artifact addressed by a hash of everything that determines it, so every frame of a
//! camera-only fly-through, and every later job of the same scene, reads it instead of
//! building it again.

pub(super) mod photons;
mod records;
mod subsurface;

pub use photons::PhotonsPass;
pub use records::RecordsPass;
pub use subsurface::SubsurfacePass;

use sha2::{Digest, Sha256};
use tessera_scene::{LightDesc, SceneDesc};

use super::TaskSpec;

/// The hash as hex.
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

/// Feeds what light transport in `desc` depends on, apart from the camera and the method's
/// settings, to `h`: units, materials, geometry, emission, lights. Floats by their bits; small
/// descriptions by their `Debug` form (Rust prints floats so they round-trip, so the form is
/// exact).
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
        // Texture coordinates and tangents decide what textures and normal maps show.
        for (tag, set) in [(b"uv0", &m.uvs), (b"uv1", &m.uvs1)] {
            if let Some(uv) = set {
                h.update(tag);
                for t in uv {
                    h.update(t.x.to_le_bytes());
                    h.update(t.y.to_le_bytes());
                }
            }
        }
        if let Some(t) = &m.tangents {
            h.update(b"tangents");
            for c in t.iter().flatten() {
                for x in c.to_array() {
                    h.update(x.to_le_bytes());
                }
            }
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

/// Tasks over index ranges [0, count) of `per_task` items each, numbered from `first`, with
/// the ranges offset by `offset` (a pass whose tasks share one index space).
pub(crate) fn index_ranges(
    kind: &str,
    step: u32,
    count: u32,
    per_task: u32,
    first: u32,
) -> Vec<TaskSpec> {
    let per_task = per_task.max(1);
    (0..count.div_ceil(per_task))
        .map(|i| {
            let start = i * per_task;
            TaskSpec::new(kind, 0, step, first + i)
                .with_range(start, start.saturating_add(per_task).min(count))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_ranges_cover_the_count_in_order() {
        let t = index_ranges("photons", 1, 60_001, 25_000, 5);
        let ranges: Vec<(u32, u32, u32)> = t.iter().map(|t| (t.index, t.start, t.end)).collect();
        assert_eq!(
            ranges,
            [(5, 0, 25_000), (6, 25_000, 50_000), (7, 50_000, 60_001)]
        );
        assert!(
            t.iter()
                .all(|t| t.is_pass() && t.step == 1 && t.pixels() == 0)
        );
        assert!(index_ranges("x", 0, 0, 10, 0).is_empty());
        // The last range ends at the count even where start + per_task would overflow.
        let last = index_ranges("x", 0, u32::MAX, u32::MAX - 1, 0);
        assert_eq!(
            last.last().map(|t| (t.start, t.end)),
            Some((u32::MAX - 1, u32::MAX))
        );
    }
}
