//! Which candidates a scene leaves, and the order the pilot measures them in: the scene's
//! features first ([`candidates`]), then what the measurements so far say ([`measured_first`],
//! [`judged`], [`defer`], [`more_photons_needed`]); see the parent module, step 1 and its
//! closing paragraph.

use glam::Vec2;
use tessera_scene::{SceneDesc, SubsurfaceMethod};

use super::{Candidate, Goal, Measurement, Model, subsurface_name};
use crate::analysis::{Analysis, concentrated_lights};
use crate::camera::Camera;
use crate::integrator::sppm;
use crate::method::{self, MethodInfo, PilotInfo, Sight};
use crate::photon::DEFAULT_PHOTONS;
use crate::scene::Scene;

/// The first candidates are measured whatever the pilot has spent (until their consensus
/// resolves the goal: [`judged`]): the path tracer, BDPT and VCM need no passes, so cost
/// little, and make the consensus that judges the biased ones (the path tracer only where it
/// has no caveat: see [`measured_first`]).
pub(super) const ALWAYS_MEASURED: usize = 3;

/// Photons of the photon map measured first where the scene does not set their count: a
/// final gather reads the map one bounce away, behind which most of its noise and kernel bias
/// is hidden, so a map of a few photons often reaches the error the default count does, at a
/// fraction of the pass. The default count is measured only where this one cannot reach the
/// goal ([`more_photons_needed`]).
pub const FEW_PHOTONS: u32 = DEFAULT_PHOTONS / 8;

/// The label of candidate `method` whose photon map has `photons` photons: the method's name
/// with the few the pilot tries first, `name:N` with more.
fn photon_label(method: &str, photons: u32) -> String {
    if photons == FEW_PHOTONS {
        method.into()
    } else {
        format!("{method}:{photons}")
    }
}

/// Whether the photon map's candidate with more photons than the first is worth measuring:
/// not where the first reaches the goal, since more photons lower only a floor already under
/// it, at the cost of a dearer pass (a time limit's lowest error may still want them).
pub(super) fn more_photons_needed(c: &Candidate, measurements: &[Measurement], goal: Goal) -> bool {
    let few = photon_label(c.method, FEW_PHOTONS);
    match c.photons {
        Some(n) if n > FEW_PHOTONS && !matches!(goal, Goal::Seconds(_)) => !measurements
            .iter()
            .any(|m| m.label == few && m.predicted_s.is_some()),
        _ => true,
    }
}

/// The candidates the scene's features leave, in pilot order, and what they ruled out: every
/// method of the registry with a [`PilotInfo`], in its order, but those that cannot render
/// the scene ([`method::refuses`]). `seen`: whether the camera sees a specular surface
/// ([`sees_specular`]).
pub(super) fn candidates(
    desc: &SceneDesc,
    analysis: &Analysis,
    seen: bool,
) -> (Vec<Candidate>, Vec<String>) {
    let mut pool: Vec<(&MethodInfo, PilotInfo)> = method::methods()
        .into_iter()
        .filter_map(|m| Some((m, m.pilot?)))
        .collect();
    pool.sort_by_key(|(_, p)| p.order);
    let mut ruled_out = Vec::new();
    let translucent = desc.translucent_materials();
    if !translucent.is_empty() {
        let (able, unable): (Vec<_>, Vec<_>) = pool.into_iter().partition(|(m, _)| m.translucent);
        if !unable.is_empty() {
            let names: Vec<&str> = unable.iter().map(|(m, _)| m.name).collect();
            ruled_out.push(format!(
                "{}: not candidates: they do not render translucent materials ({})",
                names.join(", "),
                translucent.join(", ")
            ));
        }
        pool = able;
    }
    pool.retain(|(m, _)| match method::refuses(m, desc) {
        Ok(()) => true,
        Err(why) => {
            ruled_out.push(format!("{}: not a candidate: {why}", m.name));
            false
        }
    });
    let candidate = |m: &MethodInfo, p: &PilotInfo| Candidate {
        label: m.name.to_string(),
        method: m.name,
        subsurface: None,
        model: p.model,
        k: p.k,
        caveat: None,
        photons: None,
        // Until every candidate is listed: whether it sees more than the camera's side.
        judges: p.model == Model::Unbiased && p.sight != Sight::CameraOnly,
        probe: p.probe,
    };
    let mut list = Vec::new();
    if !translucent.is_empty() {
        // Each method renders with each subsurface method, the scene's own first (it is the
        // one a job's spp means); all but the random walk are approximations (biased).
        let mut methods = vec![
            desc.integrator.subsurface,
            SubsurfaceMethod::RandomWalk,
            SubsurfaceMethod::Dipole,
            SubsurfaceMethod::Hierarchical,
        ];
        let mut seen = Vec::new();
        methods.retain(|m| {
            let new = !seen.contains(m);
            seen.push(*m);
            new
        });
        for (m, p) in &pool {
            list.extend(methods.iter().map(|&s| {
                let model = if s == SubsurfaceMethod::RandomWalk {
                    p.model
                } else {
                    Model::Biased
                };
                Candidate {
                    label: format!("{}:{}", m.name, subsurface_name(s)),
                    subsurface: Some(s),
                    model,
                    k: p.k.min(TRANSLUCENT_K),
                    judges: model == Model::Unbiased && p.sight != Sight::CameraOnly,
                    ..candidate(m, p)
                }
            }));
        }
    } else {
        // Caustics of a concentrated light are rare, bright samples for a method that finds
        // them only by hitting the light ([`Sight`]): a pilot of a few thousand paths does
        // not see them, so their variance cannot be measured.
        let mut first_photon_map = None;
        let concentrated = if analysis.caustics {
            concentrated_lights(desc, analysis)
        } else {
            Vec::new()
        };
        for (m, p) in &pool {
            let misses = match p.sight {
                Sight::All => None,
                Sight::CameraOnly => Some(""),
                Sight::NoSpecularJoin => seen.then_some(" seen in a specular surface"),
            };
            let caveat = misses.filter(|_| !concentrated.is_empty()).map(|seen_in| {
                format!(
                    "its caustics of {}{seen_in} are rare, bright samples a pilot does not see",
                    concentrated.join(", ")
                )
            });
            // A photon map of a few photons, then (where those cannot reach the goal) of
            // the default count, unless the scene sets its own.
            let photons: &[Option<u32>] =
                if p.photon_map && desc.integrator.photon.photons.is_none() {
                    &[Some(FEW_PHOTONS), Some(DEFAULT_PHOTONS)]
                } else {
                    &[None]
                };
            if p.photon_map {
                first_photon_map.get_or_insert(list.len());
            }
            list.extend(photons.iter().map(|&n| Candidate {
                label: n.map_or(m.name.to_string(), |n| photon_label(m.name, n)),
                caveat: caveat.clone(),
                photons: n,
                ..candidate(m, p)
            }));
        }
        if photon_map_first(desc) {
            let progressive = list.iter().position(|c| c.model == Model::Progressive);
            if let (Some(progressive), Some(photon_map)) = (progressive, first_photon_map) {
                list.swap(progressive, photon_map);
            }
        }
    }
    // The unbiased candidates whose pilot sees more than the camera's side judge the
    // others; where none does, every unbiased one.
    if !list.iter().any(|c| c.judges) {
        for c in &mut list {
            c.judges = c.model == Model::Unbiased;
        }
    }
    (list, ruled_out)
}

/// Pilot samples per half of a candidate rendering translucent materials, at most: as many
/// as the bidirectional candidates' pilots take elsewhere.
const TRANSLUCENT_K: u32 = 4;

/// Puts the candidates with a caveat that judge no other (the path tracer: the consensus
/// leaves it out where a bidirectional method is measured) last, unless the goal is the path
/// tracer's error at the job's spp (which its pilot measures): chosen only where nothing else
/// can be, they are measured only if the pilot has time left. Returns how many candidates are
/// measured whatever the pilot has spent: the first [`ALWAYS_MEASURED`] less those moved.
pub(super) fn measured_first(candidates: &mut [Candidate], goal: Goal) -> usize {
    let first = ALWAYS_MEASURED.min(candidates.len());
    if matches!(goal, Goal::PathSpp(_)) {
        return first;
    }
    let last = |c: &Candidate| c.caveat.is_some() && !c.judges();
    let moved = candidates[..first].iter().filter(|c| last(c)).count();
    candidates.sort_by_key(last);
    first - moved
}

/// Orders the candidates still to measure (`rest`, indices into `candidates`) once the
/// judges measured so far resolve the goal (their own relMSE is under it), which ends the
/// candidates measured whatever the pilot spends: more judges are not needed to tell a floor,
/// so the unbiased candidates left are measured after the biased ones, as the share allows.
/// The photon map goes before SPPM: a goal the judges resolve at a pilot's few samples is one
/// the render reaches in few, where the photon map pays its photons once and hides its
/// kernel's bias behind a gather bounce, while SPPM pays photons every iteration and its
/// first iterations' radii are its widest.
pub(super) fn judged(candidates: &[Candidate], rest: &mut [usize]) {
    rest.sort_by_key(|&j| match candidates[j].model {
        Model::Biased => 0,
        Model::Progressive => 1,
        Model::Unbiased => 2,
    });
}

/// Moves the candidate at `order[at]` to the end of `order` where a judge is still to be
/// measured after it, and says whether it did. For a biased candidate whose turn comes while
/// the judges measured so far cannot tell a floor at the goal from their noise: its prediction
/// would say just that, and it could not be chosen, unless a judge still to come resolves the
/// goal; where none is, it is not measured.
pub(super) fn defer(candidates: &[Candidate], order: &mut Vec<usize>, at: usize) -> bool {
    if !order[at + 1..].iter().any(|&j| candidates[j].judges()) {
        return false;
    }
    let i = order.remove(at);
    order.push(i);
    true
}

/// Whether the camera sees a specular surface: a grid of rays through frame `frame`'s film.
pub(super) fn sees_specular(desc: &SceneDesc, scene: &Scene, frame: u32) -> bool {
    const GRID: u32 = 32;
    let camera = Camera::new(&desc.camera_at(frame), &desc.film);
    let (w, h) = (desc.film.width as f32, desc.film.height as f32);
    (0..GRID * GRID).any(|i| {
        let film = Vec2::new(
            ((i % GRID) as f32 + 0.5) / GRID as f32 * w,
            ((i / GRID) as f32 + 0.5) / GRID as f32 * h,
        );
        scene
            .intersect(&camera.generate_ray(film, Vec2::splat(0.5)))
            .is_some_and(|si| scene.material(si.material).flags.specular)
    })
}

/// Whether the photon map is measured before SPPM: where the film has more pixels than an
/// SPPM iteration has photons. Each SPPM iteration then costs more than a camera path per
/// pixel, its photons aside, where the photon map traces its photons once and the film once
/// (with final gathering); SPPM's few cheap iterations are what win it small films. Measured
/// first, the likelier winner lets the tenth-of-the-best rule skip the other: SPPM's pilot
/// iterations are wasted where the photon map wins, the photon map's whole pass where SPPM
/// does.
fn photon_map_first(desc: &SceneDesc) -> bool {
    let film = u64::from(desc.film.width) * u64::from(desc.film.height);
    film > u64::from(sppm::photons_per_iteration(desc))
}

#[cfg(test)]
mod tests {
    use super::super::tests::{built, scene};
    use super::*;
    use crate::analysis::analyze;

    /// The candidates are the registry's methods with a pilot, but those that refuse the
    /// scene, which the report names with their reason: path-space MLT under a thin lens.
    #[test]
    fn a_method_that_refuses_the_scene_is_ruled_out_with_its_reason() {
        let mut desc = scene("cornell-box");
        let labels = |desc: &SceneDesc| {
            let (list, out) = candidates(desc, &analyze(desc), false);
            (list.into_iter().map(|c| c.label).collect::<Vec<_>>(), out)
        };
        let (pinhole, out) = labels(&desc);
        assert!(pinhole.iter().any(|l| l == "mlt"), "{pinhole:?}");
        assert!(out.is_empty(), "{out:?}");
        desc.camera.lens = tessera_scene::Lens::Thin {
            aperture_radius: 0.05,
            focus_distance: 5.0,
        };
        let (thin, out) = labels(&desc);
        let without: Vec<&String> = pinhole.iter().filter(|l| *l != "mlt").collect();
        assert_eq!(thin.iter().collect::<Vec<_>>(), without);
        assert!(
            out.len() == 1
                && out[0].starts_with("mlt: not a candidate")
                && out[0].contains("pinhole"),
            "{out:?}"
        );
    }

    /// SPPM is measured before the photon map unless the film has more pixels than an SPPM
    /// iteration has photons.
    #[test]
    fn photon_map_goes_first_on_films_larger_than_an_iteration() {
        let mut desc = scene("cornell-box");
        let order = |desc: &SceneDesc| -> Vec<String> {
            let (list, _) = candidates(desc, &analyze(desc), false);
            list.into_iter()
                .map(|c| c.label)
                .filter(|l| l == "sppm" || l == "photon")
                .collect()
        };
        desc.film.width = 256;
        desc.film.height = 256;
        assert_eq!(order(&desc), ["sppm", "photon"]);
        desc.film.width = 1920;
        desc.film.height = 1080;
        assert_eq!(order(&desc), ["photon", "sppm"]);
        desc.integrator.photon.photons = Some(1920 * 1080);
        assert_eq!(order(&desc), ["sppm", "photon"]);
    }

    /// The pool's path tracer has a caveat (caustics of a small light): for a target error it
    /// is measured last and the first two candidates (BDPT, VCM) whatever the pilot has
    /// spent; for the path tracer's own error at the job's spp it stays first. BDPT's caveat
    /// (the caustics are seen through the water) does not move it: it judges the others.
    #[test]
    fn a_path_tracer_with_a_caveat_is_measured_last_unless_its_error_is_the_goal() {
        let desc = scene("pool");
        let seen = sees_specular(&desc, &built(&desc), 1);
        assert!(seen);
        let labels = |goal| {
            let (mut list, _) = candidates(&desc, &analyze(&desc), seen);
            let always = measured_first(&mut list, goal);
            assert!(
                list.iter()
                    .find(|c| c.label == "bdpt")
                    .is_some_and(|c| c.caveat.is_some())
            );
            (
                always,
                list.into_iter().map(|c| c.label).collect::<Vec<_>>(),
            )
        };
        let (always, order) = labels(Goal::Error(0.01));
        assert_eq!(always, 2);
        assert_eq!(order[..2], ["bdpt", "vcm"]);
        assert_eq!(order.last().map(String::as_str), Some("path"));
        let (always, order) = labels(Goal::PathSpp(16));
        assert_eq!(always, ALWAYS_MEASURED);
        assert_eq!(order[..3], ["path", "bdpt", "vcm"]);
    }

    /// On the Cornell box, once the path tracer judges the goal alone, the photon map, then
    /// SPPM, are measured before BDPT, VCM and the Metropolis methods.
    #[test]
    fn once_the_judges_resolve_the_goal_the_biased_candidates_go_next() {
        let desc = scene("cornell-box");
        let (mut list, _) = candidates(&desc, &analyze(&desc), false);
        assert_eq!(
            measured_first(&mut list, Goal::Error(0.01)),
            ALWAYS_MEASURED
        );
        let mut order: Vec<usize> = (0..list.len()).collect();
        judged(&list, &mut order[1..]);
        let labels: Vec<&str> = order.iter().map(|&i| list[i].label.as_str()).collect();
        assert_eq!(
            labels,
            [
                "path",
                "photon",
                "photon:200000",
                "sppm",
                "bdpt",
                "vcm",
                "pssmlt",
                "mlt"
            ]
        );
    }

    /// A biased candidate whose turn comes while the judges cannot resolve the goal waits
    /// behind the judges still to come (PSSMLT, MLT), in its order; with none left after it,
    /// it is not measured.
    #[test]
    fn a_biased_candidate_waits_for_judges_that_can_tell_its_floor() {
        let desc = scene("cornell-glass");
        let (mut list, _) = candidates(&desc, &analyze(&desc), true);
        measured_first(&mut list, Goal::Error(0.01));
        let mut order: Vec<usize> = (0..list.len()).collect();
        let labels = |order: &[usize]| -> Vec<String> {
            order.iter().map(|&i| list[i].label.clone()).collect()
        };
        assert_eq!(
            labels(&order),
            [
                "bdpt",
                "vcm",
                "sppm",
                "photon",
                "photon:200000",
                "pssmlt",
                "mlt",
                "path"
            ]
        );
        assert!(defer(&list, &mut order, 3));
        assert!(defer(&list, &mut order, 3));
        assert_eq!(
            labels(&order),
            [
                "bdpt",
                "vcm",
                "sppm",
                "pssmlt",
                "mlt",
                "path",
                "photon",
                "photon:200000"
            ]
        );
        assert!(!defer(&list, &mut order, 6));
        assert!(!defer(&list, &mut order, 7));
        assert_eq!(labels(&order)[6..], ["photon", "photon:200000"]);
    }

    /// The photon map with the default count is measured only where the few photons' map
    /// cannot reach the goal (or the goal is a time's lowest error); a scene that sets its
    /// count has one photon-map candidate, with that count.
    #[test]
    fn more_photons_are_measured_only_where_few_cannot_reach_the_goal() {
        let desc = scene("cornell-box");
        let (list, _) = candidates(&desc, &analyze(&desc), false);
        let photon: Vec<_> = list.iter().filter(|c| c.method == "photon").collect();
        assert_eq!(photon.len(), 2);
        let (few, more) = (photon[0], photon[1]);
        assert_eq!(
            (few.photons, more.photons),
            (Some(FEW_PHOTONS), Some(DEFAULT_PHOTONS))
        );
        let measured = |predicted_s: Option<f64>| Measurement {
            label: few.label.clone(),
            pilot_s: 0.1,
            handed_s: 0.1,
            setup_s: 0.1,
            sample_s: 0.1,
            rel_var: 0.01,
            floor: Some(0.0),
            untold: None,
            spp: predicted_s.map(|_| 2),
            predicted_s,
            predicted_error: None,
            note: None,
            caveat: None,
        };
        let e = Goal::Error(0.01);
        assert!(!more_photons_needed(more, &[measured(Some(0.5))], e));
        assert!(more_photons_needed(more, &[measured(None)], e));
        assert!(more_photons_needed(more, &[], e));
        assert!(more_photons_needed(
            more,
            &[measured(Some(0.5))],
            Goal::Seconds(1.0)
        ));
        assert!(more_photons_needed(few, &[measured(Some(0.5))], e));

        let mut own = desc.clone();
        own.integrator.photon.photons = Some(50_000);
        let (list, _) = candidates(&own, &analyze(&own), false);
        let photon: Vec<_> = list.iter().filter(|c| c.method == "photon").collect();
        assert_eq!(photon.len(), 1);
        assert_eq!(
            (photon[0].label.as_str(), photon[0].photons),
            ("photon", None)
        );
    }

    /// BDPT has a caveat where caustics of a concentrated light are seen in a specular
    /// surface: the glass box's camera sees its sphere, the plain box's sees nothing specular
    /// (and has no such caustics).
    #[test]
    fn bdpt_has_a_caveat_where_caustics_are_seen_in_a_specular_surface() {
        let caveat = |name: &str| {
            let desc = scene(name);
            let seen = sees_specular(&desc, &built(&desc), 1);
            let (list, _) = candidates(&desc, &analyze(&desc), seen);
            let bdpt = list.into_iter().find(|c| c.label == "bdpt");
            (seen, bdpt.and_then(|c| c.caveat))
        };
        let (seen, glass) = caveat("cornell-glass");
        assert!(seen);
        assert!(
            glass
                .as_ref()
                .is_some_and(|c| c.contains("seen in a specular surface")),
            "{glass:?}"
        );
        assert_eq!(caveat("cornell-box"), (false, None));
        // The same caustics unseen: no caveat.
        let desc = scene("cornell-glass");
        let (list, _) = candidates(&desc, &analyze(&desc), false);
        assert!(list.iter().all(|c| c.label != "bdpt" || c.caveat.is_none()));
    }
}
