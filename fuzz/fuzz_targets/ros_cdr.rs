#![no_main]
//! Fuzz target `ros_cdr`: the body is [`vgps_fuzz_bodies::ros_cdr`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::ros_cdr(data));
