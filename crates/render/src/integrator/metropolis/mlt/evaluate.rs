//! A path's measurement contribution and every strategy's density (C_s = f / p_s), which
//! the acceptance ratios of all mutations are written in.

use super::*;

impl Mlt {
    /// Evaluates path `x` into `e`: every C_s = f / p_s, the colour and film position, the
    /// selection densities. False where f = 0 (or the path is off the extended film).
    pub(super) fn evaluate(&self, ctx: &Ctx, x: &[Vertex], e: &mut PathEval) -> bool {
        let k = x.len() - 1;
        let n = x.len();
        for v in [
            &mut e.c,
            &mut e.sel_fwd,
            &mut e.sel_rev,
            &mut e.g,
            &mut e.pa_fwd,
            &mut e.pa_rev,
            &mut e.conv_fwd,
            &mut e.conv_rev,
            &mut e.eye_from,
        ] {
            v.clear();
            v.resize(n, 0.0);
        }
        // The lens end, with W_e and the direction density over the extended film.
        let to_cam = dir(&x[k], &x[k - 1]);
        let Some((we, pdf_cam, cos_cam, raster)) = ctx.camera.pinhole_importance(to_cam) else {
            return false;
        };
        if !on_extended_film(ctx, raster) {
            return false;
        }
        let film = &ctx.scene.film;
        let ext = (film.width as f64 * film.height as f64) / ctx_area(ctx);
        let (we, pdf_cam) = (we as f64 * ext, pdf_cam as f64 * ext);
        e.raster = raster;
        // The light end.
        let Some((li, light)) = ctx.light_of(&x[0]) else {
            return false;
        };
        let w01 = dir(&x[0], &x[1]);
        // A point or spot light: a delta in position (its density 1 in the discrete
        // measure), intensity instead of radiance, no cosine, never hit from the eye side. A
        // directional light alike, in direction, with irradiance.
        let point = ctx.is_delta_light(&x[0]);
        // A light at infinity: a direction (density per solid angle), the next vertex's
        // density per unit area of its disk; no distance and no cosine at the light.
        let infinite = x[0].infinite;
        let pmf = ctx.scene.lights.pmf(li);
        let le = match (infinite, point) {
            (true, true) => match light.sample_li(x[1].p, Vec2::ZERO) {
                Some(ls) if ls.wi.dot(x[0].wo) > 1.0 - 1e-4 => ls.li,
                _ => return false,
            },
            (true, false) => ctx.le(&x[0], &x[1]),
            (false, true) => light.intensity(w01),
            (false, false) => light.le_surface(x[0].ng, w01, x[0].p),
        };
        let (pa0, sel0) = if infinite {
            let disk = light.pdf_le(w01, w01, ctx.bounds).0;
            let direction = if point {
                pmf
            } else {
                ctx.pdf_le(&x[0], &x[1]).0
            };
            (direction, disk)
        } else {
            let (pos, pdf_dir) = light.pdf_le(x[0].ng, w01, ctx.bounds);
            (pmf * if point { 1.0 } else { pos }, pdf_dir)
        };
        e.pa_fwd[0] = pa0 as f64;
        e.sel_fwd[0] = sel0 as f64;
        // Edges: G and the per-area conversions toward each end.
        for i in 0..k {
            let d = x[i + 1].p - x[i].p;
            let d2 = d.length_squared();
            if d2 == 0.0 {
                return false;
            }
            let wn = d / d2.sqrt();
            let d2 = if i == 0 && infinite { 1.0 } else { d2 };
            let ca = if i == 0 && (point || infinite) {
                1.0
            } else {
                x[i].ng.dot(wn).abs() as f64
            };
            let cb = if i + 1 == k {
                cos_cam as f64
            } else {
                x[i + 1].ng.dot(wn).abs() as f64
            };
            let d2 = d2 as f64;
            e.g[i] = ca * cb / d2;
            e.conv_fwd[i] = cb / d2;
            e.conv_rev[i] = if i == 0 && point { 0.0 } else { ca / d2 };
        }
        e.pa_fwd[1] = e.sel_fwd[0] * e.conv_fwd[0];
        e.pa_rev[k - 1] = pdf_cam * e.conv_rev[k - 1];
        let mut color = Spectrum::ONE;
        let mut mag = 1.0f64;
        let norm = |f: Spectrum, color: &mut Spectrum, mag: &mut f64| {
            let m = f.max_element();
            if m > 0.0 && m.is_finite() {
                *color *= f / m;
                *mag *= m as f64;
                true
            } else {
                false
            }
        };
        if !norm(le, &mut color, &mut mag) {
            return false;
        }
        for i in 1..k {
            let Some(s) = scatter(
                ctx,
                &x[i],
                dir(&x[i], &x[i - 1]),
                dir(&x[i], &x[i + 1]),
                x[i].delta,
            ) else {
                return false;
            };
            if !norm(s.f, &mut color, &mut mag) {
                return false;
            }
            e.sel_fwd[i] = s.sel_imp as f64;
            e.sel_rev[i] = s.sel_rad as f64;
            if i + 1 < k {
                e.pa_fwd[i + 1] = s.pdf_imp as f64 * e.conv_fwd[i];
            }
            e.pa_rev[i - 1] = s.pdf_rad as f64 * e.conv_rev[i - 1];
        }
        let lum = luminance(color) as f64;
        if lum <= 0.0 {
            return false;
        }
        e.color = color / lum as f32;
        let base = mag * lum * we;
        // C_s = base × (1 / p_pos) Π_{i<s} G_{i−1}/pa_fwd_i × G_{s−1} × Π_{i≥s} G_i/pa_rev_i.
        let ratio = |num: f64, den: f64| if den > 0.0 { num / den } else { f64::NAN };
        // Suffix products of the eye side (NaN once a density is zero: that strategy cannot).
        let mut eye = 1.0f64;
        e.eye_from[k] = 1.0;
        for i in (0..k).rev() {
            eye *= ratio(e.g[i], e.pa_rev[i]);
            e.eye_from[i] = eye;
        }
        e.c[0] = base * e.eye_from[0];
        let mut light_to = ratio(1.0, e.pa_fwd[0]);
        for s in 1..=k {
            if s >= 2 {
                light_to *= ratio(e.g[s - 2], e.pa_fwd[s - 1]);
            }
            let joinable = (s == 1 || !x[s - 1].delta) && (s == k || !x[s].delta);
            e.c[s] = if joinable {
                base * light_to * e.g[s - 1] * e.eye_from[s]
            } else {
                0.0
            };
        }
        for c in &mut e.c {
            if !c.is_finite() {
                *c = 0.0;
            }
        }
        true
    }
}

/// Scattering at interior vertex `v` between `wp` (toward the light side) and `wn` (toward
/// the eye side); `None` where it is zero or inconsistent.
fn scatter(ctx: &Ctx, v: &Vertex, wp: Vec3A, wn: Vec3A, delta: bool) -> Option<Scatter> {
    let si = v.si.as_ref()?;
    let material = ctx.scene.material(si.material);
    let cos_p = wp.dot(si.ng).abs();
    if cos_p == 0.0 {
        return None;
    }
    if !delta {
        let fr = material.frame(si, wn);
        let (wo, wi) = (fr.to_local(wn), fr.to_local(wp));
        if !consistent(si, wn, wp, wo, wi) {
            return None;
        }
        let bsdf = material.bsdf_at(si);
        let f = bsdf.eval(wo, wi, TransportMode::Radiance) * (wi.z.abs() / cos_p);
        let pdf_rad = bsdf.pdf(wo, wi, TransportMode::Radiance);
        let fi = material.frame(si, wp);
        let pdf_imp = bsdf.pdf(fi.to_local(wp), fi.to_local(wn), TransportMode::Importance);
        return Some(Scatter {
            f,
            pdf_imp,
            pdf_rad,
            sel_imp: pdf_imp,
            sel_rad: pdf_rad,
        });
    }
    let lobe = ctx.delta_lobe(si, wn, wp)?;
    Some(Scatter {
        f: lobe.c_rad / cos_p,
        pdf_imp: lobe.pdf_imp,
        pdf_rad: lobe.p_rad,
        sel_imp: lobe.p_imp,
        sel_rad: lobe.p_rad,
    })
}
