#![no_main]
//! Fuzz target `building_footprints`: the body is [`vgps_fuzz_bodies::building_footprints`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::building_footprints(data));
