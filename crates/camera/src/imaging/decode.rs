//! PNG decoding with size limits, and the dimension check against a calibration.
//!
//! The header's dimensions are read and checked against [`DecodeLimits`] *before* anything
//! is allocated, so a hostile header cannot make the decoder allocate without bound; the
//! `image` crate's own [`image::Limits`] are set as a second guard. Every error names the
//! file ([`ImagingError`]); nothing panics on malformed input.

use super::ImagingError;
use crate::calibration::{Camera, CameraModel};
use image::codecs::png::PngDecoder;
use image::{DynamicImage, GrayImage, ImageDecoder};
use std::io::Cursor;
use std::path::{Path, PathBuf};

/// The PNG signature.
const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n'];

/// Bytes before the end of the IHDR width and height fields (signature 8, chunk length 4,
/// chunk type 4, width 4, height 4).
const IHDR_END: usize = 24;

/// Name used in errors for in-memory data.
const MEMORY: &str = "<memory>";

/// Size limits of [`decode_png`]. The default accepts up to 8192 × 8192 pixels and 256 MiB of
/// decoder allocations (a 1024 × 768 camera frame is 0.75 MiB).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DecodeLimits {
    /// Largest accepted width (pixels).
    pub max_width: u32,
    /// Largest accepted height (pixels).
    pub max_height: u32,
    /// Largest accepted decoder allocation (bytes), the decoded image included.
    pub max_bytes: u64,
}

impl Default for DecodeLimits {
    fn default() -> Self {
        Self {
            max_width: 8192,
            max_height: 8192,
            max_bytes: 256 << 20,
        }
    }
}

impl DecodeLimits {
    /// Limits for exactly the image size of `camera` (a frame of any other size is rejected
    /// from its header).
    pub fn for_camera(camera: &Camera) -> Self {
        let (width, height) = camera.image_size();
        Self {
            max_width: width,
            max_height: height,
            // Room for a 16-bit RGBA source converted to 8-bit grey.
            max_bytes: u64::from(width) * u64::from(height) * 10 + (1 << 20),
        }
    }
}

/// Decodes PNG bytes to an 8-bit grayscale image (other colour types and bit depths are
/// converted: 16-bit scaled to 8 bits, colour to Rec. 601 luma: [`super::formats`]), within `limits`.
///
/// Errors name `<memory>` as the file; [`read_png`] names the real file.
///
/// # Example
/// ```
/// use vgps_camera::imaging::{DecodeLimits, ImagingError, decode_png, encode_png};
/// let image = image::GrayImage::from_pixel(4, 3, image::Luma([9]));
/// let bytes = encode_png(&image)?;
/// assert_eq!(decode_png(&bytes, &DecodeLimits::default())?, image);
/// // A tiny limit rejects the header before decoding.
/// let small = DecodeLimits { max_width: 2, ..DecodeLimits::default() };
/// assert!(matches!(decode_png(&bytes, &small), Err(ImagingError::TooLarge { width: 4, .. })));
/// assert!(matches!(decode_png(b"GIF89a", &small), Err(ImagingError::NotPng { .. })));
/// # Ok::<(), ImagingError>(())
/// ```
pub fn decode_png(bytes: &[u8], limits: &DecodeLimits) -> Result<GrayImage, ImagingError> {
    decode_named(bytes, limits, Path::new(MEMORY))
}

/// Reads and decodes a PNG file (see [`decode_png`]); errors name the file.
pub fn read_png(path: &Path, limits: &DecodeLimits) -> Result<GrayImage, ImagingError> {
    let bytes = std::fs::read(path).map_err(|source| ImagingError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    decode_named(&bytes, limits, path)
}

/// Checks that `image` has the dimensions of `camera`'s calibration;
/// [`ImagingError::WrongDimensions`] (naming `path`) otherwise — a per-frame status.
pub fn check_dimensions(
    image: &GrayImage,
    camera: &Camera,
    path: &Path,
) -> Result<(), ImagingError> {
    let (expected_width, expected_height) = camera.image_size();
    if image.dimensions() == (expected_width, expected_height) {
        Ok(())
    } else {
        Err(ImagingError::WrongDimensions {
            path: path.to_path_buf(),
            width: image.width(),
            height: image.height(),
            expected_width,
            expected_height,
        })
    }
}

fn decode_named(
    bytes: &[u8],
    limits: &DecodeLimits,
    path: &Path,
) -> Result<GrayImage, ImagingError> {
    let path_buf = || PathBuf::from(path);
    if bytes.len() < IHDR_END || bytes[..8] != PNG_SIGNATURE || &bytes[12..16] != b"IHDR" {
        return Err(ImagingError::NotPng { path: path_buf() });
    }
    let field =
        |at: usize| u32::from_be_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
    let (width, height) = (field(16), field(20));
    let too_large = || ImagingError::TooLarge {
        path: path_buf(),
        width,
        height,
        max_width: limits.max_width,
        max_height: limits.max_height,
        max_bytes: limits.max_bytes,
    };
    if width > limits.max_width
        || height > limits.max_height
        || u64::from(width) * u64::from(height) > limits.max_bytes
    {
        return Err(too_large());
    }
    let mut image_limits = image::Limits::default();
    image_limits.max_image_width = Some(limits.max_width);
    image_limits.max_image_height = Some(limits.max_height);
    image_limits.max_alloc = Some(limits.max_bytes);
    let decode_error = |e: image::ImageError| match e {
        image::ImageError::Limits(_) => too_large(),
        other => ImagingError::Decode {
            path: path_buf(),
            message: other.to_string(),
        },
    };
    let decoder =
        PngDecoder::with_limits(Cursor::new(bytes), image_limits).map_err(decode_error)?;
    if decoder.color_type() == image::ColorType::L8 {
        let (w, h) = decoder.dimensions();
        let mut buffer = vec![0u8; decoder.total_bytes() as usize];
        decoder.read_image(&mut buffer).map_err(decode_error)?;
        return GrayImage::from_raw(w, h, buffer).ok_or_else(|| ImagingError::Decode {
            path: path_buf(),
            message: "decoded buffer size does not match the header".into(),
        });
    }
    let image = DynamicImage::from_decoder(decoder).map_err(decode_error)?;
    // Rec. 601 luminance, 16-bit scaled (not truncated): see `formats`.
    Ok(super::formats::to_luma8(&image))
}

/// Encodes an 8-bit grayscale image as PNG with fast compression (the setting measured to
/// give the best speed/size for noisy night frames: see `docs/lamp-detection.md`).
pub fn encode_png(image: &GrayImage) -> Result<Vec<u8>, ImagingError> {
    use image::ImageEncoder;
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    let mut out = Vec::with_capacity(image.as_raw().len() / 2);
    PngEncoder::new_with_quality(&mut out, CompressionType::Fast, FilterType::Sub)
        .write_image(
            image.as_raw(),
            image.width(),
            image.height(),
            image::ExtendedColorType::L8,
        )
        .map_err(|e| ImagingError::Encode {
            message: e.to_string(),
        })?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::calibration_files::ladybug2_lens;

    fn frame() -> GrayImage {
        GrayImage::from_fn(64, 48, |x, y| image::Luma([((x * 3 + y * 5) % 251) as u8]))
    }

    #[test]
    fn truncated_png_is_a_decode_error() {
        let bytes = crate::imaging::encode_png(&frame()).unwrap();
        // (The last 12 bytes are the IEND chunk, whose loss is harmless.)
        for cut in [bytes.len() - 13, bytes.len() / 2, 40, 30] {
            let r = decode_png(&bytes[..cut], &DecodeLimits::default());
            assert!(
                matches!(r, Err(ImagingError::Decode { .. })),
                "cut {cut}: {r:?}"
            );
        }
        for cut in [0, 8, 20] {
            let r = decode_png(&bytes[..cut], &DecodeLimits::default());
            assert!(
                matches!(r, Err(ImagingError::NotPng { .. })),
                "cut {cut}: {r:?}"
            );
        }
    }

    #[test]
    fn corrupted_data_is_an_error_not_a_panic() {
        let bytes = crate::imaging::encode_png(&frame()).unwrap();
        let mut rng = vgps_geometry::synthetic::rng(4);
        use rand::RngExt;
        for _ in 0..200 {
            let mut b = bytes.clone();
            for _ in 0..4 {
                let i = rng.random_range(8..b.len());
                b[i] = rng.random();
            }
            // Either decodes (a harmless flip) or returns a typed error.
            let _ = decode_png(&b, &DecodeLimits::default());
        }
    }

    #[test]
    fn non_png_file_names_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frame.png");
        std::fs::write(&path, b"this is not an image at all, just text").unwrap();
        let e = read_png(&path, &DecodeLimits::default()).unwrap_err();
        assert!(matches!(e, ImagingError::NotPng { .. }));
        assert!(e.to_string().contains("frame.png"), "{e}");
        let missing = read_png(&dir.path().join("none.png"), &DecodeLimits::default()).unwrap_err();
        assert!(
            matches!(missing, ImagingError::Io { .. }) && missing.to_string().contains("none.png")
        );
    }

    #[test]
    fn huge_header_dimensions_are_rejected_before_allocation() {
        let mut bytes = crate::imaging::encode_png(&frame()).unwrap();
        // Declare 100000 × 100000 pixels (and 8192 × 8193: just over the default limit).
        for (w, h) in [(100_000u32, 100_000u32), (8192, 8193), (u32::MAX, u32::MAX)] {
            bytes[16..20].copy_from_slice(&w.to_be_bytes());
            bytes[20..24].copy_from_slice(&h.to_be_bytes());
            let r = decode_png(&bytes, &DecodeLimits::default());
            assert!(
                matches!(r, Err(ImagingError::TooLarge { width, height, .. }) if width == w && height == h),
                "{r:?}"
            );
        }
        // Within the per-axis limits but over the byte budget.
        bytes[16..20].copy_from_slice(&8000u32.to_be_bytes());
        bytes[20..24].copy_from_slice(&8000u32.to_be_bytes());
        let small = DecodeLimits {
            max_bytes: 1 << 20,
            ..DecodeLimits::default()
        };
        assert!(matches!(
            decode_png(&bytes, &small),
            Err(ImagingError::TooLarge { .. })
        ));
    }

    #[test]
    fn wrong_dimensions_against_the_calibration() {
        let camera = Camera::from(ladybug2_lens());
        let image = frame();
        let e = check_dimensions(&image, &camera, Path::new("cam0/000001.png")).unwrap_err();
        assert!(matches!(
            e,
            ImagingError::WrongDimensions {
                width: 64,
                height: 48,
                expected_width: 1024,
                expected_height: 768,
                ..
            }
        ));
        assert!(e.to_string().contains("cam0/000001.png"));
        let right = GrayImage::new(1024, 768);
        assert!(check_dimensions(&right, &camera, Path::new("x")).is_ok());
        // The camera's own limits reject a larger frame from its header.
        let bytes = crate::imaging::encode_png(&GrayImage::new(1025, 768)).unwrap();
        let r = decode_png(&bytes, &DecodeLimits::for_camera(&camera));
        assert!(matches!(r, Err(ImagingError::TooLarge { width: 1025, .. })));
    }

    #[test]
    fn other_colour_types_are_converted_to_grey() {
        use image::ImageEncoder;
        let rgb = image::RgbImage::from_pixel(5, 4, image::Rgb([200, 200, 200]));
        let mut bytes = Vec::new();
        image::codecs::png::PngEncoder::new(&mut bytes)
            .write_image(rgb.as_raw(), 5, 4, image::ExtendedColorType::Rgb8)
            .unwrap();
        let grey = decode_png(&bytes, &DecodeLimits::default()).unwrap();
        assert_eq!(grey.dimensions(), (5, 4));
        assert!(grey.as_raw().iter().all(|&p| p == 200));
        let wide =
            image::ImageBuffer::<image::Luma<u16>, _>::from_pixel(3, 2, image::Luma([0x8000u16]));
        let mut bytes = Vec::new();
        image::codecs::png::PngEncoder::new(&mut bytes)
            .write_image(
                &wide
                    .as_raw()
                    .iter()
                    .flat_map(|v| v.to_ne_bytes())
                    .collect::<Vec<u8>>(),
                3,
                2,
                image::ExtendedColorType::L16,
            )
            .unwrap();
        let grey = decode_png(&bytes, &DecodeLimits::default()).unwrap();
        assert!(
            grey.as_raw().iter().all(|&p| p == 128),
            "{:?}",
            grey.as_raw()
        );
    }
}
