//! One candidate's pilot: the scene at a small film ([`pilot_desc`]), rendered as two
//! independent halves with its passes timed apart ([`run`]), within what the pilot may still
//! spend ([`Allowance`]); see the parent module, step 2.

use std::time::Instant;

use tessera_scene::{FilmDesc, FilterDesc, SceneDesc};

use super::predict::rel;
use super::progressive::{rgb, sppm_photons, sppm_second_half};
use super::radii::Shrinkage;
use super::{Candidate, Model};
use crate::analysis::analyze;
use crate::integrator::sppm::SppmSettings;
use crate::method::local::{Built, Local, Progress};
use crate::method::sppm::SppmFrame;
use crate::method::{Job, Loaded, plan};
use crate::scene::Scene;

/// The pilot's share of the film's pixels, within [`PILOT_PIXELS`]. The first candidates
/// are measured whatever the pilot spends, at a few samples a pixel: on a film whose best
/// method reaches the goal in a few whole-film iterations, their cost is the pilot's
/// overhead, and it grows with this share. A smaller share leaves fewer pixels to estimate
/// from, and larger ones, which alias more: a low-noise method's variance shows that most,
/// and the consensus tells a floor less well.
const PILOT_FRACTION: f64 = 32.0;
/// Pilot pixels: the film's over [`PILOT_FRACTION`], within these bounds (the upper one sets
/// the pilot of every film above 131 072 pixels).
const PILOT_PIXELS: (u64, u64) = (256, 4096);
/// What a candidate's pilot may spend once the first candidates are measured: `left` seconds
/// of the pilot's share, and `reusable`, the most seconds of work the render takes over from
/// it (passes, SPPM's photons) that `left` allows.
#[derive(Debug, Clone, Copy)]
pub(super) struct Allowance {
    pub(super) left: f64,
    pub(super) reusable: f64,
}

impl Allowance {
    pub(super) const UNLIMITED: Allowance = Allowance {
        left: f64::INFINITY,
        reusable: f64::INFINITY,
    };

    /// `left` seconds, `budget` being the best prediction so far. Reusable work is lost only
    /// where its candidate loses. Before it is measured, all that is known of a candidate
    /// whose reusable work takes w seconds is that it takes at least w; its time is taken as
    /// equally likely anywhere in [w, w + budget], so it loses with probability w / budget and
    /// the work's expected loss is w² / budget: at most `left` where w ≤ √(left × budget).
    /// Cheap passes beside a slow best are measured; a pass near the best prediction counts
    /// nearly in full.
    pub(super) fn of(left: f64, budget: f64) -> Allowance {
        let reusable = if left <= 0.0 {
            0.0
        } else {
            (left * budget).sqrt()
        };
        Allowance { left, reusable }
    }
}

/// The scene at about 1/[`PILOT_FRACTION`] of its pixels (within [`PILOT_PIXELS`]), same view. A filter with
/// negative lobes (Mitchell) becomes a box: with a pilot's few samples a pixel's Σ w can come
/// near 0 and its ratio Σ w·L / Σ w blow up, which says nothing of how the render's error
/// falls at the samples it will take. SPPM, which divides by T·E[w] instead of Σ w, keeps
/// the film's filter ([`run`]).
pub(super) fn pilot_desc(desc: &SceneDesc) -> SceneDesc {
    let (w, h) = (desc.film.width as f64, desc.film.height as f64);
    let film = w * h;
    let want = (film / PILOT_FRACTION).clamp(PILOT_PIXELS.0 as f64, PILOT_PIXELS.1 as f64);
    let s = (want / film).sqrt().min(1.0);
    let mut d = desc.clone();
    d.film.width = ((w * s).round() as u32).max(1);
    d.film.height = ((h * s).round() as u32).max(1);
    if let FilterDesc::Mitchell { .. } = d.film.filter {
        d.film.filter = FilterDesc::Box { radius: 0.5 };
    }
    d
}

/// Tiles of a pilot's film get this many per thread at least (where its pixels allow), so
/// every thread has work and the last tiles do not leave threads idle.
const PILOT_TILES_PER_THREAD: u32 = 4;

/// The tile side for a pilot film of `width`×`height` on `threads` threads: the largest
/// power of two up to the render's default with [`PILOT_TILES_PER_THREAD`] tiles per thread
/// (at least 4 pixels). The render's default tile would cut a pilot's few hundred pixels into
/// one tile, one thread's work; the tile does not change the image.
fn pilot_tile(width: u32, height: u32, threads: usize) -> u32 {
    let want = PILOT_TILES_PER_THREAD as u64 * threads.max(1) as u64;
    let mut tile = crate::method::default_tile(width, height);
    while tile > 4 && (width.div_ceil(tile) as u64) * (height.div_ceil(tile) as u64) < want {
        tile /= 2;
    }
    tile
}

/// A candidate's pilot images: two independent halves and their mean.
pub(super) struct Halves {
    /// k samples, and k more (independent of the first).
    pub(super) a: Vec<[f64; 3]>,
    pub(super) b: Vec<[f64; 3]>,
    /// All 2k samples.
    pub(super) both: Vec<[f64; 3]>,
}

impl Halves {
    /// relMSE of one half (its variance), divided by `d` (see [`predict::divisor`]).
    pub(super) fn half_rel_mse(&self, d: &[[f64; 3]]) -> f64 {
        rel(d, |p, c| {
            let x = self.a[p][c] - self.b[p][c];
            0.5 * x * x
        })
    }

    /// relMSE of the mean of both halves against `r`, divided by `d`.
    pub(super) fn rel_mse(&self, r: &[[f64; 3]], d: &[[f64; 3]]) -> f64 {
        rel(d, |p, c| {
            let x = self.both[p][c] - r[p][c];
            x * x
        })
    }
}

/// A candidate's pilot.
pub(super) struct Run {
    pub(super) images: Halves,
    /// The passes of the first half (the job's seed).
    pub(super) artifacts: Vec<(String, Loaded)>,
    /// Wall seconds the render pays once: the passes, and a frame's work that grows with
    /// neither pixels nor samples ([`crate::method::Finished::fixed_s`]).
    pub(super) setup_s: f64,
    /// Wall seconds of the 2k samples (less their frames' fixed work), and of the part of them that grows with the pixels
    /// (see [`crate::method::Finished::pixels_s`]).
    pub(super) frame_s: f64,
    pub(super) pixels_s: Option<f64>,
    pub(super) pilot_s: f64,
    /// Wall seconds of the pilot's work that the render takes over where this candidate
    /// wins: its passes and SPPM's photons.
    pub(super) handed_s: f64,
    /// How SPPM's radii shrink, from the photons its first half found.
    pub(super) shrinkage: Option<Shrinkage>,
}

/// What a candidate's pilot came to.
pub(super) enum Pilot {
    Ran(Run),
    /// Not measured: what it would cost, and why that is too much.
    TooDear(String),
}

/// The pixel-wise mean of two images.
fn mean(a: &[[f64; 3]], b: &[[f64; 3]]) -> Vec<[f64; 3]> {
    a.iter()
        .zip(b)
        .map(|(x, y)| [0, 1, 2].map(|i| 0.5 * (x[i] + y[i])))
        .collect()
}

/// Renders candidate `c`'s pilot of `pilot` (the scene at a smaller film than the render's
/// `film`).
pub(super) fn run(
    c: &Candidate,
    pilot: &SceneDesc,
    film: FilmDesc,
    scene: &mut Scene,
    frame: u32,
    threads: usize,
    Allowance { left, reusable }: Allowance,
) -> Result<Pilot, String> {
    let start = Instant::now();
    let mut desc = pilot.clone();
    super::super::set_method(&mut desc, c.method, c.subsurface, c.photons);
    desc.integrator.spp = c.k;
    // SPPM's pixel is its filter-weighted sum over T·E[w], not a ratio that a negative lobe
    // can blow up: the weights' own noise is part of its variance (larger under a Mitchell
    // filter than a box), which a box would hide. Its floor is then measured against
    // judges under a box, and also counts the two filters' difference, against SPPM.
    if c.model == Model::Progressive {
        desc.film.filter = film.filter;
    }
    let noop = |_: Progress| {};
    // Both halves render the same film: one tile size for both.
    let tile = pilot_tile(desc.film.width, desc.film.height, threads);
    let job = Job {
        cache_film: Some(film),
        tile,
        ..Job::new(desc.clone(), frame)
    };
    let p = plan(&job)?;
    scene.set_settings(&desc);
    let local = Local::new(p.as_ref(), scene, &desc, threads, &noop);
    // The passes (a photon map, its irradiance cache) are the render's where it wins, and
    // built here whatever the film: timed on their first tasks (and their finish estimated
    // from those tasks' results), they stop there when dearer than what is left.
    if let Built::TooDear(all) = local.passes_within(reusable)? {
        return Ok(Pilot::TooDear(format!(
            "its passes would take at least {all:.2} s at their first tasks' pace, with their finish, more than {:.2} s ({:.2} s left, the render reusing them where it wins)",
            reusable.max(0.0),
            left.max(0.0)
        )));
    }
    let setup_s = start.elapsed().as_secs_f64();
    // A frame's fixed work (a Metropolis bootstrap) costs the same whatever the film: timed
    // on a part of it, the pilot stops here when its two frames would cost more than is left.
    if let Some(probe) = c.probe.filter(|_| left.is_finite()) {
        let all = probe(&desc, scene, frame, c.k)?;
        if all > left {
            return Ok(Pilot::TooDear(format!(
                "its two frames would take {all:.2} s at its first part's pace, more than the {:.2} s left",
                left.max(0.0)
            )));
        }
    }
    let rendering = Instant::now();
    // SPPM's photons do not depend on the film: the pilot's are the render's first 2k
    // iterations', shot here and handed on with the passes, unless they cost more than is left.
    let sppm =
        (c.model == Model::Progressive).then(|| SppmSettings::resolve(&desc, &analyze(&desc)));
    let shooting = Instant::now();
    let photons = match &sppm {
        Some((photon, settings)) => {
            match sppm_photons(scene, photon, *settings, frame, 2 * c.k, reusable) {
                Ok(photons) => photons,
                Err(all) => {
                    return Ok(Pilot::TooDear(format!(
                        "its photons would take {all:.2} s at its first chunk's pace, more than {:.2} s ({:.2} s left, the render reusing them where it wins)",
                        reusable.max(0.0),
                        left.max(0.0)
                    )));
                }
            }
        }
        None => Vec::new(),
    };
    let photons_s = shooting.elapsed().as_secs_f64();
    let local = local.with_artifacts(photons.iter().cloned());
    let (mut state, first) = local.frame_with_state(frame)?;
    let a = rgb(&first.image);
    let shrinkage = match &sppm {
        Some((_, settings)) => state
            .as_any()
            .downcast_ref::<SppmFrame>()
            .and_then(|f| Shrinkage::measure(f.state(), c.k, settings.alpha as f64)),
        None => None,
    };
    let mut pixels_s = first.pixels_s;
    // Work that grows with neither pixels nor samples: its seconds over the frames rendered,
    // and how many frames.
    let mut fixed = (first.fixed_s, 1.0);
    let continued = match c.model {
        // SPPM's later iterations gather in smaller radii: not a second sample of its first.
        Model::Progressive => None,
        _ => local.more(frame, state.as_mut(), 2 * c.k),
    };
    let mut frame_s = rendering.elapsed().as_secs_f64();
    let artifacts = local.artifacts();
    drop(local);
    let (b, both) = match continued {
        Some(done) => {
            let done = done?;
            // The continued frame's are the whole frame's.
            pixels_s = done.pixels_s;
            fixed = (done.fixed_s, 1.0);
            let both = rgb(&done.image);
            // The second half: the 2k mean less the first half's share.
            let b = both
                .iter()
                .zip(&a)
                .map(|(m, x)| [0, 1, 2].map(|i| 2.0 * m[i] - x[i]))
                .collect();
            (b, both)
        }
        None => {
            let b = if let Some((photon, settings)) = &sppm {
                let second = Instant::now();
                let b =
                    sppm_second_half(&desc, scene, photon, *settings, frame, c.k, &photons, &film)?;
                frame_s += second.elapsed().as_secs_f64() - b.probe_s;
                // Both halves' pixels as the render's spacing would have them.
                pixels_s = pixels_s.map(|a| (a + b.pixels_s) * b.spacing);
                b.image
            } else {
                let mut other = desc.clone();
                other.integrator.seed = other.integrator.seed.wrapping_add(1);
                let job = Job {
                    tile,
                    ..Job::new(other.clone(), frame)
                };
                let p = plan(&job)?;
                scene.set_settings(&other);
                let local = Local::new(p.as_ref(), scene, &other, threads, &noop);
                local.passes()?;
                let second = Instant::now();
                let other = local.frame(frame)?;
                frame_s += second.elapsed().as_secs_f64();
                pixels_s = pixels_s.zip(other.pixels_s).map(|(a, b)| a + b);
                fixed = (fixed.0 + other.fixed_s, 2.0);
                rgb(&other.image)
            };
            let both = mean(&a, &b);
            (b, both)
        }
    };
    Ok(Pilot::Ran(Run {
        images: Halves { a, b, both },
        artifacts,
        // A frame's fixed work is paid once by the render, as its passes are.
        setup_s: setup_s + fixed.0 / fixed.1,
        frame_s: frame_s - fixed.0,
        pixels_s,
        pilot_s: start.elapsed().as_secs_f64(),
        // The passes are what it spent before its frames (its plan alone where it has none).
        handed_s: setup_s + photons_s,
        shrinkage,
    }))
}
#[cfg(test)]
mod tests {
    use super::super::tests::{built, one_sample, scene};
    use super::super::{Choice, FEW_PHOTONS};
    use super::*;

    /// Why a pilot given no time was not run; it must not have run.
    fn refused(pilot: Result<Pilot, String>) -> String {
        match pilot {
            Ok(Pilot::TooDear(why)) => why,
            Ok(Pilot::Ran(_)) => panic!("the pilot ran with no time left"),
            Err(e) => panic!("{e}"),
        }
    }

    /// A pilot's film is cut so that every thread has tiles to render: the indirect room's
    /// pilot (a few hundred pixels) fits one default tile, which one thread would render
    /// while the others wait. Large pilot films keep tiles no larger than the render's.
    #[test]
    fn every_thread_has_tiles_of_a_pilot_s_film() {
        let count = |w: u32, h: u32, t: u32| (w.div_ceil(t) * h.div_ceil(t)) as usize;
        let p = pilot_desc(&scene("indirect-room")).film;
        assert_eq!(crate::method::default_tile(p.width, p.height), 32);
        assert_eq!(count(p.width, p.height, 32), 1);
        for threads in [1, 2, 4] {
            let t = pilot_tile(p.width, p.height, threads);
            assert!(
                count(p.width, p.height, t) >= PILOT_TILES_PER_THREAD as usize * threads,
                "{}×{} pixels, tile {t}, {threads} threads",
                p.width,
                p.height
            );
        }
        let big = pilot_desc(&scene("cornell-box")).film;
        assert!(pilot_tile(big.width, big.height, 2) <= 32);
        // A film too small for that gets the smallest tile, not nothing.
        assert_eq!(pilot_tile(3, 2, 64), 4);
    }

    /// No time left, nor reusable work.
    const NOTHING_LEFT: Allowance = Allowance {
        left: 0.0,
        reusable: 0.0,
    };

    /// A Metropolis frame's bootstrap (100 000 brightness samples and as many bootstrap
    /// paths, whatever the film) is paid once by the render: the pilot counts it with the
    /// passes, not with the samples it scales to the full film. On a 16×16 film with one
    /// mutation per pixel a half, it is most of the pilot. Timed on one group of chains
    /// first, the pilot stops there when its frames cost more than is left.
    #[test]
    fn a_metropolis_pilot_counts_its_bootstrap_once_and_apart_from_its_samples() {
        let mut desc = scene("cornell-box");
        desc.film.width = 16;
        desc.film.height = 16;
        let mut built = built(&desc);
        for method in ["pssmlt", "mlt"] {
            let c = one_sample(method, Model::Unbiased);
            let Ok(Pilot::Ran(r)) =
                run(&c, &desc, desc.film, &mut built, 1, 2, Allowance::UNLIMITED)
            else {
                panic!("{method}'s pilot did not run");
            };
            assert!(
                r.setup_s > r.frame_s && r.frame_s > 0.0,
                "{method}: setup {} s, samples {} s",
                r.setup_s,
                r.frame_s
            );
            // With no time left it stops after one group of chains.
            let why = refused(run(&c, &desc, desc.film, &mut built, 1, 2, NOTHING_LEFT));
            assert!(why.contains("its two frames"), "{why}");
        }
    }

    /// SPPM's pilot renders with the film's filter where the others' take a box for a
    /// Mitchell one: under Mitchell's negative lobes its weights' noise raises its variance
    /// (measured on the material spheres), and a box pilot
    /// would hide it. From the same pilot film (a box), its halves differ clearly more for a
    /// Mitchell render than for a box one.
    #[test]
    fn sppm_s_pilot_counts_the_noise_of_the_film_s_filter() {
        let desc = scene("material-spheres");
        let pilot = pilot_desc(&desc);
        assert!(matches!(pilot.film.filter, FilterDesc::Box { .. }));
        assert!(matches!(desc.film.filter, FilterDesc::Mitchell { .. }));
        let mut built = built(&pilot);
        let c = one_sample("sppm", Model::Progressive);
        let mut halves =
            |film: FilmDesc| match run(&c, &pilot, film, &mut built, 1, 2, Allowance::UNLIMITED) {
                Ok(Pilot::Ran(r)) => r.images,
                _ => panic!("sppm's pilot did not run"),
            };
        let mitchell = halves(desc.film);
        let boxed = halves(FilmDesc {
            filter: FilterDesc::Box { radius: 0.5 },
            ..desc.film
        });
        // Both divided by the box's mean, the quieter.
        let variance =
            |h: &Halves| rel(&boxed.both, |p, ch| 0.5 * (h.a[p][ch] - h.b[p][ch]).powi(2));
        let (mitchell, boxed) = (variance(&mitchell), variance(&boxed));
        assert!(
            mitchell > 1.4 * boxed,
            "relMSE of a half {mitchell} under Mitchell, {boxed} under a box"
        );
    }

    /// The photon map's pilot times its passes' first tasks and stops there when they would
    /// cost more than is left, as SPPM's photons do; with time enough it builds them and
    /// hands them on, and counts their time as the render's.
    #[test]
    fn a_photon_map_pilot_stops_at_its_first_tasks_when_its_passes_cost_more_than_is_left() {
        let mut desc = scene("cornell-box");
        desc.film.width = 32;
        desc.film.height = 32;
        let mut built = built(&desc);
        let c = one_sample("photon", Model::Biased);
        let why = refused(run(&c, &desc, desc.film, &mut built, 1, 2, NOTHING_LEFT));
        assert!(why.contains("its passes would take"), "{why}");
        match run(&c, &desc, desc.film, &mut built, 1, 2, Allowance::UNLIMITED) {
            Ok(Pilot::Ran(r)) => {
                assert!(!r.artifacts.is_empty(), "no photon map handed on");
                // Its passes are the render's work, timed as such and within the pilot.
                assert!(
                    r.handed_s > 0.0 && r.handed_s <= r.pilot_s,
                    "handed on {} s of a {} s pilot",
                    r.handed_s,
                    r.pilot_s
                );
            }
            Ok(Pilot::TooDear(why)) => panic!("{why}"),
            Err(e) => panic!("{e}"),
        }
    }

    /// The photon map's pilot renders its small film from the render's irradiance cache:
    /// built from the render's film under the render's key, so that the render takes every
    /// pass of the pilot's as its own, and the records are those the render would make. With
    /// the few photons the pilot measures first, the render the choice plans has the same
    /// keys.
    #[test]
    fn a_photon_map_pilot_builds_the_render_s_irradiance_cache() {
        let mut desc = scene("cornell-box");
        desc.film.width = 96;
        desc.film.height = 96;
        let pilot = pilot_desc(&desc);
        assert!(
            pilot.film.width < desc.film.width,
            "the pilot's film is the render's"
        );
        let mut built = built(&desc);
        let c = Candidate {
            photons: Some(FEW_PHOTONS),
            ..one_sample("photon", Model::Biased)
        };
        let Ok(Pilot::Ran(r)) = run(
            &c,
            &pilot,
            desc.film,
            &mut built,
            1,
            2,
            Allowance::UNLIMITED,
        ) else {
            panic!("the photon map's pilot did not run");
        };
        let mut render = desc.clone();
        Choice {
            method: "photon".into(),
            subsurface: None,
            photons: c.photons,
            spp: 1,
            target_error: None,
            report: Vec::new(),
        }
        .apply(&mut render);
        let job = Job::new(render.clone(), 1);
        let p = plan(&job).expect("the render plans");
        built.set_settings(&render);
        let local = Local::new(p.as_ref(), &built, &render, 2, &|_| {});
        local.passes().expect("the render's passes");
        let own = local.artifacts();
        let passes = p.passes();
        assert_eq!(passes.len(), 2, "photon maps and an irradiance cache");
        for pass in passes {
            let find = |a: &[(String, Loaded)]| {
                a.iter()
                    .find(|(k, _)| k == pass.key())
                    .map(|(_, l)| l.clone())
                    .unwrap_or_else(|| panic!("{} not among the artifacts", pass.name()))
            };
            let (pilot, render) = (find(&r.artifacts), find(&own));
            if let (Some(a), Some(b)) = (
                pilot.downcast_ref::<crate::irradiance::IrradianceCache>(),
                render.downcast_ref::<crate::irradiance::IrradianceCache>(),
            ) {
                assert!(!b.is_empty(), "the render's cache has records");
                assert_eq!(
                    a.records(),
                    b.records(),
                    "the pilot's records are the render's"
                );
            }
        }
    }
}
