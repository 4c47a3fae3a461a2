#![no_main]
//! Fuzz target `png_decode`: the body is [`vgps::fuzzing::png_decode`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::png_decode(data));
