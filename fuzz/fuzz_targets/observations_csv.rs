#![no_main]
//! Fuzz target `observations_csv`: the body is [`vgps_fuzz_bodies::observations_csv`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::observations_csv(data));
