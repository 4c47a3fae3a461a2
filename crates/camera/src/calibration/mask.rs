//! A camera's mask: the pixels that never see the world (the vehicle's body, the black
//! border of a lens or of an undistorted image), part of a rig's calibration.

use super::{CalibrationError, MAX_IMAGE_SIDE_PX, Pixel};
use image::ImageEncoder;
use std::path::Path;

/// One bit per pixel of a `width × height` image: set = the pixel never sees the world.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CameraMask {
    width: u32,
    height: u32,
    words_per_row: usize,
    bits: Vec<u64>,
}

impl CameraMask {
    /// A mask from a row-major predicate over the pixels (`masked(u, v)`).
    ///
    /// # Errors
    /// [`CalibrationError::InvalidParameters`] for a zero or too large size.
    pub fn from_fn(
        width: u32,
        height: u32,
        masked: impl Fn(u32, u32) -> bool,
    ) -> Result<Self, CalibrationError> {
        super::check_size("mask", width, height)?;
        let words_per_row = (width as usize).div_ceil(64);
        let mut bits = vec![0u64; words_per_row * height as usize];
        for v in 0..height {
            for u in 0..width {
                if masked(u, v) {
                    bits[v as usize * words_per_row + u as usize / 64] |= 1 << (u % 64);
                }
            }
        }
        Ok(Self {
            width,
            height,
            words_per_row,
            bits,
        })
    }

    /// Reads a PNG mask: a pixel whose (grey or colour) value is 0 — black — never sees the
    /// world; any other value does (the convention of the NCLT masks of ethz-asl/nclt_tools).
    ///
    /// # Errors
    /// [`CalibrationError::InvalidParameters`] naming the file: unreadable, not a PNG, or a
    /// size over [`MAX_IMAGE_SIDE_PX`].
    pub fn read_png(path: &Path) -> Result<Self, CalibrationError> {
        let bytes = std::fs::read(path).map_err(|e| CalibrationError::InvalidParameters {
            model: "mask",
            reason: format!("{}: {e}", path.display()),
        })?;
        Self::from_png_bytes(&bytes, path)
    }

    /// A mask from the bytes of a PNG file (the convention of [`CameraMask::read_png`]);
    /// `path` only names the source in errors.
    ///
    /// # Errors
    /// [`CalibrationError::InvalidParameters`] naming `path`: not a PNG, or a size over
    /// [`MAX_IMAGE_SIDE_PX`].
    pub fn from_png_bytes(bytes: &[u8], path: &Path) -> Result<Self, CalibrationError> {
        let err = |reason: String| CalibrationError::InvalidParameters {
            model: "mask",
            reason: format!("{}: {reason}", path.display()),
        };
        let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes));
        reader.set_format(image::ImageFormat::Png);
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(MAX_IMAGE_SIDE_PX);
        limits.max_image_height = Some(MAX_IMAGE_SIDE_PX);
        limits.max_alloc = Some(1 << 30);
        reader.limits(limits);
        let img = reader
            .decode()
            .map_err(|e| err(format!("not a readable PNG: {e}")))?
            .into_luma8();
        Self::from_fn(img.width(), img.height(), |u, v| {
            img.get_pixel(u, v)[0] == 0
        })
        .map_err(|e| err(e.to_string()))
    }

    /// The mask as the bytes of an 8-bit grey PNG: masked pixels black (0), the others
    /// white (255), so that [`CameraMask::from_png_bytes`] reads it back equal.
    pub fn to_png_bytes(&self) -> Vec<u8> {
        let img = image::GrayImage::from_fn(self.width, self.height, |u, v| {
            image::Luma([if self.is_masked(u, v) { 0 } else { 255 }])
        });
        let mut out = Vec::new();
        // Encoding an in-memory grey image of a valid size into a Vec cannot fail.
        let _ = image::codecs::png::PngEncoder::new(&mut out).write_image(
            img.as_raw(),
            self.width,
            self.height,
            image::ExtendedColorType::L8,
        );
        out
    }

    /// `(width, height)` in pixels.
    pub fn dimensions(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Whether integer pixel `(u, v)` is masked (pixels outside the mask are not).
    pub fn is_masked(&self, u: u32, v: u32) -> bool {
        u < self.width
            && v < self.height
            && self.bits[v as usize * self.words_per_row + u as usize / 64] >> (u % 64) & 1 == 1
    }

    /// Whether the pixel holding the sub-pixel position `pixel` (integer = centre) is
    /// masked; positions outside the image or not finite are not.
    pub fn is_masked_at(&self, pixel: &Pixel) -> bool {
        let (u, v) = (pixel.x.round(), pixel.y.round());
        // `as u32` saturates; the range test keeps only pixels of the image.
        u >= 0.0
            && v >= 0.0
            && u < f64::from(self.width)
            && v < f64::from(self.height)
            && self.is_masked(u as u32, v as u32)
    }

    /// Number of masked pixels.
    pub fn count(&self) -> u64 {
        self.bits.iter().map(|w| u64::from(w.count_ones())).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    #[test]
    fn bits_and_sub_pixel_look_up() {
        let m = CameraMask::from_fn(70, 3, |u, v| u == 65 && v == 1).expect("mask");
        assert!(m.is_masked(65, 1) && !m.is_masked(64, 1) && !m.is_masked(65, 0));
        assert!(m.is_masked_at(&Vector2::new(65.4, 0.6)));
        assert!(!m.is_masked_at(&Vector2::new(65.6, 1.0)));
        assert!(!m.is_masked_at(&Vector2::new(f64::NAN, 1.0)));
        assert!(!m.is_masked_at(&Vector2::new(-0.4, 1.0)) && !m.is_masked(70, 1));
        assert_eq!(m.count(), 1);
    }
}
