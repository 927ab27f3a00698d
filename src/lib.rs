//! # liftfw — portable control core of a screw-jack car scissor lift
//!
//! Everything that decides, computes or estimates lives here; the embassy firmware
//! (`src/main.rs`, `src/board/`) only moves numbers between the hardware and [`control::Controller::step`],
//! and `host-sim` runs the very same `step` against a float64 plant.
//!
//! The core is `no_std`, allocation-free and float-free on the hot path. Floats appear only
//! where a configuration is validated and quantised once (design in float, quantise once).
//!
//! Module map, lowest layer first (a module names only its own layer and lower ones;
//! `tests/layering.rs` checks it; data flows one way per tick: sensors → estimate → decide →
//! actuators):
//! - [`units`]: typed fixed-point quantities with their Q formats.
//! - [`math`]: integer kernels (e^(−y), √, 1/x) with proven error bounds.
//! - [`text`]: numbers and replies as text without `core::fmt`'s machinery.
//! - [`keys`]: every setting's key and accepted range, and [`ConfigError`], which names them.
//! - [`model`]: the fixed-point screw-nut model of seed 000 (geometry, friction laws, contact).
//! - [`estimator`]: the real-time friction-torque estimator built on the model.
//! - [`ident`]: online identification of the load and the thread's friction scale.
//! - [`detect`]: detectors on board-visible signals and the model's state (stick-slip).
//! - [`control`]: the per-tick entry point shared by the board and host-sim.
//! - [`config`]: the settings registry and the flash record.
//! - [`console`]: the line protocol.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]
#![cfg_attr(test, allow(clippy::unwrap_used, clippy::expect_used))]

pub mod config;
pub mod console;
pub mod control;
pub mod detect;
pub mod estimator;
pub mod ident;
pub mod keys;
pub mod math;
pub mod model;
pub mod text;
pub mod units;

pub use keys::ConfigError;
