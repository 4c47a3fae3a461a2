#![no_main]
//! Fuzz target `lut`: the body is [`vgps_fuzz_bodies::lut`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::lut(data));
