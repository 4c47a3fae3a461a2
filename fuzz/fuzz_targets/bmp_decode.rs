#![no_main]
//! Fuzz target `bmp_decode`: the body is [`vgps::fuzzing::bmp_decode`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::bmp_decode(data));
