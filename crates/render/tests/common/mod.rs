//! What the convergence tests share: scenes at the size of their 32×32 path-traced
//! references, the error against them, and the check that it falls.

use std::path::Path;

use tessera_render::metrics::compare;
use tessera_render::read_exr;

/// The two threads CI has.
pub fn pool() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("pool")
}

/// Scene `name` at the size of its 32×32 reference, and the reference.
pub fn scene_and_reference(
    name: &str,
) -> (tessera_scene::SceneDesc, tessera_scene::image::RgbImage) {
    scene_at_reference(name, "reference-32.exr")
}

/// Scene `name` at the size of its reference `file` (in the scene's folder), and the
/// reference.
pub fn scene_at_reference(
    name: &str,
    file: &str,
) -> (tessera_scene::SceneDesc, tessera_scene::image::RgbImage) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(name);
    let reference = read_exr(&root.join(file)).expect("reference");
    let mut desc = tessera_scene::load(&root.join("scene.json")).unwrap_or_else(|e| panic!("{e}"));
    desc.film.width = reference.width;
    desc.film.height = reference.height;
    (desc, reference)
}

/// relMSE and mean ratio of `image` against `reference`, emitter pixels left out.
pub fn error_against(
    image: &tessera_render::Image,
    reference: &tessera_scene::image::RgbImage,
) -> (f64, f64) {
    let rgb: Vec<glam::Vec3A> = image.pixels.iter().map(|p| p.rgb.into()).collect();
    let refs: Vec<glam::Vec3A> = reference.pixels.iter().map(|&t| t.into()).collect();
    // Pixels on or beside the visible emitter are left out: their error is the film's
    // antialiasing of a light 60× brighter than the walls (whether a sample lands on it), the
    // same for every integrator at this spp, and it would drown the effect measured here.
    let (w, h) = (reference.width as i32, reference.height as i32);
    let bright = |x: i32, y: i32| {
        x >= 0 && y >= 0 && x < w && y < h && refs[(y * w + x) as usize].max_element() > 1.0
    };
    let keep: Vec<usize> = (0..w * h)
        .filter(|&i| {
            let (x, y) = (i % w, i / w);
            !(-1..=1).any(|dy| (-1..=1).any(|dx| bright(x + dx, y + dy)))
        })
        .map(|i| i as usize)
        .collect();
    let pick = |v: &[glam::Vec3A]| keep.iter().map(|&i| v[i]).collect::<Vec<_>>();
    let e = compare(&pick(&rgb), &pick(&refs));
    (e.rel_mse, e.mean_ratio)
}

/// Prints `errors` (relMSE, mean ratio) of `what` at each of `budgets`, and asserts the
/// relMSE falls from each budget to the next and the last mean is within `mean_tol` of 1.
pub fn assert_falls(what: &str, budgets: &[String], errors: &[(f64, f64)], mean_tol: f64) {
    for (b, (rel, mean)) in budgets.iter().zip(errors) {
        eprintln!("{what}, {b}: relMSE {rel:.3e}, mean/ref {mean:.4}");
    }
    assert!(
        errors.windows(2).all(|w| w[1].0 < w[0].0),
        "{what}: relMSE must fall as the budget grows: {errors:?}"
    );
    let (_, mean) = errors[errors.len() - 1];
    assert!((mean - 1.0).abs() < mean_tol, "{what}: mean/ref {mean}");
}

/// The Metropolis renderer `kind` (pssmlt or mlt) with `desc`'s settings.
#[allow(dead_code, reason = "used by the Metropolis tests only")]
pub fn metropolis(
    kind: &str,
    desc: &tessera_scene::SceneDesc,
) -> tessera_render::integrator::metropolis::Metropolis {
    use tessera_render::integrator::metropolis::{Metropolis, mlt::Mlt, pssmlt::Pssmlt};
    match kind {
        "pssmlt" => Metropolis::Pssmlt(Pssmlt::new(desc)),
        "mlt" => Metropolis::Mlt(Mlt::new(desc)),
        other => panic!("{other} is not a Metropolis renderer"),
    }
}

/// A Metropolis renderer (`kind`: pssmlt or mlt) on scene `name` at its reference's size:
/// relMSE at 4, 32, 256 and 4096 mutations per pixel falls and the mean ends within 1 % of the
/// reference; and 8 mutations per pixel of cornell-glass are the same bits on one thread and
/// on two. The mean away from the bulb's pixels is the noisy part: over seeds 0–7 at 256
/// mutations per pixel cornell-glass's spread σ ≈ 0.85 % for pssmlt (b from 10⁵ BDPT
/// samples, paths through the glass to the bulb among them); at 4096, σ ≈ 0.37 % (pssmlt) and
/// 0.2 % (mlt) over seeds 0–5, so 1 % is 2.7σ and 5σ there.
#[allow(dead_code, reason = "used by the Metropolis tests only")]
pub fn assert_metropolis_converges_deterministically(kind: &str) {
    let setup = |name: &str| {
        let (desc, reference) = scene_and_reference(name);
        let m = metropolis(kind, &desc);
        let camera = tessera_render::camera::Camera::new(&desc.camera, &desc.film);
        (tessera_render::Scene::build(&desc), camera, m, reference)
    };
    let budgets = [4, 32, 256, 4096];
    let labels: Vec<String> = budgets
        .iter()
        .map(|m| format!("{m} mutations/px"))
        .collect();
    for name in ["cornell-box", "cornell-glass"] {
        let (scene, camera, m, reference) = setup(name);
        let errors: Vec<(f64, f64)> = budgets
            .iter()
            .map(|&n| {
                let (image, _) = pool()
                    .install(|| m.render(&scene, &camera, n, &|_| {}))
                    .expect("renders");
                error_against(&image, &reference)
            })
            .collect();
        assert_falls(&format!("{name}: {}", m.name()), &labels, &errors, 0.01);
    }
    let (scene, camera, m, _) = setup("cornell-glass");
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a pool");
    let a = one
        .install(|| m.render(&scene, &camera, 8, &|_| {}))
        .expect("renders")
        .0;
    let b = pool()
        .install(|| m.render(&scene, &camera, 8, &|_| {}))
        .expect("renders")
        .0;
    assert!(
        a.pixels.iter().zip(&b.pixels).all(|(p, q)| p.rgb == q.rgb),
        "{}: one thread and two differ",
        m.name()
    );
}

/// Writes `json` as `scene.json` in a fresh temporary folder named after `name`, with `files`
/// (name, source path) copied beside it, and loads it.
#[allow(dead_code, reason = "not every test binary writes scenes")]
pub fn load_json(name: &str, json: &str, files: &[(&str, &Path)]) -> tessera_scene::SceneDesc {
    let dir = std::env::temp_dir().join(format!("tessera-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    for (file, from) in files {
        std::fs::copy(from, dir.join(file)).expect("copy a scene file");
    }
    let path = dir.join("scene.json");
    std::fs::write(&path, json).expect("write scene");
    tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// Per direct-light (depth-1) strategy of BDPT, from its images in independent `batches`:
/// (s, mean of the unweighted image over batches, standard error of that mean).
#[allow(dead_code, reason = "used by the BDPT tests only")]
pub fn depth1_unweighted(
    batches: &[Vec<tessera_render::integrator::bdpt::StrategyImage>],
) -> Vec<(u32, f64, f64)> {
    (0..batches[0].len())
        .filter(|&i| batches[0][i].s + batches[0][i].t == 3)
        .map(|i| {
            let m: Vec<f64> = batches
                .iter()
                .map(|b| image_mean(&b[i].unweighted))
                .collect();
            let avg = m.iter().sum::<f64>() / m.len() as f64;
            let var = m.iter().map(|x| (x - avg).powi(2)).sum::<f64>() / (m.len() - 1) as f64;
            (batches[0][i].s, avg, (var / m.len() as f64).sqrt())
        })
        .collect()
}

/// Asserts every two of `stats` (s, mean, standard error) agree within four standard errors.
#[allow(dead_code, reason = "used by the BDPT tests only")]
pub fn assert_strategies_agree(stats: &[(u32, f64, f64)]) {
    for a in stats {
        for b in stats {
            let tol = 4.0 * (a.2 * a.2 + b.2 * b.2).sqrt();
            assert!(
                (a.1 - b.1).abs() <= tol,
                "strategies s = {} and s = {} disagree: {stats:?}",
                a.0,
                b.0
            );
        }
    }
}

/// The mean of an image over its pixels and channels.
#[allow(dead_code, reason = "used by the BDPT tests only")]
pub fn image_mean(img: &tessera_render::Image) -> f64 {
    img.pixels
        .iter()
        .map(|p| p.rgb.iter().sum::<f32>() as f64)
        .sum::<f64>()
        / (3 * img.pixels.len()) as f64
}

/// BDPT's per-strategy images (depth ≤ 1) of `desc` in 8 independent batches of `per_batch`
/// samples each.
#[allow(dead_code, reason = "used by the BDPT tests only")]
pub fn strategy_batches(
    desc: &tessera_scene::SceneDesc,
    per_batch: u32,
) -> Vec<Vec<tessera_render::integrator::bdpt::StrategyImage>> {
    let scene = tessera_render::Scene::build(desc);
    let camera = tessera_render::camera::Camera::new(&desc.camera, &desc.film);
    let bdpt = tessera_render::integrator::bdpt::Bdpt::new(desc);
    (0..8)
        .map(|b| {
            let range = tessera_render::film::SampleRange {
                start: per_batch * b,
                end: per_batch * (b + 1),
            };
            pool()
                .install(|| bdpt.render_strategies(&scene, &camera, range, 1))
                .expect("renders")
        })
        .collect()
}

/// VCM's image of `desc` after `iterations`, on `threads` threads.
#[allow(dead_code, reason = "used by the VCM tests only")]
pub fn vcm_image(
    desc: &tessera_scene::SceneDesc,
    iterations: u32,
    threads: usize,
) -> tessera_render::Image {
    let scene = tessera_render::Scene::build(desc);
    let camera = tessera_render::camera::Camera::new(&desc.camera, &desc.film);
    let vcm = tessera_render::integrator::vcm::Vcm::new(desc, &scene);
    let range = tessera_render::film::SampleRange {
        start: 0,
        end: iterations,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a pool");
    let (sums, _) = pool
        .install(|| vcm.render_range(&scene, &camera, range, &|_| {}))
        .expect("renders");
    sums.image(camera.exposure)
}

/// `desc` by method `name` (`spp` samples, seed `seed`) through its own plan, tasks and fold,
/// as `tessera render` runs it, on the two threads CI has.
#[allow(dead_code, reason = "used by the tests that run every method")]
pub fn render_by_method(
    desc: &tessera_scene::SceneDesc,
    name: &str,
    spp: u32,
    seed: u64,
) -> tessera_render::Image {
    use tessera_render::method::{self, Job, local::Local};
    let mut d = desc.clone();
    d.integrator.method = name.into();
    d.integrator.spp = spp;
    d.integrator.seed = seed;
    let scene = tessera_render::Scene::build(&d);
    let job = Job::new(d.clone(), 1);
    let plan = method::plan(&job).unwrap_or_else(|e| panic!("{name}: {e}"));
    let noop = |_| {};
    pool().install(|| {
        let local = Local::new(plan.as_ref(), &scene, &d, 2, &noop);
        local.passes().unwrap_or_else(|e| panic!("{name}: {e}"));
        local
            .frame(1)
            .unwrap_or_else(|e| panic!("{name}: {e}"))
            .image
    })
}

/// A base64 data URI of `bytes`, for glTF buffers and images written by tests.
#[allow(dead_code, reason = "used by the tests that write glTF files")]
pub fn data_uri(bytes: &[u8]) -> String {
    use base64::Engine;
    format!(
        "data:application/octet-stream;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(bytes)
    )
}

/// The glTF document `doc` loaded as a scene (no warnings allowed) on a `side`² film.
#[allow(dead_code, reason = "used by the tests that write glTF files")]
pub fn load_gltf(doc: &serde_json::Value, side: u32) -> tessera_scene::SceneDesc {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let path = dir.path().join("scene.gltf");
    std::fs::write(&path, doc.to_string()).expect("write");
    let mut d = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    d.film.width = side;
    d.film.height = side;
    d
}

/// A rectangle of [`quads_gltf`]: its centre and two half-extent vectors, u × v pointing
/// where it faces (its normal), and its material's index. Texture coordinates run 0..1.
#[allow(dead_code, reason = "used by the tests that write glTF files")]
pub struct Quad {
    pub centre: [f32; 3],
    pub u: [f32; 3],
    pub v: [f32; 3],
    pub material: usize,
}

/// A glTF document of `quads` (one mesh each, POSITION and TEXCOORD_0) with `materials`,
/// a perspective camera of vertical field `yfov` placed by `camera` (a node's translation
/// and rotation), and KHR_lights_punctual `lights` each with its node's placement.
#[allow(dead_code, reason = "used by the tests that write glTF files")]
pub fn quads_gltf(
    quads: &[Quad],
    materials: Vec<serde_json::Value>,
    camera: serde_json::Value,
    yfov: f32,
    lights: Vec<(serde_json::Value, serde_json::Value)>,
) -> serde_json::Value {
    use serde_json::json;
    let mut b: Vec<u8> = Vec::new();
    let (mut accessors, mut views, mut meshes, mut nodes) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut view = |b: &mut Vec<u8>, bytes: Vec<u8>| {
        let offset = b.len();
        b.extend(&bytes);
        views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": bytes.len()}));
        views.len() - 1
    };
    for (k, q) in quads.iter().enumerate() {
        let corner = |su: f32, sv: f32| -> [f32; 3] {
            std::array::from_fn(|i| q.centre[i] + su * q.u[i] + sv * q.v[i])
        };
        let corners = [
            corner(-1.0, -1.0),
            corner(1.0, -1.0),
            corner(1.0, 1.0),
            corner(-1.0, 1.0),
        ];
        let positions: Vec<u8> = corners
            .iter()
            .flatten()
            .flat_map(|c| c.to_le_bytes())
            .collect();
        let uvs: Vec<u8> = [0f32, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0]
            .iter()
            .flat_map(|c| c.to_le_bytes())
            .collect();
        let indices: Vec<u8> = [0u16, 1, 2, 0, 2, 3, 0, 0]
            .iter()
            .flat_map(|i| i.to_le_bytes())
            .collect();
        let (lo, hi) = corners
            .iter()
            .fold(([f32::MAX; 3], [f32::MIN; 3]), |(lo, hi), c| {
                (
                    std::array::from_fn(|i| lo[i].min(c[i])),
                    std::array::from_fn(|i| hi[i].max(c[i])),
                )
            });
        let p = view(&mut b, positions);
        let t = view(&mut b, uvs);
        let i = view(&mut b, indices);
        let a = accessors.len();
        accessors.push(json!({"bufferView": p, "componentType": 5126, "count": 4,
                              "type": "VEC3", "min": lo, "max": hi}));
        accessors.push(json!({"bufferView": t, "componentType": 5126, "count": 4,
                              "type": "VEC2"}));
        accessors.push(json!({"bufferView": i, "componentType": 5123, "count": 6,
                              "type": "SCALAR"}));
        meshes.push(json!({"primitives": [{
            "attributes": {"POSITION": a, "TEXCOORD_0": a + 1}, "indices": a + 2,
            "material": q.material}]}));
        nodes.push(json!({"mesh": k}));
    }
    let mut camera_node = camera;
    camera_node["camera"] = json!(0);
    nodes.push(camera_node);
    let mut punctual = Vec::new();
    for (k, (mut node, light)) in lights.into_iter().enumerate() {
        node["extensions"] = json!({"KHR_lights_punctual": {"light": k}});
        nodes.push(node);
        punctual.push(light);
    }
    let node_ids: Vec<usize> = (0..nodes.len()).collect();
    let mut used = std::collections::BTreeSet::new();
    for m in &materials {
        if let Some(e) = m.get("extensions").and_then(|e| e.as_object()) {
            used.extend(e.keys().cloned());
        }
    }
    if !punctual.is_empty() {
        used.insert("KHR_lights_punctual".to_string());
    }
    let mut doc = json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": used,
        "scene": 0,
        "scenes": [{"nodes": node_ids}],
        "nodes": nodes,
        "cameras": [{"type": "perspective",
                     "perspective": {"yfov": yfov, "aspectRatio": 1.0, "znear": 0.01}}],
        "meshes": meshes,
        "materials": materials,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": b.len(), "uri": data_uri(&b)}]
    });
    if !punctual.is_empty() {
        doc["extensions"] = json!({"KHR_lights_punctual": {"lights": punctual}});
    }
    doc
}

/// The mean RGB of `desc` rendered by method `name` (`spp`, `seed`), as
/// [`render_by_method`] renders it.
#[allow(dead_code, reason = "used by the tests that run every method")]
pub fn mean_rgb(desc: &tessera_scene::SceneDesc, name: &str, spp: u32, seed: u64) -> [f64; 3] {
    let image = render_by_method(desc, name, spp, seed);
    let n = image.pixels.len() as f64;
    image.pixels.iter().fold([0.0f64; 3], |m, p| {
        std::array::from_fn(|c| m[c] + p.rgb[c] as f64 / n)
    })
}

/// Asserts that every method of the registry but `direct` (direct light only, by definition)
/// and `auto` (which plans one of the others), each by its own plan, tasks and fold at 256
/// samples, agrees with `reference` (the path tracer's, much longer): the mean ratio of two
/// seeds within four times their spread (a floor of 0.3 %), plus the kernel bias of the
/// density-estimation methods. Prints each method's figures.
#[allow(dead_code, reason = "used by the tests that run every method")]
pub fn assert_every_method_agrees(
    desc: &tessera_scene::SceneDesc,
    reference: &tessera_scene::image::RgbImage,
) {
    let mut report = Vec::new();
    let mut failures = Vec::new();
    for name in tessera_render::method::names() {
        if name == "direct" || name == "auto" {
            continue;
        }
        let means: Vec<f64> = [2, 3]
            .iter()
            .map(|&seed| error_against(&render_by_method(desc, name, 256, seed), reference).1)
            .collect();
        let mean = (means[0] + means[1]) / 2.0;
        // The noise of the two renders' mean, from their difference (σ of one render's mean
        // ratio ≈ |m₂ − m₃|/√2, of the average of two σ/√2), with a floor for a pair that
        // happened to agree.
        let sigma = ((means[0] - means[1]).abs() / 2.0).max(0.003);
        let bias = if matches!(name, "photon" | "sppm") {
            0.015
        } else {
            0.0
        };
        let tolerance = 4.0 * sigma + bias;
        report.push(format!(
            "{name}: mean ratio {:.4} and {:.4}, tolerance {tolerance:.4}",
            means[0], means[1]
        ));
        if (mean - 1.0).abs() > tolerance {
            failures.push(name);
        }
    }
    println!("{}", report.join("\n"));
    assert!(
        failures.is_empty(),
        "{failures:?} disagree with the path tracer:\n{}",
        report.join("\n")
    );
}

/// Asserts that path-space MLT's bootstrap (`n` paths weighted by its own f and densities)
/// estimates the brightness BDPT does, within four standard errors, and prints both.
#[allow(dead_code, reason = "used by the Metropolis tests")]
pub fn assert_bootstrap_agrees_with_bdpt(
    what: &str,
    desc: &tessera_scene::SceneDesc,
    n: u64,
) -> f64 {
    let scene = tessera_render::Scene::build(desc);
    let camera = tessera_render::camera::Camera::new(&desc.camera, &desc.film);
    let ((m, m_se), (b, b_se)) = pool()
        .install(|| {
            tessera_render::integrator::metropolis::mlt::Mlt::new(desc)
                .brightness_check(&scene, &camera, n)
        })
        .expect("runs");
    let z = (m - b) / (m_se * m_se + b_se * b_se).sqrt();
    eprintln!("{what}: bootstrap {m:.5e} ± {m_se:.1e}, bdpt {b:.5e} ± {b_se:.1e}, z {z:.2}");
    assert!(
        z.abs() < 4.0,
        "the estimates differ by {z:.1} standard errors"
    );
    m_se / m
}

/// Batches per independent reference (scripts/references/make.py), the degrees of freedom of
/// its variance.
#[allow(dead_code, reason = "used by the tests against independent references")]
pub const BATCHES: f64 = 16.0;

/// An independent reference (tests/data/references: Mitsuba 3's): per pixel, the mean of
/// [`BATCHES`] renders and the variance of that mean.
#[allow(dead_code, reason = "used by the tests against independent references")]
pub struct Reference {
    pub mean: Vec<[f64; 3]>,
    pub var: Vec<[f64; 3]>,
}

/// Scene `name` at the size of its independent reference, box-filtered, paths ending after
/// 64 bounces (as the reference was made), with the reference.
#[allow(dead_code, reason = "used by the tests against independent references")]
pub fn mitsuba_reference(name: &str) -> (tessera_scene::SceneDesc, Reference) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let file = root
        .join("tests/data/references")
        .join(format!("{name}.exr"));
    let bytes = std::fs::read(&file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    let names = ["R", "G", "B", "variance.R", "variance.G", "variance.B"];
    let (w, h, ch) = tessera_scene::image::read_exr_channels(&bytes, &names)
        .unwrap_or_else(|e| panic!("{}: {e}", file.display()));
    let pixels = (w * h) as usize;
    let at = |c: usize, i: usize| [ch[c][i] as f64, ch[c + 1][i] as f64, ch[c + 2][i] as f64];
    let reference = Reference {
        mean: (0..pixels).map(|i| at(0, i)).collect(),
        var: (0..pixels).map(|i| at(3, i)).collect(),
    };
    let path = root.join("scenes").join(name).join("scene.json");
    let mut desc = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    desc.film.width = w;
    desc.film.height = h;
    desc.film.filter = tessera_scene::FilterDesc::Box { radius: 0.5 };
    desc.integrator.max_depth = 64;
    (desc, reference)
}
