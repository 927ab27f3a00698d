//! host-sim: the lift's digital twin.
//!
//! - [`twin`]: the simulated lift — the float64 [`physics`] (the fixed-point core's reference
//!   twin), the [`solver`] (fixed-step Bogacki–Shampine RK23 and the event locator), the
//!   [`plant`] (screw-nut dynamics with stick/slip, the Fig. 2 drive profile, the
//!   motor/bridge/battery and the board's sensors), a run ([`sim`]: plant + driver — paper
//!   profile, the liftfw core, or open-loop duty) with its ground-truth [`trace`], and the
//!   stick-slip episodes labelled from the plant's phase log ([`truth`]); the faults a user
//!   injects into a closed-loop run ([`inject`]: sensors, supply, jam, overload, a hung control
//!   task).
//! - [`apps`]: the twin in use — `host-sim lift` ([`apps::lift`]) and the simulated board with
//!   the core's console on loopback TCP ([`apps::serve`]).
//! - [`commands`]: the `host-sim` command line, one module per subcommand; [`plotting`]: what
//!   the apps' and the studies' plots share (the font).
//! - [`studies`]: the twin measured — seed 000's matrix and its reproduction report
//!   ([`studies::paper`]), the step-size convergence study ([`studies::convergence`]), the core's
//!   stick-slip detector scored against the truth ([`studies::stickslip`]) and the ball-screw
//!   load distribution with geometric errors of seed 001 ([`studies::load_distribution`]).
//!
//! The twin's modules are also at the crate root (`host_sim::physics`, …): everything else,
//! here and in the core's tests, is built on them.
#![warn(missing_docs)]

pub mod apps;
pub mod cli;
pub mod commands;
pub mod plotting;
pub mod studies;
pub mod twin;

pub use twin::{inject, physics, plant, sim, solver, trace, truth};
