//! The enum of every camera model, with static dispatch of [`CameraModel`].

use super::{
    CameraModel, Equirectangular, KannalaBrandt, Lut, Pinhole, Pixel, SplinePinhole,
    TabulatedPinhole,
};
use nalgebra::{Matrix2x3, Matrix3x2, Vector3};
use serde::{Deserialize, Serialize};

/// Any camera model, for storage in a rig and for serde (tagged by a `"model"` field:
/// `"pinhole"`, `"kannala_brandt"`, `"equirectangular"`, `"lut"`, the other fields being the
/// model's parameter struct).
///
/// Implements [`CameraModel`] by a `match` (no `Box<dyn>`, inlinable in hot loops).
///
/// # Example
/// ```
/// use vgps_camera::calibration::{Camera, CameraModel};
/// let json = r#"{"model": "equirectangular", "width": 2048, "height": 1024}"#;
/// let camera: Camera = serde_json::from_str(json).unwrap();
/// assert_eq!(camera.image_size(), (2048, 1024));
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case")]
pub enum Camera {
    /// A pinhole camera with optional radial-tangential distortion.
    Pinhole(Pinhole),
    /// A Kannala-Brandt (OpenCV fisheye) camera.
    KannalaBrandt(KannalaBrandt),
    /// An equirectangular panorama.
    Equirectangular(Equirectangular),
    /// A pixel → bearing lookup table.
    Lut(Lut),
    /// A pinhole with tabulated (NCLT `D2U`/`U2D`) distortion, or unbounded.
    TabulatedPinhole(TabulatedPinhole),
    /// A raw image rectified to a pinhole by B-spline warps (a Ladybug `.conf` camera).
    SplinePinhole(SplinePinhole),
}

macro_rules! dispatch {
    ($self:ident, $m:ident => $e:expr) => {
        match $self {
            Camera::Pinhole($m) => $e,
            Camera::KannalaBrandt($m) => $e,
            Camera::Equirectangular($m) => $e,
            Camera::Lut($m) => $e,
            Camera::TabulatedPinhole($m) => $e,
            Camera::SplinePinhole($m) => $e,
        }
    };
}

/// Each model's per-call methods, never inlined into [`Camera`]'s dispatch.
///
/// Inlined, the six models' bodies merge into one large function whose prologue saves six
/// registers and whose register pressure spills in every arm: through `Camera`, the LUT's
/// pixel → bearing took 5–6 ns more per call than the LUT called directly (26.5–27.2
/// against 21.0–21.3 ns, best of 30 rounds over the `calibration/bearing/lut` benchmark's
/// pixels, two runs; 22.5–22.7 ns with these). Out of line, the dispatch is a jump table of
/// tail calls and each model keeps its own code.
mod out_of_line {
    use super::{CameraModel, Matrix2x3, Matrix3x2, Pixel, Vector3};

    #[inline(never)]
    pub(super) fn try_bearing<M: CameraModel>(m: &M, pixel: &Pixel) -> Option<Vector3<f64>> {
        m.try_bearing(pixel)
    }

    #[inline(never)]
    pub(super) fn try_pixel<M: CameraModel>(m: &M, bearing: &Vector3<f64>) -> Option<Pixel> {
        m.try_pixel(bearing)
    }

    #[inline(never)]
    pub(super) fn try_bearing_with_jacobian<M: CameraModel>(
        m: &M,
        pixel: &Pixel,
    ) -> Option<(Vector3<f64>, Matrix3x2<f64>)> {
        m.try_bearing_with_jacobian(pixel)
    }

    #[inline(never)]
    pub(super) fn try_pixel_with_jacobian<M: CameraModel>(
        m: &M,
        bearing: &Vector3<f64>,
    ) -> Option<(Pixel, Matrix2x3<f64>)> {
        m.try_pixel_with_jacobian(bearing)
    }
}

impl Camera {
    /// The model's name as in its serde tag.
    pub fn model_name(&self) -> &'static str {
        match self {
            Camera::Pinhole(_) => "pinhole",
            Camera::KannalaBrandt(_) => "kannala_brandt",
            Camera::Equirectangular(_) => "equirectangular",
            Camera::Lut(_) => "lut",
            Camera::TabulatedPinhole(_) => "tabulated_pinhole",
            Camera::SplinePinhole(_) => "spline_pinhole",
        }
    }
}

impl CameraModel for Camera {
    #[inline]
    fn image_size(&self) -> (u32, u32) {
        dispatch!(self, m => m.image_size())
    }

    #[inline]
    fn is_inside(&self, pixel: &Pixel) -> bool {
        dispatch!(self, m => m.is_inside(pixel))
    }

    #[inline]
    fn try_bearing(&self, pixel: &Pixel) -> Option<Vector3<f64>> {
        dispatch!(self, m => out_of_line::try_bearing(m, pixel))
    }

    /// One dispatch for the whole batch, then the model's own loop.
    #[inline]
    fn bearings_into(&self, pixels: &[Pixel], out: &mut [Option<Vector3<f64>>]) -> usize {
        dispatch!(self, m => m.bearings_into(pixels, out))
    }

    #[inline]
    fn try_pixel(&self, bearing: &Vector3<f64>) -> Option<Pixel> {
        dispatch!(self, m => out_of_line::try_pixel(m, bearing))
    }

    #[inline]
    fn try_bearing_with_jacobian(&self, pixel: &Pixel) -> Option<(Vector3<f64>, Matrix3x2<f64>)> {
        dispatch!(self, m => out_of_line::try_bearing_with_jacobian(m, pixel))
    }

    #[inline]
    fn try_pixel_with_jacobian(&self, bearing: &Vector3<f64>) -> Option<(Pixel, Matrix2x3<f64>)> {
        dispatch!(self, m => out_of_line::try_pixel_with_jacobian(m, bearing))
    }
}

impl From<Pinhole> for Camera {
    fn from(m: Pinhole) -> Self {
        Camera::Pinhole(m)
    }
}

impl From<KannalaBrandt> for Camera {
    fn from(m: KannalaBrandt) -> Self {
        Camera::KannalaBrandt(m)
    }
}

impl From<Equirectangular> for Camera {
    fn from(m: Equirectangular) -> Self {
        Camera::Equirectangular(m)
    }
}

impl From<Lut> for Camera {
    fn from(m: Lut) -> Self {
        Camera::Lut(m)
    }
}

impl From<TabulatedPinhole> for Camera {
    fn from(m: TabulatedPinhole) -> Self {
        Camera::TabulatedPinhole(m)
    }
}

impl From<SplinePinhole> for Camera {
    fn from(m: SplinePinhole) -> Self {
        Camera::SplinePinhole(m)
    }
}
