//! The twin in use: the lift in closed loop with the core, and the simulated board.

pub mod lift;
pub mod serve;
