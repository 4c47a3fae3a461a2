#![no_main]
//! Fuzz target `drive_json`: the body is [`vgps_fuzz_bodies::drive_json`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::drive_json(data));
