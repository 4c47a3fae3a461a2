//! Decoding of JPEG (baseline, progressive), PNG, TIFF and BMP to Rec. 601 luminance, and
//! the typed errors of bad input (`vgps::imaging::formats`).
use image::{ImageEncoder, Luma, Rgb};
use std::path::Path;
use vgps::imaging::formats::{jpeg_frame_header, scale16, to_luma8};
use vgps::imaging::{DecodeLimits, ImageFormat, ImagingError, decode_image, read_image};

fn limits() -> DecodeLimits {
    DecodeLimits::default()
}

/// The test gradient of `tests/data/night/progressive_64x48.jpg`.
fn gradient() -> image::RgbImage {
    image::RgbImage::from_fn(64, 48, |x, y| {
        Rgb([
            (x * 4 % 256) as u8,
            (y * 5 % 256) as u8,
            ((x + y) * 2 % 256) as u8,
        ])
    })
}

fn rec601(p: &Rgb<u8>) -> f64 {
    0.299 * f64::from(p[0]) + 0.587 * f64::from(p[1]) + 0.114 * f64::from(p[2])
}

fn jpeg(image: &image::RgbImage, quality: u8) -> Vec<u8> {
    let mut bytes = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, quality)
        .encode_image(image)
        .expect("encode");
    bytes
}

/// Mean absolute difference between a decoded luminance and the Rec. 601 luma of `rgb`.
fn mean_error(grey: &image::GrayImage, rgb: &image::RgbImage) -> f64 {
    assert_eq!(grey.dimensions(), rgb.dimensions());
    grey.pixels()
        .zip(rgb.pixels())
        .map(|(g, p)| (f64::from(g[0]) - rec601(p)).abs())
        .sum::<f64>()
        / f64::from(grey.width() * grey.height())
}

#[test]
fn baseline_colour_jpeg_decodes_to_rec601_luma() {
    let rgb = gradient();
    let bytes = jpeg(&rgb, 95);
    assert_eq!(jpeg_frame_header(&bytes).map(|h| h.marker), Some(0xC0));
    let grey = decode_image(&bytes, &limits()).expect("decode");
    let error = mean_error(&grey, &rgb);
    assert!(error < 2.0, "mean |Y − Rec.601| = {error} DN");
    // Rec. 709 weights would be off by far more on this gradient (a wrong-weights check).
    let rec709: f64 = rgb
        .pixels()
        .zip(grey.pixels())
        .map(|(p, g)| {
            let y = 0.2126 * f64::from(p[0]) + 0.7152 * f64::from(p[1]) + 0.0722 * f64::from(p[2]);
            (y - f64::from(g[0])).abs()
        })
        .sum::<f64>()
        / (64.0 * 48.0);
    assert!(rec709 > 2.0 * error, "709 {rec709} vs 601 {error}");
}

/// The luma-only JPEG path (the Y plane, no chroma upsampling or colour conversion) equals
/// the full colour decode (the `image` crate's RGB) converted with the documented Rec. 601
/// weights within ±1 DN wherever no RGB channel clips at 0 or 255 (there the colour
/// decode loses what the Y plane keeps): the rounding of R, G and B and of the weights.
#[test]
fn luma_only_jpeg_decode_equals_the_colour_decode_converted() {
    // Mid-range colours (no clipping) with edges and a gradient, 4:2:0 chroma at quality 90.
    let rgb = image::RgbImage::from_fn(96, 64, |x, y| {
        let block = if (x / 16 + y / 16) % 2 == 0 { 40 } else { 0 };
        Rgb([
            (60 + x + block) as u8,
            (70 + 2 * y) as u8,
            (150 - x / 2 + block / 2) as u8,
        ])
    });
    for (picture, quality) in [(&rgb, 90u8), (&rgb, 60), (&gradient(), 95)] {
        let bytes = jpeg(picture, quality);
        let luma = decode_image(&bytes, &limits()).expect("luma decode");
        let colour = image::load_from_memory_with_format(&bytes, image::ImageFormat::Jpeg)
            .expect("colour decode")
            .to_rgb8();
        let converted = to_luma8(&image::DynamicImage::ImageRgb8(colour.clone()));
        let (mut compared, mut largest) = (0, 0i32);
        for ((y, c), p) in luma.pixels().zip(converted.pixels()).zip(colour.pixels()) {
            if p.0.iter().any(|&v| v == 0 || v == 255) {
                continue;
            }
            compared += 1;
            largest = largest.max((i32::from(y[0]) - i32::from(c[0])).abs());
        }
        assert!(compared > 1000, "{compared} pixels compared");
        assert!(largest <= 1, "quality {quality}: max |ΔDN| = {largest}");
    }
}

#[test]
fn progressive_jpeg_decodes() {
    let path = Path::new("tests/data/night/progressive_64x48.jpg");
    let bytes = std::fs::read(path).expect("test data");
    assert_eq!(jpeg_frame_header(&bytes).map(|h| h.marker), Some(0xC2));
    let grey = read_image(path, &limits()).expect("decode");
    let error = mean_error(&grey, &gradient());
    assert!(error < 2.0, "mean |Y − Rec.601| = {error} DN");
}

#[test]
fn grey_jpeg_round_trips_closely() {
    let grey = image::GrayImage::from_fn(40, 30, |x, y| Luma([(x * 6 + y) as u8]));
    let mut bytes = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 100)
        .encode_image(&grey)
        .expect("encode");
    assert_eq!(jpeg_frame_header(&bytes).map(|h| h.components), Some(1));
    let back = decode_image(&bytes, &limits()).expect("decode");
    let worst = back
        .pixels()
        .zip(grey.pixels())
        .map(|(a, b)| a[0].abs_diff(b[0]))
        .max();
    assert!(worst <= Some(2), "{worst:?}");
}

#[test]
fn png_tiff_bmp_give_the_same_luminance() {
    let rgb = gradient();
    let expected: Vec<u8> = rgb
        .pixels()
        .map(|p| {
            ((77 * u32::from(p[0]) + 150 * u32::from(p[1]) + 29 * u32::from(p[2]) + 128) >> 8) as u8
        })
        .collect();
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(rgb.as_raw(), 64, 48, image::ExtendedColorType::Rgb8)
        .expect("png");
    let mut tiff = std::io::Cursor::new(Vec::new());
    image::codecs::tiff::TiffEncoder::new(&mut tiff)
        .write_image(rgb.as_raw(), 64, 48, image::ExtendedColorType::Rgb8)
        .expect("tiff");
    let mut bmp = Vec::new();
    image::codecs::bmp::BmpEncoder::new(&mut bmp)
        .write_image(rgb.as_raw(), 64, 48, image::ExtendedColorType::Rgb8)
        .expect("bmp");
    for (name, bytes) in [("png", png), ("tiff", tiff.into_inner()), ("bmp", bmp)] {
        let grey = decode_image(&bytes, &limits()).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(grey.as_raw(), &expected, "{name}");
    }
}

#[test]
fn sixteen_bit_png_and_tiff_are_scaled_not_truncated() {
    // 0x00FF and 0x01FE: their high bytes are 0 and 1, the scaled values
    // round(255 · 255 / 65535) = 1 and round(510 · 255 / 65535) = 2.
    let values = [0u16, 0x00FF, 0x01FE, 0x80FF, 0xFFFF, 65000];
    let expected: Vec<u8> = values.iter().map(|&v| scale16(v)).collect();
    assert_eq!(expected, [0, 1, 2, 128, 255, 253]);
    let raw: Vec<u8> = values.iter().flat_map(|v| v.to_ne_bytes()).collect();
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(&raw, 3, 2, image::ExtendedColorType::L16)
        .expect("png");
    let mut tiff = std::io::Cursor::new(Vec::new());
    image::codecs::tiff::TiffEncoder::new(&mut tiff)
        .write_image(&raw, 3, 2, image::ExtendedColorType::L16)
        .expect("tiff");
    for (name, bytes) in [("png", png), ("tiff", tiff.into_inner())] {
        let grey = decode_image(&bytes, &limits()).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(grey.as_raw(), &expected, "{name}");
    }
    // 16-bit colour: Rec. 601 luma of the 16-bit values, then scaled.
    let rgb16: Vec<u8> = [0xFFFFu16, 0, 0]
        .iter()
        .flat_map(|v| v.to_ne_bytes())
        .collect();
    let mut tiff = std::io::Cursor::new(Vec::new());
    image::codecs::tiff::TiffEncoder::new(&mut tiff)
        .write_image(&rgb16, 1, 1, image::ExtendedColorType::Rgb16)
        .expect("tiff");
    let grey = decode_image(&tiff.into_inner(), &limits()).expect("decode");
    assert_eq!(grey.as_raw(), &[76]); // 0.299 · 255 = 76.2
}

#[test]
fn real_photo_decodes_with_its_size() {
    let grey = read_image(
        Path::new("tests/data/night/unsplash_street_lamps.jpg"),
        &limits(),
    )
    .expect("decode");
    assert_eq!(grey.dimensions(), (1334, 2000));
    // The night sky at the top is dark, a labelled lamp head (142, 934) is saturated.
    assert!(grey.get_pixel(600, 100)[0] < 30);
    assert_eq!(grey.get_pixel(142, 934)[0], 255);
}

/// Replaces the JPEG frame header's fields (precision, height, width, components).
fn patch_sof(
    bytes: &mut [u8],
    precision: Option<u8>,
    size: Option<(u16, u16)>,
    components: Option<u8>,
) {
    let at = (2..bytes.len() - 1)
        .find(|&i| bytes[i] == 0xFF && bytes[i + 1] == 0xC0)
        .expect("SOF0");
    if let Some(p) = precision {
        bytes[at + 4] = p;
    }
    if let Some((w, h)) = size {
        bytes[at + 5..at + 7].copy_from_slice(&h.to_be_bytes());
        bytes[at + 7..at + 9].copy_from_slice(&w.to_be_bytes());
    }
    if let Some(c) = components {
        bytes[at + 9] = c;
    }
}

#[test]
fn bad_jpegs_are_typed_errors() {
    let good = jpeg(&gradient(), 90);
    // Truncated: strict decoding refuses to fill the missing rows with grey.
    for cut in [good.len() - 40, good.len() / 2, 300, 20, 3] {
        let r = decode_image(&good[..cut], &limits());
        assert!(
            matches!(r, Err(ImagingError::Corrupt { format: "JPEG", .. })),
            "cut {cut}: {r:?}"
        );
    }
    // 12-bit samples.
    let mut b = good.clone();
    patch_sof(&mut b, Some(12), None, None);
    let e = decode_image(&b, &limits()).expect_err("12 bit");
    assert!(
        matches!(e, ImagingError::Unsupported { .. }) && e.to_string().contains("12-bit"),
        "{e}"
    );
    // CMYK (four components).
    let mut b = good.clone();
    patch_sof(&mut b, None, None, Some(4));
    let e = decode_image(&b, &limits()).expect_err("cmyk");
    assert!(
        matches!(e, ImagingError::Unsupported { .. }) && e.to_string().contains("CMYK"),
        "{e}"
    );
    // A header claiming 65535 × 65535 = 4.3·10⁹ pixels: refused from the header.
    let mut b = good.clone();
    patch_sof(&mut b, None, Some((65535, 65535)), None);
    let e = decode_image(&b, &limits()).expect_err("huge");
    assert!(
        matches!(
            e,
            ImagingError::TooLarge {
                width: 65535,
                height: 65535,
                ..
            }
        ),
        "{e}"
    );
    // Errors name the file.
    let dir = tempfile::tempdir().expect("tmp");
    let path = dir.path().join("cam3_000042.jpg");
    std::fs::write(&path, &good[..good.len() / 2]).expect("write");
    let e = read_image(&path, &limits()).expect_err("truncated");
    assert!(e.to_string().contains("cam3_000042.jpg"), "{e}");
    // Unknown formats.
    assert!(matches!(
        decode_image(b"GIF89a\x01\x00\x01\x00", &limits()),
        Err(ImagingError::NotAnImage { .. })
    ));
    assert_eq!(ImageFormat::sniff(&good), Some(ImageFormat::Jpeg));
}

/// Sets the value of TIFF tag `tag` (a SHORT or LONG in its entry) in a little-endian TIFF.
fn patch_tiff_tag(bytes: &mut [u8], tag: u16, value: u32) {
    assert_eq!(&bytes[..4], b"II*\0");
    let ifd = u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]) as usize;
    let n = u16::from_le_bytes([bytes[ifd], bytes[ifd + 1]]) as usize;
    for k in 0..n {
        let e = ifd + 2 + 12 * k;
        if u16::from_le_bytes([bytes[e], bytes[e + 1]]) == tag {
            let kind = u16::from_le_bytes([bytes[e + 2], bytes[e + 3]]);
            if kind == 3 {
                bytes[e + 8..e + 10].copy_from_slice(&(value as u16).to_le_bytes());
            } else {
                bytes[e + 8..e + 12].copy_from_slice(&value.to_le_bytes());
            }
            return;
        }
    }
    panic!("tag {tag} not found");
}

#[test]
fn bad_tiffs_are_typed_errors() {
    let grey = image::GrayImage::from_fn(32, 16, |x, y| Luma([(x + y) as u8]));
    let mut tiff = std::io::Cursor::new(Vec::new());
    image::codecs::tiff::TiffEncoder::new(&mut tiff)
        .write_image(grey.as_raw(), 32, 16, image::ExtendedColorType::L8)
        .expect("tiff");
    let good = tiff.into_inner();
    assert_eq!(decode_image(&good, &limits()).expect("decode"), grey);
    // Compression 34712 (JPEG 2000): not a compression the codec has.
    let mut b = good.clone();
    patch_tiff_tag(&mut b, 259, 34712);
    let e = decode_image(&b, &limits()).expect_err("compression");
    assert!(
        matches!(e, ImagingError::Unsupported { format: "TIFF", .. }),
        "{e}"
    );
    // A header claiming 65536 × 65536 pixels.
    let mut b = good.clone();
    patch_tiff_tag(&mut b, 256, 65000);
    patch_tiff_tag(&mut b, 257, 65000);
    let e = decode_image(&b, &limits()).expect_err("huge");
    assert!(
        matches!(
            e,
            ImagingError::TooLarge {
                width: 65000,
                height: 65000,
                ..
            }
        ),
        "{e}"
    );
    // Truncated.
    let e = decode_image(&good[..good.len() / 2], &limits()).expect_err("truncated");
    assert!(
        matches!(e, ImagingError::Corrupt { format: "TIFF", .. }),
        "{e}"
    );
}

#[test]
fn mutated_images_never_panic() {
    // A fast smoke test; the fuzz bodies run the same code over a large corpus
    // (`vgps::fuzzing::image_decode`, docs/fuzzing.md).
    let seeds = [
        jpeg(&gradient(), 80),
        std::fs::read("tests/data/night/progressive_64x48.jpg").expect("data"),
    ];
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for seed in &seeds {
        for _ in 0..300 {
            let mut b = seed.clone();
            for _ in 0..1 + next() % 6 {
                let i = (next() % b.len() as u64) as usize;
                b[i] = next() as u8;
            }
            if let Ok(image) = decode_image(&b, &limits()) {
                assert!(image.width() <= 8192 && image.height() <= 8192);
            }
        }
    }
}
