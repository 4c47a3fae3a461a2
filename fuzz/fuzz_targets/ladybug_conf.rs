#![no_main]
//! Fuzz target `ladybug_conf`: the body is [`vgps::fuzzing::ladybug_conf`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::ladybug_conf(data));
