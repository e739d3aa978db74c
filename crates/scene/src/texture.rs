//! Image textures as the scene gives them: decoded once (PNG or JPEG, 8 or 16 bits per
//! channel) into texels that read as linear values — colour decoded from sRGB, data
//! (roughness, metalness, normals) as stored — with the sampler's wrap modes and the texture
//! coordinate transform.

use std::sync::Arc;

use glam::{Affine2, Vec2, Vec4};

/// What a texture's values mean, which decides how they are decoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TextureRole {
    /// sRGB-encoded colour (base colour, emission): decoded to linear.
    Color,
    /// Linear data (metallic-roughness, normals): read as stored.
    Data,
}

/// Texels as the file stores them (4 channels), and how their values decode to linear:
/// production textures are large, so 8-bit files stay 4 bytes a texel and are decoded where
/// they are read.
#[derive(Clone)]
pub enum Texels {
    /// 8-bit RGB in sRGB encoding, alpha linear (colour from an 8-bit file).
    Srgb8(Vec<[u8; 4]>),
    /// 8-bit linear values (data from an 8-bit file).
    Linear8(Vec<[u8; 4]>),
    /// 16-bit linear values (data from a 16-bit file).
    Linear16(Vec<[u16; 4]>),
    /// Linear values (colour from a 16-bit file, decoded once; generated textures).
    Float(Vec<Vec4>),
}

impl std::fmt::Debug for Texels {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let kind = match self {
            Texels::Srgb8(_) => "sRGB8",
            Texels::Linear8(_) => "linear8",
            Texels::Linear16(_) => "linear16",
            Texels::Float(_) => "float",
        };
        write!(f, "Texels({kind} × {})", self.len())
    }
}

impl Texels {
    pub fn len(&self) -> usize {
        match self {
            Texels::Srgb8(t) | Texels::Linear8(t) => t.len(),
            Texels::Linear16(t) => t.len(),
            Texels::Float(t) => t.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Bytes the texels take.
    pub fn bytes(&self) -> usize {
        match self {
            Texels::Srgb8(t) | Texels::Linear8(t) => t.len() * 4,
            Texels::Linear16(t) => t.len() * 8,
            Texels::Float(t) => t.len() * 16,
        }
    }

    /// Texel `i` in linear values.
    #[inline]
    pub fn get(&self, i: usize) -> Vec4 {
        match self {
            Texels::Srgb8(t) => {
                let [r, g, b, a] = t[i];
                let lut = srgb8_table();
                Vec4::new(
                    lut[r as usize],
                    lut[g as usize],
                    lut[b as usize],
                    a as f32 / 255.0,
                )
            }
            Texels::Linear8(t) => Vec4::from(t[i].map(f32::from)) / 255.0,
            Texels::Linear16(t) => Vec4::from(t[i].map(f32::from)) / 65535.0,
            Texels::Float(t) => t[i],
        }
    }

    /// Texels of the same kind holding the linear `values` (rounded to the nearest code).
    pub fn like(&self, values: &[Vec4]) -> Texels {
        let code = |v: f32, max: f32| (v.clamp(0.0, 1.0) * max).round();
        match self {
            Texels::Srgb8(_) => Texels::Srgb8(
                values
                    .iter()
                    .map(|v| {
                        let e = |c: f32| code(linear_to_srgb(c), 255.0) as u8;
                        [e(v.x), e(v.y), e(v.z), code(v.w, 255.0) as u8]
                    })
                    .collect(),
            ),
            Texels::Linear8(_) => Texels::Linear8(
                values
                    .iter()
                    .map(|v| v.to_array().map(|c| code(c, 255.0) as u8))
                    .collect(),
            ),
            Texels::Linear16(_) => Texels::Linear16(
                values
                    .iter()
                    .map(|v| v.to_array().map(|c| code(c, 65535.0) as u16))
                    .collect(),
            ),
            Texels::Float(_) => Texels::Float(values.to_vec()),
        }
    }

    /// FNV-1a over the stored values in 8-byte words: a content hash, not a cryptographic one.
    fn hash(&self) -> u64 {
        let mut h = 0xcbf2_9ce4_8422_2325u64;
        let mut eat = |w: u64| {
            h ^= w;
            h = h.wrapping_mul(0x100_0000_01b3);
        };
        match self {
            Texels::Srgb8(t) | Texels::Linear8(t) => {
                t.iter().for_each(|p| eat(u32::from_le_bytes(*p) as u64))
            }
            Texels::Linear16(t) => t
                .iter()
                .for_each(|p| eat(p.iter().fold(0u64, |w, &c| (w << 16) | c as u64))),
            Texels::Float(t) => t.iter().for_each(|p| {
                let [a, b, c, d] = p.to_array().map(f32::to_bits);
                eat(((a as u64) << 32) | b as u64);
                eat(((c as u64) << 32) | d as u64);
            }),
        }
        h
    }
}

/// The 256 linear values of 8-bit sRGB codes.
fn srgb8_table() -> &'static [f32; 256] {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)))
}

/// A decoded image, rows top to bottom.
#[derive(Clone)]
pub struct TextureImage {
    /// Where it came from, for messages (`images[2] "wood.png"`).
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub texels: Texels,
    /// A content hash (of the stored texels and their kind), so that scenes compare and hash
    /// by it.
    pub hash: u64,
}

impl std::fmt::Debug for TextureImage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "TextureImage({} {}×{} #{:016x})",
            self.name, self.width, self.height, self.hash
        )
    }
}

impl PartialEq for TextureImage {
    fn eq(&self, o: &Self) -> bool {
        self.width == o.width && self.height == o.height && self.hash == o.hash
    }
}

impl TextureImage {
    /// Bytes the texels take.
    pub fn bytes(&self) -> usize {
        self.texels.bytes()
    }

    /// Texel (x, y) in linear values.
    #[inline]
    pub fn texel(&self, x: u32, y: u32) -> Vec4 {
        self.texels.get((y * self.width + x) as usize)
    }

    pub fn new(name: &str, width: u32, height: u32, texels: Texels) -> Self {
        let kind = match &texels {
            Texels::Srgb8(_) => 1u64,
            Texels::Linear8(_) => 2,
            Texels::Linear16(_) => 3,
            Texels::Float(_) => 4,
        };
        let hash = texels.hash() ^ kind;
        TextureImage {
            name: name.into(),
            width,
            height,
            texels,
            hash,
        }
    }

    /// Builds an image from linear texels (tests, generated textures).
    pub fn from_texels(name: &str, width: u32, height: u32, texels: Vec<Vec4>) -> Self {
        Self::new(name, width, height, Texels::Float(texels))
    }
}

/// The sRGB transfer function's inverse (IEC 61966-2-1): encoded value in [0, 1] to linear.
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// The sRGB transfer function (IEC 61966-2-1): linear value in [0, 1] to encoded.
pub fn linear_to_srgb(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Decodes a PNG or JPEG file's bytes for `role`; `name` is for messages. 8-bit files keep
/// their codes; 16-bit data keeps its codes; 16-bit colour is decoded to linear floats.
pub fn decode(bytes: &[u8], name: &str, role: TextureRole) -> Result<TextureImage, String> {
    let bad = |e: image::ImageError| format!("cannot decode the image (PNG or JPEG expected): {e}");
    let reader = || {
        image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| format!("cannot read the image: {e}"))
    };
    // The header's size is checked before the decoder allocates for it: against the limit,
    // and against what the file's bytes could hold.
    let header = reader()?;
    let format = header.format();
    let (width, height) = header.into_dimensions().map_err(bad)?;
    crate::budget::check_image_size(width as u64, height as u64)?;
    if let Some((least, why)) = format.and_then(|f| least_bytes(f, width as u64, height as u64))
        && least > bytes.len() as u64
    {
        return Err(format!(
            "its header claims {width}×{height} pixels, which takes at least {least} bytes ({why}); the file has {}",
            bytes.len()
        ));
    }
    let img = crate::image::guarded(|| reader()?.decode().map_err(bad))?;
    let (width, height) = (img.width(), img.height());
    let eight = matches!(
        img.color(),
        image::ColorType::L8
            | image::ColorType::La8
            | image::ColorType::Rgb8
            | image::ColorType::Rgba8
    );
    let texels = match (eight, role) {
        (true, role) => {
            let rgba: Vec<[u8; 4]> = img.into_rgba8().pixels().map(|p| p.0).collect();
            match role {
                TextureRole::Color => Texels::Srgb8(rgba),
                TextureRole::Data => Texels::Linear8(rgba),
            }
        }
        (false, TextureRole::Data) => {
            Texels::Linear16(img.into_rgba16().pixels().map(|p| p.0).collect())
        }
        (false, TextureRole::Color) => Texels::Float(
            img.into_rgba32f()
                .pixels()
                .map(|p| {
                    let d = srgb_to_linear;
                    Vec4::new(d(p[0]), d(p[1]), d(p[2]), p[3])
                })
                .collect(),
        ),
    };
    Ok(TextureImage::new(name, width, height, texels))
}

/// The fewest bytes in which a file of `format` can hold a `width`×`height` image, and why: a
/// header may state any size, but the data that fills it compresses only so far, so a small
/// file cannot make the decoder allocate for a large image it does not hold.
/// - PNG: each row is a filter byte and its pixels at no less than 1 bit each, which deflate
///   shrinks at most 1032:1 (its longest match, 258 bytes, in no less than 2 bits).
/// - JPEG: each 8×8 block of the full-resolution component carries a DC code of at least one
///   bit (ITU-T T.81 Huffman codes are 1 to 16 bits long; arithmetic coding, which could go
///   below, is not read by the decoder).
fn least_bytes(format: image::ImageFormat, width: u64, height: u64) -> Option<(u64, &'static str)> {
    match format {
        image::ImageFormat::Png => Some((
            height.saturating_mul(1 + width.div_ceil(8)) / 1032,
            "a 1-bit row and its filter byte, deflated at most 1032:1",
        )),
        image::ImageFormat::Jpeg => Some((
            width.div_ceil(8).saturating_mul(height.div_ceil(8)) / 8,
            "a bit at least for each 8×8 block",
        )),
        _ => None,
    }
}

/// How coordinates outside [0, 1] map back into the image (glTF's sampler modes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Wrap {
    #[default]
    Repeat,
    MirroredRepeat,
    ClampToEdge,
}

/// A texture as a material uses it.
#[derive(Debug, Clone, PartialEq)]
pub struct TextureDesc {
    pub image: Arc<TextureImage>,
    /// Wrap modes along u and v.
    pub wrap: [Wrap; 2],
    /// Which texture coordinate set it reads (TEXCOORD_n).
    pub texcoord: u32,
    /// KHR_texture_transform: uv' = transform · uv.
    pub transform: Affine2,
}

impl TextureDesc {
    pub fn new(image: Arc<TextureImage>) -> Self {
        TextureDesc {
            image,
            wrap: [Wrap::Repeat; 2],
            texcoord: 0,
            transform: Affine2::IDENTITY,
        }
    }

    /// The texture coordinates of `uv` after the texture's transform.
    pub fn map(&self, uv: Vec2) -> Vec2 {
        self.transform.transform_point2(uv)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_decoding_matches_the_standard() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        // 8-bit 128 is 0.2158605 linear; the linear segment below 0.04045.
        assert!((srgb_to_linear(128.0 / 255.0) - 0.215_860_5).abs() < 1e-6);
        assert!((srgb_to_linear(0.04) - 0.04 / 12.92).abs() < 1e-9);
    }

    #[test]
    fn a_png_decodes_to_linear_colour_or_stored_data_by_role() {
        // A 2×1 8-bit PNG: (128, 0, 255) and (255, 255, 255), written by the image crate.
        let mut png = Vec::new();
        let img = image::RgbaImage::from_raw(2, 1, vec![128, 0, 255, 255, 255, 255, 255, 128])
            .expect("image");
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .expect("png");
        let c = decode(&png, "t.png", TextureRole::Color).expect("decode");
        assert_eq!(c.bytes(), 8, "8-bit texels stay 4 bytes");
        assert!((c.texel(0, 0).x - 0.215_860_5).abs() < 1e-5 && c.texel(0, 0).z == 1.0);
        assert!(
            (c.texel(1, 0).w - 128.0 / 255.0).abs() < 1e-6,
            "alpha is linear"
        );
        let d = decode(&png, "t.png", TextureRole::Data).expect("decode");
        assert!((d.texel(0, 0).x - 128.0 / 255.0).abs() < 1e-6);
        assert_ne!(c, d);
        assert!(decode(b"not an image", "x.png", TextureRole::Data).is_err());
    }

    #[test]
    fn sixteen_bit_files_keep_their_precision_and_codes_round_trip() {
        let img = image::ImageBuffer::<image::Rgba<u16>, _>::from_raw(
            1,
            1,
            vec![1000u16, 30000, 65535, 65535],
        )
        .expect("image");
        let mut png = Vec::new();
        img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .expect("png");
        let d = decode(&png, "t.png", TextureRole::Data).expect("decode");
        assert!((d.texel(0, 0).x - 1000.0 / 65535.0).abs() < 1e-7);
        let c = decode(&png, "t.png", TextureRole::Color).expect("decode");
        assert!((c.texel(0, 0).y - srgb_to_linear(30000.0 / 65535.0)).abs() < 1e-6);
        // Every 8-bit sRGB code survives decoding and re-encoding.
        let codes: Vec<[u8; 4]> = (0..=255u8).map(|v| [v, v, v, v]).collect();
        let t = Texels::Srgb8(codes.clone());
        let linear: Vec<Vec4> = (0..256).map(|i| t.get(i)).collect();
        match t.like(&linear) {
            Texels::Srgb8(back) => assert_eq!(back, codes),
            _ => panic!("kind changed"),
        }
    }

    /// A 1×1 image of `format`, its header rewritten to claim `w`×`h` pixels.
    pub(crate) fn lying_image(format: image::ImageFormat, w: u32, h: u32) -> Vec<u8> {
        let mut bytes = Vec::new();
        image::RgbImage::from_raw(1, 1, vec![10, 20, 30])
            .expect("image")
            .write_to(&mut std::io::Cursor::new(&mut bytes), format)
            .expect("encode");
        match format {
            image::ImageFormat::Png => {
                // IHDR: length, "IHDR", width, height, …, then the CRC of type and data.
                let at = bytes.windows(4).position(|w| w == b"IHDR").expect("IHDR");
                bytes[at + 4..at + 8].copy_from_slice(&w.to_be_bytes());
                bytes[at + 8..at + 12].copy_from_slice(&h.to_be_bytes());
                let crc = crc32fast::hash(&bytes[at..at + 17]);
                bytes[at + 17..at + 21].copy_from_slice(&crc.to_be_bytes());
            }
            image::ImageFormat::Jpeg => {
                // SOF0: FF C0, length, precision, height, width (16 bits each).
                let at = bytes
                    .windows(2)
                    .position(|w| w == [0xFF, 0xC0])
                    .expect("SOF0");
                bytes[at + 5..at + 7].copy_from_slice(&(h as u16).to_be_bytes());
                bytes[at + 7..at + 9].copy_from_slice(&(w as u16).to_be_bytes());
            }
            _ => unreachable!("PNG or JPEG"),
        }
        bytes
    }

    /// AFL++ found a small progressive JPEG claiming a size within the pixel limit that the
    /// decoder spent seconds and hundreds of megabytes filling with nothing: a claimed size
    /// is also one the file's bytes could hold.
    #[test]
    fn a_claimed_size_the_file_cannot_hold_is_refused_before_decoding() {
        for format in [image::ImageFormat::Png, image::ImageFormat::Jpeg] {
            let lying = lying_image(format, 8000, 8000);
            assert!(lying.len() < 2048);
            let e = decode(&lying, "t", TextureRole::Color).unwrap_err();
            assert!(
                e.contains("8000×8000")
                    && e.contains("takes at least")
                    && e.contains(&format!("the file has {}", lying.len())),
                "{format:?}: {e}"
            );
        }
        // A real image as large as its bytes allow is read: a flat 4096×4096 PNG deflates
        // near the bound.
        let flat = image::GrayImage::from_pixel(4096, 4096, image::Luma([128]));
        let mut png = Vec::new();
        flat.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .expect("encode");
        let t = decode(&png, "flat", TextureRole::Data).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((t.width, t.height), (4096, 4096));
    }

    /// AFL++ found a JPEG on which zune-jpeg's AVX2 upsampler fails an assertion (in release
    /// builds too): the file is refused, saying so, and nothing panics past the decoder.
    #[test]
    fn a_panic_in_the_jpeg_decoder_refuses_the_file() {
        let bytes = crate::image::fuzz_regression("image/jpeg-upsampler-assert.jpg");
        // A CPU without AVX2 takes the scalar upsampler, which may read the file.
        if let Err(e) = decode(&bytes, "t", TextureRole::Color) {
            assert!(
                e.contains("malformed file") || e.contains("cannot decode"),
                "{e}"
            );
        }
    }

    #[test]
    fn a_claimed_size_over_the_limit_is_refused_before_decoding() {
        for format in [image::ImageFormat::Png, image::ImageFormat::Jpeg] {
            let honest = lying_image(format, 1, 1);
            assert!(
                decode(&honest, "t", TextureRole::Color).is_ok(),
                "{format:?}"
            );
            let lying = lying_image(format, 60000, 60000);
            assert!(lying.len() < 2048);
            let e = decode(&lying, "t", TextureRole::Color).unwrap_err();
            assert!(
                e.contains("60000×60000") && e.contains("limit"),
                "{format:?}: {e}"
            );
        }
    }
}
