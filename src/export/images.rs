//! Texels out of the paging file and into the image files a glTF viewer reads: a node's atlas (mip 0), a
//! rect's inner rectangle cropped from it (a period image), an original texture (mip 0 of its stored
//! chain); encoded as JPEG where the tree is opaque and PNG where it has alpha.
//!
//! Viewers decode these to RGBA8 and build their own mip chains, so the GPU holds `4 · w · h · 4/3`
//! bytes per image ([`gpu_bytes`]) where atlastree's own renderer holds the BC1/BC3 blocks (0.5 / 1 byte
//! per texel, `docs/3dtiles.md`).

use crate::ids::BlockId;
use crate::store::{StoreError, TreeFile};
use crate::texfmt::TexFormat;
use image::RgbaImage;

/// How an image is encoded.
#[derive(Copy, Clone, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ImageCodec {
    /// JPEG at [`JPEG_QUALITY`] (opaque trees: alpha is 255 everywhere).
    Jpeg,
    /// PNG (alpha trees).
    Png,
}

/// JPEG quality of opaque images (0–100).
pub const JPEG_QUALITY: u8 = 90;

impl ImageCodec {
    pub fn extension(self) -> &'static str {
        match self {
            ImageCodec::Jpeg => "jpg",
            ImageCodec::Png => "png",
        }
    }

    pub fn mime(self) -> &'static str {
        match self {
            ImageCodec::Jpeg => "image/jpeg",
            ImageCodec::Png => "image/png",
        }
    }

    /// The codec for a tree: PNG where alpha matters.
    pub fn for_alpha(alpha: bool) -> ImageCodec {
        if alpha {
            ImageCodec::Png
        } else {
            ImageCodec::Jpeg
        }
    }

    /// Encodes `img` (RGBA8; JPEG drops alpha).
    pub fn encode(self, img: &RgbaImage) -> Result<Vec<u8>, image::ImageError> {
        let mut out = Vec::new();
        match self {
            ImageCodec::Jpeg => {
                let rgb = image::DynamicImage::ImageRgba8(img.clone()).to_rgb8();
                let enc =
                    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, JPEG_QUALITY);
                rgb.write_with_encoder(enc)?;
            }
            ImageCodec::Png => {
                let enc = image::codecs::png::PngEncoder::new_with_quality(
                    &mut out,
                    image::codecs::png::CompressionType::Fast,
                    image::codecs::png::FilterType::Adaptive,
                );
                img.write_with_encoder(enc)?;
            }
        }
        Ok(out)
    }
}

/// Bytes a viewer's GPU holds for a `w × h` RGBA8 image with a full mip chain (4/3 of level 0).
pub fn gpu_bytes(w: u32, h: u32) -> u64 {
    u64::from(w) * u64::from(h) * 4 * 4 / 3
}

/// Mip 0 of the `size²` atlas in `block`, decoded to RGBA8.
pub(super) fn atlas_level0(
    file: &TreeFile,
    block: BlockId,
    format: TexFormat,
    size: u32,
) -> Result<RgbaImage, StoreError> {
    let bytes = file.block(block)?;
    level0(&bytes, block, format, size, size, 0)
}

/// Mip 0 of the `w × h` image at byte `offset` of `bytes`, block `block`'s verified bytes (an atlas at
/// 0; the originals of one block lie back to back, each a full chain), decoded to RGBA8.
pub(super) fn level0(
    bytes: &[u8],
    block: BlockId,
    format: TexFormat,
    w: u32,
    h: u32,
    offset: u64,
) -> Result<RgbaImage, StoreError> {
    let len = format.level_bytes_rect(w, h);
    let short = || StoreError::BlockLength {
        block,
        expected: offset + len,
        got: bytes.len() as u64,
    };
    let start = usize::try_from(offset).map_err(|_| short())?;
    let end = usize::try_from(offset + len).map_err(|_| short())?;
    let level = bytes.get(start..end).ok_or_else(short)?;
    let rgba = crate::texfmt::decode_level_rect(format, level, w, h);
    RgbaImage::from_raw(w, h, rgba).ok_or_else(short)
}

/// The texels of `[x, y, w, h]` (leaf-atlas texels of a leaf `d` levels below the atlas's node, whose cell
/// offset inside the node is `(ox, oy)` leaf atlases) in the node's atlas `img`: the rectangle scaled by
/// `2^−d` exactly (fractional where `d` > 2: inner rectangles are 4-aligned), resampled bilinearly at the
/// centres of `round(w · 2^−d) × round(h · 2^−d)` texels (at least one): the image spans exactly the rect,
/// so a wrapping sampler repeats it with the rect's period. Where the scaled rectangle is whole texels the
/// result is a plain copy.
pub(super) fn crop_scaled(
    img: &RgbaImage,
    [x, y, w, h]: [u32; 4],
    (ox, oy, d): (u32, u32, u32),
) -> RgbaImage {
    let size = f64::from(img.width());
    let s = (-(f64::from(d))).exp2();
    let to_node = |o: u32, p: u32| (f64::from(o) * size + f64::from(p)) * s;
    let (x0, y0) = (to_node(ox, x), to_node(oy, y));
    let (fw, fh) = (f64::from(w) * s, f64::from(h) * s);
    let (ow, oh) = ((fw.round() as u32).max(1), (fh.round() as u32).max(1));
    RgbaImage::from_fn(ow, oh, |i, j| {
        let u = x0 + (f64::from(i) + 0.5) * fw / f64::from(ow);
        let v = y0 + (f64::from(j) + 0.5) * fh / f64::from(oh);
        bilinear(img, u, v)
    })
}

/// `img` at the point `(u, v)` (texel units, texel centres at half-integers), bilinear, clamped to the
/// image.
fn bilinear(img: &RgbaImage, u: f64, v: f64) -> image::Rgba<u8> {
    let (w, h) = (img.width() as i64, img.height() as i64);
    let (fx, fy) = (u - 0.5, v - 0.5);
    let (x0, y0) = (fx.floor(), fy.floor());
    let (tx, ty) = (fx - x0, fy - y0);
    let at = |x: f64, y: f64| {
        let xi = (x as i64).clamp(0, w - 1) as u32;
        let yi = (y as i64).clamp(0, h - 1) as u32;
        img.get_pixel(xi, yi).0.map(f64::from)
    };
    let (a, b, c, e) = (
        at(x0, y0),
        at(x0 + 1.0, y0),
        at(x0, y0 + 1.0),
        at(x0 + 1.0, y0 + 1.0),
    );
    let mut out = [0u8; 4];
    for k in 0..4 {
        let top = a[k] * (1.0 - tx) + b[k] * tx;
        let bottom = c[k] * (1.0 - tx) + e[k] * tx;
        out[k] = (top * (1.0 - ty) + bottom * ty).round().clamp(0.0, 255.0) as u8;
    }
    image::Rgba(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_crop_two_levels_up_is_a_quarter_at_its_cell() {
        let img = RgbaImage::from_fn(64, 64, |x, y| image::Rgba([x as u8, y as u8, 0, 255]));
        // Leaf cell (1, 2) of 4 × 4 under the node: its texel (8, 4) is node texel (16 + 2, 32 + 1).
        let c = crop_scaled(&img, [8, 4, 16, 8], (1, 2, 2));
        assert_eq!((c.width(), c.height()), (4, 2));
        assert_eq!(c.get_pixel(0, 0).0, [18, 33, 0, 255]);
        assert_eq!(c.get_pixel(3, 1).0, [21, 34, 0, 255]);
    }

    #[test]
    fn a_fractional_crop_spans_exactly_the_scaled_rect() {
        // x = 4 leaf texels, 3 levels up: node texel 0.5 .. 0.5 + 16/8 = 2.5: two texels centred on 1.0
        // and 2.0, each the mean of its two neighbours on a horizontal ramp.
        let img = RgbaImage::from_fn(64, 64, |x, _| image::Rgba([(10 * x) as u8, 0, 0, 255]));
        let c = crop_scaled(&img, [4, 0, 16, 16], (0, 0, 3));
        assert_eq!((c.width(), c.height()), (2, 2));
        assert_eq!(c.get_pixel(0, 0).0[0], 5);
        assert_eq!(c.get_pixel(1, 0).0[0], 15);
    }

    #[test]
    fn jpeg_and_png_round_trip_sizes() {
        let img = RgbaImage::from_pixel(8, 4, image::Rgba([10, 200, 30, 128]));
        for codec in [ImageCodec::Jpeg, ImageCodec::Png] {
            let bytes = codec.encode(&img).unwrap();
            let back = image::load_from_memory(&bytes).unwrap();
            assert_eq!((back.width(), back.height()), (8, 4));
        }
        assert_eq!(gpu_bytes(256, 256), 349_525);
    }
}
