#![no_main]
//! Fuzz target `truth_formats`: the body is [`vgps_fuzz_bodies::truth_formats`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::truth_formats(data));
