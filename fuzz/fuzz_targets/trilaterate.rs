#![no_main]
//! Fuzz target `trilaterate`: the body is [`vgps::fuzzing::trilateration`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::trilateration(data));
