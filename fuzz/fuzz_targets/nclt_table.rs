#![no_main]
//! Fuzz target `nclt_table`: the body is [`vgps_fuzz_bodies::nclt_table`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::nclt_table(data));
