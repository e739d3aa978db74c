//! A small log-log line plot as a PNG: decade grid, tick labels, one coloured line per series
//! and a legend. Text is drawn with the 8×8 bitmap font of `font8x8`, so no font files are
//! needed.

use image::{ImageEncoder, Rgb, RgbImage};

const W: u32 = 760;
const H: u32 = 500;
const LEFT: i32 = 80;
const RIGHT: i32 = 24;
const TOP: i32 = 36;
const BOTTOM: i32 = 56;
const COLOURS: [[u8; 3]; 6] = [
    [31, 119, 180],
    [214, 39, 40],
    [44, 160, 44],
    [148, 103, 189],
    [255, 127, 14],
    [23, 190, 207],
];

fn put(img: &mut RgbImage, x: i32, y: i32, c: [u8; 3]) {
    if x >= 0 && y >= 0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, Rgb(c));
    }
}

fn text(img: &mut RgbImage, x: i32, y: i32, s: &str, c: [u8; 3]) {
    for (i, ch) in s.chars().enumerate() {
        let glyph = font8x8::legacy::BASIC_LEGACY
            .get(ch as usize)
            .copied()
            .unwrap_or([0; 8]);
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8 {
                if bits >> col & 1 == 1 {
                    put(img, x + i as i32 * 8 + col, y + row as i32, c);
                }
            }
        }
    }
}

/// A line `width` pixels thick (Bresenham, stamped as squares).
fn line(img: &mut RgbImage, (x0, y0): (i32, i32), (x1, y1): (i32, i32), c: [u8; 3], width: i32) {
    let (dx, dy) = ((x1 - x0).abs(), -(y1 - y0).abs());
    let (sx, sy) = (if x0 < x1 { 1 } else { -1 }, if y0 < y1 { 1 } else { -1 });
    let (mut x, mut y, mut err) = (x0, y0, dx + dy);
    loop {
        for ox in 0..width {
            for oy in 0..width {
                put(img, x + ox - width / 2, y + oy - width / 2, c);
            }
        }
        if x == x1 && y == y1 {
            break;
        }
        let e2 = 2 * err;
        if e2 >= dy {
            err += dy;
            x += sx;
        }
        if e2 <= dx {
            err += dx;
            y += sy;
        }
    }
}

/// Decades [lo, hi] covering the positive values, at least one decade wide.
fn decades(values: impl Iterator<Item = f64>) -> (i32, i32) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in values.filter(|v| *v > 0.0 && v.is_finite()) {
        lo = lo.min(v.log10());
        hi = hi.max(v.log10());
    }
    if !lo.is_finite() {
        return (0, 1);
    }
    let (lo, hi) = (lo.floor() as i32, hi.ceil() as i32);
    (lo, hi.max(lo + 1))
}

/// Plots `series` (name, [(x, y)]) on log-log axes, one colour and legend entry per name
/// (series of one name, such as one per seed, share them); returns PNG bytes.
pub fn log_log(
    y_label: &str,
    x_label: &str,
    series: &[(String, Vec<(f64, f64)>)],
) -> anyhow::Result<Vec<u8>> {
    let mut img = RgbImage::from_pixel(W, H, Rgb([255, 255, 255]));
    let all = || series.iter().flat_map(|(_, p)| p.iter());
    let (x0, x1) = decades(all().map(|p| p.0));
    let (y0, y1) = decades(all().map(|p| p.1));
    let (pw, ph) = (W as i32 - LEFT - RIGHT, H as i32 - TOP - BOTTOM);
    let px =
        |x: f64| LEFT + ((x.log10() - x0 as f64) / (x1 - x0) as f64 * pw as f64).round() as i32;
    let py =
        |y: f64| TOP + ph - ((y.log10() - y0 as f64) / (y1 - y0) as f64 * ph as f64).round() as i32;
    let (grid, axis, ink) = ([225, 225, 225], [90, 90, 90], [20, 20, 20]);
    for d in x0..=x1 {
        let x = px(10f64.powi(d));
        line(&mut img, (x, TOP), (x, TOP + ph), grid, 1);
        let label = format!("1e{d}");
        text(
            &mut img,
            x - 4 * label.len() as i32,
            TOP + ph + 8,
            &label,
            ink,
        );
    }
    for d in y0..=y1 {
        let y = py(10f64.powi(d));
        line(&mut img, (LEFT, y), (LEFT + pw, y), grid, 1);
        let label = format!("1e{d}");
        text(
            &mut img,
            LEFT - 8 - 8 * label.len() as i32,
            y - 4,
            &label,
            ink,
        );
    }
    line(&mut img, (LEFT, TOP + ph), (LEFT + pw, TOP + ph), axis, 1);
    line(&mut img, (LEFT, TOP), (LEFT, TOP + ph), axis, 1);
    text(
        &mut img,
        LEFT + pw / 2 - 4 * x_label.len() as i32,
        H as i32 - 24,
        x_label,
        ink,
    );
    text(
        &mut img,
        8,
        12,
        &format!("{y_label} against {x_label} (log-log)"),
        ink,
    );
    let mut names: Vec<&str> = Vec::new();
    for (name, points) in series {
        let (i, first) = match names.iter().position(|n| n == name) {
            Some(i) => (i, false),
            None => {
                names.push(name);
                (names.len() - 1, true)
            }
        };
        let c = COLOURS[i % COLOURS.len()];
        let pts: Vec<(i32, i32)> = points
            .iter()
            .filter(|(x, y)| *x > 0.0 && *y > 0.0)
            .map(|&(x, y)| (px(x), py(y)))
            .collect();
        for w in pts.windows(2) {
            line(&mut img, w[0], w[1], c, 2);
        }
        for &p in &pts {
            line(&mut img, (p.0 - 3, p.1), (p.0 + 3, p.1), c, 5);
        }
        if !first {
            continue;
        }
        let ly = TOP + 10 + 14 * i as i32;
        line(
            &mut img,
            (LEFT + pw - 150, ly + 4),
            (LEFT + pw - 126, ly + 4),
            c,
            3,
        );
        text(&mut img, LEFT + pw - 118, ly, name, ink);
    }
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out).write_image(
        img.as_raw(),
        W,
        H,
        image::ExtendedColorType::Rgb8,
    )?;
    Ok(out)
}
