//! The record a detector gives for one landmark seen in one image.

/// One detection: a pixel in one camera of one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct PixelDetection {
    /// The frame.
    pub frame: u64,
    /// The camera index in the rig.
    pub camera: usize,
    /// Column (pixel centre at integers).
    pub u: f64,
    /// Row (pixel centre at integers).
    pub v: f64,
    /// Detector strength, when given (free units, larger = stronger).
    pub strength: Option<f64>,
    /// Class label (e.g. `streetlight`, `corner`), when given.
    pub class: Option<String>,
}
