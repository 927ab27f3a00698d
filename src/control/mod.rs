//! The control tick: `Controller::step(now, inputs) -> outputs`.
//!
//! This is the only function the firmware's control task and host-sim call every tick.
//! Inputs are what the board's peripherals deliver (raw counts and codes), outputs are what
//! its peripherals accept. Conversion to physical units happens here, in the core, so that
//! host-sim exercises exactly the arithmetic the board runs.
//!
//! One tick, in order (data flows one way):
//! 1. [`sense`]: encoder counter → position, ADC codes → A and V, switches debounced;
//! 2. [`crate::estimator`]: pose, speed, the model's torques and the measured torque;
//! 3. [`protect`]: every monitor; a trip latches a [`Fault`] with a snapshot and coasts the bridge;
//! 4. the supervisor (`supervisor.rs`): buttons and commands → Idle / Lifting / Lowering / Holding / Fault;
//! 5. [`profile`]: the ramped reference toward the target (a limit stop or a set height);
//! 6. [`speed`]: PI speed loop with the model's torque as feed-forward → duty (at rest too for a
//!    ball screw, which is not self-locking: `hold`).
//!
//! The halt planner works on the *screw* position: the encoder sits on the motor, and under a
//! torque T the coupling (stiffness k) lets the screw lag the gear output by T/k (≈ 0.47 rad,
//! 0.55 mm of head height at rated load near α₀). While driving, the estimated screw position is
//! the encoder position minus the model's twist, so the head stops at the target and not half a
//! millimetre short of it.
//!
//! The controller's state comes in three parts: what it derives from its configuration
//! (`derived.rs`: limit stops in counts, scales, gains, tick counts), the working state of
//! motion control (`motion.rs`: profile, speed loop, monitors, detectors), both built with the
//! configuration, and the live state a new configuration keeps (`supervisor.rs`: encoder,
//! state machine, fault, buttons, where the lift rests, the latest measurements). A tick's
//! measurements pass from phase to phase as values (`Reading`).

pub mod clip;
pub mod config;
mod creep;
mod derived;
pub mod edges;
mod hold;
mod loadid;
pub mod lube;
mod motion;
pub mod park;
pub mod profile;
pub mod protect;
pub mod sense;
pub mod speed;
mod supervisor;

use crate::estimator::{Estimator, Measurements, TickEstimate};
use crate::units::{Amperes, Instant, Kilograms, Metres, NewtonMetres, RadiansPerSecond, Volts, Q};
use crate::ConfigError;
use config::ControlConfig;
use derived::{Derived, ARRIVED_COUNTS};
use motion::Motion;
pub use protect::FaultKind;
use protect::Sample;
pub use sense::Switches;
use supervisor::Live;
pub use supervisor::{Command, Event, Fault, Refusal, State};

/// Raw inputs sampled by the board at the start of a control tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Inputs {
    /// Free-running 16-bit quadrature counter of the motor encoder (timer CNT register).
    pub encoder_count: u16,
    /// µs from the latest change of `encoder_count` to the moment it was sampled, from a
    /// 1 MHz capture timer (16-bit, wrapping; the core reads it only on ticks where the count
    /// changed, so the wrap never matters). 0 on a board without edge capture: edges are then
    /// timed to the tick. See [`edges`].
    pub encoder_edge_age: u16,
    /// Motor current ADC code (12-bit, right aligned), sampled mid-PWM-period.
    pub current_raw: u16,
    /// Supply voltage ADC code (12-bit, right aligned) from the battery divider.
    pub supply_raw: u16,
    /// Digital inputs (limit switches, buttons), already debounced or not: see [`Switches`].
    pub switches: Switches,
}

/// What the H-bridge should do for the next tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Bridge {
    /// Both half-bridges off: the motor free-wheels (the screw is self-locking when stopped).
    #[default]
    Coast,
    /// Both low sides on: the motor is short-circuited and brakes dynamically.
    Brake,
    /// Drive with a signed duty cycle in Q15 (`i16::MAX` ≈ +100 %, lifting; negative: lowering).
    Drive(i16),
}

/// Outputs applied by the board at the end of a control tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Outputs {
    /// H-bridge command.
    pub bridge: Bridge,
    /// True when this tick completed normally: only then may the board feed the watchdog.
    pub feed_watchdog: bool,
    /// Power the spring-applied holding brake's coil (release it). False (engaged) at rest,
    /// on every fault and whenever `drive.brake` is `none` (`hold.rs`).
    pub brake_release: bool,
    /// Something worth a log line happened this tick.
    pub event: Option<Event>,
}

/// A snapshot for the console's `status` line and telemetry.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Status {
    /// Supervisor state.
    pub state: State,
    /// Head height (model, from the encoder).
    pub height: Metres,
    /// Screw speed.
    pub screw_speed: RadiansPerSecond,
    /// Motor current.
    pub current: Amperes,
    /// Supply.
    pub supply: Volts,
    /// Estimated thread friction torque T_r.
    pub friction_torque: NewtonMetres,
    /// A stick-slip episode is under way (`crate::detect::stickslip`).
    pub stick_slip: bool,
    /// Coupling-torque drop of the last detected slip.
    pub stick_slip_amplitude: NewtonMetres,
    /// Stick-slip episodes since boot.
    pub stick_slip_episodes: u32,
    /// The latched fault, if any.
    pub fault: Option<FaultKind>,
    /// Encoder position, counts.
    pub position: i32,
    /// The position is known (false: homing on the lower limit switch is required).
    pub homed: bool,
    /// The identified load, its interval and the friction scale (`crate::ident`).
    pub load: crate::ident::LoadReport,
    /// T_r at the ends of the friction scale's interval (with the loads it implies).
    pub friction_torque_range: (NewtonMetres, NewtonMetres),
    /// The motion under way (or the last one) runs slower than `motion.cruise_speed`: the
    /// screw speed the motor reached at the present load and supply (`limit_cruise`).
    pub cruise_limit: Option<RadiansPerSecond>,
    /// Ball screw: the friction coefficient identified from the current and the law's, once a
    /// lift/lowering pair has been solved (`lube`).
    #[cfg(feature = "ball-screw")]
    pub lube: Option<lube::LubeReport>,
}

/// One tick's measurements, as the phases of the tick pass them on (and as the supervisor keeps
/// the latest: commands, the fault snapshot and the status read them between ticks).
#[derive(Clone, Copy, Debug, Default)]
struct Reading {
    current: Amperes,
    supply: Volts,
    /// The switches, debounced.
    switches: Switches,
    estimate: TickEstimate,
}

impl Reading {
    /// `*self = *x`, field by field: the core is built for size (opt-level "z"), where the
    /// compiler copies a struct of this size (52 bytes) through a call to `memcpy`, ≈ 90
    /// instructions on every tick; field by field it is a load and a store each. Exhaustive
    /// patterns: a new field is a compile error here, not a field left behind.
    #[inline(always)]
    fn set(&mut self, x: &Reading) {
        let Reading {
            current,
            supply,
            switches,
            estimate:
                TickEstimate {
                    height,
                    screw_speed,
                    screw_accel,
                    friction_torque,
                    axial,
                    thread_torque,
                    model_screw_torque,
                    model_motor_torque,
                    measured_screw_torque,
                    flags,
                },
        } = *x;
        self.current = current;
        self.supply = supply;
        self.switches = switches;
        let e = &mut self.estimate;
        e.height = height;
        e.screw_speed = screw_speed;
        e.screw_accel = screw_accel;
        e.friction_torque = friction_torque;
        e.axial = axial;
        e.thread_torque = thread_torque;
        e.model_screw_torque = model_screw_torque;
        e.model_motor_torque = model_motor_torque;
        e.measured_screw_torque = measured_screw_torque;
        e.flags = flags;
    }
}

/// The control core: the configuration and what it derives, the estimator, and the state.
#[derive(Clone, Debug)]
pub struct Controller {
    /// The configuration in force and every number derived from it: rebuilt whole by
    /// [`Controller::reconfigure`].
    derived: Derived,
    /// The model (derived from the configuration) and its speed filter (live).
    est: Estimator,
    /// Motion control's working state.
    motion: Motion,
    /// The live state a new configuration keeps.
    live: Live,
    /// The load and friction identification (`loadid.rs`).
    loadid: loadid::Identification,
}

impl Controller {
    /// Validate `cfg` and start at rest with the encoder at `position` counts (the position
    /// survives power loss with the configuration: the lead screw is self-locking).
    pub fn new(cfg: &ControlConfig, position: i32) -> Result<Controller, ConfigError> {
        // The ball-screw build gives a law in τ on a ball screw to the estimator in the screw
        // rate (`ControlConfig::build_estimator`).
        let est = cfg.build_estimator()?;
        let derived = Derived::new(cfg, est.geometry())?;
        let loadid = loadid::Identification::new(cfg, &est, position);
        Ok(Controller {
            motion: Motion::new(&derived, position),
            derived,
            est,
            live: Live::new(position),
            loadid,
        })
    }
    /// Validate `cfg` and start at rest with the position unknown (power was lost while the
    /// lift moved, or no position was stored): every motion is refused with
    /// [`Refusal::NotHomed`] except lowering, which runs until the lower limit switch closes
    /// and then sets the position to [`LimitStops::switch_lower`](config::LimitStops). The soft
    /// lower stop is not enforced on that run (the switch is the stop); stall, over-current and
    /// the other protections are.
    pub fn new_unhomed(cfg: &ControlConfig) -> Result<Controller, ConfigError> {
        Controller::new_at(cfg, None)
    }

    /// [`Controller::new`] at `Some(position)`, [`Controller::new_unhomed`] at `None`: one
    /// construction path for a caller that may have either (the firmware's boot).
    pub fn new_at(cfg: &ControlConfig, position: Option<i32>) -> Result<Controller, ConfigError> {
        // Adjusted inside the `Result` (`?` would move the controller out of it and back
        // into a new one: two more copies and stack slots).
        let mut made = Controller::new(cfg, position.unwrap_or(0));
        if let (Ok(c), None) = (&mut made, position) {
            // Until homed, assume the lowest position: the model's load (and feed-forward) is
            // then the largest the lift can see.
            c.set_position(c.derived.switch_counts);
            c.live.homed = false;
        }
        made
    }

    /// The position is known (a homing run is not needed).
    pub fn homed(&self) -> bool {
        self.live.homed
    }

    fn set_position(&mut self, position: i32) {
        let by = position.saturating_sub(self.live.enc.position());
        self.motion.edges.shift(by);
        self.live.enc.rebase(position);
        self.est.rebase(by);
        self.live.hold_position = position;
        self.motion.hold_target = position;
        self.motion.profile.reset(position);
        self.motion.last_ref_counts = position;
    }

    /// The configuration in force.
    pub fn config(&self) -> &ControlConfig {
        &self.derived.cfg
    }

    /// The estimator (geometry, model).
    pub fn estimator(&self) -> &Estimator {
        &self.est
    }

    /// Supervisor state.
    pub fn state(&self) -> State {
        self.live.state
    }

    /// The latched fault.
    pub fn fault(&self) -> Option<&Fault> {
        self.live.fault.as_ref()
    }

    /// The last estimate (what the tick reads; the estimator's `details` gives the rest).
    pub fn estimate(&self) -> &TickEstimate {
        &self.live.latest.estimate
    }

    /// The stick-slip detector's report of the last tick.
    pub fn stick_slip_output(&self) -> &crate::detect::stickslip::StickSlipOutput {
        self.motion.stick_slip.output()
    }

    /// Motor encoder position in counts.
    pub fn position_counts(&self) -> i32 {
        self.live.enc.position()
    }

    /// Limit stops in encoder counts (lower, upper).
    pub fn limit_counts(&self) -> (i32, i32) {
        (self.derived.lower_counts, self.derived.upper_counts)
    }

    /// The current motion target, counts (screw position).
    pub fn target_counts(&self) -> i32 {
        self.motion.profile.target_counts()
    }

    /// The reference (screw) position of the last tick, counts, and the screw-position estimate.
    pub fn tracking(&self) -> (i32, i32) {
        (self.motion.last_ref_counts, self.screw_position())
    }

    /// Values for the status line.
    pub fn status(&self) -> Status {
        let latest = &self.live.latest;
        let stick_slip = self.motion.stick_slip.output();
        let (stick, lowering) = self.load_readings();
        let friction_torque = stick.map_or_else(
            || self.friction_at_load(lowering.unwrap_or(self.loadid.load)),
            |s| s.1,
        );
        let mut load = self.loadid.ident.report();
        if let Some(m) = stick.map(|s| s.0).or(lowering) {
            load.load = m;
            // The interval holds the reading ± 1/32 (3.1 %): the breakaways read the dry lifts
            // of `host-sim estimate` within −0.7…+1.7 % (docs/model.md "Stick-slip"); the
            // mean torque's own interval alone had missed a rated car read 0.6 % light. (An
            // empty head's lowering reading, a few kg, widens it by a fraction of a kilogram.)
            let band = Kilograms::from_raw(m.bits() >> 5);
            load.load_lo = load.load_lo.min(m.sat_sub(band));
            load.load_hi = load.load_hi.max(m.sat_add(band));
        }
        Status {
            state: self.live.state,
            height: latest.estimate.height,
            screw_speed: latest.estimate.screw_speed,
            current: latest.current,
            supply: latest.supply,
            friction_torque,
            stick_slip: stick_slip.active,
            stick_slip_amplitude: stick_slip.amplitude,
            stick_slip_episodes: stick_slip.episodes,
            fault: self.live.fault.map(|f| f.kind),
            position: self.live.enc.position(),
            homed: self.live.homed,
            load,
            friction_torque_range: self.friction_range(
                friction_torque,
                load.load_hi,
                lowering.is_some(),
            ),
            cruise_limit: self.motion.cruise_limit,
            #[cfg(feature = "ball-screw")]
            lube: if self.holds_actively() {
                self.motion.lube.report()
            } else {
                None
            },
        }
    }

    /// The ball screw's friction identification (`lube`).
    #[cfg(feature = "ball-screw")]
    pub fn lube(&self) -> &lube::LubeMonitor {
        &self.motion.lube
    }

    /// Replace the configuration while the lift is at rest (Idle, Holding or Fault, screw
    /// slower than `control.rest_speed`): the live state (position, state, a latched fault,
    /// the buttons, the latest measurements) is kept whole, everything derived from the
    /// configuration is rebuilt, and the next tick runs with it. Refused while moving
    /// ([`Refusal::InMotion`]), so a motion never sees a half-applied change; refused whole if
    /// [`Controller::new`] refuses `cfg`.
    pub fn reconfigure(&mut self, cfg: &ControlConfig) -> Result<(), Refusal> {
        let old = &self.derived.cfg;
        let turning = self.live.latest.estimate.screw_speed.sat_abs() > old.estimator.rest_speed;
        if self.live.moving() || turning {
            return Err(Refusal::InMotion);
        }
        // The candidate is adjusted inside the `Result` and moved once, into `self`: unwrapping
        // it first (`?`) copied the controller into a second stack slot, and this runs
        // in the console task with the controller's lock held (interrupts off).
        let mut made = Controller::new(cfg, self.live.enc.position());
        let Ok(next) = &mut made else {
            return Err(Refusal::BadConfig);
        };
        next.live = self.live;
        // Of motion control's state, what the new configuration leaves as it was.
        let same_model = cfg.estimator == old.estimator;
        // A τ law on a ball screw also depends on the ball screw and the rated load.
        #[cfg(feature = "ball-screw")]
        let same_model = same_model && next.est.law() == self.est.law();
        if same_model {
            // Same model and filter: keep the speed estimate running (swapped: `self` is
            // replaced by `next` below).
            core::mem::swap(&mut next.est, &mut self.est);
        }
        if cfg.estimator.tick_us == old.estimator.tick_us {
            next.motion.debounce = self.motion.debounce;
        }
        next.motion.brake.keep_timing(&self.motion.brake);
        // The same sense scaling: keep the current-sense zero measured at rest.
        if cfg.sensing == old.sensing {
            next.derived.adc = self.derived.adc;
        }
        // The car stays on the lift and the thread is the same: keep what was identified.
        if same_model {
            next.loadid = self.loadid;
        } else {
            if self.loadid.ident.report().scale_known {
                next.restore_friction_scale(self.loadid.ident.scale());
            }
            next.loadid.store = self.loadid.store;
        }
        #[cfg(feature = "ball-screw")]
        if cfg.ball_screw == old.ball_screw
            && cfg.lube == old.lube
            && cfg.estimator == old.estimator
        {
            next.motion.lube = self.motion.lube;
        }
        // Counts mean another height under another geometry or drive: the position is then
        // unknown until the lift is homed again.
        let same_counts = cfg.estimator.geometry == old.estimator.geometry
            && cfg.estimator.drive == old.estimator.drive;
        next.live.homed &= same_counts;
        if !next.live.homed {
            let at = next.derived.switch_counts;
            next.set_position(at);
        }
        if let Ok(next) = made {
            *self = next;
        }
        Ok(())
    }

    /// Screw position estimate: the encoder less the coupling twist. The twist comes from the
    /// *measured* torque (low-passed), not the model's: the model assumes the rated load, and
    /// with an empty lift it would over-correct by the whole rated twist. At rest, the twist the
    /// last motion left, less what has unwound since (`step`).
    #[inline(always)]
    fn screw_position(&self) -> i32 {
        let twist = self
            .derived
            .twist_scale
            .apply32(self.motion.torque_lp.bits());
        self.live.enc.position().saturating_sub(twist)
    }

    /// One control tick. Never panics, whatever the inputs.
    #[inline(never)]
    pub fn step(&mut self, now: Instant, inputs: &Inputs) -> Outputs {
        // 1. Sense.
        let delta = self.live.enc.update(inputs.encoder_count);
        let current = self.derived.adc.current(inputs.current_raw);
        let supply = self.derived.adc.supply(inputs.supply_raw);
        let switches = self.motion.debounce.update(inputs.switches);
        let moving = self.live.moving();
        let dir: i8 = match self.live.state {
            State::Lifting => 1,
            State::Lowering => -1,
            _ => 0,
        };
        // 2. Estimate at the rated load (the speed loop's feed-forward keeps its tuning; the
        // status reports the model at the identified load, `loadid.rs`); the speed filter gets
        // the position between counts.
        let position = self.live.enc.position();
        let between = self
            .motion
            .edges
            .update_fraction(now, position, inputs.encoder_edge_age);
        let estimate = self.est.step_at(
            now,
            &Measurements {
                position_counts: position,
                motor_current: current,
                load: self.derived.cfg.rated_load,
                commanded_dir: dir,
            },
            between,
        );
        let x = Reading {
            current,
            supply,
            switches,
            estimate,
        };
        self.live.latest.set(&x);
        let active_hold = self.holds_actively();
        let m = &mut self.motion;
        if moving {
            let d = x.estimate.measured_screw_torque.sat_sub(m.torque_lp);
            m.torque_lp = m.torque_lp.sat_add(NewtonMetres::from_raw(d.bits() >> 3));
        } else if active_hold {
            m.torque_lp = NewtonMetres::ZERO;
        } else {
            // At rest the coupling keeps the twist the motion left it (the thread self-locks),
            // less what unwinds back through the motor: the encoder's travel, while the screw
            // stands, is the twist's. The screw's position is the encoder less it (the next
            // start's reference begins there: it had begun at the encoder, and a lowering after
            // a lift then drove the motor up until the reference caught up with the twist).
            let t = m.torque_lp.bits();
            let u = t.saturating_add(delta.saturating_mul(self.derived.torque_per_count.bits()));
            // (Toward 0, never past it; no `clamp`: its panic path costs flash.)
            m.torque_lp = NewtonMetres::from_raw(if t > 0 {
                u.min(t).max(0)
            } else {
                u.max(t).min(0)
            });
        }

        // 3. Protections.
        m.motion_ticks = if moving {
            m.motion_ticks.saturating_add(1)
        } else {
            0
        };
        let reference = if moving {
            self.reference_speed()
        } else {
            RadiansPerSecond::ZERO
        };
        let emf_speed = self.emf_speed(&x);
        let project = |t: NewtonMetres| if dir < 0 { t.sat_neg() } else { t };
        let holdoff = self.derived.ticks.overload_holdoff;
        let sample = Sample {
            moving,
            lowering: dir < 0,
            duty: self.motion.last_duty,
            delta,
            current,
            supply,
            emf_speed,
            speed: x.estimate.screw_speed,
            reference,
            cruise: self.derived.cfg.motion.cruise_speed,
            travel_while_stopped: if moving || self.live.state == State::Fault {
                0
            } else {
                position.saturating_sub(self.live.hold_position)
            },
            measured_torque: project(x.estimate.measured_screw_torque),
            // The model at the identified load (the torque monitor then watches for an
            // obstruction, not for a heavier car: the load trip does, `loadid.rs`).
            model_torque: project(x.estimate.model_screw_torque.sat_add(self.loadid.offset)),
            overload_armed: moving
                && matches!(self.motion.last_bridge, Bridge::Drive(_))
                && self.motion.motion_ticks > holdoff,
            lagging: moving && self.motion.lagging,
        };
        if self.live.state != State::Fault {
            if let Some(kind) = self.motion.monitors.check(&self.derived.limits, &sample) {
                self.latch(now, kind);
            }
        }
        self.identify_load(now, moving, dir);
        // Limit switches: both closed is a wiring fault; one closed in the direction of
        // travel stops the lift at once.
        let both = Switches::LIMIT_UPPER | Switches::LIMIT_LOWER;
        if switches.is_active(both) && self.live.state != State::Fault {
            self.latch(now, FaultKind::SwitchesImplausible);
        }
        if moving && self.live.state != State::Fault {
            let switch = if dir > 0 {
                Switches::LIMIT_UPPER
            } else {
                Switches::LIMIT_LOWER
            };
            let lower_closed = switches.is_active(Switches::LIMIT_LOWER);
            let homing = !self.live.homed && (dir < 0) == lower_closed;
            if homing || switches.is_active(switch) {
                self.limit_switch(now, dir, homing);
            }
        }

        // 4. Buttons.
        self.buttons(switches, inputs.switches.0);

        // 5–6. Motion (the brake's output first: a motion waits for it to release).
        self.brake_step();
        let bridge = match self.live.state {
            State::Lifting | State::Lowering => self.drive(&x),
            _ => {
                // Settling after a stop: the rotor coasts down and the wound coupling unwinds
                // through the motor; that motion is commanded, so the runaway reference follows
                // it for SETTLE_MS (a runaway is measured from where the lift settled).
                self.live.rest_ticks = self.live.rest_ticks.saturating_add(1);
                if self.live.rest_ticks <= self.derived.ticks.settle {
                    self.live.hold_position = self.live.enc.position();
                }
                let bridge = self.at_rest_bridge(&x);
                self.rest_current_zero(inputs.current_raw);
                bridge
            }
        };
        self.detect_stick_slip(&x);
        #[cfg(feature = "ball-screw")]
        if self.holds_actively() {
            self.identify_friction(&x);
        }
        self.motion.last_duty = match bridge {
            Bridge::Drive(d) => d,
            _ => 0,
        };
        self.motion.last_bridge = bridge;
        let mut out = Outputs {
            bridge,
            feed_watchdog: true,
            brake_release: self.motion.brake.release,
            event: None,
        };
        // Only a tick with an event copies it out: `take` copies the whole `Option` (44
        // bytes), which at opt-level "z" is a `memcpy` call (see `Reading::set`).
        if self.live.pending_event.is_some() {
            out.event = self.live.pending_event.take();
        }
        out
    }

    /// A tick at rest: once the lift has settled and the bridge did not drive last tick (no
    /// current in the sense path), the current code is a sample of the sense's zero
    /// (`sense::Adc::rest_sample`). Out of line: at rest only (kept out of the moving
    /// tick's register allocation).
    #[inline(never)]
    fn rest_current_zero(&mut self, code: u16) {
        if matches!(self.motion.last_bridge, Bridge::Drive(_))
            || self.live.rest_ticks <= self.derived.ticks.settle
        {
            self.derived.adc.rest_interrupted();
            return;
        }
        let _ = self.derived.adc.rest_sample(code);
    }

    /// The rest of the tick, which its outputs do not wait for: call once a tick after
    /// applying [`Self::step`]'s outputs (the firmware's control task does, after the bridge
    /// and the brake). Bounded: at most one exact pose node of the estimator's next pose
    /// segments ([`Estimator::prepare`]), so the tick that crosses into a segment decides its
    /// outputs as fast as any other. Skipping it changes no output, only makes the step that
    /// enters a new segment slower (it computes the nodes itself).
    #[inline]
    pub fn finish_tick(&mut self) {
        self.est.prepare();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use fixed::types::I16F16;

    /// `Controller::new`'s speeds in counts per tick through the unsigned `mul_div_u64` are
    /// the `i128` arithmetic they replaced, bit for bit, over the validated drives, ticks
    /// and speeds (corners and a sweep).
    #[test]
    fn derived_speeds_match_their_i128_form() {
        use crate::math::{div128, mul128, shl128};
        let mut checked = 0;
        for counts_per_rev in [4u32, 48, 1000, 4096, 65_536] {
            for gear in [1.0, 7.5, 60.0, 1000.0] {
                for tick_us in [100u32, 1000, 10_000] {
                    for speed in [0.2, 1.375, 20.0] {
                        let mut cfg = ControlConfig::DEFAULT;
                        cfg.estimator.drive.counts_per_rev = counts_per_rev;
                        cfg.estimator.drive.gear_ratio = I16F16::from_num(gear);
                        cfg.estimator.tick_us = tick_us;
                        cfg.motion.cruise_speed = RadiansPerSecond::from_f64(speed);
                        cfg.stick_slip.escape_speed = RadiansPerSecond::from_f64(speed);
                        let Ok(c) = Controller::new(&cfg, 0) else {
                            continue;
                        };
                        let (mant, shift) = c.est.geometry().screw_rad_per_count().parts();
                        let cprq16 = div128(shl128(1, 32 + shift), i128::from(mant.max(1))) as i64;
                        let per_tick = |s: RadiansPerSecond| {
                            div128(
                                mul128(
                                    i128::from(s.bits()),
                                    i128::from(cprq16) * i128::from(tick_us),
                                ),
                                1_000_000,
                            ) as i64
                        };
                        assert_eq!(c.derived.cruise_q32, per_tick(cfg.motion.cruise_speed));
                        assert_eq!(c.derived.escape_q32, per_tick(cfg.stick_slip.escape_speed));
                        let per_motor_rad = div128(
                            i128::from(cprq16) << 16,
                            i128::from(cfg.estimator.drive.gear_ratio.to_bits().max(1)),
                        );
                        let nut_q40 = i64::from(c.est.geometry().travel(1 << 16).bits())
                            - i64::from(c.est.geometry().travel(0).bits());
                        let limits = protect::Limits::new(
                            &cfg.protection,
                            tick_us,
                            per_motor_rad as i64,
                            nut_q40,
                            cfg.motion.cruise_speed,
                        );
                        assert_eq!(
                            c.derived.limits.max_counts_per_tick,
                            limits.max_counts_per_tick
                        );
                        checked += 1;
                    }
                }
            }
        }
        // Most combinations are valid configurations (a few drives refuse the limit stops).
        assert!(checked >= 60, "only {checked} configurations built");
    }
}
