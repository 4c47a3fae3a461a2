#![no_main]
//! Fuzz target `drive_tables`: the body is [`vgps_fuzz_bodies::drive_tables`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::drive_tables(data));
