//! What a render counted: rays, samples, and the samples it had to drop.

/// Counters kept per tile (no shared state in the sample loop).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct RayStats {
    /// Rays traced: camera, continuation and shadow rays.
    pub rays: u64,
    pub samples: u64,
    /// Samples whose radiance was NaN or infinite and was dropped before the film.
    pub nonfinite: u64,
}

impl RayStats {
    pub fn add(&mut self, o: &RayStats) {
        self.rays += o.rays;
        self.samples += o.samples;
        self.nonfinite += o.nonfinite;
    }
}
