//! Lazily decoded images.
//!
//! The importer reads only an image's header (dimensions, colour type, alpha) and keeps either the
//! encoded bytes (embedded / data-URI images) or the file path; the pixels are decoded on demand by
//! [`ImageSource::decode`], so a scene with hundreds of large textures never holds them all decoded.

use super::error::SceneError;
use std::io::{Read, Seek, SeekFrom};
use std::path::PathBuf;
use std::sync::Arc;

/// Side of the fallback checkerboard that replaces missing or undecodable images, in texels.
pub(super) const FALLBACK_SIZE: u32 = 8;
/// The two colours of the fallback checkerboard (sRGB RGBA8): magenta and black, visibly wrong.
pub const FALLBACK_COLORS: [[u8; 4]; 2] = [[255, 0, 255, 255], [0, 0, 0, 255]];

/// Where an image's pixels come from.
#[derive(Clone, Debug)]
pub enum ImageData {
    /// An external file, read and decoded on demand.
    File(PathBuf),
    /// Encoded bytes (PNG/JPEG) of an embedded, GLB or data-URI image.
    Bytes(Arc<[u8]>),
    /// A 1×1 image of one sRGB RGBA8 colour (untextured materials).
    Solid([u8; 4]),
    /// The 8×8 magenta/black checker standing in for a missing or undecodable image.
    Fallback,
}

/// An image of the scene, known by its header; pixels are decoded by [`ImageSource::decode`].
#[derive(Clone, Debug)]
pub struct ImageSource {
    /// Human-readable name: the glTF image name, its file name, or a description ("solid #rrggbbaa").
    pub name: String,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// True if the image has an alpha channel (colour type with alpha, or a PNG `tRNS` chunk), or for a
    /// solid colour whose alpha is below 255.
    pub has_alpha: bool,
    /// The stored colour format, e.g. "Rgb8", "Rgba16", "Palette8", "L8", "La16", "Solid", "Fallback".
    pub color: String,
    /// Where the pixels come from.
    pub data: ImageData,
    /// The index of the glTF image it was read from (its fallback too); `None` for solid colours and
    /// images made in memory. A shard plan file names images by it ([`ImageRef`]).
    pub gltf_image: Option<u32>,
}

/// Where a shard of a planned build finds one image of the scene without importing its geometry
/// (`store::plan`, [`super::import_images`]).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ImageRef {
    /// The glTF image of this index (loaded, or its fallback when it cannot be read, as the import does).
    Gltf(u32),
    /// A 1×1 image of one sRGB RGBA8 colour (an untextured material).
    Solid([u8; 4]),
}

impl ImageSource {
    /// How a plan names this image, `None` for an image made in memory (a synthetic scene).
    pub fn image_ref(&self) -> Option<ImageRef> {
        match (&self.data, self.gltf_image) {
            (ImageData::Solid(c), _) => Some(ImageRef::Solid(*c)),
            (_, Some(i)) => Some(ImageRef::Gltf(i)),
            _ => None,
        }
    }
}

/// A decoded image: RGBA8, sRGB colour, straight alpha, row-major, top row first.
#[derive(Clone, Debug)]
pub struct DecodedImage {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[u8; 4]>,
}

impl DecodedImage {
    /// True when every texel's alpha is 255. The texels are ANDed together as `u32`s in runs of 4096
    /// with no exit inside a run, so the loop vectorises (a `p[3] == 255` test per texel with an early
    /// exit does not, and a build checks every texel it decodes once or twice).
    pub fn is_opaque(&self) -> bool {
        self.pixels.chunks(4096).all(|run| {
            let and = run.iter().fold(u32::MAX, |m, p| m & u32::from_le_bytes(*p));
            and >> 24 == 0xFF
        })
    }
}

/// What the header of an encoded image says.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct ImageHeader {
    pub width: u32,
    pub height: u32,
    pub has_alpha: bool,
    pub color: String,
    /// A JPEG without its end-of-image marker near its end (a truncated file, most likely: decoders draw
    /// what is there and fill the rest) or with fewer bytes after its first scan starts than its frame's
    /// blocks take (a frame header claiming more than the data covers), or a PNG without its `IEND` chunk (its decode fails), reported
    /// by the import as a warning.
    pub truncated: bool,
}

impl ImageSource {
    /// A 1×1 image of one sRGB RGBA8 colour.
    pub fn solid(rgba: [u8; 4]) -> Self {
        let [r, g, b, a] = rgba;
        ImageSource {
            name: format!("solid #{r:02x}{g:02x}{b:02x}{a:02x}"),
            width: 1,
            height: 1,
            has_alpha: a < 255,
            color: "Solid".into(),
            data: ImageData::Solid(rgba),
            gltf_image: None,
        }
    }

    /// The fallback checkerboard for the image called `name` (missing or undecodable).
    pub fn fallback(name: &str) -> Self {
        ImageSource {
            name: format!("{name} (missing: fallback checker)"),
            width: FALLBACK_SIZE,
            height: FALLBACK_SIZE,
            has_alpha: false,
            color: "Fallback".into(),
            data: ImageData::Fallback,
            gltf_image: None,
        }
    }

    /// Number of texels (`width * height`).
    pub fn texels(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// Encoded size in bytes: the file's length (0 if it cannot be read) or the embedded bytes; 0 for
    /// solid and fallback images.
    pub fn encoded_bytes(&self) -> u64 {
        match &self.data {
            ImageData::File(p) => std::fs::metadata(p).map_or(0, |m| m.len()),
            ImageData::Bytes(b) => b.len() as u64,
            ImageData::Solid(_) | ImageData::Fallback => 0,
        }
    }

    /// True for the fallback checkerboard.
    pub fn is_fallback(&self) -> bool {
        matches!(self.data, ImageData::Fallback)
    }

    /// Decodes the image to RGBA8 (sRGB, straight alpha, top row first). 16-bit channels are rounded to
    /// 8 bits (`(v + 128) / 257`); palette and grey images are expanded. Errors name the image. The
    /// decoded size must match the header read at import.
    pub fn decode(&self) -> Result<DecodedImage, SceneError> {
        let decoded = match &self.data {
            ImageData::Solid(rgba) => DecodedImage {
                width: 1,
                height: 1,
                pixels: vec![*rgba],
            },
            ImageData::Fallback => fallback_checker(),
            ImageData::Bytes(bytes) => {
                decode_encoded(std::io::Cursor::new(&bytes[..]), &self.name)?
            }
            ImageData::File(path) => {
                let file =
                    crate::util::open_regular(path).map_err(|e| SceneError::ImageDecode {
                        image: self.name.clone(),
                        reason: format!("{}: {e}", path.display()),
                    })?;
                decode_encoded(std::io::BufReader::new(file), &self.name)?
            }
        };
        if decoded.width != self.width || decoded.height != self.height {
            return Err(SceneError::ImageDecode {
                image: self.name.clone(),
                reason: format!(
                    "decoded size {}x{} differs from header size {}x{}",
                    decoded.width, decoded.height, self.width, self.height
                ),
            });
        }
        Ok(decoded)
    }
}

/// The fallback checkerboard at `width × height` (8 × 8 cells, or one texel per cell on a shorter side),
/// for an image whose header was read but whose pixels do not decode: the build sized its atlas rects
/// and its stored original by the header, so both draw the same squares; the 8 × 8 board, resampled to
/// the header's size, was blurred in the atlas and replicated in the original (9.5 dB between the modes;
/// fault hunt, session 31). The caller bounds the sides (the build: an original's largest, so both
/// still resample the same board); a side of 0 gives the 8 × 8 board.
pub fn fallback_checker_sized(width: u32, height: u32) -> DecodedImage {
    if width == 0 || height == 0 {
        return fallback_checker();
    }
    let cell = |i: u32, n: u32| u64::from(i) * u64::from(n.min(FALLBACK_SIZE)) / u64::from(n);
    let pixels = (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .map(|(x, y)| FALLBACK_COLORS[((cell(x, width) + cell(y, height)) % 2) as usize])
        .collect();
    DecodedImage {
        width,
        height,
        pixels,
    }
}

/// The 8×8 magenta/black checkerboard ([`FALLBACK_COLORS`]) drawn for images that cannot be decoded.
pub fn fallback_checker() -> DecodedImage {
    let n = FALLBACK_SIZE;
    let pixels = (0..n * n)
        .map(|i| FALLBACK_COLORS[(((i % n) + (i / n)) % 2) as usize])
        .collect();
    DecodedImage {
        width: n,
        height: n,
        pixels,
    }
}

/// The most one decode may allocate: half the machine's memory (the build's default budget, which
/// refuses a scene whose images cannot fit before any decode), at least the `image` crate's own 512 MiB.
/// Its default alone turned a 16384² RGB orthophoto or an 8200² 16-bit PNG into the magenta fallback
/// whatever `--max-memory` allowed; a header claiming 60000² still falls back rather than abort.
pub(crate) fn decode_alloc_limit() -> u64 {
    const IMAGE_CRATE_DEFAULT: u64 = 512 << 20;
    static LIMIT: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
    *LIMIT.get_or_init(|| {
        crate::util::memory_limit_bytes()
            .map_or(IMAGE_CRATE_DEFAULT, |m| (m / 2).max(IMAGE_CRATE_DEFAULT))
    })
}

/// Bytes a decode of a `w × h` image of `color` holds at once: the decoder's buffer (`native` bytes) and,
/// unless it is RGBA8 already, the RGBA8 copy made of it; a JPEG's decoder may hold its coefficients
/// (16 bits a sample, a progressive file's whole frame) beside its buffer before the copy is made.
fn decode_peak(w: u32, h: u32, color: image::ColorType, native: u64, jpeg: bool) -> u64 {
    let rgba8 = (u64::from(w) * u64::from(h)).saturating_mul(4);
    let converted = match color {
        image::ColorType::Rgba8 => native,
        _ => native.saturating_add(rgba8),
    };
    if jpeg {
        converted.max(native.saturating_mul(3))
    } else {
        converted
    }
}

/// Decodes a PNG/JPEG stream to RGBA8.
fn decode_encoded<R: Read + Seek + std::io::BufRead>(
    reader: R,
    name: &str,
) -> Result<DecodedImage, SceneError> {
    decode_encoded_within(reader, name, decode_alloc_limit())
}

/// [`decode_encoded`] within `limit` bytes.
fn decode_encoded_within<R: Read + Seek + std::io::BufRead>(
    reader: R,
    name: &str,
    limit: u64,
) -> Result<DecodedImage, SceneError> {
    let err = |reason: String| SceneError::ImageDecode {
        image: name.to_string(),
        reason,
    };
    let mut reader = image::ImageReader::new(reader)
        .with_guessed_format()
        .map_err(|e| err(e.to_string()))?;
    let jpeg = reader.format() == Some(image::ImageFormat::Jpeg);
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(limit);
    reader.limits(limits);
    let decoder = reader.into_decoder().map_err(|e| err(e.to_string()))?;
    // The decoder's limit covers its own buffer; the RGBA8 copy of a grey or RGB image comes beside it
    // (a 715-byte JPEG claiming 35000² grey was admitted at 1.2 GB and took 6 GB to convert: a panic
    // under a 3 GB address-space limit, an OOM kill in a 2 GiB container; fault hunt, session 35).
    let (w, h) = image::ImageDecoder::dimensions(&decoder);
    let color = image::ImageDecoder::color_type(&decoder);
    let peak = decode_peak(
        w,
        h,
        color,
        image::ImageDecoder::total_bytes(&decoder),
        jpeg,
    );
    if peak > limit {
        return Err(err(format!(
            "{w}×{h} takes {} to decode and convert to RGBA8, over the {} one decode may take (half the \
             memory this process may use, at least 512 MiB)",
            crate::util::human_bytes(peak),
            crate::util::human_bytes(limit)
        )));
    }
    let img = image::DynamicImage::from_decoder(decoder).map_err(|e| err(e.to_string()))?;
    let rgba = img.into_rgba8();
    let (width, height) = rgba.dimensions();
    let pixels: Vec<[u8; 4]> = bytemuck::cast_vec(rgba.into_raw());
    Ok(DecodedImage {
        width,
        height,
        pixels,
    })
}

/// Reads the header of an encoded PNG or JPEG image: dimensions, colour format and alpha, without
/// decoding pixels. PNG headers are parsed directly (to report palette and bit depth and to see a
/// `tRNS` chunk); other formats go through `image`'s decoder header.
pub(super) fn read_header<R: Read + Seek + std::io::BufRead>(
    mut reader: R,
) -> Result<ImageHeader, String> {
    let mut sig = [0u8; 8];
    let n = read_up_to(&mut reader, &mut sig).map_err(|e| e.to_string())?;
    reader.seek(SeekFrom::Start(0)).map_err(|e| e.to_string())?;
    if n == 8 && sig == PNG_SIGNATURE {
        let header = read_png_header(&mut reader)?;
        let truncated = !png_ends_with_iend(&mut reader)?;
        return Ok(ImageHeader {
            truncated,
            ..header
        });
    }
    let truncated = sig.starts_with(&[0xFF, 0xD8, 0xFF]) && !jpeg_ends_with_eoi(&mut reader)?;
    reader.seek(SeekFrom::Start(0)).map_err(|e| e.to_string())?;
    use image::ImageDecoder;
    let decoder = image::ImageReader::new(reader)
        .with_guessed_format()
        .map_err(|e| e.to_string())?
        .into_decoder()
        .map_err(|e| e.to_string())?;
    let (width, height) = decoder.dimensions();
    let ct = decoder.color_type();
    if width == 0 || height == 0 {
        return Err(format!("empty image {width}x{height}"));
    }
    Ok(ImageHeader {
        width,
        height,
        has_alpha: ct.has_alpha(),
        color: format!("{ct:?}"),
        truncated,
    })
}

/// Bytes at the end of a JPEG searched for its end-of-image marker: encoders may pad after it, and the
/// marker cannot occur inside entropy-coded data (a 0xFF there is followed by 0x00 or a restart code).
const JPEG_TAIL: u64 = 4096;

/// Whether the JPEG in `reader` has its end-of-image marker (`FF D9`) in its last [`JPEG_TAIL`] bytes,
/// past the start of its first scan ([`jpeg_scan_start`]), and at least the bytes its frame's blocks take
/// from there ([`JpegScan::min_bytes`]). The marker of an embedded thumbnail (EXIF APP1) made a file cut
/// short after it read as whole, and a frame header claiming more texels than the data covers drew one
/// flat colour without a warning (fault hunts, session 35). A file whose segments do not lead to a scan
/// is cut short; one whose markers do not parse is searched whole, as before. Files with a longer
/// trailer after it (e.g. a motion photo's video) read as truncated: a warning only.
fn jpeg_ends_with_eoi<R: Read + Seek>(reader: &mut R) -> Result<bool, String> {
    let scan = match jpeg_scan_start(reader) {
        Ok(Some(scan)) => scan,
        Ok(None) => return Ok(false),
        Err(_) => JpegScan::default(),
    };
    let (tail_at, bytes) = tail(reader, JPEG_TAIL)?;
    let len = tail_at + bytes.len() as u64;
    if len.saturating_sub(scan.at) < scan.min_bytes {
        return Ok(false);
    }
    let skip = usize::try_from(scan.at.saturating_sub(tail_at)).unwrap_or(usize::MAX);
    Ok(bytes
        .get(skip.min(bytes.len())..)
        .is_some_and(|b| b.windows(2).any(|w| w == [0xFF, 0xD9])))
}

/// Where a JPEG's first scan starts and the fewest bytes its entropy-coded data can take.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct JpegScan {
    /// The byte after the first `SOS` segment.
    at: u64,
    /// One bit for each 8×8 block of each component of a Huffman-coded DCT frame (`SOF0`–`SOF2`): every
    /// block's DC difference is a Huffman code of at least one bit, in a baseline scan and in a
    /// progressive file's first DC scan alike (a baseline block takes two, with its end-of-block code).
    /// 0 for other frames (arithmetic coding, lossless) and a height left to a `DNL` marker.
    min_bytes: u64,
}

/// [`JpegScan::min_bytes`] of a frame header's body (`SOFn` after its length: precision, height, width,
/// components, then three bytes a component: id, sampling factors `H << 4 | V`, table).
fn frame_min_bytes(body: &[u8]) -> u64 {
    let Some((&[_, h1, h0, w1, w0, n], rest)) = body.split_first_chunk::<6>() else {
        return 0;
    };
    let (height, width) = (
        u64::from(u16::from_be_bytes([h1, h0])),
        u64::from(u16::from_be_bytes([w1, w0])),
    );
    let sampling: Vec<(u64, u64)> = (rest.chunks_exact(3).take(usize::from(n)))
        .map(|c| (u64::from(c[1] >> 4), u64::from(c[1] & 15)))
        .collect();
    let (hmax, vmax) = sampling
        .iter()
        .fold((0, 0), |(h, v), &(hc, vc)| (h.max(hc), v.max(vc)));
    if hmax == 0 || vmax == 0 || sampling.iter().any(|&(h, v)| h == 0 || v == 0) {
        return 0;
    }
    let blocks: u64 = (sampling.iter())
        .map(|&(h, v)| {
            (width * h).div_ceil(hmax).div_ceil(8) * (height * v).div_ceil(vmax).div_ceil(8)
        })
        .sum();
    blocks / 8
}

/// Where the JPEG in `reader` starts its first scan's entropy-coded data, and the fewest bytes that data
/// can take: the marker segments from `SOI` walked by their lengths up to `SOS`, the frame header read on
/// the way. `Ok(None)` where the file ends first (cut short in its headers); `Err` where its markers do
/// not parse as one image's segments (a second SOI, an EOI before any scan).
fn jpeg_scan_start<R: Read + Seek>(reader: &mut R) -> Result<Option<JpegScan>, String> {
    reader.seek(SeekFrom::Start(0)).map_err(|e| e.to_string())?;
    // The next two bytes, `None` at the end of the file.
    let read2 = |r: &mut R| -> Result<Option<[u8; 2]>, String> {
        let mut two = [0u8; 2];
        let n = read_up_to(r, &mut two).map_err(|e| e.to_string())?;
        Ok((n == 2).then_some(two))
    };
    if read2(reader)? != Some([0xFF, 0xD8]) {
        return Err("no SOI".into());
    }
    let mut at = 2u64;
    let mut min_bytes = 0;
    loop {
        let Some(two) = read2(reader)? else {
            return Ok(None);
        };
        if two[0] != 0xFF {
            return Err(format!("no marker at byte {at}"));
        }
        let marker = two[1];
        at += 2;
        // Fill bytes (0xFF 0xFF …) and markers without a length (TEM, RSTn).
        if marker == 0xFF {
            reader
                .seek(SeekFrom::Current(-1))
                .map_err(|e| e.to_string())?;
            at -= 1;
            continue;
        }
        if marker == 0x01 || (0xD0..=0xD7).contains(&marker) {
            continue;
        }
        if marker == 0xD8 || marker == 0xD9 {
            // A second SOI, or EOI before any scan (a tables-only file): not a plain image's segments.
            return Err(format!("marker {marker:#04x} at byte {at} before any scan"));
        }
        let Some(two) = read2(reader)? else {
            return Ok(None);
        };
        let length = u64::from(u16::from_be_bytes(two));
        if length < 2 {
            return Err(format!("segment length {length} at byte {at}"));
        }
        if matches!(marker, 0xC0..=0xC2) {
            let mut body = vec![0u8; (length - 2) as usize];
            let n = read_up_to(reader, &mut body).map_err(|e| e.to_string())?;
            min_bytes = frame_min_bytes(&body[..n]);
        }
        at += length;
        if marker == 0xDA {
            return Ok(Some(JpegScan { at, min_bytes }));
        }
        reader
            .seek(SeekFrom::Start(at))
            .map_err(|e| e.to_string())?;
    }
}

/// Where the last `n` bytes of `reader` start, and those bytes (all of it when shorter).
fn tail<R: Read + Seek>(reader: &mut R, n: u64) -> Result<(u64, Vec<u8>), String> {
    let len = reader.seek(SeekFrom::End(0)).map_err(|e| e.to_string())?;
    let start = len.saturating_sub(n);
    reader
        .seek(SeekFrom::Start(start))
        .map_err(|e| e.to_string())?;
    let mut tail = Vec::with_capacity((len - start) as usize);
    reader.read_to_end(&mut tail).map_err(|e| e.to_string())?;
    Ok((start, tail))
}

/// Whether the PNG in `reader` has its `IEND` chunk (type and CRC) in its last 64 KiB: a file cut short
/// has none, and its decode fails (the build then draws the magenta fallback).
fn png_ends_with_iend<R: Read + Seek>(reader: &mut R) -> Result<bool, String> {
    const IEND: [u8; 8] = [b'I', b'E', b'N', b'D', 0xAE, 0x42, 0x60, 0x82];
    // Bytes appended after IEND (a trailer) are searched past too, up to this many.
    const PNG_TAIL: u64 = 1 << 16;
    Ok(tail(reader, PNG_TAIL)?
        .1
        .windows(IEND.len())
        .any(|w| w == IEND))
}

const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

/// Reads as many bytes as are available up to `buf.len()`.
fn read_up_to<R: Read>(r: &mut R, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..])? {
            0 => break,
            k => n += k,
        }
    }
    Ok(n)
}

/// Parses the PNG signature, `IHDR` and the chunks up to the first `IDAT` (looking for `tRNS`).
fn read_png_header<R: Read + Seek>(mut r: R) -> Result<ImageHeader, String> {
    let mut sig = [0u8; 8];
    r.read_exact(&mut sig)
        .map_err(|e| format!("PNG signature: {e}"))?;
    let mut ihdr: Option<(u32, u32, u8, u8)> = None;
    let mut trns = false;
    loop {
        let mut head = [0u8; 8];
        r.read_exact(&mut head)
            .map_err(|e| format!("PNG chunk header: {e}"))?;
        let len = u32::from_be_bytes([head[0], head[1], head[2], head[3]]);
        let kind = [head[4], head[5], head[6], head[7]];
        if len > 0x7fff_ffff {
            return Err(format!("PNG chunk length {len} too large"));
        }
        match &kind {
            b"IHDR" => {
                if len != 13 {
                    return Err(format!("PNG IHDR length {len}, expected 13"));
                }
                let mut d = [0u8; 13];
                r.read_exact(&mut d).map_err(|e| format!("PNG IHDR: {e}"))?;
                let w = u32::from_be_bytes([d[0], d[1], d[2], d[3]]);
                let h = u32::from_be_bytes([d[4], d[5], d[6], d[7]]);
                ihdr = Some((w, h, d[8], d[9]));
                r.seek(SeekFrom::Current(4)).map_err(|e| e.to_string())?; // CRC
                continue;
            }
            b"tRNS" => trns = true,
            b"IDAT" | b"IEND" => break,
            _ => {}
        }
        if ihdr.is_none() {
            return Err("PNG: first chunk is not IHDR".into());
        }
        r.seek(SeekFrom::Current(i64::from(len) + 4))
            .map_err(|e| e.to_string())?;
    }
    let (width, height, depth, ctype) = ihdr.ok_or("PNG without IHDR")?;
    if width == 0 || height == 0 {
        return Err(format!("empty PNG {width}x{height}"));
    }
    let (base, alpha_channel) = match ctype {
        0 => ("L", false),
        2 => ("Rgb", false),
        3 => ("Palette", false),
        4 => ("La", true),
        6 => ("Rgba", true),
        other => return Err(format!("PNG colour type {other} invalid")),
    };
    let valid_depth = match ctype {
        0 => matches!(depth, 1 | 2 | 4 | 8 | 16),
        3 => matches!(depth, 1 | 2 | 4 | 8),
        _ => matches!(depth, 8 | 16),
    };
    if !valid_depth {
        return Err(format!(
            "PNG bit depth {depth} invalid for colour type {ctype}"
        ));
    }
    Ok(ImageHeader {
        width,
        height,
        has_alpha: alpha_channel || trns,
        color: format!("{base}{depth}"),
        truncated: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn is_opaque_finds_one_translucent_texel_anywhere() {
        let n = 3 * 4096 + 17;
        let mut img = DecodedImage {
            width: n as u32,
            height: 1,
            pixels: vec![[12, 34, 56, 255]; n],
        };
        assert!(img.is_opaque());
        for at in [0, 4095, 4096, n - 1] {
            for alpha in [0, 1, 127, 254] {
                img.pixels[at][3] = alpha;
                assert!(!img.is_opaque(), "alpha {alpha} at {at}");
                img.pixels[at][3] = 255;
            }
        }
        // Colour bytes of 255 do not make a translucent texel opaque.
        img.pixels[5] = [255, 255, 255, 254];
        assert!(!img.is_opaque());
        let empty = DecodedImage {
            width: 0,
            height: 0,
            pixels: vec![],
        };
        assert!(empty.is_opaque());
    }

    #[test]
    fn fallback_is_checker() {
        let img = ImageSource::fallback("x.png").decode().unwrap();
        assert_eq!((img.width, img.height), (8, 8));
        assert_eq!(img.pixels[0], FALLBACK_COLORS[0]);
        assert_eq!(img.pixels[1], FALLBACK_COLORS[1]);
        assert_eq!(img.pixels[8], FALLBACK_COLORS[1]);
        assert_eq!(img.pixels[9], FALLBACK_COLORS[0]);
    }

    #[test]
    fn solid_decodes_to_its_colour() {
        let s = ImageSource::solid([1, 2, 3, 4]);
        assert!(s.has_alpha);
        assert_eq!(s.decode().unwrap().pixels, vec![[1, 2, 3, 4]]);
    }

    fn png_bytes(img: image::DynamicImage) -> Vec<u8> {
        let mut out = std::io::Cursor::new(Vec::new());
        img.write_to(&mut out, image::ImageFormat::Png).unwrap();
        out.into_inner()
    }

    /// A PNG cut short keeps its header but loses its `IEND`: truncated (its decode fails); whole, or
    /// with bytes after `IEND`, it is not.
    #[test]
    fn a_png_cut_short_reads_as_truncated() {
        let img = image::RgbaImage::from_fn(64, 48, |x, y| image::Rgba([x as u8, y as u8, 7, 255]));
        let png = png_bytes(image::DynamicImage::ImageRgba8(img));
        let header = |bytes: &[u8]| read_header(std::io::Cursor::new(bytes)).unwrap();
        assert!(!header(&png).truncated);
        let mut padded = png.clone();
        padded.extend_from_slice(&[0u8; 100]);
        assert!(!header(&padded).truncated);
        for cut in [png.len() - 1, png.len() / 2] {
            let h = header(&png[..cut]);
            assert_eq!(
                (h.width, h.height, h.truncated),
                (64, 48, true),
                "cut at {cut}"
            );
        }
    }

    #[test]
    fn a_jpeg_cut_short_reads_as_truncated_and_padding_after_its_end_does_not() {
        // Noisy, so the scan data (where a cut lands) is most of the file.
        let img = image::RgbImage::from_fn(256, 192, |x, y| {
            let h = (x.wrapping_mul(2_654_435_761) ^ y.wrapping_mul(40_503)).rotate_left(x % 13);
            image::Rgb([h as u8, (h >> 8) as u8, (h >> 16) as u8])
        });
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new(&mut jpeg)
            .encode_image(&img)
            .unwrap();
        let header = |bytes: &[u8]| read_header(std::io::Cursor::new(bytes)).unwrap();
        let whole = header(&jpeg);
        assert_eq!(
            (whole.width, whole.height, whole.truncated),
            (256, 192, false)
        );
        let mut padded = jpeg.clone();
        padded.extend_from_slice(&[0u8; 100]);
        assert!(!header(&padded).truncated);
        for cut in [jpeg.len() - 2, jpeg.len() / 2] {
            let h = header(&jpeg[..cut]);
            assert!(h.truncated, "cut at {cut} of {}", jpeg.len());
            assert_eq!(
                (h.width, h.height),
                (256, 192),
                "the header itself is intact"
            );
        }
        // An APP1 segment (an EXIF thumbnail) ending in an end-of-image marker, after SOI: the file cut
        // a little into its scan still reads as truncated (the thumbnail's marker was taken as the
        // file's), and whole as not.
        let mut app1 = vec![0xFF, 0xE1, 0x00, 0x08, b'E', b'x', 0xFF, 0xD8, 0xFF, 0xD9];
        app1[3] = (app1.len() - 2) as u8;
        let with_thumb = [&jpeg[..2], &app1[..], &jpeg[2..]].concat();
        assert!(!header(&with_thumb).truncated);
        let cut = 3000; // past the headers, the thumbnail within the last 4 KiB
        assert!(header(&with_thumb[..cut]).truncated);
        // Cut inside the headers: no scan to start.
        assert_eq!(
            jpeg_scan_start(&mut std::io::Cursor::new(&with_thumb[..8])),
            Ok(None)
        );
    }

    /// A decode's peak counts the RGBA8 copy beside the decoder's buffer, except where that is RGBA8
    /// already, and a JPEG's coefficients: a 35000² grey JPEG holds 1.2 GB decoded and 4.9 GB more
    /// converted; a tiny file claiming that size is refused before any of it is allocated.
    #[test]
    fn a_decodes_peak_counts_its_rgba8_copy() {
        use image::ColorType;
        let (w, h) = (35_000, 35_000);
        let texels = 35_000u64 * 35_000;
        assert_eq!(decode_peak(w, h, ColorType::L8, texels, false), texels * 5);
        assert_eq!(
            decode_peak(w, h, ColorType::Rgb8, 3 * texels, true),
            texels * 9
        );
        assert_eq!(
            decode_peak(w, h, ColorType::Rgba8, 4 * texels, false),
            texels * 4
        );
        assert_eq!(
            decode_peak(w, h, ColorType::Rgba16, 8 * texels, false),
            texels * 12
        );
        // A 16² grey JPEG whose frame header claims 35000²: its decoder's 1.2 GB fit 2 GiB, its RGBA8
        // copy beside them does not: refused, naming the need.
        let mut jpeg = Vec::new();
        let img = image::GrayImage::from_fn(16, 16, |x, y| image::Luma([(x * 16 + y) as u8]));
        image::codecs::jpeg::JpegEncoder::new(&mut jpeg)
            .encode_image(&img)
            .unwrap();
        let sof = jpeg.windows(2).position(|m| m == [0xFF, 0xC0]).unwrap();
        // SOF0: marker, length (2), precision (1), height (2), width (2).
        jpeg[sof + 5..sof + 9].copy_from_slice(&[0x88, 0xB8, 0x88, 0xB8]);
        let cursor = std::io::Cursor::new(&jpeg[..]);
        let e = decode_encoded_within(cursor, "bomb.jpg", 2 << 30).unwrap_err();
        assert!(e.to_string().contains("35000×35000 takes"), "{e}");
    }

    /// A frame header claiming more blocks than the data after the scan starts can code (one bit each)
    /// reads as truncated: a 64×48 JPEG patched to claim 4096×4096 decoded as one flat colour without a
    /// warning (fault hunt, session 35). The bound is below what any whole file takes: a flat 2048² grey,
    /// the least data a baseline file of that size holds, reads as whole, and so do a grey and a
    /// subsampled colour file.
    #[test]
    fn a_jpeg_frame_claiming_more_than_its_data_reads_as_truncated() {
        let encode = |img: image::DynamicImage| {
            let mut jpeg = Vec::new();
            image::codecs::jpeg::JpegEncoder::new(&mut jpeg)
                .encode_image(&img)
                .unwrap();
            jpeg
        };
        let header = |bytes: &[u8]| read_header(std::io::Cursor::new(bytes)).unwrap();
        let noisy = image::RgbImage::from_fn(64, 48, |x, y| {
            let h = (x.wrapping_mul(2_654_435_761) ^ y.wrapping_mul(40_503)).rotate_left(x % 13);
            image::Rgb([h as u8, (h >> 8) as u8, (h >> 16) as u8])
        });
        let mut jpeg = encode(noisy.into());
        assert!(!header(&jpeg).truncated);
        let sof = jpeg.windows(2).position(|m| m == [0xFF, 0xC0]).unwrap();
        // SOF0: marker, length (2), precision (1), height (2), width (2).
        jpeg[sof + 5..sof + 9].copy_from_slice(&[0x10, 0x00, 0x10, 0x00]);
        let claimed = header(&jpeg);
        assert_eq!(
            (claimed.width, claimed.height, claimed.truncated),
            (4096, 4096, true)
        );
        let flat = image::RgbImage::from_pixel(2048, 2048, image::Rgb([128, 128, 128]));
        let flat = encode(flat.into());
        let scan = jpeg_scan_start(&mut std::io::Cursor::new(&flat))
            .unwrap()
            .unwrap();
        assert!(scan.min_bytes > 0 && scan.min_bytes <= flat.len() as u64 - scan.at);
        assert!(!header(&flat).truncated);
        let grey = image::GrayImage::from_pixel(1024, 512, image::Luma([7]));
        assert!(!header(&encode(grey.into())).truncated);
    }

    /// The segment walker steps over fill bytes and markers without a length (RSTn, TEM), and takes a
    /// second SOI, or an EOI before any scan, as no plain image's segments.
    #[test]
    fn the_jpeg_walker_steps_over_fill_bytes_and_lengthless_markers() {
        let walk = |bytes: &[u8]| jpeg_scan_start(&mut std::io::Cursor::new(bytes));
        // SOI, fill, TEM, RST3, COM (length 4: 2 bytes), SOS (length 3: 1 byte), then data.
        let file = [
            0xFF, 0xD8, 0xFF, 0xFF, 0x01, 0xFF, 0xD3, 0xFF, 0xFE, 0x00, 0x04, 0xFF, 0xD9, 0xFF,
            0xDA, 0x00, 0x03, 0x00, 0x11,
        ];
        assert_eq!(
            walk(&file),
            Ok(Some(JpegScan {
                at: 18,
                min_bytes: 0
            }))
        );
        assert_eq!(walk(&file[..16]), Ok(None));
        assert!(walk(&[0xFF, 0xD8, 0xFF, 0xD8, 0xFF, 0xDA, 0, 2]).is_err());
        assert!(walk(&[0xFF, 0xD8, 0xFF, 0xD9]).is_err());
    }

    #[test]
    fn png_header_and_16_bit_rounding() {
        let mut img = image::ImageBuffer::<image::Rgb<u16>, _>::new(3, 2);
        img.put_pixel(0, 0, image::Rgb([0, 128, 65535]));
        img.put_pixel(1, 0, image::Rgb([257 * 7 + 129, 257 * 7 + 128, 256]));
        let bytes = png_bytes(image::DynamicImage::ImageRgb16(img));
        let h = read_header(std::io::Cursor::new(&bytes[..])).unwrap();
        assert_eq!(
            h,
            ImageHeader {
                width: 3,
                height: 2,
                has_alpha: false,
                color: "Rgb16".into(),
                truncated: false,
            }
        );
        let src = ImageSource {
            name: "t".into(),
            width: 3,
            height: 2,
            has_alpha: false,
            color: h.color,
            data: ImageData::Bytes(bytes.into()),
            gltf_image: None,
        };
        let d = src.decode().unwrap();
        // (v + 128) / 257 = round(v / 257): 0 → 0, 128 → 0, 65535 → 255, 257·7+129 → 8, 257·7+128 → 7,
        // 256 → 1.
        assert_eq!(d.pixels[0], [0, 0, 255, 255]);
        assert_eq!(d.pixels[1], [8, 7, 1, 255]);
    }

    #[test]
    fn header_of_garbage_is_an_error() {
        assert!(read_header(std::io::Cursor::new(&b"not an image at all"[..])).is_err());
        let mut trunc = PNG_SIGNATURE.to_vec();
        trunc.extend_from_slice(&[0, 0, 0, 13, b'I', b'H']);
        assert!(read_header(std::io::Cursor::new(&trunc[..])).is_err());
    }
}
