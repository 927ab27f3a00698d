//! The simulated lift: physics, plant, solver, a run, its ground truth and the faults injected
//! into it.

pub mod inject;
pub mod physics;
pub mod plant;
pub mod sim;
pub mod solver;
pub mod trace;
pub mod truth;
