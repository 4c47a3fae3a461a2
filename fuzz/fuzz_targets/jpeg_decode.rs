#![no_main]
//! Fuzz target `jpeg_decode`: the body is [`vgps::fuzzing::jpeg_decode`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::jpeg_decode(data));
