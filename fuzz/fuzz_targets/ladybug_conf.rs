#![no_main]
//! Fuzz target `ladybug_conf`: the body is [`vgps_fuzz_bodies::ladybug_conf`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::ladybug_conf(data));
