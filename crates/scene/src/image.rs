//! Reading float RGB images (OpenEXR) — environment maps and reference images.

#[cfg(test)]
use std::path::Path;

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

/// Reads an OpenEXR file's headers alone and checks every layer's stated size against
/// [`crate::budget::MAX_IMAGE_PIXELS`], and the bytes all its channels take decoded against
/// [`crate::budget::MAX_IMAGE_BYTES`] (the decoder unpacks every channel of a block, read or
/// not), before any pixel is allocated.
fn check_exr_size(bytes: &[u8]) -> Result<(), String> {
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false)
        .map_err(|e| format!("expected an OpenEXR image: {e}"))?;
    for header in &meta.headers {
        let (w, h) = (
            header.layer_size.width() as u64,
            header.layer_size.height() as u64,
        );
        crate::budget::check_image_size(w, h)?;
        crate::budget::check_image_bytes(
            w,
            h,
            header.channels.list.len(),
            header.channels.bytes_per_pixel as u64,
        )?;
    }
    Ok(())
}

/// Runs a third-party decoder on this thread, a panic in it an error of the file: the
/// decoders assert things of their input that a malformed file breaks (zune-jpeg's
/// upsampler, exr's block unpacking), and a panic must fail the one file, not the
/// coordinator validating a job or the worker with tasks in hand. The exr crate's decoders
/// are built `non_parallel`: its parallel one unpacks blocks on a thread pool of its own,
/// where a panic aborts the whole process.
pub(crate) fn guarded<T, E: std::fmt::Display>(
    read: impl FnOnce() -> Result<T, E>,
) -> Result<T, String> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(read)) {
        Ok(r) => r.map_err(|e| e.to_string()),
        Err(panic) => Err(format!(
            "the decoder failed on a malformed file ({})",
            panic
                .downcast_ref::<&str>()
                .copied()
                .or(panic.downcast_ref::<String>().map(String::as_str))
                .unwrap_or("no message")
        )),
    }
}

/// The named channels of the first layer of an OpenEXR file, as f32 in row order, with the
/// layer's width and height (e.g. `variance.R` of a Tessera EXR).
pub fn read_exr_channels(
    bytes: &[u8],
    names: &[&str],
) -> Result<(u32, u32, Vec<Vec<f32>>), String> {
    use exr::prelude::*;
    check_exr_size(bytes)?;
    let image = guarded(|| {
        read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .non_parallel()
            .from_buffered(std::io::Cursor::new(bytes))
    })
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

/// Decodes the first RGB(A) layer of an OpenEXR file. Alpha is ignored.
pub fn read_exr_rgb(bytes: &[u8]) -> Result<RgbImage, String> {
    use exr::prelude::*;
    check_exr_size(bytes)?;
    let image = guarded(|| {
        read()
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
            .non_parallel()
            .from_buffered(std::io::Cursor::new(bytes))
    })
    .map_err(|e| format!("expected an OpenEXR image with R, G and B channels: {e}"))?;
    Ok(image.layer_data.channel_data.pixels)
}

/// An input that once made a fuzz target fail: `crates/fuzz/regressions/PATH`.
#[cfg(test)]
pub(crate) fn fuzz_regression(path: &str) -> Vec<u8> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../fuzz/regressions")
        .join(path);
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `bytes`, an OpenEXR file, with its header's data window rewritten to claim
    /// `claim`×`claim` pixels (the pixels stay as they were).
    fn claim_data_window(mut bytes: Vec<u8>, claim: i32) -> Vec<u8> {
        // dataWindow: box2i, four i32 after its name, type and size.
        let key = b"dataWindow\0box2i\0";
        let at = bytes
            .windows(key.len())
            .position(|w| w == key)
            .expect("dataWindow")
            + key.len()
            + 4;
        bytes[at + 8..at + 12].copy_from_slice(&(claim - 1).to_le_bytes());
        bytes[at + 12..at + 16].copy_from_slice(&(claim - 1).to_le_bytes());
        bytes
    }

    /// A small, valid OpenEXR file of `w`×`h` pixels, then its header's data window
    /// rewritten to claim `claim`×`claim` (the pixels stay as they were).
    pub(crate) fn lying_exr(w: usize, h: usize, claim: i32) -> Vec<u8> {
        use exr::prelude::*;
        let mut bytes = std::io::Cursor::new(Vec::new());
        Image::from_channels(
            (w, h),
            SpecificChannels::rgb(|_: Vec2<usize>| (0.5f32, 0.5f32, 0.5f32)),
        )
        .write()
        .to_buffered(&mut bytes)
        .expect("write");
        claim_data_window(bytes.into_inner(), claim)
    }

    /// An OpenEXR file of 8×8 pixels in `channels` half-float channels, its data window then
    /// rewritten to claim `claim`×`claim`.
    fn many_channel_exr(channels: usize, claim: i32) -> Vec<u8> {
        use exr::prelude::*;
        let list: Vec<AnyChannel<FlatSamples>> = (0..channels)
            .map(|i| {
                AnyChannel::new(
                    format!("c{i}").as_str(),
                    FlatSamples::F16(vec![f16::ZERO; 64]),
                )
            })
            .collect();
        let layer = Layer::new(
            (8, 8),
            LayerAttributes::default(),
            Encoding::UNCOMPRESSED,
            AnyChannels::sort(list.into()),
        );
        let mut bytes = std::io::Cursor::new(Vec::new());
        Image::from_layer(layer)
            .write()
            .to_buffered(&mut bytes)
            .expect("write");
        claim_data_window(bytes.into_inner(), claim)
    }

    #[test]
    fn channels_that_would_decode_past_the_byte_limit_are_refused_before_decoding() {
        // 11000² pixels is within the pixel limit; 3000 half-float channels of them are far
        // past the byte limit.
        let lying = many_channel_exr(3000, 11000);
        assert!(lying.len() < 1 << 20, "{}", lying.len());
        for e in [
            read_exr_rgb(&lying).unwrap_err(),
            read_exr_channels(&lying, &["c0"]).unwrap_err(),
        ] {
            assert!(e.contains("3000 channels") && e.contains("limit"), "{e}");
        }
        // The same channels at their honest size decode.
        let honest = many_channel_exr(3000, 8);
        let (w, h, c) = read_exr_channels(&honest, &["c7"]).expect("decodes");
        assert_eq!((w, h, c[0].len()), (8, 8, 64));
    }

    #[test]
    fn a_claimed_size_over_the_limit_is_refused_before_decoding() {
        let honest = lying_exr(8, 8, 8);
        assert_eq!(read_exr_rgb(&honest).expect("decodes").pixels.len(), 64);
        let lying = lying_exr(8, 8, 60000);
        assert!(lying.len() < 4096);
        for e in [
            read_exr_rgb(&lying).unwrap_err(),
            read_exr_channels(&lying, &["R"]).unwrap_err(),
        ] {
            assert!(e.contains("60000×60000") && e.contains("limit"), "{e}");
        }
    }

    /// A B44 block whose OpenEXR arithmetic wraps (AFL++ found it aborting a debug build from
    /// the decoder's thread pool): it decodes, as a release build and OpenEXR decode it.
    #[test]
    fn a_b44_block_whose_arithmetic_wraps_decodes() {
        let bytes = fuzz_regression("image/b44-block-that-wraps.exr");
        let image = read_exr_rgb(&bytes).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(image.pixels.len(), (image.width * image.height) as usize);
    }

    /// A panic inside the decoder fails that file, with what it said, and nothing else.
    #[test]
    fn a_panic_in_the_decoder_is_an_error_of_the_file() {
        let r: Result<(), String> =
            guarded(|| -> Result<(), String> { panic!("index out of bounds") });
        let e = r.unwrap_err();
        assert!(
            e.contains("malformed file") && e.contains("index out of bounds"),
            "{e}"
        );
    }
}
