#![no_main]
//! Fuzz target `native_json`: the body is [`vgps_fuzz_bodies::native_json`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::native_json(data));
