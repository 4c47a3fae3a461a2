#![no_main]
//! Fuzz target `png_decode`: the body is [`vgps_fuzz_bodies::png_decode`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::png_decode(data));
