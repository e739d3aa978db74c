//! SPPM's pilot: its photons, shot whatever the film and handed on to the render, their cost
//! told by the first chunk, and its second half (see the parent module, step 2).

use std::ops::Range;
use std::sync::Arc;
use std::time::Instant;

use rayon::prelude::*;
use tessera_scene::SceneDesc;

use super::run::rgb;
use crate::camera::Camera;
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

/// SPPM's second half: the photons of iterations k..2k of the job's seed (`photons`, by key:
/// those the render's iterations k..2k use) gathered at the camera paths of the next seed's
/// first k iterations, from the initial radii: the same estimator as the first half's k
/// iterations, on independent samples.
/// Its image, and the wall seconds of its camera paths and gathering.
pub(super) fn sppm_second_half(
    desc: &SceneDesc,
    scene: &Scene,
    photon: &PhotonSettings,
    settings: SppmSettings,
    frame: u32,
    k: u32,
    photons: &[(String, Loaded)],
) -> Result<(Vec<[f64; 3]>, f64), String> {
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
    for t in k..2 * k {
        let vps = sppm.visible_points_parallel(&camera, t - k);
        let r2 = state.radii2();
        let mut sums = Vec::new();
        for chunk in sppm::chunks(settings.photons) {
            let key = sppm::photons_key(photon, &settings, frame, t, &chunk);
            let tree = photons
                .iter()
                .find(|(name, _)| *name == key)
                .and_then(|(_, p)| p.clone().downcast::<KdTree<Photon>>().ok())
                .ok_or_else(|| format!("auto: sppm's pilot lost its photons ({key})"))?;
            sums.push(sppm.gather_parallel(&vps, &r2, &tree));
        }
        state.add_iteration(&vps.camera, sums.iter().map(Vec::as_slice), settings.alpha);
    }
    Ok((
        rgb(&state.image(camera.exposure)),
        start.elapsed().as_secs_f64(),
    ))
}

#[cfg(test)]
mod tests {
    use super::super::tests::{built, scene};
    use super::*;
    use crate::analysis::analyze;
    use crate::method::local::{Local, Progress};
    use crate::method::{Job, plan};

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
