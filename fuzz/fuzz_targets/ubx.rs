#![no_main]
//! Fuzz target `ubx`: the body is [`vgps_fuzz_bodies::ubx`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::ubx(data));
