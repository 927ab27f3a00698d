//! The simulated lift: physics, plant, solver, a run and its ground truth.

pub mod physics;
pub mod plant;
pub mod sim;
pub mod solver;
pub mod trace;
pub mod truth;
