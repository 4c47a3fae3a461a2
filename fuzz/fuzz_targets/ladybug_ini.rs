#![no_main]
//! Fuzz target `ladybug_ini`: the body is [`vgps_fuzz_bodies::ladybug_ini`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::ladybug_ini(data));
