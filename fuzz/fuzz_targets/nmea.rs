#![no_main]
//! Fuzz target `nmea`: the body is [`vgps_fuzz_bodies::nmea`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::nmea(data));
