//! # vgps-geometry — the geometry under visual GPS
//!
//! The shared types and the mathematics of vgps, with no I/O:
//! - [`geo`]: WGS84 geodetic ↔ ECEF ↔ local ENU frames.
//! - [`geometry`]: the shared types (poses, rays, solution lists) and small vector helpers.
//! - [`solvers`]: minimal and non-minimal pose solvers, one per file, uniform signatures.
//! - [`attitude`]: rotation from known directions (TRIAD, Wahba), Euler angles.
//! - [`triangulation`]: landmark positions from rays.
//! - [`robust`]: the generic robust estimator (MSAC + local optimisation) and robust
//!   absolute pose with known correspondences.
//! - `synthetic` (feature `synthetic`): the test kit — reproducible random helpers and the
//!   synthetic problems of tests and benchmarks.
//!
//! ## Conventions (one set, everywhere)
//! - **Geodetic**: WGS84 latitude and longitude in degrees, ellipsoidal height in metres.
//!   Geometry is never done in degrees: it is done in ECEF or in a local East-North-Up (ENU)
//!   frame anchored at an origin ([`geo::LocalFrame`]).
//! - **Rig (body) frame**: x forward, y left, z up.
//! - **Camera frame**: x right, y down, z forward.
//! - **Pixels**: `(u, v)` = (column, row); integer coordinates are pixel centres; `(0, 0)` is
//!   the centre of the top-left pixel.
//! - **Transforms** are named `a_from_b`: `enu_from_rig` maps a vector or point expressed in
//!   the rig frame into the ENU frame (`point_in_enu = enu_from_rig * point_in_rig`). Points are
//!   named by their frame (`point_in_enu`). A pose `world_from_rig` is an isometry whose
//!   translation is the rig origin in the world frame.
//! - **Attitude** is reported as the quaternion `enu_from_rig` (w, x, y, z) and as heading
//!   (clockwise from true north, of the rig +x axis), pitch (rig +x above the horizon is
//!   positive) and roll (right side down is positive), in degrees at the edges.
//! - **Units**: metres and radians inside the library; degrees only at the edges (files, CLI).
//!
//! ## Errors
//! Each module has one `thiserror` error enum. Functions that may fail on degenerate
//! geometry return an empty solution list, `None` (`try_*`), or a typed error — never NaN or
//! infinity.
#![deny(missing_docs)]
#![forbid(unsafe_code)]

/// The default standard deviation of a measured bearing, radians (0.1°): the one default
/// of every estimator in the workspace (the pose refinement, robust absolute pose, the fix,
/// the matcher and the localizer; `vgps_core::measurement` re-exports it beside the
/// effective bearing σ). Written as `0.1_f64.to_radians()` computes it, so that the value
/// is the same bit for bit.
pub const DEFAULT_BEARING_SIGMA_RAD: f64 = 0.1 * (std::f64::consts::PI / 180.0);

pub mod attitude;
pub mod geo;
pub mod geometry;
pub mod robust;
pub mod solvers;
mod sym3;
#[cfg(any(test, feature = "synthetic"))]
pub mod synthetic;
pub mod triangulation;
