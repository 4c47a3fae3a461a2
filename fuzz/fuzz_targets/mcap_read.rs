#![no_main]
//! Fuzz target `mcap_read`: the body is [`vgps_fuzz_bodies::mcap_read`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::mcap_read(data));
