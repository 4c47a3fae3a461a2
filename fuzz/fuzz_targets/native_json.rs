#![no_main]
//! Fuzz target `native_json`: the body is [`vgps::fuzzing::native_json`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::native_json(data));
