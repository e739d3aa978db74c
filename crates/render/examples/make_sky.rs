//! Writes the latitude–longitude sky used by `scenes/material-spheres`: a blue gradient above
//! the horizon, a warm ground below, and a sun 1.5° in radius whose radiance is 4000 times the
//! zenith's, so that rendering it well needs the environment's importance sampling.
//!
//!     cargo run --release -p tessera-render --example make_sky -- scenes/material-spheres/sky.exr

use std::f32::consts::PI;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args().nth(1).ok_or("usage: make_sky OUT.exr")?;
    let (w, h) = (512usize, 256usize);
    // Sun: 35° above the horizon, to the left of and behind a camera looking along +Z.
    let (elev, azim) = (35f32.to_radians(), 140f32.to_radians());
    let sun = [
        -elev.cos() * azim.sin(),
        elev.sin(),
        elev.cos() * azim.cos(),
    ];
    let cos_sun = 1.5f32.to_radians().cos();
    let pixel = |x: usize, y: usize| -> (f32, f32, f32) {
        // The direction convention of the renderer's environment light.
        let theta = PI * (y as f32 + 0.5) / h as f32;
        let phi = 2.0 * PI * ((x as f32 + 0.5) / w as f32 - 0.5);
        let d = [
            -theta.sin() * phi.sin(),
            theta.cos(),
            theta.sin() * phi.cos(),
        ];
        let c = d[0] * sun[0] + d[1] * sun[1] + d[2] * sun[2];
        if c >= cos_sun {
            return (4000.0, 3700.0, 3300.0);
        }
        if d[1] < 0.0 {
            let k = 0.35 + 0.15 * (1.0 + d[1]);
            return (0.42 * k, 0.36 * k, 0.30 * k);
        }
        let t = d[1].powf(0.6);
        let glow = 0.6 * ((c - 1.0) * 12.0).exp();
        let mix = |horizon: f32, zenith: f32| horizon * (1.0 - t) + zenith * t + glow;
        (mix(1.05, 0.28), mix(1.10, 0.48), mix(1.20, 0.95))
    };
    exr::prelude::write_rgb_file(&path, w, h, |x, y| {
        let (r, g, b) = pixel(x, y);
        (
            half::f16::from_f32(r),
            half::f16::from_f32(g),
            half::f16::from_f32(b),
        )
    })?;
    println!("wrote {path} ({w}×{h})");
    Ok(())
}
