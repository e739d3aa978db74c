//! `tessera compare`: error of an image against a reference.

use std::path::PathBuf;

use anyhow::ensure;
use tessera_render::metrics;

#[derive(clap::Args)]
pub struct CompareArgs {
    /// The image to judge (OpenEXR).
    pub image: PathBuf,
    /// The reference (OpenEXR, same size).
    pub reference: PathBuf,
}

pub fn run(args: CompareArgs) -> anyhow::Result<()> {
    let image = tessera_render::read_exr(&args.image)?;
    let reference = tessera_render::read_exr(&args.reference)?;
    ensure!(
        (image.width, image.height) == (reference.width, reference.height),
        "{}: size {}×{} differs from the reference's {}×{}",
        args.image.display(),
        image.width,
        image.height,
        reference.width,
        reference.height
    );
    let nonfinite = image.pixels.iter().filter(|p| !p.is_finite()).count();
    let to_a = |v: &[glam::Vec3]| v.iter().map(|&p| p.into()).collect::<Vec<glam::Vec3A>>();
    let e = metrics::compare(&to_a(&image.pixels), &to_a(&reference.pixels));
    crate::print(&format!(
        "relMSE {:.4e}  RMSE {:.4e}  mean/reference {:.5}  non-finite pixels {nonfinite}\n",
        e.rel_mse, e.rmse, e.mean_ratio
    ))
}
