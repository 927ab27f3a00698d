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

pub use crate::text::Words;
pub use line::{Feed, LineBuffer};
pub use parse::{parse, HelpTopic, ParseError, Request};
pub use reply::{
    write_cruise_warning, write_get, write_help, write_key_help, write_limits, write_load,
    write_lube_warning, write_parse_error, write_refused, write_set, write_status,
    write_stick_slip_warning, write_thread_dry_warning, StatusView,
};
pub use value::ValueError;

/// Longest line accepted, bytes (without the line end).
pub const MAX_LINE: usize = 96;
