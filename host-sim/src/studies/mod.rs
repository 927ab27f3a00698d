//! The twin measured: the papers' studies and the core's detector scored against the truth.

pub mod convergence;
pub mod estimate;
pub mod load_distribution;
pub mod paper;
pub mod stickslip;
