//! Arbitrary UART bytes through the line buffer, the parser and every reply writer.
#![no_main]

use core::fmt::Write;
use libfuzzer_sys::fuzz_target;
use liftfw::config::settings;
use liftfw::config::ValidatedConfig;
use liftfw::console::{self, Feed, LineBuffer, Request};

fuzz_target!(|data: &[u8]| {
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
    }
    // Whatever was accepted is still a valid configuration.
    assert_eq!(ValidatedConfig::new(*cfg.get()), Ok(cfg));
});
