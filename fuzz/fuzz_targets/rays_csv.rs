#![no_main]
//! Fuzz target `rays_csv`: the body is [`vgps_fuzz_bodies::rays_csv`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::rays_csv(data));
