#![no_main]
//! Fuzz target `ladybug_ini`: the body is [`vgps::fuzzing::ladybug_ini`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::ladybug_ini(data));
