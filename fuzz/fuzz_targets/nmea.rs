#![no_main]
//! Fuzz target `nmea`: the body is [`vgps::fuzzing::nmea`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::nmea(data));
