//! # vgps-sim — simulated worlds for tests, benchmarks and the demo
//!
//! - [`simulate`]: simulated drives (city, route, detections, satellite GPS with outages).
//! - [`day`]: day frames of buildings lit by the sun, with the truth of their corners.
//! - [`render`]: night frames of street lamps through a calibrated camera.
//! - [`night`]: realistic night frames: the day scene at night with lamps, lit windows,
//!   car lights, wet-road reflections, bloom and vignetting.
//! - [`synthetic`]: every synthetic-problem generator of the workspace in one place.
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod day;
pub mod night;
pub mod render;
pub mod simulate;
pub mod synthetic;
