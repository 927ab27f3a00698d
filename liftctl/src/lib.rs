//! liftctl: configure a liftfw lift's limit stops and settings and watch it from a PC, over the
//! firmware's console protocol (docs/console.md) on a serial port or, for host-sim's simulated
//! board, loopback TCP.
//!
//! - [`board`]: the console link, one command and one checked reply at a time.
//! - [`settings`]: PC-side checks with the core's own parser and registry, ordered changes
//!   undone on failure, TOML export and import.
//! - [`watch`]: live status, CSV and PNG.

pub mod board;
pub mod settings;
pub mod watch;
