#![no_main]
//! Fuzz target `lut`: the body is [`vgps::fuzzing::lut`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::lut(data));
