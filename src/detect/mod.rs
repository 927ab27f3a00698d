//! Detectors that run every control tick on what the board measures and on the model's state.
//!
//! - [`stickslip`]: stick-slip of the lead screw–nut contact (docs/stick-slip.md).
pub mod stickslip;
