#![no_main]
//! Fuzz target `triangulate`: the body is [`vgps::fuzzing::triangulate`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::triangulate(data));
