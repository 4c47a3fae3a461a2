#![no_main]
//! Fuzz target `nclt_gps`: the body is [`vgps::fuzzing::nclt_gps`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::nclt_gps(data));
