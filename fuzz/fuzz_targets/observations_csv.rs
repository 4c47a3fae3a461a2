#![no_main]
//! Fuzz target `observations_csv`: the body is [`vgps::fuzzing::observations_csv`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::observations_csv(data));
