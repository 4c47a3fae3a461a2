#![no_main]
//! Fuzz target `nclt_calibration`: the body is [`vgps_fuzz_bodies::nclt_calibration`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::nclt_calibration(data));
