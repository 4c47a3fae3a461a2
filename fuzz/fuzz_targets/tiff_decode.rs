#![no_main]
//! Fuzz target `tiff_decode`: the body is [`vgps_fuzz_bodies::tiff_decode`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::tiff_decode(data));
