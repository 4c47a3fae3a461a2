#![no_main]
//! Fuzz target `landmarks_csv`: the body is [`vgps_fuzz_bodies::landmarks_csv`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::landmarks_csv(data));
