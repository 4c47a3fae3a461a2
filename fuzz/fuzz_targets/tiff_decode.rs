#![no_main]
//! Fuzz target `tiff_decode`: the body is [`vgps::fuzzing::tiff_decode`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::tiff_decode(data));
