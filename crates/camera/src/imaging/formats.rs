//! Decoding of camera frames in any of the formats cameras and datasets write — JPEG
//! (baseline and progressive), PNG (8 and 16 bit), TIFF (8 and 16 bit), BMP — to the 8-bit
//! luminance the lamp detector reads, within [`DecodeLimits`].
//!
//! # Luminance
//! Colour is converted with the **Rec. 601** luma weights `Y = 0.299 R + 0.587 G + 0.114 B`
//! on the stored (gamma-encoded) values: the weights JFIF defines for a JPEG's Y channel, so
//! a colour JPEG's luminance is its decoded Y plane (no chroma is decoded at all) and a PNG,
//! TIFF or BMP of the same picture gives the same grey levels. Alpha is ignored. 16-bit
//! samples are **scaled** to 8 bits, `round(v · 255 / 65535)`, not truncated to their high
//! byte; 32-bit float samples are clamped to `[0, 1]` and scaled by 255.
//!
//! # Decoders
//! JPEG goes to `zune-jpeg` directly, asking for its luma output (the fastest path measured:
//! `docs/dev/journal.md`); PNG, TIFF and BMP go through the `image` crate's codecs.
//!
//! # Limits and errors
//! The format is told from the file's first bytes, not its name. The dimensions are read from
//! the header (a JPEG's start-of-frame, parsed here) and checked against [`DecodeLimits`]
//! *before* the pixels are decoded, so a header claiming 65535 × 65535 pixels (4.3·10⁹) is a
//! [`ImagingError::TooLarge`] without any large allocation. A JPEG that is truncated or
//! corrupt is an error (the decoder runs in strict mode: no grey fill of missing data);
//! a CMYK/YCCK, 12-bit, lossless or arithmetic-coded JPEG and a TIFF with a compression the
//! codec lacks are [`ImagingError::Unsupported`]. Every error names the file; nothing panics.

use super::ImagingError;
use super::decode::{DecodeLimits, decode_png};
use image::{DynamicImage, GrayImage, ImageDecoder};
use std::io::Cursor;
use std::path::Path;
use zune_jpeg::JpegDecoder;
use zune_jpeg::zune_core::bytestream::ZCursor;
use zune_jpeg::zune_core::colorspace::ColorSpace;
use zune_jpeg::zune_core::options::DecoderOptions;

/// Name used in errors for in-memory data.
const MEMORY: &str = "<memory>";

/// Rec. 601 luma weights of R, G, B in 1/256 (77 + 150 + 29 = 256).
const LUMA601_8: [u32; 3] = [77, 150, 29];

/// Rec. 601 luma weights of R, G, B in 1/65536 (19595 + 38470 + 7471 = 65536).
const LUMA601_16: [u64; 3] = [19595, 38470, 7471];

/// Largest JPEG dimension (the start-of-frame fields are 16 bits).
const JPEG_MAX_SIDE: usize = u16::MAX as usize;

/// An image file format [`decode_image`] reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ImageFormat {
    /// PNG, 8 or 16 bit, any colour type.
    Png,
    /// JPEG (JFIF/EXIF), baseline or progressive, 8-bit, grey or YCbCr.
    Jpeg,
    /// TIFF, 8 or 16 bit, uncompressed, LZW, Deflate or PackBits.
    Tiff,
    /// Windows bitmap.
    Bmp,
}

impl ImageFormat {
    /// The format's name as used in messages (`PNG`, `JPEG`, `TIFF`, `BMP`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Png => "PNG",
            Self::Jpeg => "JPEG",
            Self::Tiff => "TIFF",
            Self::Bmp => "BMP",
        }
    }

    /// The format of `bytes`, from its signature; `None` for anything else.
    ///
    /// ```
    /// use vgps_camera::imaging::ImageFormat;
    /// assert_eq!(ImageFormat::sniff(&[0xFF, 0xD8, 0xFF, 0xE0]), Some(ImageFormat::Jpeg));
    /// assert_eq!(ImageFormat::sniff(b"II*\0"), Some(ImageFormat::Tiff));
    /// assert_eq!(ImageFormat::sniff(b"GIF89a"), None);
    /// ```
    pub fn sniff(bytes: &[u8]) -> Option<Self> {
        if bytes.starts_with(&[0x89, b'P', b'N', b'G']) {
            Some(Self::Png)
        } else if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
            Some(Self::Jpeg)
        } else if bytes.starts_with(b"II*\0") || bytes.starts_with(b"MM\0*") {
            Some(Self::Tiff)
        } else if bytes.starts_with(b"BM") {
            Some(Self::Bmp)
        } else {
            None
        }
    }
}

/// Decodes an image of any supported format ([`ImageFormat`]) to 8-bit luminance (see the
/// [module docs](self) for the weights and the limits). Errors name `<memory>`.
///
/// # Example
/// ```
/// use vgps_camera::imaging::{DecodeLimits, ImagingError, decode_image};
/// let grey = image::GrayImage::from_fn(16, 8, |x, y| image::Luma([(x * 16 + y) as u8]));
/// let mut jpeg = Vec::new();
/// image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 95).encode_image(&grey)
///     .map_err(|e| ImagingError::Encode { message: e.to_string() })?;
/// let back = decode_image(&jpeg, &DecodeLimits::default())?;
/// assert_eq!(back.dimensions(), (16, 8));
/// assert!(back.as_raw().iter().zip(grey.as_raw()).all(|(a, b)| a.abs_diff(*b) <= 3));
/// assert!(matches!(decode_image(b"GIF89a..", &DecodeLimits::default()),
///     Err(ImagingError::NotAnImage { .. })));
/// # Ok::<(), ImagingError>(())
/// ```
pub fn decode_image(bytes: &[u8], limits: &DecodeLimits) -> Result<GrayImage, ImagingError> {
    decode_image_named(bytes, limits, Path::new(MEMORY))
}

/// Reads and decodes an image file of any supported format (see [`decode_image`]); errors
/// name the file.
pub fn read_image(path: &Path, limits: &DecodeLimits) -> Result<GrayImage, ImagingError> {
    let bytes = std::fs::read(path).map_err(|source| ImagingError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    decode_image_named(&bytes, limits, path)
}

/// [`decode_image`] with errors naming `path`.
pub fn decode_image_named(
    bytes: &[u8],
    limits: &DecodeLimits,
    path: &Path,
) -> Result<GrayImage, ImagingError> {
    match ImageFormat::sniff(bytes) {
        Some(ImageFormat::Png) => decode_png(bytes, limits).map_err(|e| rename(e, path)),
        Some(ImageFormat::Jpeg) => decode_jpeg(bytes, limits, path),
        Some(format @ (ImageFormat::Tiff | ImageFormat::Bmp)) => {
            decode_with_image(bytes, limits, path, format)
        }
        None => Err(ImagingError::NotAnImage {
            path: path.to_path_buf(),
        }),
    }
}

/// Replaces `<memory>` in an error of [`decode_png`] by `path`.
fn rename(error: ImagingError, path: &Path) -> ImagingError {
    let p = path.to_path_buf();
    match error {
        ImagingError::NotPng { .. } => ImagingError::NotPng { path: p },
        ImagingError::TooLarge {
            width,
            height,
            max_width,
            max_height,
            max_bytes,
            ..
        } => ImagingError::TooLarge {
            path: p,
            width,
            height,
            max_width,
            max_height,
            max_bytes,
        },
        ImagingError::Decode { message, .. } => ImagingError::Decode { path: p, message },
        other => other,
    }
}

fn too_large(path: &Path, width: u64, height: u64, limits: &DecodeLimits) -> ImagingError {
    ImagingError::TooLarge {
        path: path.to_path_buf(),
        width: u32::try_from(width).unwrap_or(u32::MAX),
        height: u32::try_from(height).unwrap_or(u32::MAX),
        max_width: limits.max_width,
        max_height: limits.max_height,
        max_bytes: limits.max_bytes,
    }
}

fn check_limits(
    path: &Path,
    width: u64,
    height: u64,
    limits: &DecodeLimits,
) -> Result<(), ImagingError> {
    if width > u64::from(limits.max_width)
        || height > u64::from(limits.max_height)
        || width.saturating_mul(height) > limits.max_bytes
    {
        Err(too_large(path, width, height, limits))
    } else {
        Ok(())
    }
}

fn unsupported(path: &Path, format: ImageFormat, message: impl Into<String>) -> ImagingError {
    ImagingError::Unsupported {
        path: path.to_path_buf(),
        format: format.name(),
        message: message.into(),
    }
}

fn corrupt(path: &Path, format: ImageFormat, message: impl Into<String>) -> ImagingError {
    ImagingError::Corrupt {
        path: path.to_path_buf(),
        format: format.name(),
        message: message.into(),
    }
}

/// What a JPEG's start-of-frame segment declares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct JpegFrameHeader {
    /// The SOF marker's low byte (`0xC0` baseline, `0xC1` extended, `0xC2` progressive, …).
    pub marker: u8,
    /// Bits per sample (8 or 12; 16 for lossless).
    pub precision: u8,
    /// Width (pixels).
    pub width: u16,
    /// Height (pixels; 0 = defined later by a DNL marker).
    pub height: u16,
    /// Number of colour components (1 grey, 3 YCbCr/RGB, 4 CMYK/YCCK).
    pub components: u8,
}

/// Finds and reads a JPEG's start-of-frame segment by walking its marker segments;
/// `None` when the data ends (or is malformed) before one.
///
/// ```
/// use vgps_camera::imaging::formats::jpeg_frame_header;
/// // SOI, then a baseline SOF0: 8 bit, 768 rows, 1024 columns, 3 components.
/// let bytes = [0xFF, 0xD8, 0xFF, 0xC0, 0, 17, 8, 3, 0, 4, 0, 3];
/// let h = jpeg_frame_header(&bytes).unwrap();
/// assert_eq!((h.marker, h.precision, h.width, h.height, h.components), (0xC0, 8, 1024, 768, 3));
/// ```
pub fn jpeg_frame_header(bytes: &[u8]) -> Option<JpegFrameHeader> {
    let mut at = 2; // after SOI
    loop {
        // A marker: one or more 0xFF fill bytes, then the code.
        if *bytes.get(at)? != 0xFF {
            return None;
        }
        while *bytes.get(at)? == 0xFF {
            at += 1;
        }
        let code = *bytes.get(at)?;
        at += 1;
        match code {
            // Standalone markers: RSTn, TEM.
            0xD0..=0xD7 | 0x01 => continue,
            // End of image or a scan before any frame header.
            0xD9 | 0xDA => return None,
            _ => {}
        }
        let length = usize::from(u16::from_be_bytes([*bytes.get(at)?, *bytes.get(at + 1)?]));
        let is_sof = matches!(code, 0xC0..=0xCF) && !matches!(code, 0xC4 | 0xC8 | 0xCC);
        if is_sof {
            let field = |i: usize| bytes.get(at + i).copied();
            return Some(JpegFrameHeader {
                marker: code,
                precision: field(2)?,
                height: u16::from_be_bytes([field(3)?, field(4)?]),
                width: u16::from_be_bytes([field(5)?, field(6)?]),
                components: field(7)?,
            });
        }
        if length < 2 {
            return None;
        }
        at += length;
    }
}

/// The width and height of a TIFF's first image, read from its first IFD (tags 256 and
/// 257, SHORT or LONG, either byte order); `None` when the data ends or is malformed first.
///
/// ```
/// use vgps_camera::imaging::formats::tiff_dimensions;
/// // Little-endian header, IFD at 8 with two entries: width 640 (SHORT), height 480 (LONG).
/// let mut b = b"II*\0\x08\0\0\0\x02\0".to_vec();
/// b.extend([0, 1, 3, 0, 1, 0, 0, 0, 0x80, 2, 0, 0]);
/// b.extend([1, 1, 4, 0, 1, 0, 0, 0, 0xE0, 1, 0, 0]);
/// assert_eq!(tiff_dimensions(&b), Some((640, 480)));
/// ```
pub fn tiff_dimensions(bytes: &[u8]) -> Option<(u32, u32)> {
    let little = match bytes.get(..4)? {
        b"II*\0" => true,
        b"MM\0*" => false,
        _ => return None,
    };
    let u16_at = |at: usize| -> Option<u16> {
        let b = [*bytes.get(at)?, *bytes.get(at + 1)?];
        Some(if little {
            u16::from_le_bytes(b)
        } else {
            u16::from_be_bytes(b)
        })
    };
    let u32_at = |at: usize| -> Option<u32> {
        let b = [
            *bytes.get(at)?,
            *bytes.get(at + 1)?,
            *bytes.get(at + 2)?,
            *bytes.get(at + 3)?,
        ];
        Some(if little {
            u32::from_le_bytes(b)
        } else {
            u32::from_be_bytes(b)
        })
    };
    let ifd = usize::try_from(u32_at(4)?).ok()?;
    let entries = usize::from(u16_at(ifd)?);
    let (mut width, mut height) = (None, None);
    for k in 0..entries {
        let e = ifd.checked_add(2 + 12 * k)?;
        let value = match u16_at(e + 2)? {
            3 => u32::from(u16_at(e + 8)?),
            4 => u32_at(e + 8)?,
            _ => continue,
        };
        match u16_at(e)? {
            256 => width = Some(value),
            257 => height = Some(value),
            _ => {}
        }
    }
    Some((width?, height?))
}

fn decode_jpeg(
    bytes: &[u8],
    limits: &DecodeLimits,
    path: &Path,
) -> Result<GrayImage, ImagingError> {
    const F: ImageFormat = ImageFormat::Jpeg;
    let Some(header) = jpeg_frame_header(bytes) else {
        return Err(corrupt(
            path,
            F,
            "no frame header (truncated or not a JPEG)",
        ));
    };
    match header.marker {
        0xC0..=0xC2 => {}
        0xC3 | 0xC7 | 0xCB | 0xCF => return Err(unsupported(path, F, "lossless JPEG")),
        0xC5 | 0xC6 => return Err(unsupported(path, F, "hierarchical JPEG")),
        _ => return Err(unsupported(path, F, "arithmetic-coded JPEG")),
    }
    if header.precision != 8 {
        return Err(unsupported(
            path,
            F,
            format!(
                "{}-bit samples (only 8-bit JPEG is decoded)",
                header.precision
            ),
        ));
    }
    match header.components {
        1 | 3 => {}
        4 => {
            return Err(unsupported(
                path,
                F,
                "CMYK/YCCK JPEG (4 components): convert it to grey or RGB",
            ));
        }
        n => return Err(unsupported(path, F, format!("{n} colour components"))),
    }
    if header.width == 0 || header.height == 0 {
        return Err(unsupported(
            path,
            F,
            format!(
                "{}×{} pixels (a zero or DNL-defined size)",
                header.width, header.height
            ),
        ));
    }
    let (width, height) = (u64::from(header.width), u64::from(header.height));
    check_limits(path, width, height, limits)?;
    let options = DecoderOptions::default()
        .set_strict_mode(true)
        .set_max_width(JPEG_MAX_SIDE)
        .set_max_height(JPEG_MAX_SIDE)
        .jpeg_set_out_colorspace(ColorSpace::Luma);
    let mut decoder = JpegDecoder::new_with_options(ZCursor::new(bytes), options);
    decoder
        .decode_headers()
        .map_err(|e| corrupt(path, F, e.to_string()))?;
    match decoder.input_colorspace() {
        Some(ColorSpace::CMYK | ColorSpace::YCCK) => {
            return Err(unsupported(path, F, "CMYK/YCCK JPEG"));
        }
        Some(_) => {}
        None => return Err(corrupt(path, F, "headers not decoded")),
    }
    let Some((w, h)) = decoder.dimensions() else {
        return Err(corrupt(path, F, "headers not decoded"));
    };
    if (w as u64, h as u64) != (width, height) {
        return Err(corrupt(path, F, "frame header and decoder disagree"));
    }
    let pixels = decoder
        .decode()
        .map_err(|e| corrupt(path, F, e.to_string()))?;
    let (w32, h32) = (u32::from(header.width), u32::from(header.height));
    GrayImage::from_raw(w32, h32, pixels)
        .ok_or_else(|| corrupt(path, F, "decoded buffer size does not match the header"))
}

fn decode_with_image(
    bytes: &[u8],
    limits: &DecodeLimits,
    path: &Path,
    format: ImageFormat,
) -> Result<GrayImage, ImagingError> {
    let mut image_limits = image::Limits::default();
    image_limits.max_image_width = Some(limits.max_width);
    image_limits.max_image_height = Some(limits.max_height);
    image_limits.max_alloc = Some(limits.max_bytes);
    let map = |e: image::ImageError| match e {
        image::ImageError::Unsupported(u) => unsupported(path, format, u.to_string()),
        image::ImageError::Limits(l) => corrupt(path, format, format!("over the limits: {l}")),
        other => corrupt(path, format, other.to_string()),
    };
    if format == ImageFormat::Tiff
        && let Some((w, h)) = tiff_dimensions(bytes)
    {
        check_limits(path, w.into(), h.into(), limits)?;
    }
    let image = match format {
        ImageFormat::Tiff => {
            let mut decoder =
                image::codecs::tiff::TiffDecoder::new(Cursor::new(bytes)).map_err(map)?;
            let (w, h) = decoder.dimensions();
            check_limits(path, w.into(), h.into(), limits)?;
            decoder.set_limits(image_limits).map_err(map)?;
            DynamicImage::from_decoder(decoder).map_err(map)?
        }
        _ => {
            let mut decoder =
                image::codecs::bmp::BmpDecoder::new(Cursor::new(bytes)).map_err(map)?;
            let (w, h) = decoder.dimensions();
            check_limits(path, w.into(), h.into(), limits)?;
            decoder.set_limits(image_limits).map_err(map)?;
            DynamicImage::from_decoder(decoder).map_err(map)?
        }
    };
    Ok(to_luma8(&image))
}

/// Scales a 16-bit sample to 8 bits, `round(v · 255 / 65535)`.
///
/// ```
/// use vgps_camera::imaging::formats::scale16;
/// assert_eq!((scale16(0), scale16(128), scale16(0x8000), scale16(65535)), (0, 0, 128, 255));
/// assert_eq!(scale16(0x01FE), 2); // the high byte alone would be 1
/// ```
pub fn scale16(v: u16) -> u8 {
    ((u32::from(v) * 255 + 32767) / 65535) as u8
}

fn luma601_8(r: u8, g: u8, b: u8) -> u8 {
    ((LUMA601_8[0] * u32::from(r)
        + LUMA601_8[1] * u32::from(g)
        + LUMA601_8[2] * u32::from(b)
        + 128)
        >> 8) as u8
}

fn luma601_16(r: u16, g: u16, b: u16) -> u8 {
    let y = (LUMA601_16[0] * u64::from(r)
        + LUMA601_16[1] * u64::from(g)
        + LUMA601_16[2] * u64::from(b)
        + 32768)
        >> 16;
    scale16(y.min(u64::from(u16::MAX)) as u16)
}

fn unit_to_u8(x: f32) -> u8 {
    if x.is_finite() {
        (x.clamp(0.0, 1.0) * 255.0).round() as u8
    } else {
        0
    }
}

/// The 8-bit Rec. 601 luminance of a decoded image (see the [module docs](self)).
///
/// ```
/// use vgps_camera::imaging::formats::to_luma8;
/// let rgb = image::RgbImage::from_pixel(1, 1, image::Rgb([255, 0, 0]));
/// assert_eq!(to_luma8(&rgb.into()).as_raw(), &[77]); // 0.299 · 255 = 76.2 → 77/256 weights
/// ```
pub fn to_luma8(image: &DynamicImage) -> GrayImage {
    let (w, h) = (image.width(), image.height());
    let data: Vec<u8> = match image {
        DynamicImage::ImageLuma8(i) => return i.clone(),
        DynamicImage::ImageLumaA8(i) => i.as_raw().chunks_exact(2).map(|p| p[0]).collect(),
        DynamicImage::ImageRgb8(i) => i
            .as_raw()
            .chunks_exact(3)
            .map(|p| luma601_8(p[0], p[1], p[2]))
            .collect(),
        DynamicImage::ImageRgba8(i) => i
            .as_raw()
            .chunks_exact(4)
            .map(|p| luma601_8(p[0], p[1], p[2]))
            .collect(),
        DynamicImage::ImageLuma16(i) => i.as_raw().iter().map(|&v| scale16(v)).collect(),
        DynamicImage::ImageLumaA16(i) => {
            i.as_raw().chunks_exact(2).map(|p| scale16(p[0])).collect()
        }
        DynamicImage::ImageRgb16(i) => i
            .as_raw()
            .chunks_exact(3)
            .map(|p| luma601_16(p[0], p[1], p[2]))
            .collect(),
        DynamicImage::ImageRgba16(i) => i
            .as_raw()
            .chunks_exact(4)
            .map(|p| luma601_16(p[0], p[1], p[2]))
            .collect(),
        other => other
            .to_rgb32f()
            .as_raw()
            .chunks_exact(3)
            .map(|p| unit_to_u8(0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2]))
            .collect(),
    };
    // The buffer has exactly w·h samples by construction; an empty image otherwise.
    GrayImage::from_raw(w, h, data).unwrap_or_else(|| GrayImage::new(0, 0))
}
