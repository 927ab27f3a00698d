//! The console: a line protocol a person types over the UART (115200 8N1).
//!
//! [`LineBuffer`] collects bytes into lines (backspace edits, CR/LF/CRLF end a line, overlong
//! lines are refused whole), [`parse`] turns a line into a [`Request`], and the `write_*`
//! functions format replies into any [`core::fmt::Write`] sink (a `heapless::String` on the
//! board). Nothing here allocates, and no input makes it panic (`tests/console_*.rs` and the
//! `fuzz/` target check that). docs/console.md is the user's reference.
//!
//! [`service`] puts it together: one complete line in, the request executed against the running
//! controller and configuration, the reply out (and `save` handed back to the caller, whose
//! flash store is async).

mod line;
mod parse;
mod reply;
pub mod service;
pub mod value;

use core::fmt;
pub use line::{Feed, LineBuffer};
pub use parse::{parse, HelpTopic, ParseError, Request};
pub(crate) use reply::{fill, height_arg, Arg};
pub use reply::{
    write_cruise_warning, write_get, write_help, write_key_help, write_limits, write_lube_warning,
    write_parse_error, write_refused, write_set, write_status, write_stick_slip_warning,
    StatusView,
};
pub use value::ValueError;

/// Longest line accepted, bytes (without the line end).
pub const MAX_LINE: usize = 96;

/// Words of a line as the user typed them, for messages: UTF-8 kept as bytes. [`parse`] checks a
/// line with [`crate::text::is_utf8`] and then works on its bytes, so the firmware links no
/// `core::str::from_utf8` (≈ 0.6 KiB of flash with its table). Made only from a checked line or
/// a `&str` (`From`), so it is always valid UTF-8; `Debug` shows it as the `&str` it is.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Words<'a>(&'a [u8]);

impl<'a> Words<'a> {
    /// The bytes (valid UTF-8).
    pub fn as_bytes(self) -> &'a [u8] {
        self.0
    }
}

impl<'a> From<&'a str> for Words<'a> {
    fn from(s: &'a str) -> Self {
        Words(s.as_bytes())
    }
}

impl fmt::Debug for Words<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match core::str::from_utf8(self.0) {
            Ok(s) => fmt::Debug::fmt(s, f),
            // Not made by this module (its words are checked): shown as bytes.
            Err(_) => fmt::Debug::fmt(self.0, f),
        }
    }
}
