//! Writing images: float OpenEXR with the AOVs, and an sRGB PNG preview.

use std::path::Path;

use image::ImageEncoder;

use crate::error::RenderError;
use crate::film::Image;

/// Metadata written into the EXR header as one text attribute `tessera` holding a JSON object
/// (keys sorted). Deterministic: no times or host names, and one attribute, because
/// the exr crate writes several in hash-map order, which would change the file's bytes from
/// run to run.
#[derive(Debug, Clone, Default)]
pub struct ExrMetadata {
    pub entries: Vec<(String, String)>,
}

/// Writes `image` as a float OpenEXR: R, G, B, A, albedo.{R,G,B}, normal.{X,Y,Z}, Z (depth
/// along the camera axis) and variance.{R,G,B} (of each pixel's estimate).
pub fn write_exr(path: &Path, image: &Image, metadata: &ExrMetadata) -> Result<(), RenderError> {
    use exr::prelude::*;
    let size = (image.width as usize, image.height as usize);
    let channel = |name: &str, f: &dyn Fn(&crate::film::Pixel) -> f32| {
        AnyChannel::new(name, FlatSamples::F32(image.pixels.iter().map(f).collect()))
    };
    let channels = AnyChannels::sort(SmallVec::from_vec(vec![
        channel("R", &|p| p.rgb[0]),
        channel("G", &|p| p.rgb[1]),
        channel("B", &|p| p.rgb[2]),
        channel("A", &|p| p.alpha),
        channel("albedo.R", &|p| p.albedo[0]),
        channel("albedo.G", &|p| p.albedo[1]),
        channel("albedo.B", &|p| p.albedo[2]),
        channel("normal.X", &|p| p.normal[0]),
        channel("normal.Y", &|p| p.normal[1]),
        channel("normal.Z", &|p| p.normal[2]),
        channel("Z", &|p| p.depth),
        channel("variance.R", &|p| p.variance[0]),
        channel("variance.G", &|p| p.variance[1]),
        channel("variance.B", &|p| p.variance[2]),
    ]));
    let mut attributes = LayerAttributes {
        software_name: Some(Text::from(concat!("tessera ", env!("CARGO_PKG_VERSION")))),
        ..Default::default()
    };
    if !metadata.entries.is_empty() {
        let object: serde_json::Map<String, serde_json::Value> = metadata
            .entries
            .iter()
            .map(|(k, v)| (k.clone(), serde_json::Value::String(v.clone())))
            .collect();
        let json = ascii_json(&serde_json::Value::Object(object).to_string());
        let text = Text::new_or_none(json.as_str()).ok_or_else(|| RenderError::Output {
            path: path.to_path_buf(),
            message: "EXR metadata is not representable as EXR text".into(),
        })?;
        attributes
            .other
            .insert(Text::from("tessera"), AttributeValue::Text(text));
    }
    let layer = Layer::new(size, attributes, Encoding::SMALL_LOSSLESS, channels);
    Image::from_layer(layer)
        .write()
        .to_file(path)
        .map_err(|e| RenderError::Output {
            path: path.to_path_buf(),
            message: e.to_string(),
        })
}

/// JSON with every non-ASCII character written as a `\uXXXX` escape (UTF-16 units): EXR text
/// attributes hold only Latin-1, and scene names, reasons and paths may be any Unicode.
fn ascii_json(json: &str) -> String {
    let mut out = String::with_capacity(json.len());
    for c in json.chars() {
        if c.is_ascii() {
            out.push(c);
        } else {
            let mut units = [0u16; 2];
            for u in c.encode_utf16(&mut units) {
                out.push_str(&format!("\\u{:04x}", u));
            }
        }
    }
    out
}

/// sRGB transfer function of a linear value in [0, 1].
fn srgb(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Encodes an 8-bit sRGB PNG of the colour channels, clipped to [0, 1].
pub fn encode_png(image: &Image) -> Result<Vec<u8>, String> {
    let bytes: Vec<u8> = image
        .pixels
        .iter()
        .flat_map(|p| p.rgb.map(|c| (srgb(c.clamp(0.0, 1.0)) * 255.0 + 0.5) as u8))
        .collect();
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(
            &bytes,
            image.width,
            image.height,
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| e.to_string())?;
    Ok(out)
}

/// Writes an 8-bit sRGB PNG of the colour channels, clipped to [0, 1].
pub fn write_png(path: &Path, image: &Image) -> Result<(), RenderError> {
    let error = |message: String| RenderError::Output {
        path: path.to_path_buf(),
        message,
    };
    let bytes = encode_png(image).map_err(error)?;
    std::fs::write(path, bytes).map_err(|e| error(e.to_string()))
}

#[cfg(test)]
mod tests {
    #[test]
    fn non_ascii_metadata_is_escaped_and_stays_json() {
        let json = serde_json::json!({ "scene": "Cornell box — 2×2 ⁻ 🎥" }).to_string();
        let escaped = super::ascii_json(&json);
        assert!(escaped.is_ascii());
        let back: serde_json::Value = serde_json::from_str(&escaped).expect("JSON");
        assert_eq!(back["scene"], "Cornell box — 2×2 ⁻ 🎥");
    }
}
