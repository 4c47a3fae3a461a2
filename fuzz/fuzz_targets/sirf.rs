#![no_main]
//! Fuzz target `sirf`: the body is [`vgps_fuzz_bodies::sirf`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::sirf(data));
