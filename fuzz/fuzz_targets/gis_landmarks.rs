#![no_main]
//! Fuzz target `gis_landmarks`: the body is [`vgps_fuzz_bodies::gis_landmarks`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::gis_landmarks(data));
