#![no_main]
//! Fuzz target `camera_mask`: the body is [`vgps_fuzz_bodies::camera_mask`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::camera_mask(data));
