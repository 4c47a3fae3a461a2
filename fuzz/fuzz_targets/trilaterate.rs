#![no_main]
//! Fuzz target `trilaterate`: the body is [`vgps_fuzz_bodies::trilateration`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::trilateration(data));
