//! Holding a ball screw ([`ScrewKind::Ball`]): it is not self-locking, so at rest the load
//! would turn it backwards.
//!
//! - **At rest** (Idle, Holding) the speed loop keeps running with a zero speed reference and
//!   the position error to where the lift came to rest: its integrator carries the holding
//!   voltage over from the motion (it is not reset when a motion ends or starts), and the
//!   model's at-rest torque (the load torque without friction) is its feed-forward. The motor
//!   draws the holding current (host-sim, 4008 at rated load: 9.7 A at 16°, 3.5 A at 30°) for
//!   as long as the lift stands; a spring-applied brake would save that (docs/control.md).
//! - **Back-driving** is uncommanded travel: at rest beyond `protect.runaway_travel`, or faster
//!   than commanded while lowering. Either latches [`FaultKind::Runaway`]; the reaction is to
//!   hold the screw where it tripped (same loop, current-limited), not to let go.
//! - **Any other fault** shorts the motor (dynamic brake) instead of letting it coast: a
//!   back-driven motor with shorted windings sinks the load slowly (≈ k_e²/R of damping)
//!   instead of dropping it, whatever is wrong with the sensors.

use super::config::ScrewKind;
use super::{Bridge, Controller, FaultKind, State};
use crate::units::RadiansPerSecond;

impl Controller {
    /// Whether this lift must be held at rest (ball screw).
    pub(super) fn holds_actively(&self) -> bool {
        self.cfg.screw == ScrewKind::Ball
    }

    /// The bridge at rest for either screw kind: the lead screw's [`Controller::rest_bridge`],
    /// or the ball screw's active hold / fault reaction.
    pub(super) fn at_rest_bridge(&mut self) -> Bridge {
        if !self.holds_actively() {
            return self.rest_bridge();
        }
        match (self.state, self.fault.map(|f| f.kind)) {
            (State::Fault, Some(FaultKind::Runaway)) => self.hold_bridge(),
            (State::Fault, _) => Bridge::Brake,
            _ => self.hold_bridge(),
        }
    }

    /// Speed loop at zero speed with the position error to `hold_target`.
    fn hold_bridge(&mut self) -> Bridge {
        let error_counts = self.hold_target.saturating_sub(self.enc.position());
        Bridge::Drive(self.speed_duty(RadiansPerSecond::ZERO, error_counts))
    }

    /// Whether the speed loop's integrator is kept across a change of state: always for a
    /// ball screw (it holds the load), except into a fault other than a back-drive.
    pub(super) fn keeps_integrator(&self, fault: Option<FaultKind>) -> bool {
        self.holds_actively() && matches!(fault, None | Some(FaultKind::Runaway))
    }
}
