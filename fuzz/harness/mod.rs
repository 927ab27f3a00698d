//! The fuzz targets' bodies, shared: cargo-fuzz runs them under libFuzzer
//! (`fuzz/fuzz_targets/*.rs`), and `tests/fuzz_harness.rs` runs the very same functions under
//! proptest in the ordinary test command (CI), for a bounded number of cases.
#![allow(dead_code)]

use core::fmt::Write;
use liftfw::config::record;
use liftfw::config::settings;
use liftfw::config::ValidatedConfig;
use liftfw::console::{self, Feed, LineBuffer, Request};
use liftfw::control::config::ControlConfig;

/// Arbitrary UART bytes through the line buffer, the parser and every reply writer; whatever
/// was accepted is still a valid configuration, and no reply carries a control byte.
pub fn console_line(data: &[u8]) {
    let mut cfg = ValidatedConfig::factory();
    let mut lb = LineBuffer::new();
    // A reply buffer the size the firmware would use: overflowing it must be an error, not a panic.
    let mut out: heapless::String<256> = heapless::String::new();
    for &b in data {
        let line = match lb.feed(b) {
            Feed::Line(l) => l,
            Feed::Overflow | Feed::Pending => continue,
        };
        out.clear();
        match console::parse(line) {
            Ok(Some(Request::Set(id, raw))) => {
                let r = settings::apply(&cfg, id, raw);
                let _ = console::write_set(&mut out, id, &r, &cfg);
                if let Ok(next) = r {
                    cfg = next;
                }
            }
            Ok(Some(Request::Get(id))) => {
                let _ = console::write_get(&mut out, &cfg, id);
            }
            Ok(Some(Request::Help(t))) => {
                let _ = console::write_help(&mut out, t);
            }
            Ok(Some(Request::Limits)) => {
                let _ = console::write_limits(&mut out, &cfg);
            }
            Ok(Some(_)) | Ok(None) => {
                let _ = out.write_str("ok");
            }
            Err(e) => {
                let _ = console::write_parse_error(&mut out, &e);
            }
        }
        // Replies go to a person's terminal: no control byte (a `help` reply's line ends
        // aside), whatever the line held.
        assert!(
            !out.bytes()
                .any(|b| (b < 0x20 && b != b'\n' && b != b'\r') || b == 0x7F),
            "{out:?}"
        );
    }
    // Whatever was accepted is still a valid configuration.
    assert_eq!(ValidatedConfig::new(*cfg.get()), Ok(cfg));
}

/// Bytes as a stored configuration record: decode and validation never panic, and a record
/// that decodes re-encodes to the same bytes. Inputs are either raw bytes or a bit mask over a
/// valid record (first byte odd), optionally with the CRC patched in afterwards (bit 1 of the
/// first byte), so the fuzzer reaches the checks behind the magic and the CRC.
pub fn config_record(input: &[u8]) {
    let Some((&mode, rest)) = input.split_first() else {
        return;
    };
    let mut data = if mode & 1 == 1 {
        let mut buf = [0u8; record::MAX_RECORD_LEN];
        let Some(n) = record::encode(&ControlConfig::DEFAULT, 1, &mut buf) else {
            panic!("the factory record encodes");
        };
        let mut v = buf[..n].to_vec();
        for (i, b) in rest.iter().enumerate() {
            v[i % n] ^= b;
        }
        v
    } else {
        rest.to_vec()
    };
    let n = data.len();
    if mode & 2 == 2 && n >= record::HEADER_LEN + 4 {
        let crc = record::crc32(&data[..n - 4]);
        data[n - 4..].copy_from_slice(&crc.to_le_bytes());
    }
    if let Ok((cfg, seq)) = record::decode(&data) {
        let mut buf = [0u8; record::MAX_RECORD_LEN];
        let Some(len) = record::encode(&cfg, seq, &mut buf) else {
            panic!("a decoded record encodes");
        };
        assert_eq!(&buf[..len], &data[..]);
        let _ = ValidatedConfig::new(cfg);
    }
}
