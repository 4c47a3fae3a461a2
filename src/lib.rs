//! # vgps — visual GPS from a spherical camera
//!
//! vgps turns a spherical camera (a Ladybug-style rig of five side cameras and one top
//! camera, or one equirectangular panorama) into a GPS receiver: bearings to landmarks with
//! surveyed WGS84 coordinates give the rig's position and attitude, each with a covariance.
//!
//! ## Architecture
//! - [`geo`]: WGS84 geodetic ↔ ECEF ↔ local ENU frames.
//! - [`geometry`]: the shared types (poses, rays, solution lists) and small vector helpers.
//! - [`solvers`]: minimal and non-minimal pose solvers, one per file, uniform signatures:
//!   [`solvers::p3p_cosines`](fn@solvers::p3p_cosines) (the law-of-cosines P3P of the Visual GPS proposal),
//!   [`solvers::p3p`](fn@solvers::p3p) (Lambda Twist), [`solvers::trilaterate`](fn@solvers::trilaterate) and [`solvers::refine_pose`](fn@solvers::refine_pose).
//! - [`attitude`]: rotation from known directions ([`attitude::triad`](fn@attitude::triad), [`attitude::wahba`](fn@attitude::wahba)).
//! - [`triangulation`]: landmark positions from rays ([`triangulation::intersect_two_rays`](fn@triangulation::intersect_two_rays),
//!   [`triangulation::triangulate_rays`](fn@triangulation::triangulate_rays)).
//! - [`mapping`]: landmark mapping from a moving rig (association, covariance, surrogates,
//!   survey mode, GPS time offset).
//! - [`calibration`]: camera models (pinhole, fisheye, panorama, LUT, NCLT tables), the
//!   camera rig, and the calibration file formats.
//! - [`fix`]: a fix from bearings to known landmarks (hypotheses, inliers, refinement,
//!   ambiguity and degeneracy statuses).
//! - [`robust`]: the generic robust estimator (MSAC + local optimisation, adaptive
//!   termination) and robust absolute pose with known correspondences.
//! - [`synthetic`]: the shared synthetic-problem generator used by tests and benchmarks.
//! - [`imaging`]: night frames of street lamps: rendering, PNG decoding with limits, the lamp
//!   detector.
//! - [`io`]: readers for the CSV inputs, with errors that name file, line and field.
//! - [`report`]: the outputs of `vgps replay` (statistics, tables, track files, plots).
//! - [`drive`]: drive logs (manifest, frames, detections, NMEA GNSS, truth): reader and writers.
//! - [`simulate`]: simulated drives (city, route, detections, GNSS with outages) for tests and demos.
//! - [`localizer`]: the frame-by-frame localizer for robot stacks (tracking, re-acquisition, surrogates).
//! - [`fuzzing`]: the bodies of the `cargo fuzz` targets (invariants checked on raw input).
//! - [`cli`]: the command implementations behind the thin `vgps` binary.
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

pub mod attitude;
pub mod calibration;
pub mod cli;
pub mod drive;
pub mod fix;
pub mod fuzzing;
pub mod geo;
pub mod geometry;
pub mod imaging;
pub mod io;
pub mod localizer;
pub mod mapping;
pub mod matcher;
pub mod report;
pub mod robust;
pub mod simulate;
pub mod solvers;
pub mod synthetic;
pub mod triangulation;
