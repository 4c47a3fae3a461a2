//! A rig of N central cameras placed in the rig frame.

use super::{CalibrationError, Camera, CameraModel, Pixel, rig_from_panorama};
use nalgebra::{IsometryMatrix3, Matrix3, Translation3, Vector3};
use vgps_geometry::geometry::{Ray, is_finite};

/// Largest accepted deviation of a `rig_from_camera` rotation from orthonormality:
/// `max |RᵀR − I|` (element-wise) and `|det R − 1|`.
pub const ROTATION_TOLERANCE: f64 = 1e-9;

/// One camera of a rig: its model and its placement `rig_from_camera`
/// (`point_in_rig = rig_from_camera * point_in_camera`; the translation is the camera centre
/// in the rig frame, metres).
#[derive(Clone, Debug, PartialEq)]
pub struct RigCamera {
    /// The camera model (bearings in the camera frame: x right, y down, z forward).
    pub model: Camera,
    /// The camera's placement in the rig frame (x forward, y left, z up).
    pub rig_from_camera: IsometryMatrix3<f64>,
}

/// A pixel of one camera of a rig.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigPixel {
    /// Index of the camera in the rig.
    pub camera: usize,
    /// The pixel in that camera's image.
    pub pixel: Pixel,
}

/// N central cameras rigidly mounted in a rig frame (x forward, y left, z up).
///
/// # Example
/// ```
/// use nalgebra::{Vector2, Vector3};
/// use vgps_camera::calibration::{Camera, Equirectangular, EquirectangularParams, Rig};
/// let pano = Equirectangular::new(EquirectangularParams { width: 2048, height: 1024 })?;
/// let rig = Rig::panorama(Camera::from(pano));
/// // The panorama's centre looks along rig +x (forward).
/// let ray = rig.ray(0, &Vector2::new(1023.5, 511.5))?;
/// assert!((ray.direction - Vector3::x()).norm() < 1e-12);
/// // A point to the left (rig +y) is seen a quarter of the width left of the centre.
/// let seen = rig.project_point(&Vector3::new(0.0, 10.0, 0.0));
/// assert_eq!(seen.len(), 1);
/// assert!((seen[0].pixel - Vector2::new(511.5, 511.5)).norm() < 1e-9);
/// # Ok::<(), vgps_camera::calibration::CalibrationError>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Rig {
    cameras: Vec<RigCamera>,
    /// Per camera, the pixels that never see the world (none by default).
    masks: Vec<Option<std::sync::Arc<super::CameraMask>>>,
    /// The rig's z axis stays within this angle of the local vertical (radians), when the
    /// calibration declares it (a vehicle rig: `level_within_deg` of the native file).
    level_within_rad: Option<f64>,
}

/// The largest angle a rig may declare it is level within ([`Rig::with_level_within_rad`]):
/// 90°, beyond which a "level" rig may be upside down.
pub const MAX_LEVEL_WITHIN_RAD: f64 = std::f64::consts::FRAC_PI_2;

impl Rig {
    /// A rig from its cameras, checking every rotation is orthonormal with determinant +1
    /// (within [`ROTATION_TOLERANCE`]) and every translation finite.
    pub fn new(cameras: Vec<RigCamera>) -> Result<Self, CalibrationError> {
        for (index, camera) in cameras.iter().enumerate() {
            let r: &Matrix3<f64> = camera.rig_from_camera.rotation.matrix();
            let orthogonality = (r.transpose() * r - Matrix3::identity()).abs().max();
            let det = (r.determinant() - 1.0).abs();
            let deviation = orthogonality.max(det);
            if !(deviation <= ROTATION_TOLERANCE) {
                return Err(CalibrationError::NonOrthonormalRotation {
                    camera: index,
                    deviation,
                    tolerance: ROTATION_TOLERANCE,
                });
            }
            if !is_finite(&camera.rig_from_camera.translation.vector) {
                return Err(CalibrationError::NonFiniteTranslation { camera: index });
            }
        }
        let masks = vec![None; cameras.len()];
        Ok(Self {
            cameras,
            masks,
            level_within_rad: None,
        })
    }

    /// A rig of one panorama at the rig origin, its centre along rig +x and its top along
    /// rig +z ([`rig_from_panorama`]).
    pub fn panorama(model: Camera) -> Self {
        Self {
            cameras: vec![RigCamera {
                model,
                rig_from_camera: IsometryMatrix3::from_parts(
                    Translation3::identity(),
                    rig_from_panorama(),
                ),
            }],
            masks: vec![None],
            level_within_rad: None,
        }
    }

    /// The rig declared level: its z axis stays within `tolerance_rad` of the local vertical
    /// (a vehicle rig, mounted level within a few degrees). The localizer and `vgps locate`
    /// then give the matcher this vertical; `None` removes the declaration.
    ///
    /// # Errors
    /// [`CalibrationError::InvalidParameters`] when the tolerance is not a finite angle in
    /// (0, [`MAX_LEVEL_WITHIN_RAD`]].
    pub fn with_level_within_rad(
        mut self,
        tolerance_rad: Option<f64>,
    ) -> Result<Self, CalibrationError> {
        if let Some(t) = tolerance_rad
            && !(t.is_finite() && t > 0.0 && t <= MAX_LEVEL_WITHIN_RAD)
        {
            return Err(CalibrationError::InvalidParameters {
                model: "rig",
                reason: format!(
                    "level within {}° is not an angle in (0°, 90°]",
                    t.to_degrees()
                ),
            });
        }
        self.level_within_rad = tolerance_rad;
        Ok(self)
    }

    /// The declared level tolerance ([`Self::with_level_within_rad`]), radians, if any.
    pub fn level_within_rad(&self) -> Option<f64> {
        self.level_within_rad
    }

    /// The rig with `mask` as camera `camera`'s mask (the pixels that never see the world);
    /// the mask must have the camera's image size.
    ///
    /// # Errors
    /// [`CalibrationError::UnknownCamera`], or [`CalibrationError::InvalidParameters`] when
    /// the sizes differ.
    pub fn with_mask(
        mut self,
        camera: usize,
        mask: super::CameraMask,
    ) -> Result<Self, CalibrationError> {
        let size = self.camera(camera)?.model.image_size();
        if mask.dimensions() != size {
            let (w, h) = mask.dimensions();
            return Err(CalibrationError::InvalidParameters {
                model: "mask",
                reason: format!(
                    "camera {camera}: mask of {w}×{h} pixels, the image has {}×{}",
                    size.0, size.1
                ),
            });
        }
        self.masks[camera] = Some(std::sync::Arc::new(mask));
        Ok(self)
    }

    /// Camera `camera`'s mask, when it has one.
    pub fn mask(&self, camera: usize) -> Option<&super::CameraMask> {
        self.masks.get(camera).and_then(|m| m.as_deref())
    }

    /// Whether `pixel` of camera `camera` is masked (never sees the world).
    pub fn is_masked(&self, camera: usize, pixel: &Pixel) -> bool {
        self.mask(camera).is_some_and(|m| m.is_masked_at(pixel))
    }

    /// The cameras.
    pub fn cameras(&self) -> &[RigCamera] {
        &self.cameras
    }

    /// Number of cameras.
    pub fn len(&self) -> usize {
        self.cameras.len()
    }

    /// True when the rig has no camera.
    pub fn is_empty(&self) -> bool {
        self.cameras.is_empty()
    }

    /// One camera, or [`CalibrationError::UnknownCamera`].
    pub fn camera(&self, index: usize) -> Result<&RigCamera, CalibrationError> {
        self.cameras
            .get(index)
            .ok_or(CalibrationError::UnknownCamera {
                index,
                count: self.cameras.len(),
            })
    }

    /// The ray in the rig frame (origin = camera centre, unit direction) of a pixel.
    ///
    /// # Errors
    /// [`CalibrationError::UnknownCamera`], or [`CalibrationError::PixelOutside`] when the
    /// pixel is outside the camera's valid image.
    #[inline]
    pub fn ray(&self, camera: usize, pixel: &Pixel) -> Result<Ray, CalibrationError> {
        let c = self.camera(camera)?;
        let bearing = c
            .model
            .try_bearing(pixel)
            .ok_or(CalibrationError::PixelOutside {
                camera,
                u: pixel.x,
                v: pixel.y,
            })?;
        Ok(Ray {
            origin: c.rig_from_camera.translation.vector,
            direction: c.rig_from_camera.rotation * bearing,
        })
    }

    /// The ray of a pixel (as [`Self::ray`]) and its angular standard deviation per axis
    /// for a pixel σ of `pixel_sigma_px`: the RMS over the two pixel axes of the camera
    /// model's Jacobian, `σ_px·√(tr(JᵀJ)/2)`. `None` for an unknown camera, a non-finite
    /// pixel, a pixel outside the image, or a σ that is not positive and finite.
    ///
    /// # Units
    /// Pixels in, metres (origin) and radians (σ) out.
    pub fn try_ray_with_sigma(
        &self,
        camera: usize,
        pixel: &Pixel,
        pixel_sigma_px: f64,
    ) -> Option<(Ray, f64)> {
        if !(pixel.x.is_finite() && pixel.y.is_finite()) {
            return None;
        }
        let c = self.camera(camera).ok()?;
        let (bearing, jacobian) = c.model.try_bearing_with_jacobian(pixel)?;
        let sigma_rad = pixel_sigma_px * ((jacobian.transpose() * jacobian).trace() / 2.0).sqrt();
        if !(sigma_rad.is_finite() && sigma_rad > 0.0) {
            return None;
        }
        Some((
            Ray {
                origin: c.rig_from_camera.translation.vector,
                direction: c.rig_from_camera.rotation * bearing,
            },
            sigma_rad,
        ))
    }

    /// Every camera and pixel that sees a direction in the rig frame (a point at infinity,
    /// so the camera centres' offsets do not matter). Empty for a zero or non-finite vector.
    pub fn project_direction(&self, direction_in_rig: &Vector3<f64>) -> Vec<RigPixel> {
        self.project_with(direction_in_rig, |c| {
            c.rig_from_camera
                .rotation
                .inverse_transform_vector(direction_in_rig)
        })
    }

    /// Every camera and pixel that sees a point in the rig frame (metres), from each
    /// camera's own centre. A camera whose centre coincides with the point sees nothing.
    pub fn project_point(&self, point_in_rig: &Vector3<f64>) -> Vec<RigPixel> {
        self.project_with(point_in_rig, |c| {
            c.rig_from_camera
                .inverse_transform_point(&(*point_in_rig).into())
                .coords
        })
    }

    /// The cameras that give a pixel for the camera-frame vector `in_camera(camera)`; none
    /// for a non-finite `input`.
    fn project_with(
        &self,
        input: &Vector3<f64>,
        in_camera: impl Fn(&RigCamera) -> Vector3<f64>,
    ) -> Vec<RigPixel> {
        if !is_finite(input) {
            return Vec::new();
        }
        self.cameras
            .iter()
            .enumerate()
            .filter_map(|(camera, c)| {
                c.model
                    .try_pixel(&in_camera(c))
                    .map(|pixel| RigPixel { camera, pixel })
            })
            .collect()
    }
}
