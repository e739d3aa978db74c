//! `tessera compare`: error of an image against a reference.

use std::path::PathBuf;

use anyhow::ensure;
use glam::Vec3;
use tessera_render::metrics;
use tessera_scene::image::RgbImage;

#[derive(clap::Args)]
pub struct CompareArgs {
    /// The image to judge (OpenEXR).
    pub image: PathBuf,
    /// The reference (OpenEXR, same size, or a whole fraction of it with --downsample).
    pub reference: PathBuf,
    /// Average the image over k × k pixels first, where it is k times the reference's size in
    /// each dimension: a render at the size users work at against a reference one can afford
    /// (its noise averages down, its bias stays; a box-filtered reference's pixel is exactly
    /// the mean of its k × k sub-pixels).
    #[arg(long)]
    pub downsample: bool,
}

/// `image` averaged over `k` × `k` blocks.
fn downsample(image: &RgbImage, k: u32) -> RgbImage {
    let (w, h) = (image.width / k, image.height / k);
    let mut pixels = vec![Vec3::ZERO; (w * h) as usize];
    for y in 0..h * k {
        for x in 0..w * k {
            pixels[((y / k) * w + x / k) as usize] += image.get(x, y);
        }
    }
    let n = (k * k) as f32;
    for p in &mut pixels {
        *p /= n;
    }
    RgbImage {
        width: w,
        height: h,
        pixels,
    }
}

pub fn run(args: CompareArgs) -> anyhow::Result<()> {
    let image = tessera_render::read_exr(&args.image)?;
    let reference = tessera_render::read_exr(&args.reference)?;
    let (rw, rh) = (reference.width, reference.height);
    let k = image.width / rw.max(1);
    let multiple = k >= 1 && (image.width, image.height) == (k * rw, k * rh);
    let (image, averaged) = if args.downsample {
        ensure!(
            multiple,
            "{}: --downsample: size {}×{} is not the reference's {rw}×{rh} times one whole number in both dimensions",
            args.image.display(),
            image.width,
            image.height,
        );
        (
            downsample(&image, k),
            format!("averaged over {k}×{k} pixels to {rw}×{rh}: "),
        )
    } else {
        ensure!(
            (image.width, image.height) == (rw, rh),
            "{}: size {}×{} differs from the reference's {rw}×{rh}{}",
            args.image.display(),
            image.width,
            image.height,
            if multiple {
                format!(" ({k} times it: --downsample averages it to the reference's size)")
            } else {
                String::new()
            }
        );
        (image, String::new())
    };
    let nonfinite = image.pixels.iter().filter(|p| !p.is_finite()).count();
    let to_a = |v: &[Vec3]| v.iter().map(|&p| p.into()).collect::<Vec<glam::Vec3A>>();
    let e = metrics::compare(&to_a(&image.pixels), &to_a(&reference.pixels));
    crate::print(&format!(
        "{averaged}relMSE {:.4e}  RMSE {:.4e}  mean/reference {:.5}  non-finite pixels {nonfinite}\n",
        e.rel_mse, e.rmse, e.mean_ratio
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each 2 × 2 block's mean, in place of the block.
    #[test]
    fn downsampling_averages_each_block() {
        let image = RgbImage {
            width: 4,
            height: 2,
            pixels: (0..8).map(|i| Vec3::splat(i as f32)).collect(),
        };
        let d = downsample(&image, 2);
        assert_eq!((d.width, d.height), (2, 1));
        // (0 + 1 + 4 + 5) / 4 and (2 + 3 + 6 + 7) / 4.
        assert_eq!(d.pixels, vec![Vec3::splat(2.5), Vec3::splat(4.5)]);
    }
}
