//! What the localizer's integration tests share: a simulated drive with its landmark map
//! and rig.

use std::sync::Arc;
use vgps_camera::calibration::Rig;
use vgps_core::localizer::LandmarkMap;
use vgps_sim::simulate::{Preset, Scenario, SimulatedDrive, simulate};

/// A simulated drive with its surveyed landmarks as a map (in the drive's local frame) and
/// its rig.
pub struct TestDrive {
    pub drive: SimulatedDrive,
    pub map: Arc<LandmarkMap>,
    pub rig: Arc<Rig>,
}

/// The `short` preset's drive of seed `seed`, cut to `length_m` metres.
pub fn short_drive(seed: u64, length_m: f64) -> TestDrive {
    let mut scenario = Scenario::preset(Preset::Short, seed);
    scenario.length_m = length_m;
    let drive = simulate(&scenario).unwrap();
    let landmarks = drive.surveyed_landmarks().unwrap();
    let map =
        Arc::new(LandmarkMap::from_landmarks(&landmarks, Some(drive.scenario.origin)).unwrap());
    let rig = Arc::new(drive.scenario.rig.clone());
    TestDrive { drive, map, rig }
}
