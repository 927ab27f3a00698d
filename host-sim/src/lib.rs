//! host-sim: the lift's digital twin.
//!
//! - [`physics`]: the float64 screw-nut model (the fixed-point core's reference twin).
//! - [`solver`]: fixed-step Bogacki–Shampine RK23 and the event locator.
//! - [`plant`]: the plant built on the physics: screw-nut dynamics with stick/slip, the Fig. 2
//!   drive profile, the motor/bridge/battery and the board's sensors.
//! - [`sim`]: a run — plant + driver (paper profile, the liftfw core, or open-loop duty) —
//!   with its ground-truth [`trace`] and summary.
//! - [`paper`]: seed 000's 18-case matrix and its reproduction report; [`plots`]: its figures.
//! - [`study`]: the step-size convergence study.
//! - [`truth`]: stick-slip episodes labelled from the plant's phase log; [`score`]: the core's
//!   stick-slip detector scored against them (`host-sim stickslip`).
//! - [`inject`]: faults a user injects into a closed-loop run (sensors, supply, jam, overload,
//!   a hung control task).
//! - [`serve`]: the simulated board with the core's console on loopback TCP (`host-sim serve`).
//! - [`ballscrew`]: the ball-screw load distribution with geometric errors (seed 001) and its study.
#![warn(missing_docs)]

pub mod ballscrew;
pub mod cli;
pub mod inject;
pub mod lift;
pub mod paper;
pub mod physics;
pub mod plant;
pub mod plots;
pub mod score;
pub mod serve;
pub mod sim;
pub mod solver;
pub mod study;
pub mod trace;
pub mod truth;
