//! Tessera's rendering core: geometry and BVH, samplers, BSDFs, lights, cameras, filters,
//! integrators and film. Knows nothing of HTTP or the farm: a tile of pixels over a range of
//! sample indices is a pure function of the scene ([`render::render_tile`]), and gives the
//! same numbers whether rendered alone or as part of a frame.

pub mod analysis;
pub mod bsdf;
pub mod bssrdf;
pub mod camera;
pub mod error;
pub mod film;
pub mod filter;
pub mod geometry;
pub mod integrator;
pub mod irradiance;
pub mod job;
pub mod light;
pub mod math;
pub mod method;
pub mod metrics;
pub mod output;
pub mod phase;
pub mod photon;
pub mod ray;
pub mod render;
pub mod sampler;
pub mod sampling;
pub mod scene;
pub mod spectrum;
pub mod stats;
pub mod texture;
pub mod wire;

pub use error::RenderError;
pub use film::{Image, SampleRange, Tile};
pub use integrator::{Integrator, RayStats};
pub use scene::Scene;

/// Reads a float RGB OpenEXR file (e.g. a reference image).
pub fn read_exr(path: &std::path::Path) -> Result<tessera_scene::image::RgbImage, RenderError> {
    let bytes = std::fs::read(path).map_err(|e| RenderError::Input {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    tessera_scene::image::read_exr_rgb(&bytes).map_err(|message| RenderError::Input {
        path: path.to_path_buf(),
        message,
    })
}
