//! Image textures at render time: a mip-map pyramid (each level the 2×2 box average of the one
//! below), looked up trilinearly at the level whose texels match the hit's footprint
//! (Williams 1983; pbrt-v4 §10.4.3), with the sampler's wrap modes. Built once per image and
//! shared by every material and thread that reads it.

use std::collections::HashMap;
use std::sync::Arc;

use glam::{Affine2, Vec2, Vec4};
use rayon::prelude::*;
use tessera_scene::texture::{Texels, TextureDesc, TextureImage, Wrap};

/// One level of a pyramid, rows top to bottom.
#[derive(Debug)]
struct Level {
    width: u32,
    height: u32,
    texels: LevelTexels,
}

/// The finest level is the image itself (shared with the scene description, not copied);
/// coarser levels are stored like it (8-bit sRGB stays 8-bit sRGB, averaged in linear).
#[derive(Debug)]
enum LevelTexels {
    Image(Arc<TextureImage>),
    Own(Texels),
}

impl Level {
    #[inline]
    fn texels(&self) -> &Texels {
        match &self.texels {
            LevelTexels::Image(i) => &i.texels,
            LevelTexels::Own(t) => t,
        }
    }
}

/// An image's mip-map pyramid, finest first.
#[derive(Debug)]
pub struct Pyramid {
    levels: Vec<Level>,
}

impl Pyramid {
    pub fn new(image: &Arc<TextureImage>) -> Self {
        let mut levels = vec![Level {
            width: image.width,
            height: image.height,
            texels: LevelTexels::Image(image.clone()),
        }];
        while let Some(l) = levels.last()
            && (l.width > 1 || l.height > 1)
        {
            let (w, h) = ((l.width / 2).max(1), (l.height / 2).max(1));
            let below = l.texels();
            // Rows in parallel: the pyramid of a production texture has tens of millions of texels.
            let linear: Vec<Vec4> = (0..h)
                .into_par_iter()
                .flat_map_iter(|y| {
                    (0..w).map(move |x| {
                        // The 2×2 texels below (fewer at an odd edge, which clamps).
                        let at = |dx: u32, dy: u32| {
                            let (sx, sy) = (
                                (2 * x + dx).min(l.width - 1),
                                (2 * y + dy).min(l.height - 1),
                            );
                            below.get((sy * l.width + sx) as usize)
                        };
                        (at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1)) * 0.25
                    })
                })
                .collect();
            let texels = below.like(&linear);
            levels.push(Level {
                width: w,
                height: h,
                texels: LevelTexels::Own(texels),
            });
        }
        Pyramid { levels }
    }

    /// Bytes the pyramid takes (the finest level included, though the scene description
    /// holds it too).
    pub fn bytes(&self) -> usize {
        self.levels.iter().map(|l| l.texels().bytes()).sum()
    }
}

/// Integer texel coordinate `i` of a side of `n` texels, wrapped.
#[inline]
fn wrap(i: i64, n: u32, mode: Wrap) -> u32 {
    let n = n as i64;
    (match mode {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::ClampToEdge => i.clamp(0, n - 1),
        Wrap::MirroredRepeat => {
            let m = i.rem_euclid(2 * n);
            if m >= n { 2 * n - 1 - m } else { m }
        }
    }) as u32
}

/// A texture as a material reads it: a shared pyramid, wrap modes and coordinate transform.
#[derive(Debug, Clone)]
pub struct MipMap {
    pyramid: Arc<Pyramid>,
    wrap: [Wrap; 2],
    transform: Affine2,
    /// How much the transform scales texture coordinates (√|det|), for footprints.
    scale: f32,
    /// Which set of texture coordinates it reads (TEXCOORD_0 or _1; others read 0).
    set: usize,
}

impl MipMap {
    pub fn new(pyramid: Arc<Pyramid>, desc: &TextureDesc) -> Self {
        MipMap {
            pyramid,
            wrap: desc.wrap,
            transform: desc.transform,
            scale: desc.transform.matrix2.determinant().abs().sqrt(),
            set: if desc.texcoord == 1 { 1 } else { 0 },
        }
    }

    /// The texture at a point's coordinates of both sets (footprints `width` in each),
    /// reading its own set.
    #[inline]
    pub fn at(&self, uv: [Vec2; 2], width: [f32; 2]) -> Vec4 {
        self.lookup(uv[self.set], width[self.set])
    }

    /// Bilinear value of level `l` at texture coordinates `st` (texel centres at half
    /// integers).
    #[inline]
    fn bilinear(&self, l: usize, st: Vec2) -> Vec4 {
        let level = &self.pyramid.levels[l];
        let texels = level.texels();
        let x = st.x * level.width as f32 - 0.5;
        let y = st.y * level.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let texel = |dx: i64, dy: i64| {
            let tx = wrap(x0 + dx, level.width, self.wrap[0]);
            let ty = wrap(y0 + dy, level.height, self.wrap[1]);
            texels.get((ty * level.width + tx) as usize)
        };
        let top = texel(0, 0) * (1.0 - fx) + texel(1, 0) * fx;
        let bottom = texel(0, 1) * (1.0 - fx) + texel(1, 1) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// The image's mean (its coarsest level).
    pub fn mean(&self) -> Vec4 {
        let last = self.pyramid.levels.last().expect("a pyramid has a level");
        last.texels().get(0)
    }

    /// The texture at `uv` for a footprint `width` wide in uv units: trilinear between the two
    /// levels whose texel size brackets the width (bilinear at the finest level below one
    /// texel; 0 asks for the finest).
    #[inline]
    pub fn lookup(&self, uv: Vec2, width: f32) -> Vec4 {
        let st = self.transform.transform_point2(uv);
        if !st.is_finite() {
            return Vec4::ZERO;
        }
        let finest = &self.pyramid.levels[0];
        let texels = width * self.scale * finest.width.max(finest.height) as f32;
        let last = (self.pyramid.levels.len() - 1) as f32;
        let level = if texels > 1.0 {
            texels.log2().min(last)
        } else {
            0.0
        };
        if level <= 0.0 {
            return self.bilinear(0, st);
        }
        let l0 = level.floor();
        let f = level - l0;
        let a = self.bilinear(l0 as usize, st);
        if f == 0.0 {
            return a;
        }
        a * (1.0 - f) + self.bilinear(l0 as usize + 1, st) * f
    }
}

/// Pyramids built so far in a scene, one per image (by its content hash), and their bytes.
#[derive(Debug, Default)]
pub struct Textures {
    pyramids: HashMap<u64, Arc<Pyramid>>,
}

impl Textures {
    /// The mip-map for `desc`, building its image's pyramid if this scene has not yet.
    pub fn mipmap(&mut self, desc: &TextureDesc) -> MipMap {
        let pyramid = self
            .pyramids
            .entry(desc.image.hash)
            .or_insert_with(|| Arc::new(Pyramid::new(&desc.image)))
            .clone();
        MipMap::new(pyramid, desc)
    }

    /// Bytes of every pyramid.
    pub fn bytes(&self) -> usize {
        self.pyramids.values().map(|p| p.bytes()).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `n`×`n` checker of single texels, black and white.
    fn checker(n: u32) -> TextureDesc {
        let texels = (0..n * n)
            .map(|i| {
                let v = ((i % n + i / n) % 2) as f32;
                Vec4::new(v, v, v, 1.0)
            })
            .collect();
        TextureDesc::new(Arc::new(TextureImage::from_texels("checker", n, n, texels)))
    }

    #[test]
    fn the_finest_level_returns_texels_at_their_centres_and_blends_between() {
        let m = Textures::default().mipmap(&checker(8));
        let centre = |x: u32, y: u32| Vec2::new((x as f32 + 0.5) / 8.0, (y as f32 + 0.5) / 8.0);
        assert_eq!(m.lookup(centre(0, 0), 0.0).x, 0.0);
        assert_eq!(m.lookup(centre(1, 0), 0.0).x, 1.0);
        // Halfway between two texel centres: their mean.
        assert!((m.lookup(Vec2::new(1.0 / 8.0, 0.5 / 8.0), 0.0).x - 0.5).abs() < 1e-6);
    }

    #[test]
    fn a_wide_footprint_averages_a_checker_instead_of_aliasing_it() {
        // Sampled at random points, a checker of single texels: with a footprint of a texel
        // or less the values are 0 and 1 (aliasing, if the footprint were a pixel's); with
        // a footprint of 4 or more texels every value is near the mean 0.5.
        let m = Textures::default().mipmap(&checker(64));
        let mut rng = 1u64;
        let mut next = || {
            rng = crate::sampler::hash::mix64(rng);
            (rng >> 40) as f32 / (1u64 << 24) as f32
        };
        for (width, spread) in [(4.0 / 64.0, 0.05f32), (16.0 / 64.0, 0.01), (1.0, 0.001)] {
            let mut worst = 0.0f32;
            for _ in 0..1000 {
                let v = m.lookup(Vec2::new(next(), next()), width).x;
                worst = worst.max((v - 0.5).abs());
            }
            assert!(
                worst <= spread,
                "footprint {width}: a value {worst} from the mean"
            );
        }
        let fine: Vec<f32> = (0..1000)
            .map(|_| m.lookup(Vec2::new(next(), next()), 0.0).x)
            .collect();
        let mean = fine.iter().sum::<f32>() / 1000.0;
        assert!((mean - 0.5).abs() < 0.05, "the finest level's mean {mean}");
        assert!(fine.iter().any(|&v| v > 0.9) && fine.iter().any(|&v| v < 0.1));
    }

    #[test]
    fn wrap_modes_repeat_mirror_and_clamp() {
        assert_eq!(wrap(-1, 4, Wrap::Repeat), 3);
        assert_eq!(wrap(5, 4, Wrap::Repeat), 1);
        assert_eq!(wrap(-1, 4, Wrap::MirroredRepeat), 0);
        assert_eq!(wrap(4, 4, Wrap::MirroredRepeat), 3);
        assert_eq!(wrap(9, 4, Wrap::MirroredRepeat), 1);
        assert_eq!(wrap(-3, 4, Wrap::ClampToEdge), 0);
        assert_eq!(wrap(7, 4, Wrap::ClampToEdge), 3);
    }

    #[test]
    fn every_level_keeps_the_images_mean() {
        let p = Pyramid::new(&checker(16).image);
        assert_eq!(p.levels.len(), 5);
        for l in &p.levels {
            let t = l.texels();
            let mean = (0..t.len()).map(|i| t.get(i).x).sum::<f32>() / t.len() as f32;
            assert!(
                (mean - 0.5).abs() < 1e-6,
                "level {}×{}: {mean}",
                l.width,
                l.height
            );
        }
    }
}
