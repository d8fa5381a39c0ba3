//! Unit tests of [`super`] (`image_source.rs`).

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
/// warning (fault hunt, session 35). The bound (one bit a block) is half what a baseline block takes at
/// least (a DC and an end-of-block code): a flat 2048² colour file and a flat grey one read as whole.
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
        0xFF, 0xD8, 0xFF, 0xFF, 0x01, 0xFF, 0xD3, 0xFF, 0xFE, 0x00, 0x04, 0xFF, 0xD9, 0xFF, 0xDA,
        0x00, 0x03, 0x00, 0x11,
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
