//! SPPM's pilot: its photons, shot whatever the film and handed on to the render, their cost
//! told by the first chunk, and its second half (see the parent module, step 2).

use std::ops::Range;
use std::sync::Arc;
use std::time::Instant;

use glam::UVec2;
use rayon::prelude::*;
use tessera_scene::{FilmDesc, SceneDesc};

use crate::camera::Camera;
use crate::film::Image;
use crate::integrator::sppm::{self, Sppm, SppmSettings, SppmState};
use crate::method::Loaded;
use crate::photon::{KdTree, Photon, PhotonSettings};
use crate::scene::Scene;

/// The photons of SPPM's first `iterations` iterations of `frame` (`photon`, `settings`:
/// SPPM's settings, resolved for the job), by the keys its photon tasks look them up under.
/// The first chunk is shot and timed alone: where the shooter's setup and all the chunks at
/// its pace would take more than `left` wall seconds, the rest are not shot and that
/// prediction is the error.
pub(super) fn sppm_photons(
    scene: &Scene,
    photon: &PhotonSettings,
    settings: SppmSettings,
    frame: u32,
    iterations: u32,
    left: f64,
) -> Result<Vec<(String, Loaded)>, f64> {
    let start = Instant::now();
    let sppm = Sppm::new(scene, photon, settings);
    let setup_s = start.elapsed().as_secs_f64();
    let work: Vec<(u32, Range<u32>)> = (0..iterations)
        .flat_map(|t| {
            sppm::chunks(settings.photons)
                .into_iter()
                .map(move |c| (t, c))
        })
        .collect();
    let shoot = |(t, chunk): &(u32, Range<u32>), parallel: bool| {
        let key = sppm::photons_key(photon, &settings, frame, *t, chunk);
        let tree = sppm.shoot(*t, chunk.clone(), parallel);
        (key, Arc::new(tree) as Loaded)
    };
    let Some((first, rest)) = work.split_first() else {
        return Ok(Vec::new());
    };
    // The first chunk alone, on every thread, as the probe: its pace is the others' in parallel.
    let chunk = Instant::now();
    let probe = shoot(first, true);
    let all = setup_s + chunk.elapsed().as_secs_f64() * work.len() as f64;
    if all > left {
        return Err(all);
    }
    let mut shot = vec![probe];
    shot.par_extend(rest.par_iter().map(|w| shoot(w, false)));
    Ok(shot)
}

/// What SPPM's second half came to.
pub(super) struct SecondHalf {
    pub(super) image: Vec<[f64; 3]>,
    /// Wall seconds of its camera paths and gathering.
    pub(super) pixels_s: f64,
    /// The pixels' seconds as they would be at the render's pixel spacing over the pilot's:
    /// [`gathering_at_the_render`]'s ratio on its share of them.
    pub(super) spacing: f64,
    /// Wall seconds of that measurement (pilot time, not the render's).
    pub(super) probe_s: f64,
}

/// SPPM's second half: the photons of iterations k..2k of the job's seed (`photons`, by key:
/// those the render's iterations k..2k use) gathered at the camera paths of the next seed's
/// first k iterations, from the initial radii: the same estimator as the first half's k
/// iterations, on independent samples. Its first iteration's gathering is also timed at the
/// render's film `film` ([`gathering_at_the_render`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn sppm_second_half(
    desc: &SceneDesc,
    scene: &Scene,
    photon: &PhotonSettings,
    settings: SppmSettings,
    frame: u32,
    k: u32,
    photons: &[(String, Loaded)],
    film: &FilmDesc,
) -> Result<SecondHalf, String> {
    let start = Instant::now();
    // Camera paths of the next seed: iteration k's of the job's seed would be the next points
    // of the first half's low-discrepancy sequence, anticorrelated with them.
    let other = PhotonSettings {
        seed: photon.seed.wrapping_add(1),
        ..*photon
    };
    let sppm = Sppm::new(scene, &other, settings);
    let camera = Camera::new(&desc.camera_at(frame), &desc.film);
    let mut state = SppmState::new(
        desc.film.width,
        desc.film.height,
        settings.initial_radius,
        scene.filter.mean_weight(),
    );
    let (mut gathering_s, mut spacing, mut probe_s) = (0.0, 1.0, 0.0);
    for t in k..2 * k {
        let vps = sppm.visible_points_parallel(&camera, t - k);
        let r2 = state.radii2();
        let trees = sppm::chunks(settings.photons)
            .into_iter()
            .map(|chunk| {
                let key = sppm::photons_key(photon, &settings, frame, t, &chunk);
                photons
                    .iter()
                    .find(|(name, _)| *name == key)
                    .and_then(|(_, p)| p.clone().downcast::<KdTree<Photon>>().ok())
                    .ok_or_else(|| format!("auto: sppm's pilot lost its photons ({key})"))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let gathering = Instant::now();
        let sums: Vec<_> = trees
            .iter()
            .map(|tree| sppm.gather_parallel(&vps, &r2, tree))
            .collect();
        let here = gathering.elapsed().as_secs_f64();
        gathering_s += here;
        if t == k {
            let probe = Instant::now();
            let there = gathering_at_the_render(&sppm, desc, film, frame, &trees, settings);
            let pixels = (desc.film.width * desc.film.height) as f64;
            spacing = match there {
                Some((s, n)) if here > 0.0 && n > 0 => (s / n as f64) / (here / pixels),
                _ => 1.0,
            };
            probe_s = probe.elapsed().as_secs_f64();
        }
        state.add_iteration(&vps.camera, sums.iter().map(Vec::as_slice), settings.alpha);
    }
    let pixels_s = start.elapsed().as_secs_f64() - probe_s;
    // Gathering is the share of the pixels' seconds whose pace depends on their spacing.
    let share = (gathering_s / pixels_s).min(1.0);
    Ok(SecondHalf {
        image: rgb(&state.image(camera.exposure)),
        pixels_s,
        spacing: 1.0 - share + share * spacing,
        probe_s,
    })
}

/// Blocks of the render's film `film` SPPM's pilot gathers at, on a grid across it.
const BLOCKS: u32 = 4;

/// `BLOCKS`² square blocks of `film`'s pixels, `pixels` of them in all or fewer, one in the
/// middle of each cell of a `BLOCKS` × `BLOCKS` grid: their side and top-left corners.
fn blocks(pixels: u32, film: &FilmDesc) -> (u32, Vec<(u32, u32)>) {
    let side = ((pixels as f64 / (BLOCKS * BLOCKS) as f64).sqrt() as u32)
        .min(film.width / BLOCKS)
        .min(film.height / BLOCKS);
    let corner = |extent: u32, i: u32| extent * (2 * i + 1) / (2 * BLOCKS) - side / 2;
    let corners = (0..BLOCKS * BLOCKS)
        .map(|b| {
            (
                corner(film.width, b % BLOCKS),
                corner(film.height, b / BLOCKS),
            )
        })
        .collect();
    (side, corners)
}

/// SPPM's gathering (each pixel's search of every photon tree) runs faster where neighbouring
/// pixels search the same part of the trees: at the render's film than at the pilot's coarser
/// one. Timed here on as many of the render's pixels as the pilot has, in `BLOCKS`² square
/// blocks spread across the film (each block's pixels row by row, as the render's are), from
/// the initial radii against `trees` (an iteration's chunks): the wall seconds and the pixels,
/// `None` where the film has no pixels to spare.
fn gathering_at_the_render(
    sppm: &Sppm,
    pilot: &SceneDesc,
    film: &FilmDesc,
    frame: u32,
    trees: &[Arc<KdTree<Photon>>],
    settings: SppmSettings,
) -> Option<(f64, usize)> {
    let (side, blocks) = blocks(pilot.film.width * pilot.film.height, film);
    if side == 0 {
        return None;
    }
    let camera = Camera::new(&pilot.camera_at(frame), film);
    let r2 = vec![sppm::radius2(settings.initial_radius as f64); (side * side) as usize];
    let vps: Vec<_> = blocks
        .par_iter()
        .map(|&(x0, y0)| {
            let pixels = (0..side * side).map(|i| UVec2::new(x0 + i % side, y0 + i / side));
            sppm.visible_points_of(&camera, 0, pixels)
        })
        .collect();
    // As the render gathers: each tree in turn, at every pixel on every thread.
    let start = Instant::now();
    for tree in trees {
        vps.par_iter().for_each(|v| {
            std::hint::black_box(sppm.gather(v, &r2, tree, 0..side * side));
        });
    }
    let n = vps.len() * (side * side) as usize;
    Some((start.elapsed().as_secs_f64(), n))
}

/// An image's pixels as f64 RGB, for the pilot's arithmetic.
pub(super) fn rgb(image: &Image) -> Vec<[f64; 3]> {
    image.pixels.iter().map(|p| p.rgb.map(f64::from)).collect()
}

#[cfg(test)]
mod tests {
    use super::super::tests::{built, scene};
    use super::*;
    use crate::analysis::analyze;
    use crate::method::local::{Local, Progress};
    use crate::method::{Job, plan};

    /// The blocks SPPM's pilot times its gathering on lie inside the render's film, apart,
    /// and hold as many pixels as the pilot's film, less what whole squares leave over.
    #[test]
    fn gathering_blocks_lie_apart_inside_the_film() {
        let film = |width, height| FilmDesc {
            width,
            height,
            filter: tessera_scene::FilterDesc::Box { radius: 0.5 },
        };
        for (pixels, w, h) in [
            (4070, 512, 384),
            (2048, 256, 256),
            (256, 16, 16),
            (4096, 1920, 1080),
            (300, 5, 7),
        ] {
            let f = film(w, h);
            let (side, corners) = blocks(pixels, &f);
            assert_eq!(corners.len(), (BLOCKS * BLOCKS) as usize);
            let n = corners.len() as u32 * side * side;
            assert!(n <= pixels, "{w}×{h}: {n} pixels for the pilot's {pixels}");
            if side < w / BLOCKS && side < h / BLOCKS {
                assert!(2 * n >= pixels, "{w}×{h}: only {n} of the pilot's {pixels}");
            }
            for (i, &(x, y)) in corners.iter().enumerate() {
                assert!(
                    x + side <= w && y + side <= h,
                    "{w}×{h}: block at ({x}, {y}) of side {side}"
                );
                for &(u, v) in &corners[..i] {
                    let apart = x >= u + side || u >= x + side || y >= v + side || v >= y + side;
                    assert!(
                        apart,
                        "{w}×{h}: blocks at ({x}, {y}) and ({u}, {v}) overlap"
                    );
                }
            }
        }
    }

    /// SPPM's photons handed on by the pilot are the ones the render would shoot: a render
    /// that takes them is the render that shoots its own, bit for bit, and it does take them
    /// (photons of other iterations under the same keys change the image).
    #[test]
    fn sppm_renders_alike_with_the_pilots_photons() {
        let mut desc = scene("indirect-room");
        desc.film.width = 32;
        desc.film.height = 24;
        desc.integrator.method = "sppm".into();
        desc.integrator.spp = 3;
        desc.integrator.photon.photons = Some(20_000);
        let scene = built(&desc);
        let render = |given: Vec<(String, Loaded)>| {
            let job = Job::new(desc.clone(), 1);
            let p = plan(&job).unwrap_or_else(|e| panic!("{e}"));
            let noop = |_: Progress| {};
            let local = Local::new(p.as_ref(), &scene, &desc, 1, &noop).with_artifacts(given);
            local.passes().unwrap_or_else(|e| panic!("{e}"));
            let image = local.frame(1).unwrap_or_else(|e| panic!("{e}")).image;
            image.pixels.iter().map(|p| p.rgb).collect::<Vec<_>>()
        };
        let (photon, settings) = SppmSettings::resolve(&desc, &analyze(&desc));
        let photons = |iterations| {
            sppm_photons(&scene, &photon, settings, 1, iterations, f64::INFINITY)
                .unwrap_or_else(|s| panic!("too dear at {s} s"))
        };
        let given = photons(2);
        assert!(!given.is_empty());
        assert!(
            given
                .iter()
                .all(|(k, _)| k.starts_with("sppm photons: frame 1, iteration "))
        );
        let own = render(Vec::new());
        assert_eq!(render(given.clone()), own);
        // The same keys holding the photons of iterations 2 and 3.
        let later = photons(4);
        let swapped: Vec<(String, Loaded)> = given
            .iter()
            .zip(later.iter().skip(given.len()))
            .map(|((key, _), (_, photons))| (key.clone(), photons.clone()))
            .collect();
        assert_ne!(render(swapped), own);
    }

    /// The first chunk, shot alone to time it, is the one its key names, as the others are;
    /// where all would take more than is left, nothing more is shot.
    #[test]
    fn the_first_chunk_times_the_photons_and_is_theirs() {
        let mut desc = scene("indirect-room");
        desc.integrator.method = "sppm".into();
        desc.integrator.photon.photons = Some(2 * sppm::PHOTONS_PER_CHUNK);
        let scene = built(&desc);
        let (photon, settings) = SppmSettings::resolve(&desc, &analyze(&desc));
        let tree = |p: &Loaded| {
            p.clone()
                .downcast::<KdTree<Photon>>()
                .unwrap_or_else(|_| panic!("not photons"))
        };
        let shot = sppm_photons(&scene, &photon, settings, 1, 2, f64::INFINITY)
            .unwrap_or_else(|s| panic!("too dear at {s} s"));
        let sppm = Sppm::new(&scene, &photon, settings);
        let chunks = sppm::chunks(settings.photons);
        assert_eq!(chunks.len(), 2);
        let expected: Vec<(u32, Range<u32>)> = (0..2)
            .flat_map(|t| chunks.iter().map(move |c| (t, c.clone())))
            .collect();
        assert_eq!(shot.len(), expected.len());
        for ((key, photons), (t, chunk)) in shot.iter().zip(&expected) {
            assert_eq!(*key, sppm::photons_key(&photon, &settings, 1, *t, chunk));
            assert_eq!(
                *tree(photons),
                sppm.shoot(*t, chunk.clone(), false),
                "{key}"
            );
        }
        match sppm_photons(&scene, &photon, settings, 1, 2, 0.0) {
            Err(all) => assert!(all > 0.0),
            Ok(shot) => panic!("{} chunks shot with no time left", shot.len()),
        }
    }
}
