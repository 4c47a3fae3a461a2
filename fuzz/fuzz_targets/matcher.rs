#![no_main]
//! Fuzz target `matcher`: the body is [`vgps::fuzzing::matcher`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::matcher(data));
