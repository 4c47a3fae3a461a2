#![no_main]
//! Fuzz target `gpx`: the body is [`vgps_fuzz_bodies::gpx`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::gpx(data));
