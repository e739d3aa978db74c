//! SPPM's pilot: its photons, shot whatever the film and handed on to the render, a probe of
//! their cost, and its second half (see the parent module, step 2).

use std::ops::Range;
use std::time::Instant;

use rayon::prelude::*;
use tessera_scene::SceneDesc;

use super::rgb;
use crate::analysis::analyze;
use crate::camera::Camera;
use crate::integrator::sppm::{self, Sppm, SppmSettings, SppmState};
use crate::method::Loaded;
use crate::photon::{KdTree, Photon, PhotonSettings};
use crate::scene::Scene;

/// The photons of SPPM's first `iterations` iterations of `frame` for `desc` (its settings
/// applied to `scene`), by the keys its photon tasks look them up under.
/// Those in `have` (by key) are taken, not shot again.
pub(super) fn sppm_photons(
    desc: &SceneDesc,
    scene: &Scene,
    frame: u32,
    iterations: u32,
    have: &[(String, Loaded)],
) -> Vec<(String, Loaded)> {
    let (photon, settings) = SppmSettings::resolve(desc, &analyze(desc));
    let sppm = Sppm::new(scene, &photon, settings);
    let work: Vec<(u32, Range<u32>)> = (0..iterations)
        .flat_map(|t| {
            sppm::chunks(settings.photons)
                .into_iter()
                .map(move |c| (t, c))
        })
        .collect();
    work.into_par_iter()
        .map(|(t, chunk)| {
            let key = sppm::photons_key(&photon, &settings, frame, t, &chunk);
            let shot = have.iter().find(|(k, _)| *k == key).map(|(_, p)| p.clone());
            let photons =
                shot.unwrap_or_else(|| std::sync::Arc::new(sppm.shoot(t, chunk, false)) as Loaded);
            (key, photons)
        })
        .collect()
}

/// SPPM's first chunk of photons (by key), and the wall seconds that `iterations` iterations'
/// photons are predicted to take at its pace.
pub(super) fn sppm_probe(
    desc: &SceneDesc,
    scene: &Scene,
    frame: u32,
    iterations: u32,
) -> (Vec<(String, Loaded)>, f64) {
    let start = Instant::now();
    let (photon, settings) = SppmSettings::resolve(desc, &analyze(desc));
    let chunks = sppm::chunks(settings.photons);
    let Some(first) = chunks.first().cloned() else {
        return (Vec::new(), 0.0);
    };
    let key = sppm::photons_key(&photon, &settings, frame, 0, &first);
    let tree = Sppm::new(scene, &photon, settings).shoot(0, first, true);
    let s = start.elapsed().as_secs_f64();
    let all = s * (chunks.len() as f64) * f64::from(iterations);
    (vec![(key, std::sync::Arc::new(tree) as Loaded)], all)
}

/// SPPM's second half: the photons of iterations k..2k of the job's seed (`photons`, by key:
/// those the render's iterations k..2k use) gathered at the camera paths of the next seed's
/// first k iterations, from the initial radii: the same estimator as the first half's k
/// iterations, on independent samples.
/// Its image, and the wall seconds of its camera paths and gathering.
pub(super) fn sppm_second_half(
    desc: &SceneDesc,
    scene: &Scene,
    frame: u32,
    k: u32,
    photons: &[(String, Loaded)],
) -> Result<(Vec<[f64; 3]>, f64), String> {
    let start = Instant::now();
    let (photon, settings) = SppmSettings::resolve(desc, &analyze(desc));
    // Camera paths of the next seed: iteration k's of the job's seed would be the next points
    // of the first half's low-discrepancy sequence, anticorrelated with them.
    let other = PhotonSettings {
        seed: photon.seed.wrapping_add(1),
        ..photon
    };
    let sppm = Sppm::new(scene, &other, settings);
    let camera = Camera::new(&desc.camera_at(frame), &desc.film);
    let mut state = SppmState::new(desc.film.width, desc.film.height, settings.initial_radius);
    for t in k..2 * k {
        let vps = sppm.visible_points_parallel(&camera, t - k);
        let r2 = state.radii2();
        let mut sums = Vec::new();
        for chunk in sppm::chunks(settings.photons) {
            let key = sppm::photons_key(&photon, &settings, frame, t, &chunk);
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
    use super::super::tests::scene;
    use super::*;
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
        let mut scene = Scene::build(&desc);
        scene.set_settings(&desc);
        let render = |given: Vec<(String, Loaded)>| {
            let job = Job::new(desc.clone(), 1);
            let p = plan(&job).unwrap_or_else(|e| panic!("{e}"));
            let noop = |_: Progress| {};
            let local = Local::new(p.as_ref(), &scene, &desc, 1, &noop).with_artifacts(given);
            local.passes().unwrap_or_else(|e| panic!("{e}"));
            let image = local.frame(1).unwrap_or_else(|e| panic!("{e}")).image;
            image.pixels.iter().map(|p| p.rgb).collect::<Vec<_>>()
        };
        let given = sppm_photons(&desc, &scene, 1, 2, &[]);
        assert!(!given.is_empty());
        assert!(
            given
                .iter()
                .all(|(k, _)| k.starts_with("sppm photons: frame 1, iteration "))
        );
        let own = render(Vec::new());
        assert_eq!(render(given.clone()), own);
        // The same keys holding the photons of iterations 2 and 3.
        let later = sppm_photons(&desc, &scene, 1, 4, &[]);
        let swapped: Vec<(String, Loaded)> = given
            .iter()
            .zip(later.iter().skip(given.len()))
            .map(|((key, _), (_, photons))| (key.clone(), photons.clone()))
            .collect();
        assert_ne!(render(swapped), own);
    }

    /// The probe's chunk is the one `sppm_photons` would shoot under its key, and is taken
    /// from it, not shot again.
    #[test]
    fn the_probes_chunk_is_the_pilots_first() {
        let mut desc = scene("indirect-room");
        desc.integrator.method = "sppm".into();
        desc.integrator.photon.photons = Some(2 * sppm::PHOTONS_PER_CHUNK);
        let mut scene = Scene::build(&desc);
        scene.set_settings(&desc);
        let (probe, all) = sppm_probe(&desc, &scene, 1, 2);
        assert_eq!(probe.len(), 1);
        assert!(all > 0.0);
        let tree = |p: &Loaded| {
            p.clone()
                .downcast::<KdTree<Photon>>()
                .unwrap_or_else(|_| panic!("not photons"))
        };
        let shot = sppm_photons(&desc, &scene, 1, 2, &[]);
        assert_eq!(shot.len(), 4);
        assert_eq!(shot[0].0, probe[0].0);
        assert_eq!(*tree(&shot[0].1), *tree(&probe[0].1));
        let given = sppm_photons(&desc, &scene, 1, 2, &probe);
        assert!(std::sync::Arc::ptr_eq(&given[0].1, &probe[0].1));
        assert_eq!(*tree(&given[1].1), *tree(&shot[1].1));
    }
}
