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
    /// blocks take (a frame header claiming more than the data covers), or a PNG without its `IEND`
    /// chunk (its decode fails), reported by the import as a warning.
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
                let file = crate::util::open_regular(path).map_err(|e| {
                    match SceneError::unless_out_of_descriptors(path, e) {
                        Ok(e) => SceneError::ImageDecode {
                            image: self.name.clone(),
                            reason: format!("{}: {e}", path.display()),
                        },
                        Err(limit) => limit,
                    }
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
/// short after it read as whole (fault hunt, session 35), and a frame header claiming more texels than
/// the data covers drew one flat colour without a warning (session 35, mended in 36). A file whose
/// segments do not lead to a scan is cut short; one whose markers do not parse is searched whole, as
/// before. Files with a longer trailer after it (e.g. a motion photo's video) read as truncated: a
/// warning only.
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
mod tests;
