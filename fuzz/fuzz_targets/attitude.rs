#![no_main]
//! Fuzz target `attitude`: the body is [`vgps_fuzz_bodies::attitude`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::attitude(data));
