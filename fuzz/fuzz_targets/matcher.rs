#![no_main]
//! Fuzz target `matcher`: the body is [`vgps_fuzz_bodies::matcher`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::matcher(data));
