//! The camera as the renderer builds it: where it is, where it looks, its lens and exposure.

use glam::Vec3;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraDesc {
    pub position: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    /// Full vertical field of view, radians.
    pub fov_y: f32,
    pub lens: Lens,
    /// Multiplier from radiance to pixel value (1 without a physical exposure).
    pub exposure_scale: f32,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Lens {
    Pinhole,
    /// Thin lens with aperture radius and focus distance, both in scene units.
    Thin {
        aperture_radius: f32,
        focus_distance: f32,
    },
}
