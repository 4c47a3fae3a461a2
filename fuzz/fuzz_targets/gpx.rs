#![no_main]
//! Fuzz target `gpx`: the body is [`vgps::fuzzing::gpx`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::gpx(data));
