//! Cameras: pinhole and thin lens, with an optional physical exposure.
//!
//! Raster coordinates run from (0, 0) at the top-left corner of the film to (width, height);
//! the image's right is `forward × up` (right-handed world), so a camera looking along +Z with
//! up +Y sees −X on the right.

use glam::{Vec2, Vec3A};
use tessera_scene::{CameraDesc, FilmDesc, Lens};

use crate::ray::Ray;
use crate::sampler::{PixelSampler, Sampler};
use crate::sampling::square_to_disk;
use crate::scene::Scene;

/// A point on the lens seen from a scene point, with the importance it carries.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImportanceSample {
    /// Unit direction from the scene point toward the lens point.
    pub wi: Vec3A,
    /// W_e of the ray from the lens point back to the scene point.
    pub we: f32,
    /// Density of the lens point per unit solid angle at the scene point.
    pub pdf: f32,
    pub raster: Vec2,
    pub p_lens: Vec3A,
    pub dist: f32,
}

#[derive(Debug, Clone)]
pub struct Camera {
    position: Vec3A,
    right: Vec3A,
    up: Vec3A,
    forward: Vec3A,
    /// tan(fov_y / 2) and the film's aspect ratio.
    tan_half: f32,
    aspect: f32,
    size: Vec2,
    lens: Lens,
    /// Multiplier from radiance to pixel value.
    pub exposure: f32,
}

impl Camera {
    pub fn new(c: &CameraDesc, film: &FilmDesc) -> Self {
        let position = Vec3A::from(c.position);
        let forward = (Vec3A::from(c.look_at) - position).normalize();
        let right = forward.cross(Vec3A::from(c.up)).normalize();
        let up = right.cross(forward);
        Camera {
            position,
            right,
            up,
            forward,
            tan_half: (0.5 * c.fov_y).tan(),
            aspect: film.width as f32 / film.height as f32,
            size: Vec2::new(film.width as f32, film.height as f32),
            lens: c.lens,
            exposure: c.exposure_scale,
        }
    }

    /// Whether rays depend on a lens sample (a pinhole camera needs none).
    pub fn has_aperture(&self) -> bool {
        matches!(self.lens, Lens::Thin { aperture_radius, .. } if aperture_radius > 0.0)
    }

    /// The ray through raster position `film`, using `u_lens` for the aperture.
    #[inline]
    pub fn generate_ray(&self, film: Vec2, u_lens: Vec2) -> Ray {
        let ndc = Vec2::new(
            2.0 * film.x / self.size.x - 1.0,
            1.0 - 2.0 * film.y / self.size.y,
        );
        let dir = self.forward
            + self.right * (ndc.x * self.tan_half * self.aspect)
            + self.up * (ndc.y * self.tan_half);
        match self.lens {
            Lens::Pinhole => Ray::new(self.position, dir.normalize()),
            Lens::Thin {
                aperture_radius,
                focus_distance,
            } => {
                // The point in focus lies where the pinhole ray meets the focal plane.
                let focus = self.position + dir * focus_distance;
                let lens = square_to_disk(u_lens) * aperture_radius;
                let o = self.position + self.right * lens.x + self.up * lens.y;
                Ray::new(o, (focus - o).normalize())
            }
        }
    }

    /// Whether `p` lies inside the view frustum (occlusion is not considered).
    pub fn in_view(&self, p: Vec3A) -> bool {
        let d = p - self.position;
        let z = d.dot(self.forward);
        z > 0.0
            && d.dot(self.right).abs() <= z * self.tan_half * self.aspect
            && d.dot(self.up).abs() <= z * self.tan_half
    }

    /// Raster position of the world point `p` (through the lens centre), if in front of the
    /// camera: the inverse of [`Self::generate_ray`] for a pinhole.
    pub fn project(&self, p: Vec3A) -> Option<Vec2> {
        let d = p - self.position;
        let z = d.dot(self.forward);
        if z <= 0.0 {
            return None;
        }
        let ndc = Vec2::new(
            d.dot(self.right) / (z * self.tan_half * self.aspect),
            d.dot(self.up) / (z * self.tan_half),
        );
        Some(Vec2::new(
            (ndc.x + 1.0) * 0.5 * self.size.x,
            (1.0 - ndc.y) * 0.5 * self.size.y,
        ))
    }

    /// Area of the lens (1 for a pinhole: its position is a delta).
    fn lens_area(&self) -> f32 {
        match self.lens {
            Lens::Thin {
                aperture_radius, ..
            } if aperture_radius > 0.0 => crate::math::PI * aperture_radius * aperture_radius,
            _ => 1.0,
        }
    }

    /// Area of the film on the plane at unit distance in front of the lens.
    fn film_area(&self) -> f32 {
        4.0 * self.tan_half * self.tan_half * self.aspect
    }

    /// Importance W_e of the ray leaving the lens at `o` along unit `d`, and the raster
    /// position it belongs to; `None` behind the camera or off the film. Normalised as in
    /// pbrt-v4 (§5.4.1): W_e = 1 / (A_film · A_lens · cos⁴θ), so ∫∫ W_e cos θ dω dA_lens = 1
    /// over the film — a light path's splats over all pixels sum to its radiance.
    pub fn we(&self, o: Vec3A, d: Vec3A) -> Option<(f32, Vec2)> {
        let cos = d.dot(self.forward);
        if cos <= 0.0 {
            return None;
        }
        let raster = self.raster(o, d)?;
        Some((
            1.0 / (self.film_area() * self.lens_area() * cos.powi(4)),
            raster,
        ))
    }

    /// Densities with which [`Self::generate_ray`] (film position uniform over the film,
    /// lens point uniform over the lens) makes the direction `d`: per unit lens area (1 for a
    /// pinhole, a delta) and per unit solid angle, 1 / (A_film cos³θ); zero off the film.
    pub fn pdf_we(&self, o: Vec3A, d: Vec3A) -> (f32, f32) {
        let cos = d.dot(self.forward);
        if cos <= 0.0 || self.raster(o, d).is_none() {
            return (0.0, 0.0);
        }
        (
            1.0 / self.lens_area(),
            1.0 / (self.film_area() * cos * cos * cos),
        )
    }

    /// For a pinhole: W_e, the direction density of [`Self::pdf_we`] and cos θ of the ray
    /// leaving along unit `d`, and its raster position, on the film or off it (for integrators
    /// whose film extends past the edge pixels); `None` behind the camera.
    pub fn pinhole_importance(&self, d: Vec3A) -> Option<(f32, f32, f32, Vec2)> {
        let cos = d.dot(self.forward);
        if cos <= 0.0 {
            return None;
        }
        let raster = self.project(self.position + d)?;
        let a = self.film_area();
        Some((
            1.0 / (a * cos.powi(4)),
            1.0 / (a * cos * cos * cos),
            cos,
            raster,
        ))
    }

    /// Raster position of the ray from lens point `o` along `d`: where it crosses the plane
    /// in focus, seen through the lens centre; `None` off the film.
    fn raster(&self, o: Vec3A, d: Vec3A) -> Option<Vec2> {
        let cos = d.dot(self.forward);
        let focus = match self.lens {
            Lens::Thin { focus_distance, .. } => focus_distance,
            Lens::Pinhole => 1.0,
        };
        let p = self.project(o + d * (focus / cos))?;
        (p.x >= 0.0 && p.y >= 0.0 && p.x < self.size.x && p.y < self.size.y).then_some(p)
    }

    /// Samples a point on the lens (`u`) seen from `p`, for connecting a light subpath to the
    /// camera; `None` if `p` is behind the camera, off the film, or on the lens.
    pub fn sample_wi(&self, p: Vec3A, u: Vec2) -> Option<ImportanceSample> {
        let p_lens = match self.lens {
            Lens::Thin {
                aperture_radius, ..
            } if aperture_radius > 0.0 => {
                let l = square_to_disk(u) * aperture_radius;
                self.position + self.right * l.x + self.up * l.y
            }
            _ => self.position,
        };
        let to_lens = p_lens - p;
        let dist = to_lens.length();
        if dist == 0.0 {
            return None;
        }
        let wi = to_lens / dist;
        let (we, raster) = self.we(p_lens, -wi)?;
        let cos = wi.dot(self.forward).abs();
        Some(ImportanceSample {
            wi,
            we,
            pdf: dist * dist / (cos * self.lens_area()),
            raster,
            p_lens,
            dist,
        })
    }

    /// The film's size in pixels (width, height).
    pub fn film_size(&self) -> Vec2 {
        self.size
    }

    /// Width in scene units of one pixel's footprint at the depth of `p` (pinhole).
    #[inline]
    pub fn pixel_footprint(&self, p: Vec3A) -> f32 {
        self.depth(p).abs() * 2.0 * self.tan_half / self.size.y
    }

    /// Depth of a point along the optical axis, in scene units.
    #[inline]
    pub fn depth(&self, p: Vec3A) -> f32 {
        (p - self.position).dot(self.forward)
    }
}

/// The camera ray of the pixel sample `sampler` was started at, and its filter weight f/pdf:
/// the film position drawn from the film's filter about the pixel centre, then the lens
/// point. Every integrator starts its pixel samples here, so they see the same film.
#[inline]
pub(crate) fn camera_ray(
    scene: &Scene,
    camera: &Camera,
    pixel: glam::UVec2,
    sampler: &mut PixelSampler,
) -> (Ray, f32) {
    let (offset, w) = scene.filter.sample(sampler.get_2d());
    let film = pixel.as_vec2() + Vec2::splat(0.5) + offset;
    let u_lens = if camera.has_aperture() {
        sampler.get_2d()
    } else {
        Vec2::ZERO
    };
    (camera.generate_ray(film, u_lens), w)
}

#[cfg(test)]
mod tests {
    use super::*;
    use tessera_scene::FilterDesc;

    fn camera(lens: Lens) -> Camera {
        let desc = CameraDesc {
            position: glam::Vec3::new(0.0, 0.0, -5.0),
            look_at: glam::Vec3::ZERO,
            up: glam::Vec3::Y,
            fov_y: 90f32.to_radians(),
            lens,
            exposure_scale: 1.0,
        };
        Camera::new(
            &desc,
            &FilmDesc {
                width: 200,
                height: 100,
                filter: FilterDesc::Box { radius: 0.5 },
            },
        )
    }

    #[test]
    fn centre_corner_and_handedness() {
        let c = camera(Lens::Pinhole);
        let r = c.generate_ray(Vec2::new(100.0, 50.0), Vec2::ZERO);
        assert!((r.d - Vec3A::Z).length() < 1e-6);
        // Top-left corner: up and to the left; left is +X when looking along +Z.
        let r = c.generate_ray(Vec2::ZERO, Vec2::ZERO);
        let expect = Vec3A::new(2.0, 1.0, 1.0).normalize();
        assert!((r.d - expect).length() < 1e-5, "{}", r.d);
    }

    #[test]
    fn project_inverts_generate_ray() {
        let c = camera(Lens::Pinhole);
        for film in [
            Vec2::new(100.0, 50.0),
            Vec2::new(3.5, 97.25),
            Vec2::new(181.0, 12.0),
        ] {
            let r = c.generate_ray(film, Vec2::ZERO);
            let back = c.project(r.at(7.0)).expect("in front");
            assert!((back - film).length() < 1e-3, "{film} → {back}");
        }
        assert_eq!(c.project(Vec3A::new(0.0, 0.0, -6.0)), None);
    }

    /// W_e maps a generated ray back to its film position, and the importance of one
    /// lens point integrates to 1 / A_lens over the film: ∫ W_e cos θ dω (a Fibonacci lattice
    /// of 400 000 directions; the film's edges cost well under the 1 % allowed).
    #[test]
    fn importance_finds_the_raster_position_and_is_normalised() {
        for lens in [
            Lens::Pinhole,
            Lens::Thin {
                aperture_radius: 0.5,
                focus_distance: 5.0,
            },
        ] {
            let c = camera(lens);
            for (film, u) in [
                (Vec2::new(100.0, 50.0), Vec2::new(0.3, 0.6)),
                (Vec2::new(3.5, 97.25), Vec2::new(0.9, 0.1)),
                (Vec2::new(181.0, 12.0), Vec2::new(0.5, 0.5)),
            ] {
                let r = c.generate_ray(film, u);
                let (we, raster) = c.we(r.o, r.d).expect("on the film");
                assert!((raster - film).length() < 1e-2, "{film} → {raster}");
                assert!(we > 0.0);
                let (pos, dir) = c.pdf_we(r.o, r.d);
                assert!(pos > 0.0 && dir > 0.0);
            }
            let n = 400_000;
            let golden = (1.0 + 5f64.sqrt()) / 2.0;
            let sum: f64 = (0..n)
                .map(|i| {
                    let u = Vec2::new(
                        ((i as f64 + 0.5) / n as f64) as f32,
                        (i as f64 / golden).fract() as f32,
                    );
                    let d = crate::sampling::square_to_uniform_sphere(u);
                    c.we(c.position, d)
                        .map_or(0.0, |(we, _)| (we * d.dot(c.forward)) as f64)
                })
                .sum();
            let integral = sum * 4.0 * std::f64::consts::PI / n as f64 * c.lens_area() as f64;
            assert!((integral - 1.0).abs() < 0.01, "{lens:?}: {integral}");
            assert!(c.we(c.position, -c.forward).is_none(), "behind the camera");
        }
    }

    /// A point connected to the camera lands where `project` puts it (pinhole), with the
    /// importance of the ray back toward it and the solid-angle density dist²/cos.
    #[test]
    fn sample_wi_connects_a_point_to_its_pixel() {
        let c = camera(Lens::Pinhole);
        let p = Vec3A::new(-1.0, 0.5, 3.0);
        let s = c.sample_wi(p, Vec2::new(0.2, 0.7)).expect("in view");
        assert!((s.raster - c.project(p).expect("in front")).length() < 1e-3);
        assert!((s.wi - (c.position - p).normalize()).length() < 1e-6);
        let (we, _) = c.we(c.position, -s.wi).expect("on the film");
        assert_eq!(s.we, we);
        let cos = s.wi.dot(c.forward).abs();
        assert!((s.pdf - s.dist * s.dist / cos).abs() < 1e-4 * s.pdf);
        assert!(
            c.sample_wi(Vec3A::new(0.0, 0.0, -9.0), Vec2::ZERO)
                .is_none()
        );
    }

    #[test]
    fn thin_lens_rays_meet_in_the_focal_plane() {
        let c = camera(Lens::Thin {
            aperture_radius: 0.5,
            focus_distance: 5.0,
        });
        let film = Vec2::new(130.0, 20.0);
        let pin = camera(Lens::Pinhole).generate_ray(film, Vec2::ZERO);
        let target = pin.at(5.0 / pin.d.z);
        for u in [
            Vec2::new(0.1, 0.9),
            Vec2::new(0.7, 0.3),
            Vec2::new(0.5, 0.5),
        ] {
            let r = c.generate_ray(film, u);
            let t = (target.z - r.o.z) / r.d.z;
            assert!((r.at(t) - target).length() < 1e-4);
        }
    }
}
