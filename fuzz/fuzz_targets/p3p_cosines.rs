#![no_main]
//! Fuzz target `p3p_cosines`: the body is [`vgps_fuzz_bodies::p3p_law_of_cosines`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::p3p_law_of_cosines(data));
