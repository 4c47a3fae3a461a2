#![no_main]
//! Fuzz target `p3p`: the body is [`vgps::fuzzing::p3p_lambda_twist`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps::fuzzing::p3p_lambda_twist(data));
