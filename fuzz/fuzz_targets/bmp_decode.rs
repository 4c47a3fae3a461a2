#![no_main]
//! Fuzz target `bmp_decode`: the body is [`vgps_fuzz_bodies::bmp_decode`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::bmp_decode(data));
