//! Brute-force reference for subsurface transport: an analog volumetric random walk in a
//! semi-infinite homogeneous medium (z < 0) under a smooth refractive boundary, lit by a thin
//! beam at normal incidence at the origin. Free paths are exponential in σt = σs + σa; each
//! collision scatters with probability σs/σt (Henyey–Greenstein phase function, parameter g)
//! or absorbs; at the boundary the walk reflects with the Fresnel probability for its angle
//! and otherwise leaves. What leaves, binned by its distance r from the entry point, is the
//! diffuse reflectance profile Rd(r) the dipole approximates (issue 7, must-show 1).

use crate::sampler::hash::{hash, mix64};

/// Rd(r) in annuli, and the total reflectance, with one standard error each.
#[derive(Debug, Clone)]
pub struct SlabProfile {
    /// Annulus edges in r (length unit of the coefficients).
    pub edges: Vec<f64>,
    /// Reflectance per unit area in each annulus, and its standard error.
    pub rd: Vec<(f64, f64)>,
    /// Total diffuse reflectance (every walk that left, Fresnel transmission at entry
    /// included), and its standard error.
    pub total: (f64, f64),
    /// Of the total, what left after exactly one scattering (the single-scattering term).
    pub single: f64,
}

/// Traces `walks` random walks (deterministic in `seed`) and bins where they leave.
pub fn slab_profile(
    sigma_s: f64,
    sigma_a: f64,
    g: f64,
    eta: f64,
    walks: u64,
    seed: u64,
    edges: &[f64],
) -> SlabProfile {
    let sigma_t = sigma_s + sigma_a;
    let albedo = sigma_s / sigma_t;
    let t_entry = 1.0 - fresnel(1.0, eta);
    let mut counts = vec![0u64; edges.len().saturating_sub(1)];
    let (mut left, mut single) = (0u64, 0u64);
    for w in 0..walks {
        let key = hash(&[seed, w]);
        let mut dim = 0u64;
        let mut rand = || {
            dim += 1;
            ((mix64(key ^ dim.wrapping_mul(0x9e37_79b9_7f4a_7c15)) >> 11) as f64)
                / (1u64 << 53) as f64
        };
        let (mut p, mut d) = ([0.0f64; 3], [0.0f64, 0.0, -1.0]);
        let mut scatters = 0u32;
        loop {
            let t = -(1.0 - rand()).ln() / sigma_t;
            let z = p[2] + t * d[2];
            if z >= 0.0 {
                // Reaches the boundary: to the crossing point, then leave or reflect.
                let s = -p[2] / d[2];
                p = [p[0] + s * d[0], p[1] + s * d[1], 0.0];
                if rand() < fresnel(d[2], eta) {
                    d[2] = -d[2];
                    continue;
                }
                if scatters > 0 {
                    left += 1;
                    single += (scatters == 1) as u64;
                    let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
                    if let Some(i) = edges.windows(2).position(|e| r >= e[0] && r < e[1]) {
                        counts[i] += 1;
                    }
                }
                break;
            }
            p = [p[0] + t * d[0], p[1] + t * d[1], z];
            if rand() >= albedo {
                break;
            }
            scatters += 1;
            d = henyey_greenstein(d, g, rand(), rand());
        }
    }
    let n = walks as f64;
    let per = |k: u64| {
        let q = k as f64 / n;
        (t_entry * q, t_entry * (q * (1.0 - q) / n).sqrt())
    };
    let rd = counts
        .iter()
        .zip(edges.windows(2))
        .map(|(&k, e)| {
            let area = std::f64::consts::PI * (e[1] * e[1] - e[0] * e[0]);
            let (v, err) = per(k);
            (v / area, err / area)
        })
        .collect();
    SlabProfile {
        edges: edges.to_vec(),
        rd,
        total: per(left),
        single: per(single).0,
    }
}

/// Fresnel reflectance for light inside a medium of relative index `eta` reaching the
/// boundary with cosine `cos_i` (> 0) to its normal; 1 under total internal reflection.
/// (For `cos_i` = 1 it is also the reflectance at normal incidence from outside.)
fn fresnel(cos_i: f64, eta: f64) -> f64 {
    crate::bsdf::fresnel::dielectric(-cos_i as f32, eta as f32) as f64
}

/// A direction scattered from `d` by the Henyey–Greenstein phase function with mean cosine
/// `g` (uniform over the sphere at g = 0).
fn henyey_greenstein(d: [f64; 3], g: f64, u1: f64, u2: f64) -> [f64; 3] {
    let cos = crate::phase::hg_cos(g, u1);
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let phi = 2.0 * std::f64::consts::PI * u2;
    // A frame around d.
    let a = if d[2].abs() < 0.9 {
        [0.0, 0.0, 1.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let cross = |x: [f64; 3], y: [f64; 3]| {
        [
            x[1] * y[2] - x[2] * y[1],
            x[2] * y[0] - x[0] * y[2],
            x[0] * y[1] - x[1] * y[0],
        ]
    };
    let t = cross(a, d);
    let tl = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
    let t = [t[0] / tl, t[1] / tl, t[2] / tl];
    let b = cross(d, t);
    let (c1, c2) = (sin * phi.cos(), sin * phi.sin());
    [
        c1 * t[0] + c2 * b[0] + cos * d[0],
        c1 * t[1] + c2 * b[1] + cos * d[1],
        c1 * t[2] + c2 * b[2] + cos * d[2],
    ]
}

#[cfg(test)]
mod tests {
    use super::super::dipole::{Dipole, Medium};
    use super::*;

    /// Must-show 1 of issue 7 on a semi-infinite slab (isotropic scattering, σs = σs′, η 1.3,
    /// 200 000 walks each): the random walk's total diffuse reflectance matches the dipole's
    /// closed form within 1 % + 3σ (measured: albedo 0.99 0.6463 ± 0.0010 vs 0.6445; marble red
    /// 0.8600 ± 0.0007 vs 0.8665), and Rd(r) from 3 to 10 mean free paths within 4 % + 3σ per
    /// annulus (measured ratios 0.96–1.05). Nearer the entry point the diffusion approximation
    /// fails, as known: at 0.25 mfp the walk gives 1.9× the dipole (single scattering, 7 % of the
    /// total, is not in it), at 1.25 mfp 0.75×.
    #[test]
    fn random_walk_on_a_slab_matches_the_dipole_within_its_known_error() {
        let marble = Medium::named("marble").expect("marble");
        let cases = [
            ("albedo 0.99", 1.0, 0.0101),
            ("marble red", marble.sigma_s_prime[0], marble.sigma_a[0]),
        ];
        for (name, ss, sa) in cases {
            let m = Medium {
                sigma_s_prime: [ss; 3],
                sigma_a: [sa; 3],
                eta: 1.3,
            };
            let d = Dipole::new(&m, 0);
            let mfp = d.z_r;
            let edges: Vec<f64> = (0..=20).map(|i| mfp * 0.5 * i as f64).collect();
            let prof = slab_profile(ss, sa, 0.0, 1.3, 200_000, 7, &edges);
            let (total, err) = prof.total;
            eprintln!(
                "{name}: total walk {total:.4} ± {err:.4} (single {:.4}), dipole {:.4}",
                prof.single,
                d.total()
            );
            assert!(
                (total - d.total()).abs() <= 0.01 * d.total() + 3.0 * err,
                "{name}: total {total} ± {err}, dipole {}",
                d.total()
            );
            for (e, &(v, err)) in edges.windows(2).zip(&prof.rd) {
                let mid = 0.5 * (e[0] + e[1]);
                let dip = d.rd(mid);
                eprintln!(
                    "  r {:.2} mfp: walk {v:.4e} ± {err:.1e}, dipole {dip:.4e}, ratio {:.3}",
                    mid / mfp,
                    v / dip
                );
                if mid >= 3.0 * mfp {
                    assert!(
                        (v - dip).abs() <= 0.04 * dip + 3.0 * err,
                        "{name}, r = {:.2} mfp: walk {v} ± {err}, dipole {dip}",
                        mid / mfp
                    );
                }
            }
        }
    }
}
