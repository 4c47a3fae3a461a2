//! Landmark detection over the images of one drive frame (the step shared by `vgps detect`
//! and `vgps replay --from-images`).
//!
//! [`detect_frame_images`] reads each camera's image named in the frame (relative to the
//! drive directory), checks it against the calibration, runs the [`ImageDetector`] — the
//! point-light [`LampDetector`] or the night-street [`StreetLampDetector`] by night, the
//! building-corner [`VertexDetector`] by day, with the camera's calibration mask applied
//! before detection — and returns the detections in the drive format, labelled with the
//! detector's landmark class ([`DEFAULT_LAMP_CLASS`] for lamps, [`CORNER_CLASS`] for
//! corners) so that the matcher pairs them only with landmarks of that class, together with
//! one [`ImageProblem`] per image
//! that could not be used — a missing file, a non-image or corrupt file, a frame of the
//! wrong size — so that a run can report it and go on with the next frame.

use crate::drive::{FrameRecord, PixelDetection};
use std::path::{Path, PathBuf};
use vgps_camera::calibration::Rig;
use vgps_camera::imaging::{
    DecodeLimits, ImagingError, LampDetector, Mask, StreetLampDetector, VertexDetector,
    check_dimensions, decode_image_named,
};

/// The class written on detections found in night images: the drive format's lamp class
/// (`landmarks.csv` `class`). The matcher pairs a classed detection only with landmarks of
/// that class; a map without the class (or without a `class` column) pairs it with any.
pub const DEFAULT_LAMP_CLASS: &str = "streetlight";

/// The class written on building corners found in day images: the drive format's class of
/// building-corner landmarks (`landmarks.csv` `class`, as the simulator writes it), so that
/// the matcher pairs a corner only with corner landmarks.
pub const CORNER_CLASS: &str = "corner";

/// The matcher's visibility range (metres) for the vertex detector's building corners.
///
/// By day the vertex detector finds building corners well beyond the matcher's default 80 m
/// (recall 23–31 % at 80–150 m, as within 80 m; docs/dev/journal.md, 2026-11-27); with 80 m
/// the matcher ignores them and a frame keeps a median of 4 surveyed corners. With 150 m the
/// day drives replayed from their images fix 83/153 and 63/87 frames instead of 70 and 5,
/// none more than 0.21 m off (journal, "day4").
pub const VERTEX_VISIBILITY_RANGE_M: f64 = 150.0;

/// Which lamp detector runs on the images.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum DetectorKind {
    /// [`LampDetector`]: every spot above a noise-based threshold (point lights on a dark
    /// background: the renderer's images).
    #[default]
    Point,
    /// [`StreetLampDetector`]: bright cores against their local background, windows,
    /// reflections, vehicle lights and ghosts rejected (real night streets).
    Street,
    /// [`VertexDetector`]: building corners by day, as the intersection of straight edges
    /// fitted in a locally rectified patch through the camera model.
    Vertex,
}

impl DetectorKind {
    /// `point`, `street` or `vertex`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Point => "point",
            Self::Street => "street",
            Self::Vertex => "vertex",
        }
    }

    /// The matcher's visibility range (metres) for this detector's detections when no
    /// `--visibility-range-m` is given: `None` (the matcher's default, 80 m) for the lamp
    /// detectors, [`VERTEX_VISIBILITY_RANGE_M`] for the vertex detector.
    pub fn visibility_range_m(self) -> Option<f64> {
        match self {
            Self::Point | Self::Street => None,
            Self::Vertex => Some(VERTEX_VISIBILITY_RANGE_M),
        }
    }

    /// The landmark class of this detector's detections: [`DEFAULT_LAMP_CLASS`] for the
    /// lamp detectors, [`CORNER_CLASS`] for the vertex detector.
    pub fn class(self) -> &'static str {
        match self {
            Self::Point | Self::Street => DEFAULT_LAMP_CLASS,
            Self::Vertex => CORNER_CLASS,
        }
    }
}

/// The detector of a drive's images: the detector kind, each camera's detection mask (from
/// the rig's calibration masks), the camera models (for the vertex detector's rectified
/// patches) and the class written on the detections.
#[derive(Clone, Debug)]
pub struct ImageDetector {
    kind: DetectorKind,
    point: LampDetector,
    street: StreetLampDetector,
    vertex: VertexDetector,
    masks: Vec<Option<Mask>>,
    models: Vec<vgps_camera::calibration::Camera>,
    class: Option<String>,
}

impl ImageDetector {
    /// The detector `kind` for the cameras of `rig` (their masks are converted once here),
    /// labelling detections with [`DetectorKind::class`].
    pub fn new(kind: DetectorKind, rig: &Rig) -> Self {
        Self {
            kind,
            point: LampDetector::default(),
            street: StreetLampDetector::default(),
            vertex: VertexDetector::default(),
            masks: (0..rig.len())
                .map(|k| rig.mask(k).map(Mask::from_camera_mask))
                .collect(),
            models: match kind {
                DetectorKind::Vertex => rig.cameras().iter().map(|c| c.model.clone()).collect(),
                DetectorKind::Point | DetectorKind::Street => Vec::new(),
            },
            class: Some(kind.class().to_string()),
        }
    }

    /// The same detector with the vertex detector `vertex` (its parameters).
    pub fn with_vertex_detector(mut self, vertex: VertexDetector) -> Self {
        self.vertex = vertex;
        self
    }

    /// The same detector with the point detector `point` (its parameters).
    pub fn with_point_detector(mut self, point: LampDetector) -> Self {
        self.point = point;
        self
    }

    /// The same detector writing `class` on its detections (`None`: no class, the matcher
    /// pairs them with any landmark).
    pub fn with_class(mut self, class: Option<String>) -> Self {
        self.class = class;
        self
    }

    /// The detector kind.
    pub fn kind(&self) -> DetectorKind {
        self.kind
    }

    /// The detections of one image of camera `camera`: `(u, v, strength)`, the camera's mask
    /// applied before detection (a mask of another size than the image is ignored: the
    /// image's size was checked against the calibration, whose mask has its size).
    ///
    /// # Errors
    /// The detector's [`ImagingError::TooManyRuns`] on a flooded image.
    pub fn detect(
        &self,
        camera: usize,
        image: &image::GrayImage,
    ) -> Result<Vec<(f64, f64, f64)>, ImagingError> {
        let mask = self
            .masks
            .get(camera)
            .and_then(Option::as_ref)
            .filter(|m| m.dimensions() == image.dimensions());
        Ok(match self.kind {
            DetectorKind::Point => self
                .point
                .detect(image, mask)?
                .lamps
                .iter()
                .map(|l| (l.u, l.v, l.strength))
                .collect(),
            DetectorKind::Street => self
                .street
                .detect_masked(image, mask)?
                .lamps
                .iter()
                .map(|l| (l.u, l.v, l.strength))
                .collect(),
            DetectorKind::Vertex => self
                .vertex
                .detect(image, self.models.get(camera), mask)
                .iter()
                .map(|c| (c.u, c.v, c.strength))
                .collect(),
        })
    }
}

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
    /// The lamp detections of the usable images (class: the detector's, by default
    /// [`DEFAULT_LAMP_CLASS`]; `strength` = the background-subtracted sum of the blob in
    /// DN), camera by camera.
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
/// ([`check_dimensions`]) and passed to `detector` (which applies the camera's mask before
/// detection). A failing image is recorded in
/// [`FrameImageResult::problems`]; the other images' detections are kept. Never panics on
/// file content.
///
/// # Example
/// ```
/// use vgps_replay::drive::FrameRecord;
/// use vgps_replay::frame_images::{DetectorKind, ImageDetector, ImageProblemKind, detect_frame_images};
/// let rig = vgps_sim::simulate::default_rig()?;
/// let dir = tempfile::tempdir()?;
/// let frame = FrameRecord { frame: 3, time_s: 0.0, images: vec![Some("none.png".into()), None] };
/// let detector = ImageDetector::new(DetectorKind::Point, &rig);
/// let result = detect_frame_images(dir.path(), &frame, &rig, &detector);
/// assert_eq!(result.images, 1);
/// assert_eq!(result.problems[0].kind, ImageProblemKind::Missing);
/// assert!(result.is_unusable());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn detect_frame_images(
    drive_dir: &Path,
    frame: &FrameRecord,
    rig: &Rig,
    detector: &ImageDetector,
) -> FrameImageResult {
    detect_frame_images_from(frame, rig, detector, &mut |_, name| {
        let path = drive_dir.join(name);
        match std::fs::read(&path) {
            Ok(bytes) => Ok((path, bytes)),
            Err(source) => Err(ImagingError::Io { path, source }),
        }
    })
}

/// Where [`detect_frame_images_from`] takes an image: `(camera, name)` → the path that names
/// it in messages and its bytes.
pub type ImageLoader<'a> = dyn FnMut(usize, &str) -> Result<(PathBuf, Vec<u8>), ImagingError> + 'a;

/// [`detect_frame_images`] with the images' bytes from `load(camera, name)` instead of the
/// drive directory: it returns the path that names the image in messages and the bytes a
/// drive file would hold (`vgps replay run.mcap` reads them from the recording). The bytes
/// are decoded as [`read_image`](vgps_camera::imaging::read_image) decodes a file
/// ([`decode_image_named`]), so a frame gives the same detections from either source.
pub fn detect_frame_images_from(
    frame: &FrameRecord,
    rig: &Rig,
    detector: &ImageDetector,
    load: &mut ImageLoader<'_>,
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
        let limits = DecodeLimits::for_camera(&rig_camera.model);
        let decoded = load(camera, name).and_then(|(path, bytes)| {
            decode_image_named(&bytes, &limits, &path)
                .and_then(|img| check_dimensions(&img, &rig_camera.model, &path).map(|()| img))
        });
        let decoded = decoded.and_then(|img| detector.detect(camera, &img));
        match decoded {
            // The mask was applied before detection; a centroid that still falls on a masked
            // pixel (a spot straddling the mask's edge) is dropped too.
            Ok(found) => result.detections.extend(
                found
                    .into_iter()
                    .filter(|&(u, v, _)| !rig.is_masked(camera, &nalgebra::Vector2::new(u, v)))
                    .map(|(u, v, strength)| PixelDetection {
                        frame: frame.frame,
                        camera,
                        u,
                        v,
                        strength: Some(strength),
                        class: detector.class.clone(),
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
