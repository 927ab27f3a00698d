//! The supervisor: the state machine (Idle / Lifting / Lowering / Holding / Fault), the
//! commands and the buttons that drive it, a motion's start, the limit switches, and the fault
//! latch with its snapshot. Its state ([`Live`]) outlives a configuration:
//! [`Controller::reconfigure`] keeps it whole.

use super::config::ButtonMode;
use super::derived::ARRIVED_COUNTS;
use super::protect::FaultKind;
use super::sense::{EncoderTracker, Switches};
use super::{Controller, Reading};
use crate::detect::stickslip::Reaction;
use crate::units::{Amperes, Instant, Metres, NewtonMetres, RadiansPerSecond, Volts, Q};

/// The supervisor's states.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum State {
    /// At rest since boot or since a fault was cleared.
    #[default]
    Idle,
    /// Driving up.
    Lifting,
    /// Driving down.
    Lowering,
    /// At rest after a motion; the screw holds the load, the controller watches for back-drive.
    Holding,
    /// Stopped by a protection; only `fault clear` leaves it.
    Fault,
}

impl State {
    /// Name for logs and the console.
    pub fn name(self) -> &'static str {
        match self {
            State::Idle => "idle",
            State::Lifting => "lifting",
            State::Lowering => "lowering",
            State::Holding => "holding",
            State::Fault => "fault",
        }
    }
}

/// A request to the supervisor (console or buttons).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Command {
    /// Lift to the upper limit stop.
    Up,
    /// Lower to the lower limit stop (a deliberate action: never from a button held at boot).
    Down,
    /// Brake along the ramp and hold.
    Stop,
    /// Move to a head height (between the limit stops).
    GoTo(Metres),
    /// Clear a latched fault (back to Idle).
    ClearFault,
}

/// Why a command was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Refusal {
    /// A fault is latched: read it with `fault`, clear it with `fault clear`.
    Faulted,
    /// The supply is below the start threshold.
    SupplyLow,
    /// Already at or beyond that limit stop (a direction command never moves the other way),
    /// or its limit switch is closed.
    AtLimit,
    /// The target lies outside the limit stops.
    OutsideLimits,
    /// Moving the other way: stop first.
    Moving,
    /// No fault to clear.
    NoFault,
    /// The position is unknown (power was lost while moving, or none was stored): only a
    /// homing run down to the lower limit switch is allowed.
    NotHomed,
    /// A configuration change while the lift moves (or its screw still turns).
    InMotion,
    /// A configuration the controller cannot run with (pass it through validation first).
    BadConfig,
    /// `fault clear` of [`FaultKind::NeedsBallScrew`]: only the ball-screw firmware clears it.
    NeedsBallScrew,
}

impl Refusal {
    /// Message for the console.
    pub fn message(self) -> &'static str {
        match self {
            Refusal::Faulted => "refused: a fault is latched (see `fault`, then `fault clear`)",
            Refusal::SupplyLow => "refused: supply below the start threshold",
            Refusal::AtLimit => {
                "refused: already at or beyond that limit; `goto` a height between the stops"
            }
            Refusal::OutsideLimits => "refused: target outside the limit stops",
            Refusal::Moving => "refused: moving the other way, stop first",
            Refusal::NoFault => "no fault latched",
            Refusal::NotHomed => {
                "refused: position unknown; hold DOWN (or `down`) to home on the lower limit switch"
            }
            Refusal::InMotion => {
                "refused: the lift is moving; `stop` and let it come to rest first"
            }
            Refusal::BadConfig => "refused: configuration not valid for the controller",
            Refusal::NeedsBallScrew => {
                "refused: the stored configuration needs the ball-screw firmware; flash that \
                 image (`cargo fw-ball`), the record is kept"
            }
        }
    }
}

impl core::fmt::Display for Refusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.message())
    }
}

/// A latched fault with the state of the lift at the moment it tripped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Fault {
    /// What tripped.
    pub kind: FaultKind,
    /// When.
    pub at: Instant,
    /// The state it interrupted.
    pub state: State,
    /// Encoder position, counts.
    pub position: i32,
    /// Head height (model).
    pub height: Metres,
    /// The position was known (false: `height` is the homing assumption, not the head's).
    pub homed: bool,
    /// Measured screw speed.
    pub screw_speed: RadiansPerSecond,
    /// Motor current.
    pub current: Amperes,
    /// Supply.
    pub supply: Volts,
    /// Duty of the tick before, Q15.
    pub duty: i16,
    /// Screw torque measured from the current.
    pub measured_torque: NewtonMetres,
    /// Screw torque of the model at the rated load (the tick's; `load` is the identified one).
    pub model_torque: NewtonMetres,
    /// The identified load (or the prior) at the moment it tripped.
    pub load: crate::units::Kilograms,
    /// `load` came from a motion's current (this one's or an earlier one's); false: it is the
    /// prior (nothing weighed yet, or a screw that never moved).
    pub load_identified: bool,
}

/// What a tick reports for the logs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Event {
    /// The supervisor changed state.
    State {
        /// Before.
        from: State,
        /// After.
        to: State,
    },
    /// A protection tripped.
    Fault(Fault),
    /// A limit switch stopped the lift before the soft limit (switch inside the soft range).
    SwitchStop,
    /// A homing run reached the lower limit switch: the position is known again.
    Homed {
        /// The encoder position the switch height maps to, counts.
        position: i32,
    },
    /// The motor cannot reach `motion.cruise_speed` at this load and supply: the motion runs
    /// at this screw speed (it may rise a little as the limit settles).
    CruiseLimited {
        /// The cruise speed the motion runs at.
        speed: RadiansPerSecond,
    },
    /// A stick-slip episode started (`crate::detect::stickslip`).
    StickSlip {
        /// Coupling-torque drop of the last completed slip (a slip's fall is measured over
        /// 8 ms, so the confirming slip's own is not complete yet).
        amplitude: NewtonMetres,
        /// Episode number since boot.
        episode: u32,
        /// The configured reaction (`Warn` and `ChangeSpeed` ask for a console warning).
        reaction: Reaction,
    },
    /// A ball screw's lift/lowering pair put the identified friction coefficient outside
    /// `ballscrew.lube_band` around the law (`lube`): lubrication or wear to check.
    #[cfg(feature = "ball-screw")]
    Lubrication(super::lube::LubeReport),
    /// A lift/lowering pair found the thread drier than `1 + ident::LUBE_BAND` times the
    /// configured law (`crate::ident`): lubrication to check.
    ThreadDry(crate::ident::LoadReport),
}

/// The controller's state that a new configuration keeps: the encoder, the supervisor's state
/// machine, fault and buttons, where the lift rests, and the latest measurements.
#[derive(Clone, Copy, Debug)]
pub(super) struct Live {
    pub(super) enc: EncoderTracker,
    pub(super) state: State,
    pub(super) fault: Option<Fault>,
    /// The position is known; false until a homing run reaches the lower switch.
    pub(super) homed: bool,
    /// Where the lift came to rest: the runaway monitor's reference.
    pub(super) hold_position: i32,
    /// Ticks since the lift came to rest.
    pub(super) rest_ticks: u32,
    /// Buttons pressed since boot/fault must be released before they count (edge-triggered).
    pub(super) buttons_armed: bool,
    /// Consecutive ticks with both motion buttons released (raw), toward arming.
    pub(super) release_ticks: u32,
    /// The motion was started by a hold-to-run button that is still held.
    pub(super) held_button: u8,
    pub(super) prev_buttons: u8,
    /// The latest tick's measurements: what commands, the fault snapshot and the status read.
    pub(super) latest: Reading,
    pub(super) pending_event: Option<Event>,
}

impl Live {
    /// At rest at `position`, buttons not armed.
    pub(super) fn new(position: i32) -> Live {
        Live {
            enc: EncoderTracker::new(position),
            state: State::Idle,
            fault: None,
            homed: true,
            hold_position: position,
            rest_ticks: u32::MAX,
            buttons_armed: false,
            release_ticks: 0,
            held_button: 0,
            prev_buttons: 0,
            latest: Reading::default(),
            pending_event: None,
        }
    }

    /// Driving up or down.
    #[inline]
    pub(super) fn moving(&self) -> bool {
        matches!(self.state, State::Lifting | State::Lowering)
    }
}

impl Controller {
    /// Report that the previous run ended in a watchdog reset: latches a fault so that the lift
    /// does not resume a motion by itself after the reboot.
    pub fn report_watchdog_reset(&mut self, now: Instant) {
        self.latch(now, FaultKind::WatchdogReset);
    }

    /// Report that the stored configuration could not be used and the factory defaults run
    /// instead ([`crate::config::store::Source::lost_stored`]): latches
    /// [`FaultKind::FactoryDefaults`], so that no motion starts on stops the user did not set
    /// until `fault clear` acknowledges it (docs/console.md "Factory defaults after a lost
    /// configuration").
    pub fn report_factory_defaults(&mut self, now: Instant) {
        self.latch(now, FaultKind::FactoryDefaults);
    }

    /// Report that the stored configuration needs the ball-screw firmware (an image without the
    /// `ball-screw` feature booted on a ball-screw record, [`crate::config::store::Source::NeedsBallScrew`]):
    /// latches [`FaultKind::NeedsBallScrew`], which no command clears. The fault state brakes
    /// the bridge and keeps the holding brake engaged (`hold.rs`).
    pub fn report_needs_ball_screw(&mut self, now: Instant) {
        self.latch(now, FaultKind::NeedsBallScrew);
    }

    /// Apply a command now (the next tick acts on it).
    pub fn command(&mut self, cmd: Command) -> Result<(), Refusal> {
        let d = &self.derived;
        let (lower, upper, switch) = (d.lower_counts, d.upper_counts, d.switch_counts);
        match cmd {
            Command::ClearFault => {
                let Some(f) = self.live.fault else {
                    return Err(Refusal::NoFault);
                };
                if f.kind == FaultKind::NeedsBallScrew {
                    return Err(Refusal::NeedsBallScrew);
                }
                self.live.fault = None;
                self.motion.monitors.reset();
                self.live.buttons_armed = false;
                self.live.release_ticks = 0;
                self.enter_rest(State::Idle);
                Ok(())
            }
            Command::Stop => {
                self.live.held_button = 0;
                if self.live.moving() {
                    if self.awaiting_brake() {
                        // Nothing moved yet: the motor holds where it took the load up.
                        self.enter_rest(State::Holding);
                    } else {
                        self.motion.profile.stop();
                    }
                }
                Ok(())
            }
            // Homing from a closed lower switch: creep up until it opens (at most to where the
            // lower stop would be).
            Command::Up
                if !self.live.homed
                    && self.live.latest.switches.is_active(Switches::LIMIT_LOWER) =>
            {
                let span = lower.saturating_sub(switch);
                self.start(self.live.enc.position().saturating_add(span), true)
            }
            Command::Up | Command::GoTo(_) if !self.live.homed && self.live.fault.is_none() => {
                Err(Refusal::NotHomed)
            }
            // Homing: aim one full stroke below the stop; the lower switch ends the run.
            Command::Down if !self.live.homed => {
                let stroke = upper.saturating_sub(switch);
                self.start(self.live.enc.position().saturating_sub(stroke), false)
            }
            // A direction command moves only in its direction: with the head above a lowered
            // upper stop `up` would lower to it (and `down` lift to a raised lower stop).
            // (A latched fault is the first reason, `start`'s.)
            Command::Up if self.live.fault.is_none() && upper <= self.screw_position() => {
                Err(Refusal::AtLimit)
            }
            Command::Down if self.live.fault.is_none() && lower >= self.screw_position() => {
                Err(Refusal::AtLimit)
            }
            Command::Up => self.start(upper, false),
            Command::Down => self.start(lower, false),
            Command::GoTo(h) => {
                let counts = self
                    .est
                    .geometry()
                    .counts_for_height(h)
                    .ok_or(Refusal::OutsideLimits)?;
                if counts < lower || counts > upper {
                    return Err(Refusal::OutsideLimits);
                }
                self.start(counts, true)
            }
        }
    }

    fn start(&mut self, target: i32, goto: bool) -> Result<(), Refusal> {
        if self.live.fault.is_some() {
            return Err(Refusal::Faulted);
        }
        let here = self.screw_position();
        let dir = (target - here).signum();
        match (self.live.state, dir) {
            (State::Lifting, d) if d < 0 => return Err(Refusal::Moving),
            (State::Lowering, d) if d > 0 => return Err(Refusal::Moving),
            _ => {}
        }
        let moving = self.live.moving();
        let latest = &self.live.latest;
        if !moving && latest.supply < self.derived.cfg.protection.supply_start_min {
            return Err(Refusal::SupplyLow);
        }
        let switch = if dir > 0 {
            Switches::LIMIT_UPPER
        } else {
            Switches::LIMIT_LOWER
        };
        if dir == 0 || (!goto && (target - here).abs() <= ARRIVED_COUNTS) {
            return Err(Refusal::AtLimit);
        }
        if latest.switches.is_active(switch) {
            return Err(Refusal::AtLimit);
        }
        if !moving {
            self.finish_rescale();
            self.motion.profile.reset(here);
            self.motion.last_ref_counts = here;
            self.motion.profile.set_cruise(self.derived.cruise_q32);
            self.motion.cruise_limit = None;
            self.motion.cruise_reported = false;
            if !self.keeps_integrator(None) {
                self.motion.speed.reset();
            }
            self.motion.monitors.reset();
            self.motion.motion_ticks = 0;
            // The homing run's or the last motion's reference speed is not this one's.
            self.motion.last_ref_rad = RadiansPerSecond::ZERO;
            self.motion.reversing = true;
        }
        self.motion.profile.set_target(target);
        self.motion.settle_ticks = 0;
        self.set_state(if dir > 0 {
            State::Lifting
        } else {
            State::Lowering
        });
        if !moving && dir < 0 {
            self.start_creep();
        }
        Ok(())
    }

    pub(super) fn set_state(&mut self, to: State) {
        let live = &mut self.live;
        if to != live.state {
            let from = live.state;
            live.state = to;
            if !matches!(live.pending_event, Some(Event::Fault(_))) {
                live.pending_event = Some(Event::State { from, to });
            }
        }
    }

    pub(super) fn enter_rest(&mut self, to: State) {
        let here = self.live.enc.position();
        self.live.held_button = 0;
        self.live.rest_ticks = 0;
        self.live.hold_position = here;
        self.motion.hold_target = here;
        self.motion.regen_left = self.derived.ticks.regen;
        if !self.keeps_integrator(None) {
            self.motion.speed.reset();
        }
        self.motion.profile.reset(here);
        self.set_state(to);
    }

    /// Latch a fault with the snapshot of the latest measurements, and stop.
    pub(super) fn latch(&mut self, now: Instant, kind: FaultKind) {
        if self.live.fault.is_some() {
            return;
        }
        // The load the status reports: a stick-slipping lift's breakaways (the mean torque reads
        // such a car ≈ 30 % light: a dry 1300 kg lift from 145 mm tripped the torque monitor
        // with load=935 kg in its snapshot while the status said 1300).
        let (load, load_identified) = self.reported_load();
        let live = &self.live;
        let e = &live.latest.estimate;
        let f = Fault {
            kind,
            at: now,
            state: live.state,
            position: live.enc.position(),
            height: e.height,
            homed: live.homed,
            screw_speed: e.screw_speed,
            current: live.latest.current,
            supply: live.latest.supply,
            duty: self.motion.last_duty,
            measured_torque: e.measured_screw_torque,
            model_torque: e.model_screw_torque,
            load,
            load_identified,
        };
        let here = live.enc.position();
        self.live.fault = Some(f);
        self.motion.brake.unwound();
        self.live.held_button = 0;
        self.motion.hold_target = here;
        if !self.keeps_integrator(Some(kind)) {
            self.motion.speed.reset();
        }
        self.motion.profile.reset(here);
        self.live.state = State::Fault;
        self.live.pending_event = Some(Event::Fault(f));
    }

    /// A motion reached its limit switch, or (`homing`) the lower switch changed on a homing
    /// run: the homing reference, a stop at the switch, or a fault if the soft limit should
    /// have stopped the lift first. Out of line and cold: it runs on one tick of a motion at
    /// most, which ends it.
    #[cold]
    #[inline(never)]
    pub(super) fn limit_switch(&mut self, now: Instant, dir: i8, homing: bool) {
        let d = &self.derived;
        if homing {
            // Homing run: the lower switch closed (lowering) or opened (creeping up from it)
            // at its configured height. That height is the screw's, so the encoder is set
            // ahead of it by the coupling twist of the moment.
            self.live.homed = true;
            let twist = d.twist_scale.apply32(self.motion.torque_lp.bits());
            let at = d.switch_counts;
            self.set_position(at.saturating_add(twist));
            self.enter_rest(State::Holding);
            self.live.pending_event = Some(Event::Homed { position: at });
        } else {
            // The soft limit should have caught it if the lift is already at or past it.
            let stop = if dir > 0 {
                d.upper_counts
            } else {
                d.lower_counts
            };
            let runaway = d.limits.runaway_counts;
            let past = (self.screw_position() - stop) * i32::from(dir) >= -runaway;
            if past {
                self.latch(now, FaultKind::LimitSwitch);
            } else {
                self.enter_rest(State::Holding);
                self.live.pending_event = Some(Event::SwitchStop);
            }
        }
    }

    /// The buttons: `pressed` the debounced levels, `raw` this tick's undebounced ones.
    pub(super) fn buttons(&mut self, switches: Switches, raw: u8) {
        let motion_buttons = Switches::BUTTON_UP | Switches::BUTTON_DOWN;
        let pressed = switches.0 & motion_buttons;
        let edges = pressed & !self.live.prev_buttons;
        self.live.prev_buttons = pressed;
        if switches.is_active(Switches::BUTTON_STOP) {
            let _ = self.command(Command::Stop);
            return;
        }
        if !self.live.buttons_armed {
            // A button held at boot or through a fault must be seen released (raw, for
            // ARM_MS) first: the debouncer's initial "released" is not evidence.
            self.live.release_ticks = if raw & motion_buttons == 0 {
                self.live.release_ticks.saturating_add(1)
            } else {
                0
            };
            self.live.buttons_armed = self.live.release_ticks >= self.derived.ticks.arm;
            return;
        }
        let held = self.live.held_button;
        if held != 0 && pressed & held == 0 {
            let _ = self.command(Command::Stop);
        }
        // Both buttons at once: do nothing new.
        if edges == Switches::BUTTON_UP && pressed == Switches::BUTTON_UP {
            if self.live.state == State::Lowering {
                let _ = self.command(Command::Stop);
            } else if self.command(Command::Up).is_ok()
                && self.derived.cfg.motion.buttons == ButtonMode::HoldToRun
            {
                self.live.held_button = Switches::BUTTON_UP;
            }
        } else if edges == Switches::BUTTON_DOWN && pressed == Switches::BUTTON_DOWN {
            // Lowering is always hold-to-run from the buttons: a car comes down only while a
            // person keeps a finger on DOWN.
            if self.live.state == State::Lifting {
                let _ = self.command(Command::Stop);
            } else if self.command(Command::Down).is_ok() {
                self.live.held_button = Switches::BUTTON_DOWN;
            }
        }
    }
}
