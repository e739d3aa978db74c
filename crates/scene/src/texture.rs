//! Image textures as the scene gives them: decoded once (PNG or JPEG, 8 or 16 bits per
//! channel), in linear values — colour decoded from sRGB, data (roughness, metalness) as
//! stored — with the sampler's wrap modes and the texture coordinate transform.

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

/// A decoded image, RGBA in linear values, rows top to bottom.
#[derive(Clone)]
pub struct TextureImage {
    /// Where it came from, for messages (`images[2] "wood.png"`).
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub texels: Vec<Vec4>,
    /// A content hash (FNV-1a of the decoded texels), so that scenes compare and hash by it.
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
        self.texels.len() * std::mem::size_of::<Vec4>()
    }

    /// Builds an image from linear texels (tests, generated textures).
    pub fn from_texels(name: &str, width: u32, height: u32, texels: Vec<Vec4>) -> Self {
        let hash = fnv(&texels);
        TextureImage {
            name: name.into(),
            width,
            height,
            texels,
            hash,
        }
    }
}

fn fnv(texels: &[Vec4]) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for t in texels {
        for c in t.to_array() {
            for b in c.to_bits().to_le_bytes() {
                h ^= b as u64;
                h = h.wrapping_mul(0x100_0000_01b3);
            }
        }
    }
    h
}

/// The sRGB transfer function's inverse (IEC 61966-2-1): encoded value in [0, 1] to linear.
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Decodes a PNG or JPEG file's bytes for `role`; `name` is for messages.
pub fn decode(bytes: &[u8], name: &str, role: TextureRole) -> Result<TextureImage, String> {
    let img = image::load_from_memory(bytes)
        .map_err(|e| format!("cannot decode the image (PNG or JPEG expected): {e}"))?;
    let (width, height) = (img.width(), img.height());
    if width == 0 || height == 0 {
        return Err("the image is empty".into());
    }
    let rgba = img.into_rgba32f();
    let decode = |v: f32| match role {
        TextureRole::Color => srgb_to_linear(v),
        TextureRole::Data => v,
    };
    let texels: Vec<Vec4> = rgba
        .pixels()
        .map(|p| Vec4::new(decode(p[0]), decode(p[1]), decode(p[2]), p[3]))
        .collect();
    Ok(TextureImage::from_texels(name, width, height, texels))
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
        assert!((c.texels[0].x - 0.215_860_5).abs() < 1e-5 && c.texels[0].z == 1.0);
        assert!(
            (c.texels[1].w - 128.0 / 255.0).abs() < 1e-6,
            "alpha is linear"
        );
        let d = decode(&png, "t.png", TextureRole::Data).expect("decode");
        assert!((d.texels[0].x - 128.0 / 255.0).abs() < 1e-6);
        assert_ne!(c, d);
        assert!(decode(b"not an image", "x.png", TextureRole::Data).is_err());
    }
}
