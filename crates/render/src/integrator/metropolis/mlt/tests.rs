use super::*;

/// On cornell-glass (glass sphere and cylinder, a small spherical bulb), for bootstrap
/// paths of every depth and strategy: the path's f / p_s as this module evaluates it
/// equals BDPT's unweighted estimate of the strategy that made it (connections s, t ≥ 2,
/// camera paths hitting the light s = 0, light tracing t = 1 onto the film, and s = 1 by
/// BDPT's rule for the light point the bootstrap drew). So f and every strategy's
/// density, specular vertices included (η², shading normals, lobe probabilities), are
/// BDPT's. And for paths on the film, BDPT's MIS weight (and VCM's, with merges) is the
/// power heuristic over these densities — through specular chains too, where a caustic
/// seen through glass must go to merging, not to the camera path that hit the bulb.
#[test]
fn path_contributions_and_weights_equal_bdpt_for_the_strategy_that_made_them() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let mut desc = tessera_scene::load(&root.join("cornell-glass/scene.json")).expect("scene");
    desc.film.width = 32;
    desc.film.height = 32;
    let scene = Scene::build(&desc);
    let camera = Camera::new(&desc.camera, &desc.film);
    let mlt = Mlt::new(&desc);
    let ctx = mlt.ctx(&scene, &camera).expect("supported");
    let film = &scene.film;
    let ext = (film.width * film.height) as f64 / ctx_area(&ctx);
    let mut work = Work::default();
    let (mut compared, mut specular, mut weighed, mut drifted) = (0, 0, 0, 0);
    for i in 0..120_000 {
        let (w, s) = mlt.bootstrap_strategy(&ctx, i, &mut work, &mut RayStats::default());
        let t = work.x.len() - s;
        let r = work.ex.raster;
        let on_film =
            r.x >= 0.0 && r.y >= 0.0 && r.x < film.width as f32 && r.y < film.height as f32;
        if w <= 0.0 || (t == 1 && !on_film) {
            continue;
        }
        let bdpt = if s == 1 {
            // BDPT samples s = 1's light point anew; its estimate for this one, by its
            // own rule: camera subpath β · f · L_e |cos θ| |cos θ_light| / (d² p_light).
            let (pt, light) = (&work.eye[t - 1], &work.y[0]);
            let d = light.p - pt.p;
            let wi = d.normalize();
            let le = ctx.scene.lights.get(match light.kind {
                crate::integrator::bdpt::Kind::Light(l) => l,
                _ => unreachable!("a light subpath starts on a light"),
            });
            let l = pt.beta
                * ctx.f_and_pdfs(pt, light, TransportMode::Radiance).0
                * le.le_surface(light.ng, -wi, light.p)
                * (wi.dot(pt.ns).abs() * wi.dot(light.ng).abs()
                    / (d.length_squared() * light.pdf_fwd));
            luminance(l) as f64
        } else {
            let mut sampler = MltSampler::independent(i);
            let (l, _, _) = ctx.connect_unweighted(
                &work.y,
                &work.eye,
                s,
                t,
                0.0,
                &mut sampler,
                &mut RayStats::default(),
            );
            luminance(l) as f64 * if t == 1 { ext } else { 1.0 }
        };
        let ours = work.ex.c[s];
        assert!(
            (bdpt - ours).abs() <= 1e-3 * bdpt.max(ours),
            "bootstrap path {i}, s = {s}, t = {t}: BDPT {bdpt:e}, here {ours:e}"
        );
        if on_film {
            // BDPT's weight (merge = 0) and VCM's (merges at the non-specular vertices
            // from the light's second on, η π r² = 10⁻² … 10⁴ scene units²) are the power heuristic over
            // this module's densities. For s = 1 (BDPT samples its light point anew) the
            // weight of this path's light point, as light sampling would have made it.
            for merge in [0.0, 1e-2, 1.0, 1e2, 1e4] {
                let w = if s == 1 {
                    let mut v = work.y[0];
                    v.nee = ctx.nee_ratio(&v, &work.eye[t - 1], v.pdf_fwd);
                    ctx.mis_weight(&work.y, &work.eye, Some(&v), s, t, merge, None)
                } else {
                    let mut sampler = MltSampler::independent(i);
                    let (_, w, _) = ctx.connect_unweighted(
                        &work.y,
                        &work.eye,
                        s,
                        t,
                        merge,
                        &mut sampler,
                        &mut RayStats::default(),
                    );
                    w
                };
                let expected = power_heuristic(&ctx, &work.x, &work.ex, ext, s, merge as f64);
                // BDPT multiplies its ratios in f32: a few long paths with grazing
                // cosines drift by up to 2 % (46 of 16 540 weights here); the rest
                // agree to 1e-3.
                let off = (w as f64 - expected).abs() / expected.max(1e-3);
                assert!(
                    off <= 3e-2,
                    "bootstrap path {i}, s = {s}, t = {t}, η π r² = {merge}: \
                     weight {w:e}, power heuristic {expected:e}"
                );
                drifted += (off > 1e-3) as u32;
                weighed += 1;
            }
        }
        compared += 1;
        specular += work.x.iter().any(|v| v.delta) as u32;
    }
    eprintln!(
        "{compared} paths compared, {specular} with specular vertices; \
         {weighed} weights, {drifted} beyond 1e-3"
    );
    assert!(
        compared > 3000 && specular > 500 && weighed > 10_000,
        "{compared} / {specular} / {weighed}"
    );
    assert!(
        drifted * 200 <= weighed,
        "{drifted} of {weighed} weights beyond 1e-3"
    );
}

/// The power-heuristic weight of strategy s for path `x`, from the densities per unit
/// area `e` holds: p_s = Π_{i<s} p→(x_i) Π_{s≤i<k} p←(x_i) over the strategies that can
/// join at s, and a merge at each non-specular vertex x_i, i ≥ `bdpt::FIRST_MERGE` and
/// i < k (p_{i+1} p←(x_i) η π r²).
/// BDPT's camera samples the film, not the extended film: `ext` (film area over extended
/// film area) takes it back out of p←(x_{k−1}).
fn power_heuristic(ctx: &Ctx, x: &[Vertex], e: &PathEval, ext: f64, s: usize, merge: f64) -> f64 {
    let k = x.len() - 1;
    let mut rev = e.pa_rev.clone();
    rev[k - 1] /= ext;
    // In logarithms: a path of 60 vertices under- or overflows even f64.
    let ln = |v: &[f64]| v.iter().map(|p| p.ln()).sum::<f64>();
    // Strategy s = 1 picks x_0 by light sampling (BDPT's `nee_ratio` times the density of
    // a light subpath's start).
    let nee = (ctx.nee_ratio(&x[0], &x[1], e.pa_fwd[0] as f32) as f64).ln();
    let lp = |s: usize| ln(&e.pa_fwd[..s]) + ln(&rev[s..k]) + if s == 1 { nee } else { 0.0 };
    let own = lp(s);
    let term = |l: f64| (2.0 * (l - own)).exp();
    let joinable = |j: usize| (j <= 1 || !x[j - 1].delta) && (j == k || !x[j].delta);
    let mut sum: f64 = (0..=k).filter(|&j| joinable(j)).map(|j| term(lp(j))).sum();
    if merge > 0.0 {
        sum += (crate::integrator::bdpt::FIRST_MERGE..k)
            .filter(|&i| !x[i].delta)
            .map(|i| term(lp(i + 1) + (rev[i] * merge).ln()))
            .sum::<f64>();
    }
    1.0 / sum
}
