#![no_main]
//! Fuzz target `raw_image`: the body is [`vgps_fuzz_bodies::raw_image`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::raw_image(data));
