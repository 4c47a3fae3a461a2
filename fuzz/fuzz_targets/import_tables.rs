#![no_main]
//! Fuzz target `import_tables`: the body is [`vgps_fuzz_bodies::import_tables`].
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| vgps_fuzz_bodies::import_tables(data));
