//! The float64 plant: the lift downstream of the board's H-bridge.
//!
//! - [`screw_nut`]: screw-nut-scissor dynamics (one equation for lifting and lowering) with the
//!   stick/slip treatment and the flank switch;
//! - [`kernel`]: the same mechanics with its constants precomputed, for the run loop;
//! - [`profile`]: seed 000's prescribed input speed (Fig. 2), for *paper mode*;
//! - [`drive`]: battery, H-bridge, DC motor and gearbox, for *closed-loop mode*;
//! - [`sensors`]: encoder, ADCs and limit switches, the board's view of the plant;
//! - [`brake`]: a spring-applied holding brake on the screw (closed-loop mode, optional).

pub mod brake;
pub mod drive;
pub mod kernel;
pub mod profile;
pub mod screw_nut;
pub mod sensors;

pub use brake::BrakeParams;
pub use drive::{BridgeState, DriveParams};
pub use profile::SpeedProfile;
pub use screw_nut::{Dir, Flank, Phase, ScrewNut, StructureDamping};
pub use sensors::{SensorParams, Sensors};
