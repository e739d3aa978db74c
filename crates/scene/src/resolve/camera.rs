//! The film, its reconstruction filter, the camera and its path, the integrator settings.

use super::*;
use crate::setting::{self, Setting};

impl Ctx<'_> {
    pub(super) fn film(&mut self, f: &FilmFile) -> FilmDesc {
        for (name, v) in [("film.width", f.width), ("film.height", f.height)] {
            if v == 0 || v > MAX_FILM_SIDE {
                self.problem(
                    name,
                    format!("expected a size from 1 to {MAX_FILM_SIDE} pixels, got {v}"),
                );
            }
        }
        let filter = match &f.filter {
            None => FilterDesc::Box { radius: 0.5 },
            Some(fl) => self.filter(fl),
        };
        FilmDesc {
            width: f.width,
            height: f.height,
            filter,
        }
    }

    pub(super) fn filter(&mut self, f: &FilterFile) -> FilterDesc {
        let not_for = |s: &mut Self, field: &str, present: bool| {
            if present {
                s.problem(
                    format!("film.filter.{field}"),
                    format!("not a parameter of the {:?} filter", f.kind),
                );
            }
        };
        let radius = |s: &mut Self, default: f32| {
            let r = f.radius.unwrap_or(default);
            s.range(
                "film.filter.radius",
                r,
                0.5,
                16.0,
                "a radius from 0.5 to 16 pixels",
            )
        };
        match f.kind {
            FilterType::Box => {
                not_for(self, "sigma", f.sigma.is_some());
                not_for(self, "b", f.b.is_some());
                not_for(self, "c", f.c.is_some());
                FilterDesc::Box {
                    radius: radius(self, 0.5),
                }
            }
            FilterType::Gaussian => {
                not_for(self, "b", f.b.is_some());
                not_for(self, "c", f.c.is_some());
                let radius = radius(self, 1.5);
                let sigma = self.positive("film.filter.sigma", f.sigma.unwrap_or(0.5));
                FilterDesc::Gaussian { radius, sigma }
            }
            FilterType::Mitchell => {
                not_for(self, "sigma", f.sigma.is_some());
                let radius = radius(self, 2.0);
                let b = self.range(
                    "film.filter.b",
                    f.b.unwrap_or(1.0 / 3.0),
                    0.0,
                    1.0,
                    "B in [0, 1]",
                );
                let c = self.range(
                    "film.filter.c",
                    f.c.unwrap_or(1.0 / 3.0),
                    0.0,
                    1.0,
                    "C in [0, 1]",
                );
                FilterDesc::Mitchell { radius, b, c }
            }
        }
    }

    /// Checks one view of the camera (the still camera or a keyframe of its path, at `path`):
    /// finite points, a view direction, an up vector not along it, a field of view; returns
    /// the full vertical field of view in radians.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn view(
        &mut self,
        path: &str,
        position: [f32; 3],
        look_at: [f32; 3],
        up: [f32; 3],
        fov_deg: f32,
        fov_axis: FovAxis,
        film: &FilmDesc,
    ) -> (Vec3, Vec3, Vec3, f32) {
        let position = self.finite3(&format!("{path}.position"), position);
        let look_at = self.finite3(&format!("{path}.look_at"), look_at);
        let up = self.finite3(&format!("{path}.up"), up);
        let forward = look_at - position;
        if forward.length_squared() == 0.0 {
            self.problem(
                format!("{path}.look_at"),
                format!("expected a point different from {path}.position"),
            );
        } else if forward
            .normalize()
            .cross(up.normalize_or_zero())
            .length_squared()
            < 1e-8
        {
            self.problem(
                format!("{path}.up"),
                "expected an up vector that is not parallel to the view direction",
            );
        }
        let fov = self.range(
            &format!("{path}.fov_deg"),
            fov_deg,
            f32::MIN_POSITIVE,
            179.0,
            "a field of view in (0, 179] degrees",
        );
        let aspect = film.width.max(1) as f32 / film.height.max(1) as f32;
        let half = (fov.to_radians() * 0.5).tan();
        let fov_y = match fov_axis {
            FovAxis::Y => fov.to_radians(),
            FovAxis::X => 2.0 * (half / aspect).atan(),
        };
        (position, look_at, up, fov_y)
    }

    /// A camera path: fps, keyframes in strictly increasing time, each a valid view, and a
    /// valid view at every frame in between (an interpolated up may not turn along the view).
    pub(super) fn camera_path(
        &mut self,
        c: &CameraFile,
        p: &CameraPathFile,
        film: &FilmDesc,
    ) -> Option<CameraPath> {
        let before = self.problems.len();
        let fps = self.range(
            "camera.path.fps",
            p.fps,
            1e-3,
            1e4,
            "frames per second in [0.001, 10000]",
        );
        if p.keyframes.is_empty() {
            self.problem("camera.path.keyframes", "expected at least one keyframe");
            return None;
        }
        let mut keyframes = Vec::with_capacity(p.keyframes.len());
        for (i, k) in p.keyframes.iter().enumerate() {
            let at = format!("camera.path.keyframes[{i}]");
            if !k.time.is_finite() {
                self.problem(
                    format!("{at}.time"),
                    format!("expected a time in seconds, got {}", k.time),
                );
            } else if let Some(prev) = keyframes.last().map(|k: &Keyframe| k.time)
                && k.time <= prev
            {
                self.problem(
                    format!("{at}.time"),
                    format!(
                        "expected keyframe times to increase, got {} after {prev}",
                        k.time
                    ),
                );
            }
            let (position, look_at, up, fov_y) = self.view(
                &at,
                k.position,
                k.look_at,
                k.up.unwrap_or(c.up),
                k.fov_deg.unwrap_or(c.fov_deg),
                c.fov_axis,
                film,
            );
            keyframes.push(Keyframe {
                time: k.time,
                position,
                look_at,
                up: up.normalize_or_zero(),
                fov_y,
            });
        }
        if self.problems.len() > before {
            return None;
        }
        let path = CameraPath { fps, keyframes };
        let frames = path.frame_count();
        if frames > MAX_FRAMES {
            self.problem(
                "camera.path",
                format!("expected at most {MAX_FRAMES} frames, the keyframes span {frames}"),
            );
            return None;
        }
        for frame in 1..=frames {
            let k = path.at(path.time(frame));
            let forward = (k.look_at - k.position).normalize_or_zero();
            if forward == Vec3::ZERO || forward.cross(k.up).length_squared() < 1e-8 {
                self.problem(
                    "camera.path.keyframes",
                    format!("at frame {frame} the interpolated camera has no valid view direction (look_at on the position, or up along the view); add a keyframe there"),
                );
                return None;
            }
        }
        Some(path)
    }

    pub(super) fn camera(&mut self, c: &CameraFile, film: &FilmDesc) -> CameraDesc {
        let (position, look_at, up, fov_y) = self.view(
            "camera", c.position, c.look_at, c.up, c.fov_deg, c.fov_axis, film,
        );
        let lens = match c.kind {
            CameraType::Pinhole => {
                for (field, given) in [
                    ("aperture_radius", c.aperture_radius.is_some()),
                    ("focus_distance", c.focus_distance.is_some()),
                ] {
                    if given {
                        self.problem(
                            format!("camera.{field}"),
                            "only a thin_lens camera has this; the camera type is pinhole",
                        );
                    }
                }
                Lens::Pinhole
            }
            CameraType::ThinLens => {
                let aperture_radius = match c.aperture_radius {
                    Some(r) => self.range(
                        "camera.aperture_radius",
                        r,
                        0.0,
                        f32::MAX,
                        "a non-negative radius in scene units",
                    ),
                    None => {
                        self.problem(
                            "camera.aperture_radius",
                            "missing: a thin_lens camera needs an aperture radius in scene units",
                        );
                        0.0
                    }
                };
                let focus_distance = match c.focus_distance {
                    Some(d) => self.positive("camera.focus_distance", d),
                    None => {
                        self.problem(
                            "camera.focus_distance",
                            "missing: a thin_lens camera needs a focus distance in scene units",
                        );
                        1.0
                    }
                };
                Lens::Thin {
                    aperture_radius,
                    focus_distance,
                }
            }
        };
        let exposure_scale = match &c.exposure {
            None => 1.0,
            Some(e) => {
                let iso = self.positive("camera.exposure.iso", e.iso);
                let t = self.positive("camera.exposure.shutter_s", e.shutter_s.0);
                let n = self.positive("camera.exposure.f_number", e.f_number);
                photometry::exposure_scale(iso as f64, t as f64, n as f64) as f32
            }
        };
        CameraDesc {
            position,
            look_at,
            up,
            fov_y,
            lens,
            exposure_scale,
        }
    }

    pub(super) fn integrator(&mut self, i: &IntegratorFile) -> IntegratorDesc {
        if i.spp == 0 {
            self.problem(
                "integrator.spp",
                "expected at least 1 sample per pixel, got 0",
            );
        }
        IntegratorDesc {
            method: self.method_name(&i.method),
            spp: i.spp,
            max_depth: i.max_depth,
            rr_depth: i.rr_depth,
            seed: i.seed,
            sampler: i.sampler.unwrap_or_default(),
            photon: self.photon_map(&i.photon_map),
            subsurface: i.subsurface.unwrap_or_default(),
            given: given(i),
        }
    }

    /// Checks a value of `setting` against the values it admits.
    fn setting<T: Copy + Into<f64>>(&mut self, setting: &Setting, v: Option<T>) -> Option<T> {
        if let Some(v) = v
            && let Err(e) = setting.kind.check(v.into())
        {
            self.problem(format!("integrator.{}", setting.name), e);
        }
        v
    }

    pub(super) fn photon_map(&mut self, f: &PhotonMapFile) -> PhotonDesc {
        let irradiance_cache = match f.irradiance_cache {
            Some(ic) if !ic.enabled => None,
            None => Some(IrradianceCacheDesc::default()),
            Some(ic) => Some(IrradianceCacheDesc {
                accuracy: self.setting(&setting::IC_ACCURACY, ic.accuracy),
                spacing: self.setting(&setting::IC_SPACING, ic.spacing),
                keyframe_step: self.setting(&setting::IC_KEYFRAME_STEP, ic.keyframe_step),
                gather_rays: self.setting(&setting::IC_GATHER_RAYS, ic.gather_rays),
            }),
        };
        PhotonDesc {
            photons: self.setting(&setting::PHOTONS, f.photons),
            caustic_photons: self.setting(&setting::CAUSTIC_PHOTONS, f.caustic_photons),
            k: self.setting(&setting::PHOTON_K, f.k),
            caustic_k: self.setting(&setting::CAUSTIC_K, f.caustic_k),
            radius: self.setting(&setting::RADIUS, f.radius),
            caustic_radius: self.setting(&setting::CAUSTIC_RADIUS, f.caustic_radius),
            gather_rays: self.setting(&setting::GATHER_RAYS, f.gather_rays),
            caustic_filter: f.caustic_filter.unwrap_or_default(),
            irradiance_cache,
            alpha: self.setting(&setting::ALPHA, f.alpha),
        }
    }
}

/// The settings of [`setting::ALL`] that `i` gives a value (an irradiance cache's group when
/// the file has the object, whatever it holds).
fn given(i: &IntegratorFile) -> Vec<&'static Setting> {
    let f = &i.photon_map;
    let ic = f.irradiance_cache;
    let is = |present: bool, s: &'static Setting| present.then_some(s);
    [
        is(i.sampler.is_some(), &setting::SAMPLER),
        is(i.subsurface.is_some(), &setting::SUBSURFACE),
        is(f.photons.is_some(), &setting::PHOTONS),
        is(f.caustic_photons.is_some(), &setting::CAUSTIC_PHOTONS),
        is(f.k.is_some(), &setting::PHOTON_K),
        is(f.caustic_k.is_some(), &setting::CAUSTIC_K),
        is(f.radius.is_some(), &setting::RADIUS),
        is(f.caustic_radius.is_some(), &setting::CAUSTIC_RADIUS),
        is(f.gather_rays.is_some(), &setting::GATHER_RAYS),
        is(f.caustic_filter.is_some(), &setting::CAUSTIC_FILTER),
        is(f.alpha.is_some(), &setting::ALPHA),
        is(ic.is_some(), &setting::IRRADIANCE_CACHE),
        is(
            ic.is_some_and(|c| c.accuracy.is_some()),
            &setting::IC_ACCURACY,
        ),
        is(
            ic.is_some_and(|c| c.spacing.is_some()),
            &setting::IC_SPACING,
        ),
        is(
            ic.is_some_and(|c| c.keyframe_step.is_some()),
            &setting::IC_KEYFRAME_STEP,
        ),
        is(
            ic.is_some_and(|c| c.gather_rays.is_some()),
            &setting::IC_GATHER_RAYS,
        ),
    ]
    .into_iter()
    .flatten()
    .collect()
}
