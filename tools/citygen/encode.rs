//! Image encoding: PNG through the `png` crate (RGB8, RGBA8, grey 8, indexed 8 with a palette) and JPEG
//! through the `image` crate. Both encoders are deterministic for identical input.

use crate::texgen::{Encoding, Pixels};

/// PNG effort: `High` for committed fixtures, `Fast` for huge throw-away scenes.
#[derive(Copy, Clone, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PngEffort {
    Fast,
    Balanced,
    High,
}

#[derive(Debug, thiserror::Error)]
pub enum EncodeError {
    #[error("PNG encoding of {width}×{height} with {channels} channel(s) failed: {source}")]
    Png {
        width: u32,
        height: u32,
        channels: u8,
        source: png::EncodingError,
    },
    #[error("JPEG encoding of {width}×{height} failed: {source}")]
    Jpeg {
        width: u32,
        height: u32,
        source: image::ImageError,
    },
    #[error("{encoding:?} needs {expected} channel(s), the generator produced {channels}")]
    Channels {
        encoding: Encoding,
        expected: u8,
        channels: u8,
    },
}

/// JPEG quality (1–100) for the photo textures.
const JPEG_QUALITY: u8 = 85;

/// Encodes `px` as `enc`; returns the file bytes.
pub fn encode(px: &Pixels, enc: Encoding, effort: PngEffort) -> Result<Vec<u8>, EncodeError> {
    let expected = match enc {
        Encoding::PngRgb | Encoding::Jpeg => 3,
        Encoding::PngRgba => 4,
        Encoding::PngGrey | Encoding::PngPalette => 1,
    };
    if px.channels != expected {
        return Err(EncodeError::Channels {
            encoding: enc,
            expected,
            channels: px.channels,
        });
    }
    if enc == Encoding::Jpeg {
        let mut out = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, JPEG_QUALITY)
            .encode(
                &px.data,
                px.width,
                px.height,
                image::ExtendedColorType::Rgb8,
            )
            .map_err(|source| EncodeError::Jpeg {
                width: px.width,
                height: px.height,
                source,
            })?;
        return Ok(out);
    }
    let err = |source| EncodeError::Png {
        width: px.width,
        height: px.height,
        channels: px.channels,
        source,
    };
    let mut out = Vec::new();
    {
        let mut e = png::Encoder::new(&mut out, px.width, px.height);
        e.set_depth(png::BitDepth::Eight);
        e.set_color(match enc {
            Encoding::PngRgba => png::ColorType::Rgba,
            Encoding::PngGrey => png::ColorType::Grayscale,
            Encoding::PngPalette => png::ColorType::Indexed,
            _ => png::ColorType::Rgb,
        });
        if let (Encoding::PngPalette, Some(p)) = (enc, &px.palette) {
            e.set_palette(p.clone());
        }
        e.set_compression(match effort {
            PngEffort::Fast => png::Compression::Fast,
            PngEffort::Balanced => png::Compression::Balanced,
            PngEffort::High => png::Compression::High,
        });
        let mut w = e.write_header().map_err(err)?;
        w.write_image_data(&px.data).map_err(err)?;
        w.finish().map_err(err)?;
    }
    Ok(out)
}
