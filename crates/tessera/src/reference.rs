//! `tessera reference`: a converged reference image for a scene that has none.
//!
//! Stopping rule: adaptive sampling (see `tessera_farm::progressive`) until the relMSE the film's
//! own variance predicts is at most `--target-error` (default 1e-4), or every tile has
//! `--max-spp` samples per pixel (default 65536), or `--time-limit` passes. The rule, the spp
//! range reached and the final estimate are written into the EXR header; the EXR carries the
//! per-pixel variance, so tests can compare renders with it within their joint noise. The
//! integrator is the path tracer, translucent materials by their random walk: unbiased whatever
//! the scene asks for.

use std::path::PathBuf;

use crate::render::{RenderArgs, Size};

#[derive(clap::Args)]
pub struct ReferenceArgs {
    /// The scene file (scene.json).
    pub scene: PathBuf,
    /// Output OpenEXR file.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Stop when the estimated relMSE is at most this.
    #[arg(long, default_value_t = 1e-4)]
    pub target_error: f64,
    /// Most samples per pixel in any tile.
    #[arg(long, default_value_t = 65536)]
    pub max_spp: u32,
    /// Start no new round after this many seconds.
    #[arg(long)]
    pub time_limit: Option<f64>,
    /// Film size WxH (overrides the scene's film).
    #[arg(long)]
    pub size: Option<Size>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

pub fn run(args: ReferenceArgs) -> anyhow::Result<()> {
    crate::print(&format!(
        "reference: adaptive until estimated relMSE ≤ {:e}, at most {} spp{}\n",
        args.target_error,
        args.max_spp,
        args.time_limit
            .map(|t| format!(", at most {t} s"))
            .unwrap_or_default()
    ))?;
    crate::render::run(RenderArgs {
        scene: args.scene,
        output: Some(args.output),
        spp: Some(args.max_spp),
        threads: args.threads,
        // Small tiles: finer adaptive steering, and parallelism on small films.
        tile: Some(8),
        samples_per_task: None,
        seed: None,
        // Unbiased whatever the scene asks for: references judge the biased methods.
        integrator: Some("path".into()),
        // Translucent materials by the brute-force random walk, not the dipole's model.
        subsurface: Some(tessera_scene::SubsurfaceMethod::RandomWalk),
        size: args.size,
        frame: 1,
        auto_choice: None,
        target_error: Some(args.target_error),
        time_limit: args.time_limit,
        quiet: args.quiet,
        strategies: None,
    })
}
