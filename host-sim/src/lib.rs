//! host-sim: the lift's digital twin.
//!
//! - [`physics`]: the float64 screw-nut model (the fixed-point core's reference twin).
#![warn(missing_docs)]

pub mod physics;
