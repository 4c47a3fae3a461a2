#![no_main]
//! Fuzz target `nclt_gps`: the body is [`vgps_fuzz_bodies::nclt_gps`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::nclt_gps(data));
