//! # liftfw — portable control core of a screw-jack car scissor lift
//!
//! Everything that decides, computes or estimates lives here; the embassy firmware
//! (`src/main.rs`, `src/board/`) only moves numbers between the hardware and [`control::Controller::step`],
//! and `host-sim` runs the very same `step` against a float64 plant.
//!
//! The core is `no_std`, allocation-free and float-free on the hot path. Floats appear only
//! where a configuration is validated and quantised once (design in float, quantise once).
//!
//! Module map (data flows one way per tick: sensors → estimate → decide → actuators):
//! - [`units`]: typed fixed-point quantities with their Q formats.
//! - [`control`]: the per-tick entry point shared by the board and host-sim.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod control;
pub mod units;
pub mod math;
