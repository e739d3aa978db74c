//! The binary form of a task's output, as workers upload it and the coordinator keeps it on
//! disk: a header, the counters, then each pixel's fixed-point sums, little-endian.
//!
//! ```text
//! "TSUM" u32 version | u32 x0 y0 x1 y1 sample_start sample_end | u64 rays samples nonfinite
//! per pixel: u64 samples, i128 w, wl[3], wl2[3], albedo[3], normal[3], depth, hit_w
//! ```

use tessera_render::film::{PixelSums, TileSums};
use tessera_render::{RayStats, SampleRange, Tile};

use crate::job::{TaskOutput, TaskSpec};

const MAGIC: &[u8; 4] = b"TSUM";
const VERSION: u32 = 1;
const HEADER: usize = 8 + 6 * 4 + 3 * 8;
const PIXEL: usize = 8 + 15 * 16;

/// Bytes of the encoded output of a tile of `pixels` pixels.
pub fn encoded_len(pixels: usize) -> usize {
    HEADER + pixels * PIXEL
}

pub fn encode(out: &TaskOutput) -> Vec<u8> {
    encode_sums(&out.sums, &out.stats)
}

/// Encodes a tile's sums and counters (what [`encode`] does with a [`TaskOutput`]'s).
pub fn encode_sums(s: &TileSums, stats: &RayStats) -> Vec<u8> {
    let mut b = Vec::with_capacity(encoded_len(s.pixels.len()));
    b.extend_from_slice(MAGIC);
    for v in [
        VERSION,
        s.tile.x0,
        s.tile.y0,
        s.tile.x1,
        s.tile.y1,
        s.samples.start,
        s.samples.end,
    ] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for v in [stats.rays, stats.samples, stats.nonfinite] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for p in &s.pixels {
        b.extend_from_slice(&p.samples.to_le_bytes());
        let w = [p.w];
        let wide = w
            .iter()
            .chain(&p.wl)
            .chain(&p.wl2)
            .chain(&p.albedo)
            .chain(&p.normal)
            .chain([&p.depth, &p.hit_w]);
        for v in wide {
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    b
}

/// Decodes an output and checks that it is the one `task` asked for.
pub fn decode(bytes: &[u8], task: &TaskSpec) -> Result<TaskOutput, String> {
    let tile = task.tile();
    let want = encoded_len(tile.pixel_count());
    if bytes.len() != want {
        return Err(format!(
            "expected {want} bytes of tile sums for a {}×{} tile, got {}",
            tile.width(),
            tile.height(),
            bytes.len()
        ));
    }
    if &bytes[0..4] != MAGIC {
        return Err("expected tile sums starting with \"TSUM\"".into());
    }
    let mut at = 4;
    let mut u32_ = || {
        let v = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap_or_default());
        at += 4;
        v
    };
    let version = u32_();
    let got_tile = Tile {
        x0: u32_(),
        y0: u32_(),
        x1: u32_(),
        y1: u32_(),
    };
    let samples = SampleRange {
        start: u32_(),
        end: u32_(),
    };
    if version != VERSION {
        return Err(format!(
            "expected tile sums version {VERSION}, got {version}"
        ));
    }
    if got_tile != tile || samples != task.samples() {
        return Err(format!(
            "expected the sums of tile {tile:?} samples {:?}, got tile {got_tile:?} samples {samples:?}",
            task.samples()
        ));
    }
    let u64_ = |at: &mut usize| {
        let v = u64::from_le_bytes(bytes[*at..*at + 8].try_into().unwrap_or_default());
        *at += 8;
        v
    };
    let stats = RayStats {
        rays: u64_(&mut at),
        samples: u64_(&mut at),
        nonfinite: u64_(&mut at),
    };
    let mut sums = TileSums::new(tile, samples);
    for p in sums.pixels.iter_mut() {
        p.samples = u64_(&mut at);
        let mut wide = [0i128; 15];
        for v in wide.iter_mut() {
            *v = i128::from_le_bytes(bytes[at..at + 16].try_into().unwrap_or_default());
            at += 16;
        }
        *p = PixelSums {
            samples: p.samples,
            w: wide[0],
            wl: [wide[1], wide[2], wide[3]],
            wl2: [wide[4], wide[5], wide[6]],
            albedo: [wide[7], wide[8], wide[9]],
            normal: [wide[10], wide[11], wide[12]],
            depth: wide[13],
            hit_w: wide[14],
        };
    }
    Ok(TaskOutput { sums, stats })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_rejects_the_wrong_tile() {
        let task = TaskSpec {
            kind: crate::job::TaskKind::Tile,
            frame: 1,
            tile_index: 0,
            x0: 2,
            y0: 3,
            x1: 5,
            y1: 4,
            sample_start: 4,
            sample_end: 9,
        };
        let mut sums = TileSums::new(task.tile(), task.samples());
        for (i, p) in sums.pixels.iter_mut().enumerate() {
            let v = (i as i128 + 1) * -(1i128 << 100);
            *p = PixelSums {
                samples: 5,
                w: v,
                wl: [v, 2 * v, 3],
                wl2: [4, 5, 6],
                albedo: [7, 8, 9],
                normal: [10, 11, 12],
                depth: 13,
                hit_w: 14 + i as i128,
            };
        }
        let out = TaskOutput {
            sums,
            stats: RayStats {
                rays: 1,
                samples: 2,
                nonfinite: 3,
            },
        };
        let bytes = encode(&out);
        assert_eq!(bytes.len(), encoded_len(3));
        assert_eq!(decode(&bytes, &task), Ok(out));
        let other = TaskSpec {
            sample_end: 8,
            ..task
        };
        assert!(
            decode(&bytes, &other)
                .unwrap_err()
                .contains("expected the sums")
        );
        assert!(decode(&bytes[1..], &task).is_err());
    }
}
