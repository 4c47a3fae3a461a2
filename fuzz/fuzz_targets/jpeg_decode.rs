#![no_main]
//! Fuzz target `jpeg_decode`: the body is [`vgps_fuzz_bodies::jpeg_decode`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::jpeg_decode(data));
