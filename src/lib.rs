//! # vgps — visual GPS from a spherical camera
//!
//! The `vgps` command-line tool. Its library target gathers the whole workspace under one
//! name for the tool's commands, examples, tests and benchmarks; a program that embeds vgps
//! depends on [`vgps_core`] (which re-exports the crates below it) rather than on this one,
//! which also pulls the command line, the simulator and the report writers.
//!
//! | module | crate | what |
//! |---|---|---|
//! | [`geo`], [`geometry`], [`solvers`], [`attitude`], [`triangulation`], [`robust`] | `vgps-geometry` | the mathematics, no I/O |
//! | [`io`] | `vgps-io` | the CSV inputs, atomic writes |
//! | [`calibration`], [`imaging`] | `vgps-camera` | pixels to bearings, images to detections |
//! | [`fix`], [`matcher`], [`localizer`], [`mapping`] | `vgps-core` | the fix, the matcher, the localizer, mapping |
//! | [`drive`], [`report`] | `vgps-replay` | drive logs and replay outputs |
//! | [`simulate`], [`synthetic`] | `vgps-sim` | simulated drives and problems |
//! | [`cli`] | this crate | the commands |
//!
//! The conventions (frames, units, names) are set once in [`vgps_geometry`].
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub use vgps_camera::calibration;
pub use vgps_core::{fix, localizer, mapping, matcher};
pub use vgps_geometry::{attitude, geo, geometry, robust, solvers, triangulation};
pub use vgps_io as io;
pub use vgps_replay::{drive, report};
pub use vgps_sim::{simulate, synthetic};

/// Images: decoding and lamp detection (`vgps-camera`), the detection of a drive frame's
/// images (`vgps-replay`) and the night renderer (`vgps-sim`).
pub mod imaging {
    pub use vgps_camera::imaging::*;
    pub use vgps_replay::frame_images::*;
    pub use vgps_sim::render::*;
}

pub mod cli;
