//! Day frames of a simulated drive: box buildings whose vertices are the corner landmarks,
//! shaded by the sun of the drive's time and place, with windows, awnings, street markings,
//! parked cars and trees, through a calibrated camera model (the day counterpart of the
//! night renderer [`crate::render`]).
//!
//! - [`sun`]: the sun's azimuth and elevation for a time and place.
//! - [`scene`]: the day scene of a simulated [`World`](crate::simulate::World).
//! - [`render`]: the ray-cast renderer and the truth of the visible corners.

pub mod render;
pub mod scene;
pub mod sun;

pub use render::{CornerTruth, DayFrame, DayOptions, DayRenderer};
pub use scene::DayScene;
pub use sun::{SunPosition, sun_position};

#[cfg(test)]
mod tests;
