#![no_main]
//! Fuzz target `drive_json`: the body is [`vgps::fuzzing::drive_json`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::drive_json(data));
