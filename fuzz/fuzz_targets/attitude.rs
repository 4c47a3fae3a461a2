#![no_main]
//! Fuzz target `attitude`: the body is [`vgps::fuzzing::attitude`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::attitude(data));
