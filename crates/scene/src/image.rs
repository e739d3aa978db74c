//! Reading float RGB images (OpenEXR) — environment maps and reference images.

use glam::Vec3;

/// A float RGB image, rows from top to bottom.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Vec3>,
}

impl RgbImage {
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[(y * self.width + x) as usize]
    }
}

/// Decodes the first RGB(A) layer of an OpenEXR file. Alpha is ignored.
/// The named channels of the first layer of an OpenEXR file, as f32 in row order, with the
/// layer's width and height (e.g. `variance.R` of a Tessera EXR).
pub fn read_exr_channels(
    bytes: &[u8],
    names: &[&str],
) -> Result<(u32, u32, Vec<Vec<f32>>), String> {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| format!("expected an OpenEXR image: {e}"))?;
    let layer = &image.layer_data;
    let (w, h) = (layer.size.width() as u32, layer.size.height() as u32);
    let channels = names
        .iter()
        .map(|name| {
            layer
                .channel_data
                .list
                .iter()
                .find(|c| c.name == **name)
                .map(|c| c.sample_data.values_as_f32().collect())
                .ok_or_else(|| format!("expected a channel named {name}"))
        })
        .collect::<std::result::Result<_, String>>()?;
    Ok((w, h, channels))
}

pub fn read_exr_rgb(bytes: &[u8]) -> Result<RgbImage, String> {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |resolution, _| RgbImage {
                width: resolution.width() as u32,
                height: resolution.height() as u32,
                pixels: vec![Vec3::ZERO; resolution.width() * resolution.height()],
            },
            |img: &mut RgbImage, pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                let i = pos.y() * img.width as usize + pos.x();
                img.pixels[i] = Vec3::new(r, g, b);
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| format!("expected an OpenEXR image with R, G and B channels: {e}"))?;
    Ok(image.layer_data.channel_data.pixels)
}
