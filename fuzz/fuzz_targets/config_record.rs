//! Bytes as a stored configuration record (`harness::config_record`, which
//! `tests/fuzz_harness.rs` also runs under proptest).
#![no_main]

#[path = "../harness/mod.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|input: &[u8]| harness::config_record(input));
