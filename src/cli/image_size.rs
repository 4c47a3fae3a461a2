//! The image size of a rig whose calibration names none (a Ladybug INI dump): from
//! `--image-size WxH`, or from the PNG headers of the drive's images (every image of every
//! such camera must agree), for `vgps detect` and `vgps replay --from-images`.

use super::CliError;
use std::io::Read;
use std::path::Path;
use vgps_camera::calibration::CameraModel;
use vgps_replay::drive::Drive;

/// Parses `WxH` or `W,H` (e.g. `2048x2448`).
///
/// # Errors
/// The reason, for clap.
pub fn parse_image_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X', ','])
        .ok_or_else(|| format!("`{s}` is not WxH"))?;
    let w: u32 = w
        .trim()
        .parse()
        .map_err(|_| format!("bad width in `{s}`"))?;
    let h: u32 = h
        .trim()
        .parse()
        .map_err(|_| format!("bad height in `{s}`"))?;
    if w == 0 || h == 0 {
        return Err(format!("image size `{s}` must be non-zero"));
    }
    Ok((w, h))
}

/// `(width, height)` from a PNG's IHDR chunk, reading 24 bytes; `None` for anything that is
/// not a PNG header.
pub fn png_dimensions(path: &Path) -> Option<(u32, u32)> {
    let mut head = [0u8; 24];
    std::fs::File::open(path).ok()?.read_exact(&mut head).ok()?;
    if head[..8] != *b"\x89PNG\r\n\x1a\n" || head[12..16] != *b"IHDR" {
        return None;
    }
    let w = u32::from_be_bytes([head[16], head[17], head[18], head[19]]);
    let h = u32::from_be_bytes([head[20], head[21], head[22], head[23]]);
    Some((w, h))
}

/// `(width, height)` from an image file's header: a PNG's IHDR chunk (24 bytes) or a JPEG's
/// start-of-frame segment (within the first 256 KiB); `None` otherwise.
pub fn header_dimensions(path: &Path) -> Option<(u32, u32)> {
    if let Some(size) = png_dimensions(path) {
        return Some(size);
    }
    let mut head = Vec::new();
    std::fs::File::open(path)
        .ok()?
        .take(256 * 1024)
        .read_to_end(&mut head)
        .ok()?;
    if !head.starts_with(&[0xFF, 0xD8]) {
        return None;
    }
    let h = vgps_camera::imaging::formats::jpeg_frame_header(&head)?;
    Some((u32::from(h.width), u32::from(h.height)))
}

/// Gives the drive's unbounded cameras an image size: `given`, else the size every PNG or
/// JPEG header of those cameras' images gives (unreadable images are skipped: they are
/// reported per frame later).
/// Returns a note for stderr when a size was applied.
///
/// # Errors
/// [`CliError::Calibration`] when images of those cameras disagree, when those cameras have
/// images but none of their headers gives a size (then `--image-size` is needed), or when
/// the calibration cannot take the size.
pub fn resolve(drive: &mut Drive, given: Option<(u32, u32)>) -> Result<Option<String>, CliError> {
    let dir = drive.dir().to_path_buf();
    resolve_with(drive, given, &|name| {
        let path = dir.join(name);
        // A missing image is reported per frame later; an existing one without a PNG/JPEG
        // header cannot give the size.
        let size = header_dimensions(&path);
        let exists = size.is_some() || path.is_file();
        (exists, size, path.display().to_string())
    })
}

/// What [`resolve_with`] learns of one image: whether it exists, the size its header gives,
/// and how messages name it.
pub type ImageHeader = (bool, Option<(u32, u32)>, String);

/// [`resolve`] with each image's header from `header(name)`: whether the image exists, the
/// size its header gives, and how messages name it (`vgps replay run.mcap` takes them from
/// the recording).
///
/// # Errors
/// As [`resolve`].
pub fn resolve_with(
    drive: &mut Drive,
    given: Option<(u32, u32)>,
    header: &dyn Fn(&str) -> ImageHeader,
) -> Result<Option<String>, CliError> {
    let unbounded: Vec<usize> = (0..drive.rig().len())
        .filter(|&i| drive.rig().cameras()[i].model.image_size() == (0, 0))
        .collect();
    if unbounded.is_empty() {
        return match given {
            Some((w, h)) => {
                // The calibration has sizes: the given one must agree (checked by load).
                drive
                    .reload_calibration((w, h))
                    .map_err(|e| CliError::Calibration(e.to_string()))?;
                Ok(None)
            }
            None => Ok(None),
        };
    }
    let size = match given {
        Some(s) => s,
        None => {
            let mut found: Option<((u32, u32), String)> = None;
            let mut unsized_image: Option<String> = None;
            for frame in drive.frames() {
                for &camera in &unbounded {
                    let Some(Some(name)) = frame.images.get(camera) else {
                        continue;
                    };
                    let (exists, size, shown) = header(name);
                    let Some(size) = size else {
                        if exists {
                            unsized_image.get_or_insert(shown);
                        }
                        continue;
                    };
                    match &found {
                        None => found = Some((size, name.clone())),
                        Some((first, first_name)) if *first != size => {
                            return Err(CliError::Calibration(format!(
                                "the calibration names no image size and the images disagree: \
                                 {first_name} is {}×{}, {name} is {}×{} (give --image-size WxH)",
                                first.0, first.1, size.0, size.1
                            )));
                        }
                        Some(_) => {}
                    }
                }
            }
            match (found, unsized_image) {
                (Some((s, _)), _) => s,
                (None, Some(name)) => {
                    return Err(CliError::Calibration(format!(
                        "the calibration names no image size for camera(s) {unbounded:?} and \
                         no image of theirs gives one in a PNG or JPEG header (e.g. {}): \
                         give --image-size WxH",
                        name
                    )));
                }
                (None, None) => return Ok(None),
            }
        }
    };
    drive
        .reload_calibration(size)
        .map_err(|e| CliError::Calibration(e.to_string()))?;
    Ok(Some(format!(
        "the calibration names no image size: using {}×{} ({})",
        size.0,
        size.1,
        if given.is_some() {
            "--image-size"
        } else {
            "the size of every image of those cameras"
        }
    )))
}
