//! Cameras: pinhole and thin lens, with an optional physical exposure.
//!
//! Raster coordinates run from (0, 0) at the top-left corner of the film to (width, height);
//! the image's right is `forward × up` (right-handed world), so a camera looking along +Z with
//! up +Y sees −X on the right.

use glam::{Vec2, Vec3A};
use tessera_scene::{CameraDesc, FilmDesc, Lens};

use crate::ray::Ray;
use crate::sampling::square_to_disk;

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
