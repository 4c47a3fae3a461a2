#![no_main]
//! Fuzz target `nclt_calibration`: the body is [`vgps::fuzzing::nclt_calibration`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::nclt_calibration(data));
