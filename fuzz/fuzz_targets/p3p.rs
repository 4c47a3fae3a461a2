#![no_main]
//! Fuzz target `p3p`: the body is [`vgps_fuzz_bodies::p3p_lambda_twist`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::p3p_lambda_twist(data));
