//! Films as image files: PNG (8-bit sRGB) and OpenEXR (32-bit float), encoded in memory so that
//! the caller can write them atomically.

use std::io::Cursor;

use glam::Vec3;
use image::codecs::png::PngEncoder;
use image::{ExtendedColorType, ImageEncoder};

use crate::color::to_srgb8;
use crate::film::{Film, Pass};
use crate::heatmap::heatmap_with_legend;

/// Why an image could not be encoded.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("cannot encode PNG: {0}")]
    Png(#[from] image::ImageError),
    #[error("cannot encode OpenEXR: {0}")]
    Exr(#[from] exr::error::Error),
}

/// An 8-bit RGB image.
#[derive(Clone, Debug, PartialEq)]
pub struct Rgb8Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<u8>,
}

impl Rgb8Image {
    /// The image as a PNG file.
    pub fn to_png(&self) -> Result<Vec<u8>, ImageError> {
        let mut bytes = Vec::new();
        PngEncoder::new(&mut bytes).write_image(
            &self.pixels,
            self.width,
            self.height,
            ExtendedColorType::Rgb8,
        )?;
        Ok(bytes)
    }
}

/// A pass of the film as a displayable image:
/// - beauty: linear radiance to sRGB;
/// - depth: nearest hit white, farthest black (linear in distance), misses black;
/// - normal: `(n + 1)/2` as RGB;
/// - prim: a colour hashed from the triangle id, misses black;
/// - nodes, triangles: heatmaps with a legend strip below (the image is taller).
pub fn pass_image(film: &Film, pass: Pass) -> Rgb8Image {
    let (w, h) = (film.width, film.height);
    let per_pixel = |f: &dyn Fn(usize) -> [u8; 3]| -> Vec<u8> {
        (0..film.radiance.len()).flat_map(f).collect()
    };
    let (pixels, height) = match pass {
        Pass::Beauty => (per_pixel(&|i| to_srgb8(film.radiance[i])), h),
        Pass::Depth => {
            let finite = film.depth.iter().copied().filter(|d| d.is_finite());
            let near = finite.clone().fold(f32::INFINITY, f32::min);
            let far = finite.fold(0.0f32, f32::max);
            let grey = |d: f32| -> u8 {
                if !d.is_finite() {
                    0
                } else if far > near {
                    (255.0 * (1.0 - 0.8 * (d - near) / (far - near))) as u8
                } else {
                    255
                }
            };
            (per_pixel(&|i| [grey(film.depth[i]); 3]), h)
        }
        Pass::Normal => (
            per_pixel(&|i| {
                let n = film.normal[i];
                if n == Vec3::ZERO {
                    [0; 3]
                } else {
                    let c = (n + 1.0) * 127.5;
                    [c.x as u8, c.y as u8, c.z as u8]
                }
            }),
            h,
        ),
        Pass::Prim => (per_pixel(&|i| prim_colour(film.prim[i])), h),
        Pass::Nodes => heatmap_with_legend(&film.nodes_visited, w, h),
        Pass::Triangles => heatmap_with_legend(&film.triangles_tested, w, h),
    };
    Rgb8Image {
        width: w,
        height,
        pixels,
    }
}

/// A bright colour per triangle id (a multiplicative hash), black for none.
fn prim_colour(prim: u32) -> [u8; 3] {
    if prim == u32::MAX {
        return [0; 3];
    }
    let h = prim.wrapping_add(1).wrapping_mul(0x9E37_79B9);
    [
        64 + (h >> 24) as u8 % 192,
        64 + (h >> 16) as u8 % 192,
        64 + (h >> 8) as u8 % 192,
    ]
}

/// The film as a single-layer OpenEXR file of 32-bit float channels: `R`, `G`, `B` (linear
/// radiance) and `Z` (depth, infinite where nothing was hit).
pub fn to_exr(film: &Film) -> Result<Vec<u8>, ImageError> {
    use exr::prelude::*;
    let width = film.width as usize;
    let channels = SpecificChannels::build()
        .with_channel("B")
        .with_channel("G")
        .with_channel("R")
        .with_channel("Z")
        .with_pixel_fn(|p: Vec2<usize>| {
            let i = p.y() * width + p.x();
            let c = film.radiance[i];
            (c.z, c.y, c.x, film.depth[i])
        });
    let image = Image::from_channels((film.width as usize, film.height as usize), channels);
    let mut cursor = Cursor::new(Vec::new());
    image.write().to_buffered(&mut cursor)?;
    Ok(cursor.into_inner())
}
