#![no_main]
//! Fuzz target `triangulate`: the body is [`vgps_fuzz_bodies::triangulate`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::triangulate(data));
