#![no_main]
//! Fuzz target `nclt_table`: the body is [`vgps::fuzzing::nclt_table`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::nclt_table(data));
