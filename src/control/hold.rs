//! Holding a ball screw ([`ScrewKind::Ball`]): it is not self-locking, so at rest the load
//! would turn it backwards.
//!
//! - **At rest** (Idle, Holding) the speed loop keeps running with a zero speed reference and
//!   the position error to where the lift came to rest: its integrator carries the holding
//!   voltage over from the motion (it is not reset when a motion ends or starts), and the
//!   model's at-rest torque (the load torque without friction) is its feed-forward. The motor
//!   draws the holding current (host-sim, 4008 at rated load: 9.7 A at 16°, 3.5 A at 30°) for
//!   as long as the lift stands, unless a holding brake is fitted (below).
//! - **Back-driving** is uncommanded travel: at rest beyond `protect.runaway_travel`, or faster
//!   than commanded while lowering. Either latches [`FaultKind::Runaway`]; the reaction is to
//!   hold the screw where it tripped (same loop, current-limited), not to let go.
//! - **Any other fault** shorts the motor (dynamic brake) instead of letting it coast: a
//!   back-driven motor with shorted windings sinks the load slowly (≈ k_e²/R of damping)
//!   instead of dropping it, whatever is wrong with the sensors.
//! - **Holding brake** (`drive.brake = spring`, either screw kind): a spring-applied brake is
//!   engaged whenever its output ([`super::Outputs::brake_release`]) is off, so it holds at
//!   boot, without power and on every fault. The core powers it only while a motion runs: a
//!   motion first lets the motor take the load with the brake still engaged (a ball screw's
//!   hold winds the coupling up to where the motor last held the load, or to the model's
//!   twist after a boot or a fault, until the encoder is there and still, at most
//!   4 × `drive.brake_ms`), then powers the brake and holds through `drive.brake_ms` while it
//!   lets go, then the profile starts; at rest the output goes off at
//!   once and the motor keeps holding for `drive.brake_ms` while the brake closes, then lets
//!   go (the lead screw's rest bridge: shorted once slow): the battery supplies nothing, and
//!   the current the unwinding coupling drives through the shorted windings dies away. The
//!   runaway reference follows the encoder over that expected travel (to where the measured
//!   torque's twist says the coupling is relaxed); travel beyond it (a slipping brake) trips.
//!   A STOP before the release is complete ends the motion there (the brake is not released
//!   only to be engaged again).

use super::config::{BrakeConfig, ScrewKind};
use super::{Bridge, Controller, FaultKind, Reading, State, ARRIVED_COUNTS};
use crate::units::{RadiansPerSecond, Q};

/// The holding brake's output and its timing.
#[derive(Clone, Copy, Debug)]
pub(super) struct BrakeState {
    present: bool,
    /// Release (and engage) time, ticks.
    delay: u32,
    /// The output: coil powered, brake released.
    pub(super) release: bool,
    /// Ticks since `release` last changed (saturating; boots as long ago).
    ticks: u32,
    /// A motion has held the load since the boot or the last fault: `hold_target` is where the
    /// motor held it, with the coupling wound up.
    wound: bool,
    /// At rest the motor has let go of the load, and the encoder's expected unwinding:
    /// (where the motor held, where the coupling is relaxed), counts.
    let_go: bool,
    unwind: (i32, i32),
    /// This motion's motor has taken the load (the brake may release), and the ticks it has
    /// tried to.
    taken: bool,
    take_ticks: u32,
}

impl BrakeState {
    pub(super) fn new(cfg: &BrakeConfig, tick_us: u32) -> BrakeState {
        BrakeState {
            present: cfg.present,
            delay: crate::units::ms_to_ticks(cfg.delay_ms, tick_us).max(1),
            release: false,
            ticks: u32::MAX,
            wound: false,
            let_go: false,
            unwind: (0, 0),
            taken: false,
            take_ticks: 0,
        }
    }

    /// Keep the output's timing across a reconfiguration at rest.
    pub(super) fn keep_timing(&mut self, old: &BrakeState) {
        self.release = old.release && self.present;
        self.ticks = old.ticks;
    }

    /// Forget where the motor held the load (a fault let it go).
    pub(super) fn unwound(&mut self) {
        self.wound = false;
        self.let_go = false;
    }
}

impl Controller {
    /// Whether this lift must be held at rest (ball screw).
    pub(super) fn holds_actively(&self) -> bool {
        cfg!(feature = "ball-screw") && self.derived.cfg.screw == ScrewKind::Ball
    }

    /// The bridge at rest for either screw kind: the lead screw's [`Controller::rest_bridge`],
    /// or the ball screw's active hold / fault reaction.
    pub(super) fn at_rest_bridge(&mut self, x: &Reading) -> Bridge {
        let b = &self.motion.brake;
        if b.present && self.live.state != State::Fault && b.ticks >= b.delay {
            return self.braked_rest(x);
        }
        if !self.holds_actively() {
            return self.rest_bridge(x);
        }
        match (self.live.state, self.live.fault.map(|f| f.kind)) {
            (State::Fault, Some(FaultKind::Runaway)) => self.hold_bridge(x),
            (State::Fault, _) => Bridge::Brake,
            _ => self.hold_bridge(x),
        }
    }

    /// The brake's output for this tick: released only while a motion runs (never in a fault,
    /// at rest or without a brake).
    #[inline]
    pub(super) fn brake_step(&mut self) {
        let moving = self.live.moving();
        let brake = &mut self.motion.brake;
        if !brake.present {
            // `release` stays false.
            return;
        }
        if !moving {
            brake.taken = false;
            brake.take_ticks = 0;
        }
        let want = moving && brake.taken;
        if want != brake.release {
            brake.release = want;
            brake.ticks = 0;
            brake.let_go = false;
        } else {
            brake.ticks = brake.ticks.saturating_add(1);
        }
    }

    /// Before a motion with a brake: first the motor takes the load with the brake still
    /// engaged (the hold winds the coupling up to `hold_target`, until the encoder is there and
    /// still, at most 4 × `drive.brake_ms`), then the output releases the brake and the motor
    /// holds through `drive.brake_ms`. Meanwhile the profile waits, and so does the overload
    /// check's hold-off. `None` once the brake is released (or without one).
    #[inline]
    pub(super) fn releasing_brake(&mut self, x: &Reading) -> Option<Bridge> {
        if self.awaiting_brake() {
            return Some(self.take_up(x));
        }
        if self.motion.brake.present {
            self.motion.brake.wound = true;
        }
        None
    }

    /// Whether this motion is still waiting for the brake (taking the load up or releasing):
    /// the profile has not started, so a STOP ends the motion at once instead of letting the
    /// brake release first.
    #[inline(always)]
    pub(super) fn awaiting_brake(&self) -> bool {
        let b = &self.motion.brake;
        b.present && !(b.release && b.ticks >= b.delay)
    }

    /// The bridge while the brake is still engaged or releasing at the start of a motion.
    #[inline(never)]
    fn take_up(&mut self, x: &Reading) -> Bridge {
        let b = self.motion.brake;
        self.motion.motion_ticks = 0;
        if !self.holds_actively() {
            self.motion.brake.taken = true;
            return self.rest_bridge(x);
        }
        if !b.taken {
            let here = self.live.enc.position();
            if b.take_ticks == 0 && !b.wound {
                // Nothing has held the load since the boot or a fault: wind the coupling up to
                // the model's at-rest torque (the rated load's) before the brake lets go.
                let twist = self
                    .derived
                    .twist_scale
                    .apply32(x.estimate.model_screw_torque.bits());
                self.motion.hold_target = here.saturating_add(twist);
            }
            self.motion.brake.take_ticks = b.take_ticks.saturating_add(1);
            let target = self.motion.hold_target;
            let there = target.saturating_sub(here).abs() <= ARRIVED_COUNTS
                && x.estimate.screw_speed.sat_abs() < self.derived.cfg.estimator.rest_speed;
            self.motion.brake.taken = there || b.take_ticks >= b.delay.saturating_mul(4);
            // The brake holds the screw: only the coupling winds up, so the position gain may
            // be 4× the hold's (16 /s).
            let error = target.saturating_sub(here);
            let duty = self.speed_duty(x, RadiansPerSecond::ZERO, error.saturating_mul(4), 0);
            return Bridge::Drive(duty);
        }
        self.hold_bridge(x)
    }

    /// At rest with the brake engaged: the motor lets go (the rest bridge: shorted once slow)
    /// and the coupling unwinds through it, from where the motor held to where the coupling is
    /// relaxed. That travel is expected: the runaway reference follows the encoder within it,
    /// so only travel beyond it (a slipping brake) counts.
    #[inline(never)]
    fn braked_rest(&mut self, x: &Reading) -> Bridge {
        let enc = self.live.enc.position();
        let brake = &mut self.motion.brake;
        if !brake.let_go {
            let twist = self
                .derived
                .twist_scale
                .apply32(x.estimate.measured_screw_torque.bits());
            brake.let_go = true;
            brake.unwind = (enc, enc.saturating_sub(twist));
        }
        let (from, to) = brake.unwind;
        self.live.hold_position = enc.clamp(from.min(to), from.max(to));
        self.rest_bridge(x)
    }

    /// Speed loop at zero speed with the position error to `hold_target`.
    fn hold_bridge(&mut self, x: &Reading) -> Bridge {
        let error_counts = self
            .motion
            .hold_target
            .saturating_sub(self.live.enc.position());
        Bridge::Drive(self.speed_duty(x, RadiansPerSecond::ZERO, error_counts, 0))
    }

    /// Whether the speed loop's integrator is kept across a change of state: always for a
    /// ball screw (it holds the load), except into a fault other than a back-drive.
    pub(super) fn keeps_integrator(&self, fault: Option<FaultKind>) -> bool {
        self.holds_actively() && matches!(fault, None | Some(FaultKind::Runaway))
    }
}
