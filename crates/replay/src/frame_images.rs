//! Lamp detection over the images of one drive frame (the step shared by `vgps detect` and
//! `vgps replay --from-images`).
//!
//! [`detect_frame_images`] reads each camera's PNG named in the frame (relative to the drive
//! directory), checks it against the calibration, runs the [`LampDetector`] and returns the
//! detections in the drive format together with one [`ImageProblem`] per image that could not
//! be used — a missing file, a non-PNG or corrupt file, a frame of the wrong size — so that
//! a run can report it and go on with the next frame.

use crate::drive::{FrameRecord, PixelDetection};
use std::path::Path;
use vgps_camera::calibration::Rig;
use vgps_camera::imaging::{
    DecodeLimits, ImagingError, LampDetector, check_dimensions, read_image,
};

/// Why one image of a frame gave no detections.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ImageProblemKind {
    /// The file does not exist or cannot be read.
    Missing,
    /// The file is not a PNG, or is truncated or corrupt.
    Unreadable,
    /// The image's size is not the calibration's (or its header exceeds it).
    WrongSize,
    /// The camera index is not in the calibration.
    UnknownCamera,
    /// The detector gave up (a flooded frame).
    DetectorFailed,
}

impl ImageProblemKind {
    /// Every kind, in report order.
    pub const ALL: [ImageProblemKind; 5] = [
        Self::Missing,
        Self::Unreadable,
        Self::WrongSize,
        Self::UnknownCamera,
        Self::DetectorFailed,
    ];

    /// A short label (`missing`, `unreadable`, `wrong_size`, `unknown_camera`,
    /// `detector_failed`).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Missing => "missing",
            Self::Unreadable => "unreadable",
            Self::WrongSize => "wrong_size",
            Self::UnknownCamera => "unknown_camera",
            Self::DetectorFailed => "detector_failed",
        }
    }

    /// The kind of an imaging error.
    pub fn of(error: &ImagingError) -> Self {
        match error {
            ImagingError::Io { .. } => Self::Missing,
            ImagingError::NotPng { .. }
            | ImagingError::NotAnImage { .. }
            | ImagingError::Corrupt { .. }
            | ImagingError::Unsupported { .. }
            | ImagingError::Decode { .. } => Self::Unreadable,
            ImagingError::TooLarge { .. } | ImagingError::WrongDimensions { .. } => Self::WrongSize,
            ImagingError::TooManyRuns { .. }
            | ImagingError::MaskDimensions { .. }
            | ImagingError::Encode { .. } => Self::DetectorFailed,
        }
    }
}

/// One image of a frame that could not be used.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageProblem {
    /// The camera index.
    pub camera: usize,
    /// What went wrong.
    pub kind: ImageProblemKind,
    /// The message (names the file).
    pub message: String,
}

/// The outcome of [`detect_frame_images`] for one frame.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct FrameImageResult {
    /// The frame number.
    pub frame: u64,
    /// The lamp detections of the usable images (class `None`, `strength` = the
    /// background-subtracted sum of the blob in DN), camera by camera.
    pub detections: Vec<PixelDetection>,
    /// Number of images named by the frame.
    pub images: usize,
    /// The images that could not be used.
    pub problems: Vec<ImageProblem>,
}

impl FrameImageResult {
    /// Whether the frame gave nothing usable: it names no image, or none of its images
    /// could be used.
    pub fn is_unusable(&self) -> bool {
        self.images == 0 || self.problems.len() >= self.images
    }

    /// The problems as one line (`; `-separated messages).
    pub fn problem_text(&self) -> String {
        if self.images == 0 {
            return "the frame names no image".into();
        }
        self.problems
            .iter()
            .map(|p| p.message.as_str())
            .collect::<Vec<_>>()
            .join("; ")
    }
}

/// Decodes and detects the images of one frame of a drive.
///
/// Each image `frame.images[k]` (a path relative to `drive_dir`) is read with
/// [`DecodeLimits::for_camera`] of camera `k` of `rig`, checked against its size
/// ([`check_dimensions`]) and passed to `detector`. A failing image is recorded in
/// [`FrameImageResult::problems`]; the other images' detections are kept. Never panics on
/// file content.
///
/// # Example
/// ```
/// use vgps_replay::drive::FrameRecord;
/// use vgps_camera::imaging::LampDetector;
/// use vgps_replay::frame_images::{ImageProblemKind, detect_frame_images};
/// let rig = vgps_sim::simulate::default_rig()?;
/// let dir = tempfile::tempdir()?;
/// let frame = FrameRecord { frame: 3, time_s: 0.0, images: vec![Some("none.png".into()), None] };
/// let result = detect_frame_images(dir.path(), &frame, &rig, &LampDetector::default());
/// assert_eq!(result.images, 1);
/// assert_eq!(result.problems[0].kind, ImageProblemKind::Missing);
/// assert!(result.is_unusable());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn detect_frame_images(
    drive_dir: &Path,
    frame: &FrameRecord,
    rig: &Rig,
    detector: &LampDetector,
) -> FrameImageResult {
    let mut result = FrameImageResult {
        frame: frame.frame,
        ..FrameImageResult::default()
    };
    for (camera, image) in frame.images.iter().enumerate() {
        let Some(name) = image else { continue };
        result.images += 1;
        let Ok(rig_camera) = rig.camera(camera) else {
            result.problems.push(ImageProblem {
                camera,
                kind: ImageProblemKind::UnknownCamera,
                message: format!("{name}: camera {camera} is not in the calibration"),
            });
            continue;
        };
        let path = drive_dir.join(name);
        let limits = DecodeLimits::for_camera(&rig_camera.model);
        let decoded = read_image(&path, &limits)
            .and_then(|img| check_dimensions(&img, &rig_camera.model, &path).map(|()| img))
            .and_then(|img| detector.detect(&img, None));
        match decoded {
            // Detections on pixels that never see the world (the calibration's mask) are
            // dropped.
            Ok(found) => result.detections.extend(
                found
                    .lamps
                    .iter()
                    .filter(|l| !rig.is_masked(camera, &nalgebra::Vector2::new(l.u, l.v)))
                    .map(|l| PixelDetection {
                        frame: frame.frame,
                        camera,
                        u: l.u,
                        v: l.v,
                        strength: Some(l.strength),
                        class: None,
                    }),
            ),
            Err(e) => result.problems.push(ImageProblem {
                camera,
                kind: ImageProblemKind::of(&e),
                message: format!("{e} (camera {camera})"),
            }),
        }
    }
    result
}
