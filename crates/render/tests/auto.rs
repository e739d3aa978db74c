//! `auto` chooses by measurement: scene features rule methods out, pilots of the rest predict
//! their time to the goal, and the choice travels with the job (planned alike everywhere).

use std::path::Path;

use tessera_render::Scene;
use tessera_render::method::auto::Choice;
use tessera_render::method::auto::pilot::{self, Goal, Selection};
use tessera_render::method::{self, Job};
use tessera_scene::SceneDesc;

fn scene(name: &str, width: u32, height: u32) -> SceneDesc {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(name)
        .join("scene.json");
    let mut d = tessera_scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    d.film.width = width;
    d.film.height = height;
    d.integrator.method = "auto".into();
    d
}

fn select(desc: &SceneDesc, goal: Goal) -> Selection {
    let mut scene = Scene::build(desc);
    let s = pilot::select(desc, &mut scene, 1, goal, 2).unwrap_or_else(|e| panic!("{e}"));
    // The scene is left as it was given.
    assert_eq!(scene.film.width, desc.film.width);
    assert_eq!(scene.integrator.method, "auto");
    s
}

fn report(s: &Selection) -> String {
    s.choice.report.join("\n")
}

/// Veach's hard case for path tracing: light reaches the room off a small patch of ceiling.
/// Every method but the path tracer gets there many times sooner; the pilot must see it, and
/// the report must account for every candidate (measured, or why not).
#[test]
fn where_light_is_indirect_auto_measures_and_leaves_the_path_tracer() {
    let desc = scene("indirect-room", 96, 72);
    let s = select(&desc, Goal::Error(1e-2));
    let text = report(&s);
    assert_ne!(s.choice.method, "path", "{text}");
    let predicted = |label: &str| {
        s.measurements
            .iter()
            .find(|m| m.label == label)
            .and_then(|m| m.predicted_s)
    };
    let path = predicted("path").unwrap_or_else(|| panic!("path was not measured:\n{text}"));
    let chosen = predicted(&s.choice.method).expect("the chosen method's prediction");
    assert!(
        path > 4.0 * chosen,
        "path {path} s, chosen {chosen} s\n{text}"
    );
    // So far behind that no judge it could make, the path tracer stands at its probe; so
    // does the first bidirectional judge, which could not tell a floor at the goal even at
    // its full samples with the one still to come, and the judges stop being measured
    // whatever the pilot spends after it.
    assert!(text.contains("path measured at 2 samples a half"), "{text}");
    assert!(
        text.contains("bdpt measured at 2 samples a half")
            && text.contains("with the 1 still to come as quiet"),
        "{text}"
    );
    assert!(
        text.contains("judges measured whatever the pilot spends stopped after bdpt"),
        "{text}"
    );
    for name in ["path", "bdpt", "vcm", "photon", "sppm", "pssmlt", "mlt"] {
        assert!(
            s.choice
                .report
                .iter()
                .any(|l| l.starts_with(&format!("{name}:"))),
            "{name} is not accounted for:\n{text}"
        );
    }
    assert!(
        text.starts_with(&format!("chose {}", s.choice.method)),
        "{text}"
    );
    // A target error stays adaptive where the chosen method refines tiles.
    if matches!(s.choice.method.as_str(), "path" | "photon") {
        assert_eq!(s.choice.target_error, Some(1e-2));
    }
}

/// On the Cornell box the path tracer can judge the others alone: its probe could resolve the
/// goal at its full samples (deepened if need be), so it renders them.
#[test]
fn where_the_path_tracer_can_judge_alone_its_probe_goes_on() {
    let desc = scene("cornell-box", 64, 64);
    let s = select(&desc, Goal::Error(1e-2));
    let text = report(&s);
    assert!(
        text.contains("path probed at 2 samples a half, then 14 more"),
        "{text}"
    );
}

/// Glass and a mirror under a sky with a sun: the path tracer's caustics of the sun are rare,
/// bright samples its pilot does not see (it predicts itself fastest there, and never gets
/// there), so it is not chosen while a bidirectional method can be. Where its error at the
/// job's spp is the goal it is measured first; for a target error, last, if the pilot has
/// time left.
#[test]
fn caustics_of_a_sun_leave_the_path_tracer_unchosen() {
    let desc = scene("material-spheres", 128, 64);
    for goal in [Goal::PathSpp(64), Goal::Error(1e-2)] {
        let s = select(&desc, goal);
        let text = report(&s);
        assert_ne!(s.choice.method, "path", "{goal:?}\n{text}");
        match s.measurements.iter().find(|m| m.label == "path") {
            Some(path) => {
                assert!(
                    path.caveat
                        .as_ref()
                        .is_some_and(|c| c.contains("environment's sun")),
                    "{text}"
                );
                assert!(
                    text.contains("chosen only if nothing else can be"),
                    "{text}"
                );
            }
            None => {
                assert_ne!(goal, Goal::PathSpp(64), "path was not measured:\n{text}");
                assert!(text.contains("path: not measured"), "{text}");
            }
        }
    }
}

/// One diffuse plane under a sun: every light path has one bounce, direct lighting is exact;
/// nothing is measured.
#[test]
fn a_scene_direct_lighting_renders_exactly_is_not_measured() {
    let desc = scene("hard/grazing-plane", 32, 24);
    let s = select(&desc, Goal::PathSpp(16));
    assert_eq!(s.choice.method, "direct", "{}", report(&s));
    assert!(s.measurements.is_empty());
    assert_eq!(s.pilot_s, 0.0);
    assert_eq!(s.handed_s, 0.0);
}

/// Translucent materials: only the path tracer renders them, with each subsurface method as a
/// candidate; the report says why the other methods are not.
#[test]
fn translucent_materials_leave_the_path_tracer_with_each_subsurface_method() {
    let desc = scene("translucent", 48, 36);
    let s = select(&desc, Goal::PathSpp(64));
    let text = report(&s);
    assert_eq!(s.choice.method, "path", "{text}");
    assert!(s.choice.subsurface.is_some(), "{text}");
    assert!(!s.measurements.is_empty(), "{text}");
    for m in &s.measurements {
        assert!(m.label.starts_with("path:"), "{}\n{text}", m.label);
    }
    assert!(
        text.contains("do not render translucent materials"),
        "{text}"
    );
}

/// A job that carries a choice is planned as the chosen method with the chosen settings, says
/// so in its decisions, and writes how to reproduce it into the EXR header.
#[test]
fn a_recorded_choice_is_planned_as_its_method() {
    let mut job = Job::new(scene("cornell-box", 32, 24), 1);
    job.choice = Some(Choice {
        method: "bdpt".into(),
        subsurface: None,
        photons: None,
        spp: 3,
        target_error: None,
        report: vec!["chose bdpt: a test".into()],
    });
    let plan = method::plan(&job).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(plan.method(), "bdpt");
    assert!(
        plan.decisions()
            .iter()
            .any(|d| d == "auto: chose bdpt: a test"),
        "{:?}",
        plan.decisions()
    );
    let meta = plan.metadata();
    let reproduce = meta
        .iter()
        .find(|(k, _)| k == "auto_reproduce")
        .map(|(_, v)| v.as_str())
        .unwrap_or_default();
    assert!(
        reproduce.starts_with("--integrator bdpt --spp 3"),
        "{meta:?}"
    );
    // Without a choice, scene analysis chooses (the path tracer for the Cornell box).
    job.choice = None;
    assert_eq!(method::plan(&job).expect("plan").method(), "path");
}

/// A photon count the pilot chose is the plan's: its photon maps are planned with it (the
/// search radius is the one for that count), and the header says how to reproduce it.
#[test]
fn a_chosen_photon_count_is_planned() {
    let mut job = Job::new(scene("cornell-box", 32, 24), 1);
    job.choice = Some(Choice {
        method: "photon".into(),
        subsurface: None,
        photons: Some(12_345),
        spp: 2,
        target_error: None,
        report: vec!["chose photon with 12345 photons: a test".into()],
    });
    let plan = method::plan(&job).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(plan.method(), "photon");
    let decisions = plan.decisions();
    assert!(
        decisions.iter().any(|d| d.contains("of 12345×2 photons")),
        "{decisions:?}"
    );
    let meta = plan.metadata();
    assert!(
        meta.iter().any(
            |(k, v)| k == "auto_reproduce" && v.contains("integrator.photon_map.photons 12345")
        ),
        "{meta:?}"
    );
}
