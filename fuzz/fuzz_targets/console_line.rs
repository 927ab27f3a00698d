//! Arbitrary UART bytes through the line buffer, the parser and every reply writer
//! (`harness::console_line`, which `tests/fuzz_harness.rs` also runs under proptest).
#![no_main]

#[path = "../harness/mod.rs"]
mod harness;

libfuzzer_sys::fuzz_target!(|data: &[u8]| harness::console_line(data));
