//! The float64 physics of the lift: seed 000's screw-nut model in the sign convention of
//! `docs/model.md` (θ > 0 lifts, the load always pushes the nut toward −x).
//!
//! This module is the reference the fixed-point core is measured against (its "float64 twin")
//! and the building block of the simulated plant. It is deliberately plain `f64` code that reads
//! like the equations; nothing here is optimised.

pub mod ballscrew;
pub mod friction;
pub mod geometry;
pub mod screw;

pub use friction::{FrictionLaw, Lubricant};
pub use geometry::Geometry;
pub use screw::{Contact, Screw};

/// Standard gravity, m/s².
pub const G: f64 = 9.806_65;
