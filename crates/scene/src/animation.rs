//! Camera paths for fly-through animations: keyframes in time, interpolated smoothly.
//!
//! Position, look-at point, up vector and field of view are each a C¹ cubic Hermite spline
//! through the keyframes, with Catmull–Rom tangents for non-uniform knot spacing
//! (m_i = (p_{i+1} − p_{i−1}) / (t_{i+1} − t_{i−1}), one-sided at the ends). Outside the
//! keyframes' time span the path holds its first or last key. Frame `n` (1-based) is at time
//! `t_0 + (n − 1) / fps`.

use glam::Vec3;

use crate::camera::CameraDesc;

/// One keyframe, in scene units and radians (validated).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Keyframe {
    /// Seconds.
    pub time: f32,
    pub position: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    /// Full vertical field of view, radians.
    pub fov_y: f32,
}

/// A camera path: keyframes sorted by strictly increasing time, and the frame rate.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraPath {
    /// Frames per second.
    pub fps: f32,
    pub keyframes: Vec<Keyframe>,
}

impl CameraPath {
    /// Frames from the first keyframe to the last: ⌊(t_last − t_0)·fps⌋ + 1.
    pub fn frame_count(&self) -> u32 {
        let (Some(first), Some(last)) = (self.keyframes.first(), self.keyframes.last()) else {
            return 1;
        };
        let span = f64::from(last.time - first.time) * f64::from(self.fps);
        // A tolerance so that 2 s at 24 fps is 49 frames despite rounding in f32 times.
        // Saturates: a span past u32::MAX frames is refused by the caller, not wrapped.
        ((span + 1e-4).floor() as u32).saturating_add(1)
    }

    /// Time of frame `frame` (1-based), seconds.
    pub fn time(&self, frame: u32) -> f32 {
        let t0 = self.keyframes.first().map_or(0.0, |k| k.time);
        (f64::from(t0) + f64::from(frame.saturating_sub(1)) / f64::from(self.fps)) as f32
    }

    /// The camera at frame `frame` (1-based): `base` (lens, exposure) with the interpolated
    /// position, look-at, up and field of view.
    pub fn camera(&self, frame: u32, base: &CameraDesc) -> CameraDesc {
        let k = self.at(self.time(frame));
        CameraDesc {
            position: k.position,
            look_at: k.look_at,
            up: k.up,
            fov_y: k.fov_y,
            ..*base
        }
    }

    /// The interpolated keyframe at time `t`.
    pub fn at(&self, t: f32) -> Keyframe {
        let keys = &self.keyframes;
        let n = keys.len();
        if n == 1 || t <= keys[0].time {
            return keys[0];
        }
        if t >= keys[n - 1].time {
            return keys[n - 1];
        }
        // The segment [i, i + 1] holding t.
        let i = keys.partition_point(|k| k.time <= t) - 1;
        let (t0, t1) = (keys[i].time, keys[i + 1].time);
        let h = t1 - t0;
        let s = (t - t0) / h;
        // Catmull–Rom tangent at key j, in units per second.
        let tangent = |f: &dyn Fn(&Keyframe) -> Vec3, j: usize| -> Vec3 {
            let a = j.saturating_sub(1);
            let b = (j + 1).min(n - 1);
            (f(&keys[b]) - f(&keys[a])) / (keys[b].time - keys[a].time)
        };
        let hermite = |f: &dyn Fn(&Keyframe) -> Vec3| -> Vec3 {
            let (s2, s3) = (s * s, s * s * s);
            let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
            let h10 = s3 - 2.0 * s2 + s;
            let h01 = -2.0 * s3 + 3.0 * s2;
            let h11 = s3 - s2;
            f(&keys[i]) * h00
                + tangent(f, i) * (h10 * h)
                + f(&keys[i + 1]) * h01
                + tangent(f, i + 1) * (h11 * h)
        };
        Keyframe {
            time: t,
            position: hermite(&|k| k.position),
            look_at: hermite(&|k| k.look_at),
            up: hermite(&|k| k.up).normalize_or_zero(),
            fov_y: hermite(&|k| Vec3::splat(k.fov_y)).x,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(time: f32, x: f32) -> Keyframe {
        Keyframe {
            time,
            position: Vec3::new(x, 0.0, 0.0),
            look_at: Vec3::new(x, 0.0, 1.0),
            up: Vec3::Y,
            fov_y: 0.5 + x * 0.01,
        }
    }

    #[test]
    fn passes_through_keyframes_and_holds_outside() {
        let path = CameraPath {
            fps: 24.0,
            keyframes: vec![key(0.0, 0.0), key(1.0, 3.0), key(3.0, -1.0)],
        };
        for k in &path.keyframes {
            let at = path.at(k.time);
            assert!((at.position - k.position).length() < 1e-5, "{at:?}");
            assert!((at.fov_y - k.fov_y).abs() < 1e-6);
        }
        assert_eq!(path.at(-1.0), path.keyframes[0]);
        assert_eq!(path.at(10.0), path.keyframes[2]);
        assert_eq!(path.frame_count(), 73);
        assert!((path.time(25) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn interpolation_is_smooth_across_keys() {
        let path = CameraPath {
            fps: 24.0,
            keyframes: vec![key(0.0, 0.0), key(1.0, 3.0), key(1.5, 2.0), key(3.0, -1.0)],
        };
        // C¹: one-sided difference quotients agree at an inner key.
        let d = 1e-3;
        for k in &path.keyframes[1..3] {
            let left = (path.at(k.time).position.x - path.at(k.time - d).position.x) / d;
            let right = (path.at(k.time + d).position.x - path.at(k.time).position.x) / d;
            assert!(
                (left - right).abs() < 0.05,
                "{left} vs {right} at {}",
                k.time
            );
        }
        // Collinear, evenly spaced keys move at constant speed (the spline reproduces lines).
        let line = CameraPath {
            fps: 10.0,
            keyframes: vec![key(0.0, 0.0), key(1.0, 1.0), key(2.0, 2.0)],
        };
        for f in 1..=line.frame_count() {
            let t = line.time(f);
            assert!((line.at(t).position.x - t).abs() < 1e-5);
        }
    }

    #[test]
    fn a_span_of_more_frames_than_u32_holds_saturates() {
        let path = CameraPath {
            fps: 1e4,
            keyframes: vec![key(0.0, 0.0), key(3e38, 1.0)],
        };
        assert_eq!(path.frame_count(), u32::MAX);
    }
}
