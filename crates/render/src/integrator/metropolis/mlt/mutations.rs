//! Veach's four mutations (§11.4): bidirectional, lens subpath, lens perturbation, caustic
//! perturbation, each returning its acceptance probability.

use super::*;

/// p_d's weight for deleting `kd` edges (Veach: mostly one or two).
fn delete_weight(kd: usize) -> f64 {
    match kd {
        1 => 0.25,
        2 => 0.5,
        _ => 0.5f64.powi(kd as i32 - 1),
    }
}

/// Probability of deleting `kd` edges starting after vertex `l` of a path of `k` edges: kd
/// from [`delete_weight`] over 1..=k+1 (x₀ may go; the lens stays), then l uniform.
fn p_delete(kd: usize, k: usize) -> f64 {
    let total: f64 = (1..=k + 1).map(delete_weight).sum();
    delete_weight(kd) / total / (k + 2 - kd) as f64
}

/// Probability of adding `ka` edges where `kd` were deleted: kd − 1, kd, kd + 1 weighted
/// 1 : 2 : 1 (at least one).
fn p_add(kd: usize, ka: usize) -> f64 {
    let w = |a: usize| if a == kd { 0.5 } else { 0.25 };
    let total: f64 = (kd.saturating_sub(1).max(1)..=kd + 1).map(w).sum();
    if ka + 1 < kd || ka > kd + 1 || ka == 0 {
        return 0.0;
    }
    w(ka) / total
}

/// Probability that `j` of `n` new vertices come from the light side, joined after vertex
/// `l`: uniform, except that an existing light vertex (l = 0) is only ever joined to.
fn p_split(l: isize, n: usize, j: usize) -> f64 {
    if l == 0 {
        (j == 0) as u8 as f64
    } else {
        1.0 / (n + 1) as f64
    }
}

impl Mlt {
    /// Veach's bidirectional mutation; returns the acceptance ratio (0: rejected).
    pub(super) fn bidirectional(
        &self,
        ctx: &Ctx,
        w: &mut Work,
        rng: &mut Rng,
        stats: &mut RayStats,
    ) -> f64 {
        let Work { x, ex, y, ey, eye } = w;
        let kx = x.len() - 1;
        // Edges deleted: kd from p_d, then where (l = −1: x₀ goes too).
        let total: f64 = (1..=kx + 1).map(delete_weight).sum();
        let mut u = rng.uniform() as f64 * total;
        let mut kd = kx + 1;
        for k in 1..=kx + 1 {
            u -= delete_weight(k);
            if u < 0.0 {
                kd = k;
                break;
            }
        }
        let l = rng.below(kx + 2 - kd) as isize - 1;
        let m = (l + kd as isize) as usize;
        let ka = match (rng.uniform(), kd) {
            (u, 1) if u < 2.0 / 3.0 => 1,
            (_, 1) => 2,
            (u, _) if u < 0.25 => kd - 1,
            (u, _) if u < 0.75 => kd,
            _ => kd + 1,
        };
        let ky = kx + ka - kd;
        if ky < MIN_DEPTH as usize + 1 || ky > self.max_depth as usize + 1 {
            return 0.0;
        }
        let na = ka - 1;
        let j = if l == 0 { 0 } else { rng.below(na + 1) };
        let first = (l + 1) as usize;
        y.clear();
        y.extend_from_slice(&x[..first]);
        // The light side: j new vertices after x_l (from a new light point if l = −1).
        if j > 0 {
            let mut ray = if l < 0 {
                let Some((v, e, _)) = ctx.light_start(&mut RngSampler(rng)) else {
                    return 0.0;
                };
                y.push(v);
                e.ray
            } else {
                let at = l as usize;
                let Some(ray) = extend(ctx, y, at, TransportMode::Importance, rng) else {
                    return 0.0;
                };
                ray
            };
            while y.len() < first + j {
                let Some(v) = trace(ctx, &ray, stats) else {
                    return 0.0;
                };
                y.push(v);
                if y.len() == first + j {
                    break;
                }
                let at = y.len() - 1;
                let Some(next) = extend(ctx, y, at, TransportMode::Importance, rng) else {
                    return 0.0;
                };
                ray = next;
            }
        }
        // The light side's end is joined, not scattered from.
        if let Some(end) = y.last_mut() {
            end.delta = false;
        }
        // The eye side: na − j new vertices before x_m, traced from x_m (the lens: a new
        // film point).
        let e = na - j;
        eye.clear();
        eye.push(x[m]);
        if m < kx {
            eye.push(x[m + 1]);
        }
        let mut ray = if e == 0 {
            None
        } else if m == kx {
            Some(film_ray(ctx, &mut RngSampler(rng)).0)
        } else {
            // eye = [x_m, x_{m+1}]: sampling at 0 toward the light side, from x_{m+1}.
            eye.swap(0, 1);
            let r = extend(ctx, eye, 1, TransportMode::Radiance, rng);
            eye.swap(0, 1);
            match r {
                Some(r) => Some(r),
                None => return 0.0,
            }
        };
        if m < kx {
            eye.pop();
        }
        while let Some(r) = ray.take() {
            let v = match trace(ctx, &r, stats) {
                Some(v) => v,
                // The new light end (l = −1, j = 0) may be the environment.
                None if l < 0 && j == 0 && eye.len() == e => match escape(ctx, &r) {
                    Some(v) => v,
                    None => return 0.0,
                },
                None => return 0.0,
            };
            eye.push(v);
            if eye.len() == e + 1 {
                break;
            }
            let at = eye.len() - 1;
            ray = match extend(ctx, eye, at, TransportMode::Radiance, rng) {
                Some(r) => Some(r),
                None => return 0.0,
            };
        }
        if e == 0 && m < kx {
            eye[0].delta = false;
        } else if e > 0 {
            eye[e].delta = false;
        }
        y.extend(eye.iter().rev());
        y.extend_from_slice(&x[m + 1..]);
        debug_assert_eq!(y.len(), ky + 1);
        anchor(y);
        // The join (none when the eye side ran into a light, l = −1 and j = 0).
        let s = first + j;
        if s > 0 {
            stats.rays += 1;
            if !visible(ctx, &y[s - 1], &y[s]) {
                return 0.0;
            }
        }
        if !self.evaluate(ctx, y, ey) || ey.c[s] <= 0.0 {
            return 0.0;
        }
        let sum = |c: &[f64], n: usize| -> f64 {
            (0..=n)
                .filter(|&jj| c[first + jj] > 0.0)
                .map(|jj| p_split(l, n, jj) / c[first + jj])
                .sum()
        };
        let (sx, sy) = (sum(&ex.c, kd - 1), sum(&ey.c, na));
        p_delete(ka, ky) * p_add(ka, kd) * sx / (p_delete(kd, kx) * p_add(kd, ka) * sy)
    }

    /// Veach's lens subpath mutation: the eye end E S* D of the path traced anew from a
    /// uniform film point; returns the acceptance ratio.
    pub(super) fn lens_subpath(
        &self,
        ctx: &Ctx,
        w: &mut Work,
        rng: &mut Rng,
        stats: &mut RayStats,
    ) -> f64 {
        let Work { x, ex, y, ey, eye } = w;
        let kx = x.len() - 1;
        let scene = ctx.scene;
        let Some(q) = lens_subpath_start(scene, x) else {
            return 0.0;
        };
        eye.clear();
        eye.push(x[kx]);
        let mut ray = film_ray(ctx, &mut RngSampler(rng)).0;
        loop {
            let Some(v) = trace(ctx, &ray, stats) else {
                return 0.0;
            };
            eye.push(v);
            if q + eye.len() - 1 > self.max_depth as usize + 1 {
                return 0.0;
            }
            if smooth(scene, &v) {
                break;
            }
            let at = eye.len() - 1;
            ray = match extend(ctx, eye, at, TransportMode::Radiance, rng) {
                Some(r) => r,
                None => return 0.0,
            };
        }
        let ky = q + eye.len() - 1;
        if ky < MIN_DEPTH as usize + 1 {
            return 0.0;
        }
        y.clear();
        y.extend_from_slice(&x[..q]);
        y.extend(eye.iter().rev());
        anchor(y);
        stats.rays += 1;
        if !visible(ctx, &y[q - 1], &y[q]) {
            return 0.0;
        }
        if !self.evaluate(ctx, y, ey) || ex.c[q] <= 0.0 {
            return 0.0;
        }
        ey.c[q] / ex.c[q]
    }

    /// Veach's lens perturbation: paths ending (L|D) D S* E, the film point moved and the
    /// specular chain retraced; returns the acceptance ratio.
    pub(super) fn lens_perturbation(
        &self,
        ctx: &Ctx,
        w: &mut Work,
        rng: &mut Rng,
        stats: &mut RayStats,
    ) -> f64 {
        let Work { x, ex, y, ey, eye } = w;
        let kx = x.len() - 1;
        let Some(q) = lens_perturbation_start(x) else {
            return 0.0;
        };
        let film = &ctx.scene.film;
        let (r1, r2) = (0.1f32, 0.05 * film.width.max(film.height) as f32);
        let r = r2 * (r1 / r2).powf(rng.uniform());
        let phi = std::f32::consts::TAU * rng.uniform();
        let raster = ex.raster + r * Vec2::new(phi.cos(), phi.sin());
        if !on_extended_film(ctx, raster) {
            return 0.0;
        }
        let ray = ctx.camera.generate_ray(raster, Vec2::ZERO);
        eye.clear();
        eye.push(x[kx]);
        let lobes = (q + 1..kx).rev().map(|i| transmits(x, i));
        if retrace(ctx, eye, ray, lobes, TransportMode::Radiance, stats).is_none() {
            return 0.0;
        }
        y.clear();
        y.extend_from_slice(&x[..q]);
        y.extend(eye.iter().rev());
        anchor(y);
        stats.rays += 1;
        if !visible(ctx, &y[q - 1], &y[q]) {
            return 0.0;
        }
        if !self.evaluate(ctx, y, ey) {
            return 0.0;
        }
        let held = |e: &PathEval| e.c[q] * (q + 1..kx).map(|i| e.sel_rev[i]).product::<f64>();
        let hx = held(ex);
        if hx <= 0.0 {
            return 0.0;
        }
        held(ey) / hx
    }

    /// Veach's caustic perturbation: paths ending (L|D) S⁺ D E, the direction leaving the
    /// light-side vertex turned and the specular chain retraced to a new point seen by the
    /// lens; returns the acceptance ratio.
    pub(super) fn caustic_perturbation(
        &self,
        ctx: &Ctx,
        w: &mut Work,
        rng: &mut Rng,
        stats: &mut RayStats,
    ) -> f64 {
        let Work { x, ex, y, ey, .. } = w;
        let kx = x.len() - 1;
        let Some(c) = caustic_start(x) else {
            return 0.0;
        };
        let (t1, t2) = (1e-4f32, 0.1f32);
        let theta = t2 * (t1 / t2).powf(rng.uniform());
        let phi = std::f32::consts::TAU * rng.uniform();
        let wd = dir(&x[c], &x[c + 1]);
        let (st, ct) = theta.sin_cos();
        let wd = Frame::from_normal(wd).to_world(Vec3A::new(st * phi.cos(), st * phi.sin(), ct));
        y.clear();
        y.extend_from_slice(&x[..=c]);
        let lobes = (c + 1..kx - 1).map(|i| transmits(x, i));
        if retrace(
            ctx,
            y,
            spawn(&x[c], wd),
            lobes,
            TransportMode::Importance,
            stats,
        )
        .is_none()
        {
            return 0.0;
        }
        y.push(x[kx]);
        stats.rays += 1;
        if !ctx.scene.unoccluded_between(y[kx - 1].end(), y[kx].end()) {
            return 0.0;
        }
        if !self.evaluate(ctx, y, ey) {
            return 0.0;
        }
        let held = |e: &PathEval| e.c[kx] * (c..kx - 1).map(|i| e.sel_fwd[i]).product::<f64>();
        let hx = held(ex);
        if hx <= 0.0 {
            return 0.0;
        }
        held(ey) / hx
    }
}
