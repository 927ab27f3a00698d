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
//! 4. the supervisor (this module): buttons and commands → Idle / Lifting / Lowering / Holding / Fault;
//! 5. [`profile`]: the ramped reference toward the target (a limit stop or a set height);
//! 6. [`speed`]: PI speed loop with the model's torque as feed-forward → duty (at rest too for a
//!    ball screw, which is not self-locking: `hold`).
//!
//! The halt planner works on the *screw* position: the encoder sits on the motor, and under a
//! torque T the coupling (stiffness k) lets the screw lag the gear output by T/k (≈ 0.47 rad,
//! 0.55 mm of head height at rated load near α₀). While driving, the estimated screw position is
//! the encoder position minus the model's twist, so the head stops at the target and not half a
//! millimetre short of it.

pub mod config;
pub mod edges;
mod hold;
pub mod lube;
pub mod park;
pub mod profile;
pub mod protect;
pub mod sense;
pub mod speed;

use crate::detect::stickslip::{DetectorInputs, Reaction, StickSlipDetector};
use crate::estimator::{Estimator, Measurements, TickEstimate};
#[cfg(feature = "ball-screw")]
use crate::model::ballscrew::BallScrew;
use crate::model::Scale;
use crate::units::{
    ms_to_ticks, qmul, sat32, Amperes, Instant, Metres, NewtonMetres, Radians, RadiansPerSecond,
    Ratio, Volts, Q,
};
use crate::ConfigError;
use config::{ButtonMode, ControlConfig};
use edges::EdgeInterpolator;
use profile::Profile;
pub use protect::FaultKind;
use protect::{Limits, Monitors, Sample};
pub use sense::Switches;
use sense::{Adc, Debouncer, EncoderTracker};
use speed::{SpeedGains, SpeedInputs, SpeedLoop};

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
    /// Screw torque of the model at rated load.
    pub model_torque: NewtonMetres,
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
    Lubrication(lube::LubeReport),
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
    /// The motion under way (or the last one) runs slower than `motion.cruise_speed`: the
    /// screw speed the motor reached at the present load and supply (`limit_cruise`).
    pub cruise_limit: Option<RadiansPerSecond>,
    /// Ball screw: the friction coefficient identified from the current and the law's, once a
    /// lift/lowering pair has been solved (`lube`).
    #[cfg(feature = "ball-screw")]
    pub lube: Option<lube::LubeReport>,
}

/// Ticks after the reference arrives during which the loop may settle before the bridge coasts.
const SETTLE_MS: u32 = 300;
/// Position error accepted as arrived, screw counts.
const ARRIVED_COUNTS: i32 = 40;
/// Debounce of the switches, ticks at 1 kHz (scaled with the tick).
const DEBOUNCE_MS: u32 = 3;
/// Buttons must be seen released this long before they can start a motion.
const ARM_MS: u32 = 50;
/// Largest dynamic-braking current allowed, A (the BTS7960's low sides are rated 40 A).
const BRAKE_AMPS: i32 = 30;
/// Overload monitoring starts this long after a motion starts (breakaway, winding the coupling).
const OVERLOAD_HOLDOFF_MS: u32 = 250;

/// The supervisor's durations in control ticks.
#[derive(Clone, Copy, Debug)]
struct TickCounts {
    /// Overload monitoring holdoff after a start (+ one ramp).
    overload_holdoff: u32,
    /// Settling after the reference arrived / after a stop.
    settle: u32,
    /// Buttons seen released before they arm.
    arm: u32,
}

impl TickCounts {
    fn new(tick_us: u32, ramp_ms: u32) -> TickCounts {
        let t = |ms: u32| ms_to_ticks(ms, tick_us);
        TickCounts {
            overload_holdoff: t(OVERLOAD_HOLDOFF_MS).saturating_add(t(ramp_ms)),
            settle: t(SETTLE_MS),
            arm: t(ARM_MS),
        }
    }
}

/// The control core: configuration (validated) and state.
#[derive(Clone, Debug)]
pub struct Controller {
    cfg: ControlConfig,
    est: Estimator,
    adc: Adc,
    enc: EncoderTracker,
    /// Sub-count position from the encoder's edge times, for the speed filter.
    edges: EdgeInterpolator,
    debounce: Debouncer,
    profile: Profile,
    gains: SpeedGains,
    speed: SpeedLoop,
    limits: Limits,
    monitors: Monitors,
    /// Limit stops in encoder counts.
    lower_counts: i32,
    upper_counts: i32,
    /// Where the lower limit switch closes, counts (the homing reference).
    switch_counts: i32,
    /// The position is known; false until a homing run reaches the lower switch.
    homed: bool,
    /// counts → screw rad (Q16).
    rad_per_count: Scale,
    /// Q16 counts/tick → screw rad/s (Q16).
    speed_scale: Scale,
    /// Screw torque (Q16 N·m) → coupling twist in counts.
    twist_scale: Scale,
    /// Durations in ticks, computed once (no division on the tick path).
    ticks: TickCounts,
    state: State,
    fault: Option<Fault>,
    last_duty: i16,
    last_bridge: Bridge,
    current: Amperes,
    supply: Volts,
    switches: Switches,
    estimate: TickEstimate,
    /// Ticks since the reference arrived (settling) and since the motion started.
    settle_ticks: u32,
    motion_ticks: u32,
    hold_position: i32,
    /// Where a ball screw is held at rest (set when the rest begins; see `hold`).
    hold_target: i32,
    /// Buttons pressed since boot/fault must be released before they count (edge-triggered).
    buttons_armed: bool,
    /// Ticks since the lift came to rest.
    rest_ticks: u32,
    /// Consecutive ticks with both motion buttons released (raw), toward arming.
    release_ticks: u32,
    /// The motion was started by a hold-to-run button that is still held.
    held_button: u8,
    prev_buttons: u8,
    /// The profile's speed of the last tick in screw rad/s (`reference_speed`), converted
    /// once when the profile steps: the tick reads it up to four times.
    last_ref_rad: RadiansPerSecond,
    /// The profile's position of the last tick, counts.
    last_ref_counts: i32,
    /// 1/(k_e·n), screw rad/s per volt.
    inv_ke_n: Ratio,
    /// R·I_limit.
    current_headroom: Volts,
    /// Measured screw torque, low-passed (1/8 per tick: 20 Hz at 1 kHz), for the twist.
    torque_lp: NewtonMetres,
    /// Highest screw speed at which shorting the motor keeps the current within [`BRAKE_AMPS`].
    brake_speed: RadiansPerSecond,
    pending_event: Option<Event>,
    /// Stick-slip detector (issue 7) and the cruise speeds it switches between, Q32
    /// counts/tick: configured, and the escape speed of the `speed` reaction.
    stick_slip: StickSlipDetector,
    cruise_q32: i64,
    escape_q32: i64,
    /// The cruise speed of the motion under way when the motor cannot reach the configured one
    /// (`limit_cruise`).
    cruise_limit: Option<RadiansPerSecond>,
    /// How far the reference may lead the screw before the planner waits for it, counts.
    lag_counts: i32,
    /// The motion's [`Event::CruiseLimited`] was reported.
    cruise_reported: bool,
    /// The last driving tick found the screw lagging (the planner waited): a stall sign.
    lagging: bool,
    /// The ball screw (`cfg.ball_screw`, compiled) and the identification of its friction.
    #[cfg(feature = "ball-screw")]
    ball_screw: BallScrew,
    #[cfg(feature = "ball-screw")]
    lube: lube::LubeMonitor,
    /// A lubrication warning (of `lube`'s latest report) waits for a tick without another event.
    #[cfg(feature = "ball-screw")]
    lube_notice: bool,
    /// The holding brake (`hold.rs`).
    brake: hold::BrakeState,
}

impl Controller {
    /// Validate `cfg` and start at rest with the encoder at `position` counts (the position
    /// survives power loss with the configuration: the lead screw is self-locking).
    pub fn new(cfg: &ControlConfig, position: i32) -> Result<Controller, ConfigError> {
        // The ball-screw build gives a law in τ on a ball screw to the estimator in the screw
        // rate (`ControlConfig::build_estimator`).
        let est = cfg.build_estimator()?;
        #[cfg(feature = "ball-screw")]
        let ball_screw = cfg.ball_screw.compile()?;
        let geometry = est.geometry();
        let (lower_counts, upper_counts, switch_counts) = cfg.validate_limit_counts(geometry)?;
        let tick_us = cfg.estimator.tick_us;
        let tick_hz = i128::from(1_000_000 / tick_us);
        let rad_per_count = geometry.screw_rad_per_count(); // counts → Q16 rad
        let speed_scale = rad_per_count.times(tick_hz, 1 << 16);
        // counts per screw rad (Q16) = 2^32 / rad_per_count(Q16 value).
        // Unsigned products and quotients through the one out-of-line `mul_div_u64`: every
        // operand is positive, and for a validated drive (4…65 536 counts/rev, gear 1…1000)
        // counts/rad (Q16) < 2^40, so the speeds below stay far inside `u64`.
        let (mant, shift) = rad_per_count.parts();
        let mul_div = crate::math::mul_div_u64;
        let counts_per_rad_q16 = mul_div(
            1 << 32,
            1 << shift.min(63),
            mant.max(1).unsigned_abs().into(),
        ) as i64;
        // Twist counts = T/k · counts/rad: from Q16 N·m.
        let k = i128::from(cfg.estimator.mechanics.coupling_stiffness.bits()); // Q16
        let twist_scale = Scale::from_ratio(i128::from(counts_per_rad_q16), k << 16);
        // Cruise: rad/s → Q32 counts/tick = ω·counts/rad·T·2^32.
        // (Both speeds are validated positive: 0.2…20 rad/s.)
        let counts_per_rad_tick = counts_per_rad_q16.unsigned_abs() * u64::from(tick_us);
        let per_tick_q32 = |speed: RadiansPerSecond| {
            mul_div(
                speed.bits().unsigned_abs().into(),
                counts_per_rad_tick,
                1_000_000,
            ) as i64
        };
        let cruise_q32 = per_tick_q32(cfg.motion.cruise_speed);
        // The planner waits while the screw lags its reference by more than 0.25 rad of the
        // screw (≈ 0.08 mm of nut on the S12x2; at least the arrival window), see `drive`.
        let lag_counts = sat32(counts_per_rad_q16 >> 18).max(ARRIVED_COUNTS);
        let escape_q32 = per_tick_q32(cfg.stick_slip.escape_speed);
        let ramp_ticks = ms_to_ticks(cfg.motion.ramp_ms, tick_us);
        let gear_ratio = cfg.estimator.drive.gear_ratio;
        let counts_per_motor_rad_q16 = mul_div(
            counts_per_rad_q16.unsigned_abs(),
            1 << 16,
            gear_ratio.to_bits().max(1).unsigned_abs().into(),
        );
        // Nut metres per count in Q40: the travel of 2^16 counts in Q24.
        let nut_q40 =
            i64::from(geometry.travel(1 << 16).bits()) - i64::from(geometry.travel(0).bits());
        let limits = Limits::new(
            &cfg.protection,
            tick_us,
            counts_per_motor_rad_q16 as i64,
            nut_q40,
            cfg.motion.cruise_speed,
        );
        let gains: SpeedGains = SpeedGains::design(
            cfg.estimator.motor.torque_constant,
            cfg.estimator.motor.resistance,
            crate::units::Factor::from_raw(gear_ratio.to_bits()),
            tick_us,
        );
        let inv_ke_n = Ratio::from_raw(sat32((1i64 << 44) / i64::from(gains.ke_n.bits().max(1))));
        let debounce_ticks = ms_to_ticks(DEBOUNCE_MS, tick_us).max(1) as u16;
        Ok(Controller {
            cfg: *cfg,
            est,
            adc: Adc::new(&cfg.sensing),
            enc: EncoderTracker::new(position),
            edges: EdgeInterpolator::new(),
            debounce: Debouncer::new(debounce_ticks),
            profile: Profile::new(position, cruise_q32, ramp_ticks, cfg.motion.ramp_shape),
            speed: SpeedLoop::default(),
            limits,
            monitors: Monitors::default(),
            lower_counts,
            upper_counts,
            switch_counts,
            homed: true,
            rad_per_count,
            speed_scale,
            twist_scale,
            ticks: TickCounts::new(tick_us, cfg.motion.ramp_ms),
            state: State::Idle,
            fault: None,
            last_duty: 0,
            last_bridge: Bridge::Coast,
            current: Amperes::ZERO,
            supply: Volts::ZERO,
            switches: Switches(0),
            estimate: TickEstimate::default(),
            settle_ticks: 0,
            motion_ticks: 0,
            hold_position: position,
            hold_target: position,
            buttons_armed: false,
            release_ticks: 0,
            rest_ticks: u32::MAX,
            held_button: 0,
            prev_buttons: 0,
            last_ref_rad: RadiansPerSecond::ZERO,
            last_ref_counts: position,
            gains,
            inv_ke_n,
            torque_lp: NewtonMetres::ZERO,
            current_headroom: qmul(cfg.protection.current_limit, cfg.estimator.motor.resistance),
            brake_speed: qmul(
                qmul::<_, _, Volts>(
                    Amperes::from_int(BRAKE_AMPS),
                    cfg.estimator.motor.resistance,
                ),
                inv_ke_n,
            ),
            pending_event: None,
            stick_slip: StickSlipDetector::new(&cfg.stick_slip, tick_us),
            cruise_q32,
            escape_q32,
            cruise_limit: None,
            lag_counts,
            cruise_reported: false,
            lagging: false,
            #[cfg(feature = "ball-screw")]
            ball_screw,
            #[cfg(feature = "ball-screw")]
            lube: lube::LubeMonitor::new(
                &cfg.lube,
                &cfg.estimator.motor,
                cfg.estimator.drive.gear_ratio,
                tick_us,
            ),
            #[cfg(feature = "ball-screw")]
            lube_notice: false,
            brake: hold::BrakeState::new(&cfg.brake, tick_us),
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
        // Adjusted inside the `Result` (`?` would move the 2 KiB controller out of it and back
        // into a new one: two more copies and stack slots).
        let mut made = Controller::new(cfg, position.unwrap_or(0));
        if let (Ok(c), None) = (&mut made, position) {
            // Until homed, assume the lowest position: the model's load (and feed-forward) is
            // then the largest the lift can see.
            c.set_position(c.switch_counts);
            c.homed = false;
        }
        made
    }

    /// The position is known (a homing run is not needed).
    pub fn homed(&self) -> bool {
        self.homed
    }

    fn set_position(&mut self, position: i32) {
        self.edges
            .shift(position.saturating_sub(self.enc.position()));
        self.enc.rebase(position);
        self.est.reset(position);
        self.hold_position = position;
        self.hold_target = position;
        self.profile.reset(position);
        self.last_ref_counts = position;
    }

    /// The configuration in force.
    pub fn config(&self) -> &ControlConfig {
        &self.cfg
    }

    /// The estimator (geometry, model).
    pub fn estimator(&self) -> &Estimator {
        &self.est
    }

    /// Supervisor state.
    pub fn state(&self) -> State {
        self.state
    }

    /// The latched fault.
    pub fn fault(&self) -> Option<&Fault> {
        self.fault.as_ref()
    }

    /// The last estimate (what the tick reads; the estimator's `details` gives the rest).
    pub fn estimate(&self) -> &TickEstimate {
        &self.estimate
    }

    /// The stick-slip detector's report of the last tick.
    pub fn stick_slip_output(&self) -> &crate::detect::stickslip::StickSlipOutput {
        self.stick_slip.output()
    }

    /// Motor encoder position in counts.
    pub fn position_counts(&self) -> i32 {
        self.enc.position()
    }

    /// Limit stops in encoder counts (lower, upper).
    pub fn limit_counts(&self) -> (i32, i32) {
        (self.lower_counts, self.upper_counts)
    }

    /// The current motion target, counts (screw position).
    pub fn target_counts(&self) -> i32 {
        self.profile.target_counts()
    }

    /// The reference (screw) position of the last tick, counts, and the screw-position estimate.
    pub fn tracking(&self) -> (i32, i32) {
        (self.last_ref_counts, self.screw_position())
    }

    /// Values for the status line.
    pub fn status(&self) -> Status {
        Status {
            state: self.state,
            height: self.estimate.height,
            screw_speed: self.estimate.screw_speed,
            current: self.current,
            supply: self.supply,
            friction_torque: self.estimate.friction_torque,
            stick_slip: self.stick_slip.output().active,
            stick_slip_amplitude: self.stick_slip.output().amplitude,
            stick_slip_episodes: self.stick_slip.output().episodes,
            fault: self.fault.map(|f| f.kind),
            position: self.enc.position(),
            homed: self.homed,
            cruise_limit: self.cruise_limit,
            #[cfg(feature = "ball-screw")]
            lube: if self.holds_actively() {
                self.lube.report()
            } else {
                None
            },
        }
    }

    /// The ball screw's friction identification (`lube`).
    #[cfg(feature = "ball-screw")]
    pub fn lube(&self) -> &lube::LubeMonitor {
        &self.lube
    }

    /// Replace the configuration while the lift is at rest (Idle, Holding or Fault, screw
    /// slower than `control.rest_speed`): the position, the state, a latched fault and the
    /// latest measurements are kept, everything derived from the configuration is rebuilt, and
    /// the next tick runs with it. Refused while moving ([`Refusal::InMotion`]), so a motion
    /// never sees a half-applied change; refused whole if [`Controller::new`] refuses `cfg`.
    pub fn reconfigure(&mut self, cfg: &ControlConfig) -> Result<(), Refusal> {
        let turning = self.estimate.screw_speed.sat_abs() > self.cfg.estimator.rest_speed;
        if matches!(self.state, State::Lifting | State::Lowering) || turning {
            return Err(Refusal::InMotion);
        }
        // The candidate is adjusted inside the `Result` and moved once, into `self`: unwrapping
        // it first (`?`) copied the 2 KiB controller into a second stack slot, and this runs
        // in the console task with the controller's lock held (interrupts off).
        let mut made = Controller::new(cfg, self.enc.position());
        let Ok(next) = &mut made else {
            return Err(Refusal::BadConfig);
        };
        let same_model = cfg.estimator == self.cfg.estimator;
        // A τ law on a ball screw also depends on the ball screw and the rated load.
        #[cfg(feature = "ball-screw")]
        let same_model = same_model && next.est.law() == self.est.law();
        if same_model {
            // Same model and filter: keep the speed estimate running. Swapped rather than
            // cloned (`self` is replaced by `next` below and reads no `est` before that; the
            // field-by-field clone was 0.3 KiB of flash).
            core::mem::swap(&mut next.est, &mut self.est);
        }
        if cfg.estimator.tick_us == self.cfg.estimator.tick_us {
            next.debounce = self.debounce;
        }
        next.enc = self.enc;
        next.state = self.state;
        next.fault = self.fault;
        next.hold_position = self.hold_position;
        next.rest_ticks = self.rest_ticks;
        next.current = self.current;
        next.supply = self.supply;
        next.switches = self.switches;
        next.estimate = self.estimate;
        next.buttons_armed = self.buttons_armed;
        next.release_ticks = self.release_ticks;
        next.prev_buttons = self.prev_buttons;
        next.pending_event = self.pending_event;
        next.brake.keep_timing(&self.brake);
        #[cfg(feature = "ball-screw")]
        if cfg.ball_screw == self.cfg.ball_screw
            && cfg.lube == self.cfg.lube
            && cfg.estimator == self.cfg.estimator
        {
            next.lube = self.lube;
        }
        // Counts mean another height under another geometry or drive: the position is then
        // unknown until the lift is homed again.
        let same_counts = cfg.estimator.geometry == self.cfg.estimator.geometry
            && cfg.estimator.drive == self.cfg.estimator.drive;
        next.homed = self.homed && same_counts;
        if !next.homed {
            let at = next.switch_counts;
            next.set_position(at);
        }
        if let Ok(next) = made {
            *self = next;
        }
        Ok(())
    }

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
        match cmd {
            Command::ClearFault => {
                let Some(f) = self.fault else {
                    return Err(Refusal::NoFault);
                };
                if f.kind == FaultKind::NeedsBallScrew {
                    return Err(Refusal::NeedsBallScrew);
                }
                self.fault = None;
                self.monitors.reset();
                self.buttons_armed = false;
                self.release_ticks = 0;
                self.enter_rest(State::Idle);
                Ok(())
            }
            Command::Stop => {
                self.held_button = 0;
                if matches!(self.state, State::Lifting | State::Lowering) {
                    if self.awaiting_brake() {
                        // Nothing moved yet: the motor holds where it took the load up.
                        self.enter_rest(State::Holding);
                    } else {
                        self.profile.stop();
                    }
                }
                Ok(())
            }
            // Homing from a closed lower switch: creep up until it opens (at most to where the
            // lower stop would be).
            Command::Up if !self.homed && self.switches.is_active(Switches::LIMIT_LOWER) => {
                let span = self.lower_counts.saturating_sub(self.switch_counts);
                self.start(self.enc.position().saturating_add(span), true)
            }
            Command::Up | Command::GoTo(_) if !self.homed && self.fault.is_none() => {
                Err(Refusal::NotHomed)
            }
            // Homing: aim one full stroke below the stop; the lower switch ends the run.
            Command::Down if !self.homed => {
                let stroke = self.upper_counts.saturating_sub(self.switch_counts);
                self.start(self.enc.position().saturating_sub(stroke), false)
            }
            // A direction command moves only in its direction: with the head above a lowered
            // upper stop `up` would lower to it (and `down` lift to a raised lower stop).
            // (A latched fault is the first reason, `start`'s.)
            Command::Up if self.fault.is_none() && self.upper_counts <= self.screw_position() => {
                Err(Refusal::AtLimit)
            }
            Command::Down if self.fault.is_none() && self.lower_counts >= self.screw_position() => {
                Err(Refusal::AtLimit)
            }
            Command::Up => self.start(self.upper_counts, false),
            Command::Down => self.start(self.lower_counts, false),
            Command::GoTo(h) => {
                let counts = self
                    .est
                    .geometry()
                    .counts_for_height(h)
                    .ok_or(Refusal::OutsideLimits)?;
                if counts < self.lower_counts || counts > self.upper_counts {
                    return Err(Refusal::OutsideLimits);
                }
                self.start(counts, true)
            }
        }
    }

    fn start(&mut self, target: i32, goto: bool) -> Result<(), Refusal> {
        if self.fault.is_some() {
            return Err(Refusal::Faulted);
        }
        let here = self.screw_position();
        let dir = (target - here).signum();
        match (self.state, dir) {
            (State::Lifting, d) if d < 0 => return Err(Refusal::Moving),
            (State::Lowering, d) if d > 0 => return Err(Refusal::Moving),
            _ => {}
        }
        let moving = matches!(self.state, State::Lifting | State::Lowering);
        if !moving && self.supply < self.cfg.protection.supply_start_min {
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
        if self.switches.is_active(switch) {
            return Err(Refusal::AtLimit);
        }
        if !moving {
            self.profile.reset(here);
            self.last_ref_counts = here;
            self.profile.set_cruise(self.cruise_q32);
            self.cruise_limit = None;
            self.cruise_reported = false;
            if !self.keeps_integrator(None) {
                self.speed.reset();
            }
            self.monitors.reset();
            self.motion_ticks = 0;
        }
        self.profile.set_target(target);
        self.settle_ticks = 0;
        self.set_state(if dir > 0 {
            State::Lifting
        } else {
            State::Lowering
        });
        Ok(())
    }

    /// The lift lags its reference by more than `lag_counts`: the motor cannot reach the
    /// profile's cruise at this load and supply (or a heavier car than the rated one). The
    /// reference waits this tick (the caller skips the planner), and the cruise steps toward
    /// the screw's measured speed + 1/16: down by at most 1/16 a lagging tick (a stick-slip
    /// stick, where the screw stands for a few ticks, barely lowers it), up to it at once (so
    /// the reference keeps leading a little and the limit finds what the motor reaches), never
    /// above `motion.cruise_speed`. The first limit of a motion is reported
    /// ([`Event::CruiseLimited`]). A profile faster than the lift ran
    /// ahead of it: the reference reached the target and the settling time ran out with the
    /// head short of it, and lowering, the reference's ramp-down made the lagging lift look
    /// like a runaway. Out of line: only on lagging ticks, which skip the planner's step.
    #[cold]
    #[inline(never)]
    fn limit_cruise(&mut self) {
        let cruise = self.cfg.motion.cruise_speed;
        let prev = self.cruise_limit.unwrap_or(cruise);
        let step = prev.sat_sub(RadiansPerSecond::from_raw(prev.bits() >> 4));
        // Only while the reference cruises (not in its ramps: accelerating from rest the
        // screw lags and is slow for a moment whatever the motor can do).
        if self.last_ref_rad.sat_abs() < step {
            return;
        }
        let w = self.estimate.screw_speed.sat_abs();
        let seen = w.sat_add(RadiansPerSecond::from_raw(w.bits() >> 4));
        let w = seen
            .max(step)
            .min(cruise)
            .max(const { RadiansPerSecond::lit("0.2") });
        if w == prev || w >= cruise {
            return;
        }
        // Reported once it has settled on what the screw does.
        if !self.cruise_reported && seen >= step && self.pending_event.is_none() {
            self.cruise_reported = true;
            self.pending_event = Some(Event::CruiseLimited { speed: w });
        }
        self.cruise_limit = Some(w);
        self.profile.set_cruise(crate::math::mul_div_u64(
            self.cruise_q32.unsigned_abs(),
            w.bits().unsigned_abs().into(),
            cruise.bits().unsigned_abs().max(1).into(),
        ) as i64);
    }

    /// Screw position estimate: the encoder less the coupling twist while driving. The twist
    /// comes from the *measured* torque (low-passed), not the model's: the model assumes the
    /// rated load, and with an empty lift it would over-correct by the whole rated twist.
    /// Not marked for speed: its out-of-line copy is 46 B at "z", 100 B for speed (3
    /// instructions a tick).
    fn screw_position(&self) -> i32 {
        if matches!(self.state, State::Lifting | State::Lowering) {
            let twist = self.twist_scale.apply32(self.torque_lp.bits());
            self.enc.position().saturating_sub(twist)
        } else {
            self.enc.position()
        }
    }

    fn set_state(&mut self, to: State) {
        if to != self.state {
            let from = self.state;
            self.state = to;
            if !matches!(self.pending_event, Some(Event::Fault(_))) {
                self.pending_event = Some(Event::State { from, to });
            }
        }
    }

    fn enter_rest(&mut self, to: State) {
        self.held_button = 0;
        self.rest_ticks = 0;
        self.hold_position = self.enc.position();
        self.hold_target = self.enc.position();
        if !self.keeps_integrator(None) {
            self.speed.reset();
        }
        self.profile.reset(self.enc.position());
        self.set_state(to);
    }

    fn latch(&mut self, now: Instant, kind: FaultKind) {
        if self.fault.is_some() {
            return;
        }
        let f = Fault {
            kind,
            at: now,
            state: self.state,
            position: self.enc.position(),
            height: self.estimate.height,
            homed: self.homed,
            screw_speed: self.estimate.screw_speed,
            current: self.current,
            supply: self.supply,
            duty: self.last_duty,
            measured_torque: self.estimate.measured_screw_torque,
            model_torque: self.estimate.model_screw_torque,
        };
        self.fault = Some(f);
        self.brake.unwound();
        self.held_button = 0;
        self.hold_target = self.enc.position();
        if !self.keeps_integrator(Some(kind)) {
            self.speed.reset();
        }
        self.profile.reset(self.enc.position());
        self.state = State::Fault;
        self.pending_event = Some(Event::Fault(f));
    }

    /// One control tick. Never panics, whatever the inputs.
    #[inline(never)]
    pub fn step(&mut self, now: Instant, inputs: &Inputs) -> Outputs {
        // 1. Sense.
        let delta = self.enc.update(inputs.encoder_count);
        self.current = self.adc.current(inputs.current_raw);
        self.supply = self.adc.supply(inputs.supply_raw);
        self.switches = self.debounce.update(inputs.switches);
        let moving = matches!(self.state, State::Lifting | State::Lowering);
        let dir: i8 = match self.state {
            State::Lifting => 1,
            State::Lowering => -1,
            _ => 0,
        };
        // 2. Estimate at rated load; the speed filter gets the position between counts.
        let position = self.enc.position();
        let between = self
            .edges
            .update_fraction(now, position, inputs.encoder_edge_age);
        self.estimate = self.est.step_at(
            now,
            &Measurements {
                position_counts: position,
                motor_current: self.current,
                load: self.cfg.rated_load,
                commanded_dir: dir,
            },
            between,
        );
        if moving {
            let d = self.estimate.measured_screw_torque.sat_sub(self.torque_lp);
            self.torque_lp = self
                .torque_lp
                .sat_add(NewtonMetres::from_raw(d.bits() >> 3));
        } else {
            self.torque_lp = NewtonMetres::ZERO;
        }

        // 3. Protections.
        self.motion_ticks = if moving {
            self.motion_ticks.saturating_add(1)
        } else {
            0
        };
        let reference = if moving {
            self.reference_speed()
        } else {
            RadiansPerSecond::ZERO
        };
        let emf_speed = self.emf_speed();
        let project = |t: NewtonMetres| if dir < 0 { t.sat_neg() } else { t };
        let holdoff = self.ticks.overload_holdoff;
        let sample = Sample {
            moving,
            lowering: dir < 0,
            duty: self.last_duty,
            delta,
            current: self.current,
            supply: self.supply,
            emf_speed,
            speed: self.estimate.screw_speed,
            reference,
            cruise: self.cfg.motion.cruise_speed,
            travel_while_stopped: if moving || self.state == State::Fault {
                0
            } else {
                self.enc.position().saturating_sub(self.hold_position)
            },
            measured_torque: project(self.estimate.measured_screw_torque),
            model_torque: project(self.estimate.model_screw_torque),
            overload_armed: moving
                && matches!(self.last_bridge, Bridge::Drive(_))
                && self.motion_ticks > holdoff,
            lagging: moving && self.lagging,
        };
        if self.state != State::Fault {
            if let Some(kind) = self.monitors.check(&self.limits, &sample) {
                self.latch(now, kind);
            }
        }
        // Limit switches: both closed is a wiring fault; one closed in the direction of
        // travel stops the lift at once.
        let both = Switches::LIMIT_UPPER | Switches::LIMIT_LOWER;
        if self.switches.is_active(both) && self.state != State::Fault {
            self.latch(now, FaultKind::SwitchesImplausible);
        }
        if moving && self.state != State::Fault {
            let switch = if dir > 0 {
                Switches::LIMIT_UPPER
            } else {
                Switches::LIMIT_LOWER
            };
            let lower_closed = self.switches.is_active(Switches::LIMIT_LOWER);
            let homing = !self.homed && (dir < 0) == lower_closed;
            if homing || self.switches.is_active(switch) {
                self.limit_switch(now, dir, homing);
            }
        }

        // 4. Buttons.
        self.buttons(inputs.switches.0);

        // 5–6. Motion (the brake's output first: a motion waits for it to release).
        self.brake_step();
        let bridge = match self.state {
            State::Lifting | State::Lowering => self.drive(),
            _ => {
                // Settling after a stop: the rotor coasts down and the wound coupling unwinds
                // through the motor; that motion is commanded, so the runaway reference follows
                // it for SETTLE_MS (a runaway is measured from where the lift settled).
                self.rest_ticks = self.rest_ticks.saturating_add(1);
                if self.rest_ticks <= self.ticks.settle {
                    self.hold_position = self.enc.position();
                }
                self.at_rest_bridge()
            }
        };
        self.detect_stick_slip();
        #[cfg(feature = "ball-screw")]
        if self.holds_actively() {
            self.identify_friction();
        }
        self.last_duty = match bridge {
            Bridge::Drive(d) => d,
            _ => 0,
        };
        self.last_bridge = bridge;
        Outputs {
            bridge,
            feed_watchdog: true,
            brake_release: self.brake.release,
            event: self.pending_event.take(),
        }
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

    /// A motion reached its limit switch, or (`homing`) the lower switch changed on a homing
    /// run: the homing reference, a stop at the switch, or a fault if the soft limit should
    /// have stopped the lift first. Out of line and compiled for size (the tick's body is
    /// compiled for speed): it runs on one tick of a motion at most, which ends it.
    #[cold]
    #[inline(never)]
    fn limit_switch(&mut self, now: Instant, dir: i8, homing: bool) {
        if homing {
            // Homing run: the lower switch closed (lowering) or opened (creeping up from it)
            // at its configured height. That height is the screw's, so the encoder is set
            // ahead of it by the coupling twist of the moment.
            self.homed = true;
            let twist = self.twist_scale.apply32(self.torque_lp.bits());
            let at = self.switch_counts;
            self.set_position(at.saturating_add(twist));
            self.enter_rest(State::Holding);
            self.pending_event = Some(Event::Homed { position: at });
        } else {
            // The soft limit should have caught it if the lift is already at or past it.
            let stop = if dir > 0 {
                self.upper_counts
            } else {
                self.lower_counts
            };
            let past =
                (self.screw_position() - stop) * i32::from(dir) >= -self.limits.runaway_counts;
            if past {
                self.latch(now, FaultKind::LimitSwitch);
            } else {
                self.enter_rest(State::Holding);
                self.pending_event = Some(Event::SwitchStop);
            }
        }
    }

    /// Stick-slip detector step on this tick's measured torque (the current answers the bridge
    /// command of the previous tick, so "driving" is that command) and the reaction.
    fn detect_stick_slip(&mut self) {
        let moving = matches!(self.state, State::Lifting | State::Lowering);
        let x = DetectorInputs {
            driving: moving && matches!(self.last_bridge, Bridge::Drive(_)),
            direction: if self.state == State::Lowering { -1 } else { 1 },
            reference: self.reference_speed(),
            measured_torque: self.estimate.measured_screw_torque,
        };
        let out = self.stick_slip.step(&x, self.est.law());
        if out.onset {
            self.stick_slip_onset();
        }
    }

    /// The reaction to a stick-slip episode's onset, and its event: out of line and compiled
    /// for size (once per episode).
    #[cold]
    #[inline(never)]
    fn stick_slip_onset(&mut self) {
        let out = self.stick_slip.output();
        let (amplitude, episode) = (out.amplitude, out.episodes);
        let reaction = self.cfg.stick_slip.reaction;
        if reaction == Reaction::ChangeSpeed {
            self.profile.set_cruise(self.escape_q32);
        }
        if self.pending_event.is_none() {
            self.pending_event = Some(Event::StickSlip {
                amplitude,
                episode,
                reaction,
            });
        }
    }

    /// Ball screw: a sample of the friction identification while moving, the pair solve and
    /// the lubrication warning once at rest (`lube`).
    #[cfg(feature = "ball-screw")]
    fn identify_friction(&mut self) {
        let moving = matches!(self.state, State::Lifting | State::Lowering);
        if moving {
            let e = &self.estimate;
            let not_thread = e.model_screw_torque.sat_sub(e.thread_torque);
            let x = lube::LubeInputs {
                driving: matches!(self.last_bridge, Bridge::Drive(_)),
                lifting: self.state == State::Lifting,
                reference: self.reference_speed(),
                speed: e.screw_speed,
                thread_torque: e.measured_screw_torque.sat_sub(not_thread),
                axial_rated: e.axial,
            };
            self.lube.sample(&self.cfg.lube, &x);
        } else if self.lube.in_motion() && self.state == State::Fault {
            // A motion a fault ended (an obstruction, a jam…) says nothing about the friction.
            self.lube.abort_motion();
        } else if self.lube.in_motion() {
            let at_lower = self.enc.position() <= self.lower_counts.saturating_add(ARRIVED_COUNTS);
            let report = self.lube.end_motion(
                &self.ball_screw,
                &self.cfg.lube,
                self.cfg.rated_load,
                at_lower,
            );
            if report.is_some_and(|r| r.out_of_band) {
                self.lube_notice = true;
            }
        }
        if self.lube_notice && self.pending_event.is_none() {
            self.lube_notice = false;
            self.pending_event = self.lube.report().map(Event::Lubrication);
        }
    }

    /// Screw speed from the motor's voltage balance, (V_a − R·i)/(k_e·n): independent of the
    /// encoder, so a dead encoder and a jammed screw can be told apart.
    fn emf_speed(&self) -> RadiansPerSecond {
        let va = Volts::from_raw(sat32(
            i64::from(self.supply.bits()) * i64::from(self.last_duty) >> 15,
        ));
        let ri: Volts = qmul(self.current, self.cfg.estimator.motor.resistance);
        qmul(va.sat_sub(ri), self.inv_ke_n)
    }

    fn buttons(&mut self, raw: u8) {
        let pressed = self.switches.0 & (Switches::BUTTON_UP | Switches::BUTTON_DOWN);
        let edges = pressed & !self.prev_buttons;
        self.prev_buttons = pressed;
        if self.switches.is_active(Switches::BUTTON_STOP) {
            let _ = self.command(Command::Stop);
            return;
        }
        if !self.buttons_armed {
            // A button held at boot or through a fault must be seen released (raw, for
            // ARM_MS) first: the debouncer's initial "released" is not evidence.
            self.release_ticks = if raw & (Switches::BUTTON_UP | Switches::BUTTON_DOWN) == 0 {
                self.release_ticks.saturating_add(1)
            } else {
                0
            };
            self.buttons_armed = self.release_ticks >= self.ticks.arm;
            return;
        }
        if self.held_button != 0 && pressed & self.held_button == 0 {
            let _ = self.command(Command::Stop);
        }
        // Both buttons at once: do nothing new.
        if edges == Switches::BUTTON_UP && pressed == Switches::BUTTON_UP {
            if self.state == State::Lowering {
                let _ = self.command(Command::Stop);
            } else if self.command(Command::Up).is_ok()
                && self.cfg.motion.buttons == ButtonMode::HoldToRun
            {
                self.held_button = Switches::BUTTON_UP;
            }
        } else if edges == Switches::BUTTON_DOWN && pressed == Switches::BUTTON_DOWN {
            // Lowering is always hold-to-run from the buttons: a car comes down only while a
            // person keeps a finger on DOWN.
            if self.state == State::Lifting {
                let _ = self.command(Command::Stop);
            } else if self.command(Command::Down).is_ok() {
                self.held_button = Switches::BUTTON_DOWN;
            }
        }
    }

    /// Profile → speed loop → bridge, and the arrival check.
    fn drive(&mut self) -> Bridge {
        if let Some(releasing) = self.releasing_brake() {
            return releasing;
        }
        // The planner waits while the screw lags its reference by more than `lag_counts` (a
        // heavier load or a lower supply than `reachable_cruise` assumed): the reference never
        // runs ahead to the target and "arrives" with the head short of it, and lowering, its
        // ramp-down never leaves a lagging lift looking like a runaway.
        let dir = if self.state == State::Lowering { -1 } else { 1 };
        let behind = self
            .last_ref_counts
            .saturating_sub(self.screw_position())
            .saturating_mul(dir);
        let mut done = false;
        // The planner holds a stuck screw's lag near `lag_counts`: past half of it, the drive
        // is pushing (the stall monitor's sign, steady while the planner steps and waits).
        self.lagging = behind > self.lag_counts >> 1;
        if behind <= self.lag_counts {
            let r = self.profile.step();
            self.last_ref_rad =
                RadiansPerSecond::from_raw(self.speed_scale.apply32(sat32(r.speed >> 16)));
            self.last_ref_counts = r.counts();
            done = r.done;
        } else {
            self.limit_cruise();
        }
        let reference = self.last_ref_rad;
        let error_counts = self.last_ref_counts.saturating_sub(self.screw_position());
        if done {
            self.settle_ticks = self.settle_ticks.saturating_add(1);
            let still = self.estimate.screw_speed.sat_abs() < self.cfg.estimator.rest_speed;
            if (error_counts.abs() <= ARRIVED_COUNTS && still)
                || self.settle_ticks > self.ticks.settle
            {
                self.enter_rest(State::Holding);
                return self.at_rest_bridge();
            }
        }
        Bridge::Drive(self.speed_duty(reference, error_counts))
    }

    /// One step of the speed loop toward `reference` with `error_counts` of position error:
    /// the duty for moving and, for a ball screw, for holding at rest (`hold.rs`).
    fn speed_duty(&mut self, reference: RadiansPerSecond, error_counts: i32) -> i16 {
        self.speed.step(
            &self.gains,
            &SpeedInputs {
                reference,
                position_error: Radians::from_raw(self.rad_per_count.apply32(error_counts)),
                measured: self.estimate.screw_speed,
                model_motor_torque: self.estimate.model_motor_torque,
                supply: self.supply,
                current_headroom: self.current_headroom,
                current: self.current,
                current_limit: self.cfg.protection.current_limit,
                resistance: self.cfg.estimator.motor.resistance,
            },
        )
    }

    /// The bridge at rest: short the motor (dynamic brake) once it turns slowly enough that the
    /// short-circuit current k_e·ω/R stays within the brake limit; coast above that. Braking
    /// matters: when a move ends, the wound-up coupling unwinds through the motor, and a coasting
    /// rotor would overshoot and drag the screw back (host-sim shows 0.7 mm of head height
    /// lost with dry threads); the brake damps it with a time constant J·R/k² of about 3 ms.
    fn rest_bridge(&self) -> Bridge {
        if self.estimate.screw_speed.sat_abs() <= self.brake_speed {
            Bridge::Brake
        } else {
            Bridge::Coast
        }
    }

    /// The profile's speed of the last tick in screw rad/s.
    #[inline]
    fn reference_speed(&self) -> RadiansPerSecond {
        self.last_ref_rad
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
                        assert_eq!(c.cruise_q32, per_tick(cfg.motion.cruise_speed));
                        assert_eq!(c.escape_q32, per_tick(cfg.stick_slip.escape_speed));
                        let per_motor_rad = div128(
                            i128::from(cprq16) << 16,
                            i128::from(cfg.estimator.drive.gear_ratio.to_bits().max(1)),
                        );
                        let nut_q40 = i64::from(c.est.geometry().travel(1 << 16).bits())
                            - i64::from(c.est.geometry().travel(0).bits());
                        let limits = Limits::new(
                            &cfg.protection,
                            tick_us,
                            per_motor_rad as i64,
                            nut_q40,
                            cfg.motion.cruise_speed,
                        );
                        assert_eq!(c.limits.max_counts_per_tick, limits.max_counts_per_tick);
                        checked += 1;
                    }
                }
            }
        }
        // Most combinations are valid configurations (a few drives refuse the limit stops).
        assert!(checked >= 60, "only {checked} configurations built");
    }
}
