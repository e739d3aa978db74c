//! The sampled BSSRDF: where light that entered at p_o leaves (pbrt-v3 §15.4, in the spirit of
//! Mertens et al. 2003's tangent-plane sampling, as King et al. 2013 made it robust on curved
//! surfaces). A radius r is drawn from one channel's profile ([`RadialTable`]), an angle φ
//! uniformly, and an axis — the normal at p_o (probability ½) or one of its two tangents (¼
//! each); a probe chord through the point at (r, φ) in the plane across that axis, as long as
//! the profile's reach, finds every surface of the same material it crosses, and one of them is
//! chosen uniformly. Its area density sums every axis and channel that could have produced it
//! (one-sample MIS, balance heuristic), each as the planar density at the radius projected
//! along that axis times |n · axis| at the hit.
//!
//! [`RadialTable`]: crate::bssrdf::profile::RadialTable

use glam::Vec4;

use crate::bssrdf::Subsurface;
use crate::math::Frame;
use crate::ray::Ray;
use crate::scene::{Scene, SurfaceInteraction};
use crate::spectrum::Spectrum;
use crate::stats::RayStats;

/// Surfaces of the material a probe chord can keep; more are not looked for.
const MAX_HITS: usize = 8;

/// Probability of probing along the normal, then along each tangent.
const AXIS_PROB: [f32; 3] = [0.5, 0.25, 0.25];

/// An exit point for light that entered at `si` (material `sub`), and the weight
/// Rd(|p_i − p_o|) / pdf(p_i) it carries (per channel; the directional factors are the
/// interface's and the exit lobe's). `u`: axis and channel, radius, angle, which hit.
pub fn sample_exit(
    scene: &Scene,
    si: &SurfaceInteraction,
    sub: &Subsurface,
    u: Vec4,
    stats: &mut RayStats,
) -> Option<(SurfaceInteraction, Spectrum)> {
    let frame = Frame::from_normal(si.ns);
    // Axes: (probe direction, the two spanning the plane across it).
    let axes = [
        (frame.n, frame.s, frame.t),
        (frame.s, frame.t, frame.n),
        (frame.t, frame.n, frame.s),
    ];
    let (axis, ux) = if u.x < AXIS_PROB[0] {
        (0, u.x / AXIS_PROB[0])
    } else if u.x < AXIS_PROB[0] + AXIS_PROB[1] {
        (1, (u.x - AXIS_PROB[0]) / AXIS_PROB[1])
    } else {
        (2, (u.x - AXIS_PROB[0] - AXIS_PROB[1]) / AXIS_PROB[2])
    };
    let channel = ((ux * 3.0) as usize).min(2);
    let table = sub.table(channel);
    let (r, r_max) = (table.sample(u.y), table.r_max());
    if r >= r_max || r.is_nan() {
        return None;
    }
    let (vz, vx, vy) = axes[axis];
    let (sin, cos) = (2.0 * std::f32::consts::PI * u.z).sin_cos();
    let half = (r_max * r_max - r * r).sqrt();
    let start = si.p + (vx * cos + vy * sin) * r - vz * half;
    let end = start + vz * (2.0 * half);

    let mut hits = [None::<SurfaceInteraction>; MAX_HITS];
    let mut count = 0;
    let mut ray = Ray::new(start, vz);
    while count < MAX_HITS {
        stats.rays += 1;
        let Some(hit) = scene.intersect(&ray) else {
            break;
        };
        if (end - hit.p).dot(vz) <= 0.0 {
            break;
        }
        if hit.material == si.material {
            hits[count] = Some(hit);
            count += 1;
        }
        ray = hit.spawn(vz);
    }
    if count == 0 {
        return None;
    }
    let pick = ((u.w * count as f32) as usize).min(count - 1);
    let pi = hits[pick]?;

    // The density of p_i over every axis and channel.
    let d = frame.to_local(pi.p - si.p);
    let n = frame.to_local(pi.ns);
    let projected = [
        (d.x * d.x + d.y * d.y).sqrt(),
        (d.y * d.y + d.z * d.z).sqrt(),
        (d.z * d.z + d.x * d.x).sqrt(),
    ];
    let cosines = [n.z.abs(), n.x.abs(), n.y.abs()];
    let mut pdf = 0.0f32;
    for a in 0..3 {
        let planar: f32 = (0..3).map(|c| sub.table(c).pdf_area(projected[a])).sum();
        pdf += AXIS_PROB[a] * planar / 3.0 * cosines[a];
    }
    pdf /= count as f32;
    if pdf <= 0.0 || pdf.is_nan() {
        return None;
    }
    let weight = sub.rd((pi.p - si.p).length()) / pdf;
    Some((pi, weight))
}
