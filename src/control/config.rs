//! Everything the user can configure about motion, limit stops and protections, with the
//! ranges the console and the flash store validate against.
//!
//! [`ControlConfig`] is the whole of it. It is validated once, by [`crate::control::Controller::new`]
//! (or [`ControlConfig::validate`]), before a single tick runs with it; the hot path never
//! re-checks. Every refusal names the setting's console key and its range.

use crate::detect::stickslip::StickSlipConfig;
use crate::estimator::EstimatorConfig;
use crate::keys::{self, check_bounds, check_range, Bound, ConfigError};
use crate::model::ballscrew::BallScrewConfig;
use crate::model::friction::LawVariable;
use crate::model::geometry::Geometry;
#[cfg_attr(not(feature = "ball-screw"), allow(unused_imports))]
use crate::units::{Amperes, Kilograms, Metres, Newtons, RadiansPerSecond, Ratio, Volts};

pub use super::lube::LubeConfig;

/// Shape of the speed ramp.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RampShape {
    /// Constant acceleration (seed 000's Fig. 2 profile).
    #[default]
    Trapezoid,
    /// Acceleration rises and falls linearly (jerk-limited): same ramp time, no acceleration
    /// step, twice the trapezoid's peak acceleration.
    SCurve,
}

/// How the UP/DOWN buttons command motion.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ButtonMode {
    /// Motion lasts only while the button is held (the safe default for a car lift).
    #[default]
    HoldToRun,
    /// A press starts motion to the limit stop; STOP (or the other button) stops it.
    Latched,
}

/// The kind of screw the jack has: it decides whether the lift holds its load by itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ScrewKind {
    /// Trapezoidal lead screw (seed 000): self-locking, the motor rests with its windings
    /// shorted once slow.
    #[default]
    Lead,
    /// Ball screw (seeds 001, 002): not self-locking. At rest the controller holds the position
    /// actively (speed loop at zero speed with the position error), and a back-driven screw
    /// (uncommanded travel) latches `Runaway` and is held where it tripped (docs/control.md).
    Ball,
}

impl ScrewKind {
    /// Whether the lift stays where it stopped with the power off (the screw is self-locking):
    /// only then may a position parked in flash be trusted at boot. An unpowered ball screw
    /// lets the load turn it back through the gearbox.
    pub fn holds_without_power(self) -> bool {
        matches!(self, ScrewKind::Lead)
    }
}

/// A spring-applied (fail-safe) holding brake on the drive: engaged whenever its output is
/// off (unpowered, at boot, on a fault), released by the core only while the lift moves
/// (`control::hold`, docs/control.md "Holding brake").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BrakeConfig {
    /// A brake is fitted and wired to the brake output.
    pub present: bool,
    /// Time the brake takes to release or to engage once its output changes, 5…1000 ms: a
    /// motion waits this long (the motor holding the load) before the profile starts, and at
    /// rest the motor holds this long after the output went off before it lets go.
    pub delay_ms: u32,
}

impl BrakeConfig {
    /// No brake (the factory setting: a brake must be fitted and wired before it is used).
    pub const NONE: BrakeConfig = BrakeConfig {
        present: false,
        delay_ms: 60,
    };

    /// Check the delay.
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range(self.delay_ms, 5, 1000, &keys::DRIVE_BRAKE_MS)
    }
}

/// Speed profile and button behaviour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotionConfig {
    /// Cruise screw speed θ̇, 0.2…20 rad/s (the default motor reaches ≈ 4.2 rad/s at rated
    /// load on a 12.6 V battery; docs/plant.md).
    pub cruise_speed: RadiansPerSecond,
    /// Time to accelerate from rest to cruise speed (and to brake back), 10…2000 ms.
    pub ramp_ms: u32,
    /// Ramp shape.
    pub ramp_shape: RampShape,
    /// Button behaviour.
    pub buttons: ButtonMode,
}

impl MotionConfig {
    /// 3 rad/s cruise (head ≈ 3.6 mm/s at α = 15°), seed 000's 60 ms trapezoid, hold-to-run.
    pub const DEFAULT: MotionConfig = MotionConfig {
        cruise_speed: RadiansPerSecond::lit("3"),
        ramp_ms: 60,
        ramp_shape: RampShape::Trapezoid,
        buttons: ButtonMode::HoldToRun,
    };
}

/// The user's limit stops, as head heights.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LimitStops {
    /// Lowest head height the lift drives to.
    pub lower: Metres,
    /// Highest head height the lift drives to.
    pub upper: Metres,
    /// Head height at which the lower limit switch closes, measured when the lift is
    /// installed: the reference the lift homes on when its position was lost (power cut while
    /// moving, or no stored position). It must lie below `lower`: the switch is the backstop
    /// under the soft stop.
    pub switch_lower: Metres,
}

impl LimitStops {
    /// Factory limits of the default lift: 145 mm (α ≈ 16.7°) and 410 mm (α ≈ 71.8°), inside
    /// the limit switches at α = 16° and 74°.
    pub const DEFAULT: LimitStops = LimitStops {
        lower: Metres::lit("0.145"),
        upper: Metres::lit("0.410"),
        switch_lower: Metres::lit("0.1403"),
    };

    /// Smallest gap between the lower limit switch and the lower stop: the halt planner's
    /// tolerance (±0.5 mm; worst measured 0.09 mm in host-sim) must not reach the switch.
    pub const SWITCH_GAP: Metres = Metres::lit("0.0005");

    /// Smallest gap between the two stops.
    pub const MIN_GAP: Metres = Metres::lit("0.010");

    /// Check the stops against the mechanism: both inside α₀ … α_max and `lower + MIN_GAP ≤ upper`.
    pub fn validate(&self, geometry: &Geometry) -> Result<(), ConfigError> {
        self.counts(geometry).map(|_| ())
    }

    /// [`LimitStops::validate`], returning the lower stop, the upper stop and the lower switch
    /// in encoder counts (the controller's form of them: mapped once, where they are checked).
    pub fn counts(&self, geometry: &Geometry) -> Result<(i32, i32, i32), ConfigError> {
        let lower = geometry
            .counts_for_height(self.lower)
            .ok_or(keys::LIMITS_LOWER.out_of_range())?;
        let upper = geometry
            .counts_for_height(self.upper)
            .ok_or(keys::LIMITS_UPPER.out_of_range())?;
        if self.lower.sat_add(Self::MIN_GAP) > self.upper {
            return Err(keys::LIMITS_LOWER.conflict("must be at least 10 mm below limits.upper"));
        }
        let switch = geometry
            .counts_for_height(self.switch_lower)
            .ok_or(keys::LIMITS_SWITCH_LOWER.out_of_range())?;
        if self.switch_lower.sat_add(Self::SWITCH_GAP) > self.lower {
            return Err(keys::LIMITS_SWITCH_LOWER.conflict("must be at least 0.5 mm below limits.lower (the switch is the backstop under the soft stop)"));
        }
        Ok((lower, upper, switch))
    }
}

/// Protection thresholds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ProtectionConfig {
    /// Motor current that trips the over-current fault on the sample that exceeds it, 1…60 A.
    pub overcurrent: Amperes,
    /// Current the speed loop never asks for (it limits the voltage to back-EMF ± R·I), 1…60 A,
    /// at most `overcurrent`. A jammed lift then sits at this current until the stall
    /// protection trips, instead of tripping over-current.
    pub current_limit: Amperes,
    /// Stall: duty magnitude at or above which "no motion" counts, 0.05…1.
    pub stall_duty: Ratio,
    /// Stall: time at high duty without encoder motion before the fault, 20…5000 ms.
    pub stall_ms: u32,
    /// Fastest plausible motor-shaft speed (faster means a broken or noisy encoder), 10…5000 rad/s.
    pub max_motor_speed: RadiansPerSecond,
    /// Refuse to start below this supply voltage, 8…16 V.
    pub supply_start_min: Volts,
    /// Stop while moving below this supply voltage (held for `supply_ms`), 6…16 V.
    pub supply_run_min: Volts,
    /// Stop above this supply voltage (charger surge, load dump), 12…20 V.
    pub supply_max: Volts,
    /// Supply out of range for this long trips the fault, 1…1000 ms.
    pub supply_ms: u32,
    /// Overload: measured screw torque above the model's torque at rated load by this
    /// fraction, 0.05…2.
    pub overload_margin: Ratio,
    /// Overload: held for this long, 10…5000 ms.
    pub overload_ms: u32,
    /// Runaway: uncommanded travel (while stopped, or faster than commanded while lowering)
    /// before the fault, nut travel 0.01…10 mm.
    pub runaway_travel: Metres,
}

impl ProtectionConfig {
    /// Defaults for the default board (40 A bridge budget, 12 V lead-acid battery).
    pub const DEFAULT: ProtectionConfig = ProtectionConfig {
        overcurrent: Amperes::lit("45"),
        current_limit: Amperes::lit("40"),
        stall_duty: Ratio::lit("0.5"),
        stall_ms: 300,
        max_motor_speed: RadiansPerSecond::lit("600"),
        supply_start_min: Volts::lit("11.0"),
        supply_run_min: Volts::lit("9.5"),
        supply_max: Volts::lit("15.5"),
        supply_ms: 20,
        overload_margin: Ratio::lit("0.25"),
        overload_ms: 200,
        runaway_travel: Metres::lit("0.0005"),
    };
}

/// ADC scalings of the board (docs/plant.md, docs/board.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensingConfig {
    /// Current-sense ADC code at 0 A, 0…4095.
    pub current_zero_code: u16,
    /// Current per ADC code, µA (1…1 000 000).
    pub current_ua_per_code: u32,
    /// Supply voltage per ADC code, µV (1…100 000).
    pub supply_uv_per_code: u32,
}

impl SensingConfig {
    /// The default board: 25 mV/A around 1.65 V (32 227 µA/code), 10 k/2.2 k divider
    /// (4 468 µV/code), 12-bit ADC at 3.3 V.
    pub const DEFAULT: SensingConfig = SensingConfig {
        current_zero_code: 2048,
        current_ua_per_code: 32_227,
        supply_uv_per_code: 4_468,
    };
}

/// The whole control configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ControlConfig {
    /// Lift geometry, drive, friction law, motor, tick rate, speed filter.
    pub estimator: EstimatorConfig,
    /// Rated load of the lift, 10…5000 kg.
    pub rated_load: Kilograms,
    /// Speed profile and buttons.
    pub motion: MotionConfig,
    /// Limit stops.
    pub limits: LimitStops,
    /// Protection thresholds.
    pub protection: ProtectionConfig,
    /// ADC scalings.
    pub sensing: SensingConfig,
    /// Stick-slip detector and its reaction.
    pub stick_slip: StickSlipConfig,
    /// Lead screw or ball screw.
    pub screw: ScrewKind,
    /// The ball screw's geometry, preload and f(τ) law (seed 002), used in ball-screw mode to
    /// identify f online from the motor current (`control::lube`). Validated in either mode.
    pub ball_screw: BallScrewConfig,
    /// The identification's sampling and the lubrication warning's band.
    pub lube: LubeConfig,
    /// The holding brake (none by default).
    pub brake: BrakeConfig,
}

impl ControlConfig {
    /// The default lift, board and motor at a 1 kHz tick, rated 1000 kg (seed 000's load).
    pub const DEFAULT: ControlConfig = ControlConfig {
        estimator: EstimatorConfig::DEFAULT,
        rated_load: Kilograms::lit("1000"),
        motion: MotionConfig::DEFAULT,
        limits: LimitStops::DEFAULT,
        protection: ProtectionConfig::DEFAULT,
        sensing: SensingConfig::DEFAULT,
        stick_slip: StickSlipConfig::DEFAULT,
        screw: ScrewKind::Lead,
        ball_screw: BallScrewConfig::SEED_001_4008,
        lube: LubeConfig::DEFAULT,
        brake: BrakeConfig::NONE,
    };

    /// The default lift with seed 001's 4008 ball screw (r_m = 20 mm, lead 8 mm, λ = 3.64°) in
    /// place of the S12x2: the estimator sees it through [`BallScrewConfig::equivalent_thread_law`]
    /// at the rated load's axial force at α = 45° (seed 002's f(τ), VG100 oil), the screw's
    /// inertia is that of a Ø35 mm × 0.4 m steel shaft (460 µkg·m²), and the cruise speed is
    /// halved (the 8 mm lead moves the nut 4.9× farther per turn than the S12x2's 2 mm).
    ///
    /// [`BallScrewConfig::equivalent_thread_law`]: crate::model::ballscrew::BallScrewConfig::equivalent_thread_law
    #[cfg(feature = "ball-screw")]
    pub fn ball_screw_4008() -> Result<ControlConfig, ConfigError> {
        let bs = BallScrewConfig::SEED_001_4008.compile()?;
        let mut c = ControlConfig::DEFAULT;
        // R = M·g/tan 45° = M·g at α = 45°.
        let reference = Newtons::from_f64(c.rated_load.to_f64() * 9.806_65);
        c.estimator.law =
            BallScrewConfig::SEED_001_4008.equivalent_thread_law(bs.axial_force(reference))?;
        c.estimator.drive.pitch_radius = BallScrewConfig::SEED_001_4008.r_m;
        c.estimator.drive.lead_angle_deg = const { fixed::types::I16F16::lit("3.643") };
        c.estimator.mechanics.inertia_ukgm2 = 460;
        c.motion.cruise_speed = const { RadiansPerSecond::lit("1.5") };
        c.screw = ScrewKind::Ball;
        Ok(c)
    }

    /// The estimator's configuration as the model runs it. On a ball screw
    /// (`drive.screw = ball`) a law written in τ (the `ball` preset) is given to the estimator
    /// as the equivalent thread law in the screw rate ([`BallScrewConfig::thread_law_fixed`],
    /// fixed point) at the rated load's axial force at α = 45° (F_p + M·g, as
    /// [`ControlConfig::ball_screw_4008`]): the estimator feeds its law |θ̇|, which a τ law
    /// would read as τ = |θ̇|/4096. Every other configuration is the estimator's as given. The
    /// configuration itself (console, store) keeps the law as the user gave it.
    #[cfg(feature = "ball-screw")]
    pub fn model_estimator(&self) -> Result<EstimatorConfig, ConfigError> {
        let mut e = self.estimator;
        if self.screw == ScrewKind::Ball && e.law.variable == LawVariable::Lubrication {
            let f = self
                .ball_screw
                .preload
                .sat_add(Geometry::weight(self.rated_load));
            e.law = self.ball_screw.thread_law_fixed(&e.law, f)?;
        }
        Ok(e)
    }

    /// The estimator the controller runs for this configuration: [`Self::model_estimator`]'s
    /// on the ball-screw build, the configuration's own otherwise. One place for the choice
    /// ([`crate::control::Controller::new`] and [`crate::config::ValidatedConfig::new`] build
    /// it); inlined, so the caller's slot takes the estimator as `Estimator::new` returns it.
    #[inline(always)]
    pub fn build_estimator(&self) -> Result<crate::estimator::Estimator, ConfigError> {
        #[cfg(feature = "ball-screw")]
        return crate::estimator::Estimator::new(&self.model_estimator()?);
        #[cfg(not(feature = "ball-screw"))]
        return crate::estimator::Estimator::new(&self.estimator);
    }

    /// Check every range that does not need the compiled geometry, then the limit stops
    /// against it. The estimator's own settings are checked by [`crate::estimator::Estimator::new`].
    pub fn validate(&self, geometry: &Geometry) -> Result<(), ConfigError> {
        self.validate_limit_counts(geometry).map(|_| ())
    }

    /// [`ControlConfig::validate`], returning the limit stops in counts
    /// ([`LimitStops::counts`]): the controller maps them once, here.
    pub(crate) fn validate_limit_counts(
        &self,
        geometry: &Geometry,
    ) -> Result<(i32, i32, i32), ConfigError> {
        // Raw bits against constant rows (`check_bounds`), in the order the checks report:
        // a `u32` above `i32::MAX` wraps negative and is refused like any value below `lo`
        // (every `lo` here is ≥ 0).
        static LOAD_MOTION_CURRENT: [Bound; 5] = [
            Bound::new(
                Kilograms::lit("10").to_bits(),
                Kilograms::lit("5000").to_bits(),
                &keys::LOAD_RATED,
            ),
            Bound::new(
                RadiansPerSecond::lit("0.2").to_bits(),
                RadiansPerSecond::lit("20").to_bits(),
                &keys::MOTION_CRUISE_SPEED,
            ),
            Bound::new(10, 2000, &keys::MOTION_RAMP_MS),
            Bound::new(
                Amperes::lit("1").to_bits(),
                Amperes::lit("60").to_bits(),
                &keys::PROTECT_OVERCURRENT,
            ),
            Bound::new(
                Amperes::lit("1").to_bits(),
                Amperes::lit("60").to_bits(),
                &keys::PROTECT_CURRENT_LIMIT,
            ),
        ];
        static STALL_SUPPLY: [Bound; 6] = [
            Bound::new(
                Ratio::lit("0.05").to_bits(),
                Ratio::ONE.to_bits(),
                &keys::PROTECT_STALL_DUTY,
            ),
            Bound::new(20, 5000, &keys::PROTECT_STALL_MS),
            Bound::new(
                RadiansPerSecond::lit("10").to_bits(),
                RadiansPerSecond::lit("5000").to_bits(),
                &keys::PROTECT_MAX_MOTOR_SPEED,
            ),
            Bound::new(
                Volts::lit("8").to_bits(),
                Volts::lit("16").to_bits(),
                &keys::PROTECT_SUPPLY_START_MIN,
            ),
            Bound::new(
                Volts::lit("6").to_bits(),
                Volts::lit("16").to_bits(),
                &keys::PROTECT_SUPPLY_RUN_MIN,
            ),
            Bound::new(
                Volts::lit("12").to_bits(),
                Volts::lit("20").to_bits(),
                &keys::PROTECT_SUPPLY_MAX,
            ),
        ];
        static OVERLOAD_SENSE: [Bound; 7] = [
            Bound::new(1, 1000, &keys::PROTECT_SUPPLY_MS),
            Bound::new(
                Ratio::lit("0.05").to_bits(),
                Ratio::lit("2").to_bits(),
                &keys::PROTECT_OVERLOAD_MARGIN,
            ),
            Bound::new(10, 5000, &keys::PROTECT_OVERLOAD_MS),
            Bound::new(
                Metres::lit("0.00001").to_bits(),
                Metres::lit("0.01").to_bits(),
                &keys::PROTECT_RUNAWAY_TRAVEL,
            ),
            Bound::new(0, 4095, &keys::SENSE_CURRENT_ZERO),
            Bound::new(1, 1_000_000, &keys::SENSE_CURRENT_UA_PER_CODE),
            Bound::new(1, 100_000, &keys::SENSE_SUPPLY_UV_PER_CODE),
        ];
        let m = &self.motion;
        let p = &self.protection;
        let s = &self.sensing;
        check_bounds(
            [
                self.rated_load.to_bits(),
                m.cruise_speed.to_bits(),
                m.ramp_ms as i32,
                p.overcurrent.to_bits(),
                p.current_limit.to_bits(),
            ],
            &LOAD_MOTION_CURRENT,
        )?;
        if p.current_limit > p.overcurrent {
            return Err(keys::PROTECT_CURRENT_LIMIT.conflict("must not exceed protect.overcurrent"));
        }
        check_bounds(
            [
                p.stall_duty.to_bits(),
                p.stall_ms as i32,
                p.max_motor_speed.to_bits(),
                p.supply_start_min.to_bits(),
                p.supply_run_min.to_bits(),
                p.supply_max.to_bits(),
            ],
            &STALL_SUPPLY,
        )?;
        if p.supply_run_min > p.supply_start_min {
            return Err(
                keys::PROTECT_SUPPLY_RUN_MIN.conflict("must not exceed protect.supply_start_min")
            );
        }
        if p.supply_start_min >= p.supply_max {
            return Err(keys::PROTECT_SUPPLY_START_MIN.conflict("must be below protect.supply_max"));
        }
        check_bounds(
            [
                p.supply_ms as i32,
                p.overload_margin.to_bits(),
                p.overload_ms as i32,
                p.runaway_travel.to_bits(),
                i32::from(s.current_zero_code),
                s.current_ua_per_code as i32,
                s.supply_uv_per_code as i32,
            ],
            &OVERLOAD_SENSE,
        )?;
        self.stick_slip.validate()?;
        #[cfg(feature = "ball-screw")]
        {
            self.ball_screw.compile()?;
            self.lube.validate()?;
            check_tau_needs_ball(self)?;
        }
        check_variant(self)?;
        self.brake.validate()?;
        self.limits.counts(geometry)
    }
}

/// The refusal's reason, in a build without the `ball-screw` feature, of a value only the
/// ball-screw variant runs.
pub const NEEDS_BALL_SCREW: &str = "needs the ball-screw firmware (this is the lead-screw image)";

/// Whether this build can run `cfg`: without the `ball-screw` feature, `drive.screw = ball` and
/// the `tau` law variable (the `ball` friction preset's) are refused with [`NEEDS_BALL_SCREW`]
/// (part of [`ControlConfig::validate`]; the store checks it before anything else, see
/// [`crate::config::store::Source::NeedsBallScrew`]). Always `Ok` with the feature.
pub fn check_variant(cfg: &ControlConfig) -> Result<(), ConfigError> {
    if cfg!(feature = "ball-screw") {
        return Ok(());
    }
    let key = if cfg.screw == ScrewKind::Ball {
        &keys::DRIVE_SCREW
    } else if cfg.estimator.law.variable == LawVariable::Lubrication {
        &keys::FRICTION_VARIABLE
    } else {
        return Ok(());
    };
    Err(key.conflict(NEEDS_BALL_SCREW))
}

/// The refusal's reason, in the ball-screw build, of the τ law variable on a lead screw.
#[cfg(feature = "ball-screw")]
pub const TAU_NEEDS_BALL: &str = "tau (the ball-screw law) needs drive.screw = ball";

/// The ball-screw build's refusal of a law in τ (the `ball` preset, `friction.variable = tau`)
/// on a lead screw: only the ball screw's model is written in τ; the estimator feeds its law
/// |θ̇| (Q16 bits), which a τ law reads as τ = |θ̇|/4096. Without the feature
/// [`check_variant`] refuses τ on any screw, with its own reason
/// (the lead-screw image's record lock-out).
#[cfg(feature = "ball-screw")]
fn check_tau_needs_ball(cfg: &ControlConfig) -> Result<(), ConfigError> {
    if cfg.screw == ScrewKind::Lead && cfg.estimator.law.variable == LawVariable::Lubrication {
        return Err(keys::FRICTION_VARIABLE.conflict(TAU_NEEDS_BALL));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::geometry::{DriveConfig, GeometryConfig};

    fn geometry() -> Geometry {
        Geometry::new(GeometryConfig::DEFAULT, DriveConfig::DEFAULT).unwrap()
    }

    #[test]
    fn default_config_is_valid() {
        ControlConfig::DEFAULT.validate(&geometry()).unwrap();
    }

    #[test]
    fn lower_stop_above_upper_is_refused_naming_the_field() {
        let mut c = ControlConfig::DEFAULT;
        c.limits.lower = Metres::lit("0.400");
        c.limits.upper = Metres::lit("0.300");
        let e = c.validate(&geometry()).unwrap_err();
        assert_eq!(
            e,
            ConfigError::Conflict {
                field: "limits.lower",
                reason: "must be at least 10 mm below limits.upper"
            }
        );
    }

    #[test]
    fn stop_outside_the_mechanism_is_refused() {
        let mut c = ControlConfig::DEFAULT;
        c.limits.upper = Metres::lit("0.5"); // above h₀ + L·sin 75° = 416 mm
        assert!(matches!(
            c.validate(&geometry()),
            Err(ConfigError::OutOfRange {
                field: "limits.upper",
                ..
            })
        ));
    }

    /// Each range row names its setting with the text the inline checks reported before the
    /// table (the registry's range text): one value at a time just outside its range.
    #[test]
    fn every_range_row_reports_its_key_and_range_text() {
        type Edit = fn(&mut ControlConfig);
        let cases: [(Edit, &str, &str); 18] = [
            (
                |c| c.rated_load = Kilograms::lit("5001"),
                "load.rated",
                "10..5000 kg",
            ),
            (
                |c| c.motion.cruise_speed = RadiansPerSecond::lit("0.1"),
                "motion.cruise_speed",
                "0.2..20 rad/s",
            ),
            (|c| c.motion.ramp_ms = 2001, "motion.ramp_ms", "10..2000 ms"),
            (
                |c| c.protection.overcurrent = Amperes::lit("61"),
                "protect.overcurrent",
                "1..60 A",
            ),
            (
                |c| c.protection.current_limit = Amperes::lit("0.5"),
                "protect.current_limit",
                "1..60 A",
            ),
            (
                |c| c.protection.stall_duty = Ratio::lit("0.04"),
                "protect.stall_duty",
                "0.05..1",
            ),
            (
                |c| c.protection.stall_ms = 19,
                "protect.stall_ms",
                "20..5000 ms",
            ),
            (
                |c| c.protection.max_motor_speed = RadiansPerSecond::lit("5001"),
                "protect.max_motor_speed",
                "10..5000 rad/s",
            ),
            (
                |c| c.protection.supply_start_min = Volts::lit("17"),
                "protect.supply_start_min",
                "8..16 V",
            ),
            (
                |c| c.protection.supply_run_min = Volts::lit("5"),
                "protect.supply_run_min",
                "6..16 V",
            ),
            (
                |c| c.protection.supply_max = Volts::lit("21"),
                "protect.supply_max",
                "12..20 V",
            ),
            (
                |c| c.protection.supply_ms = 0,
                "protect.supply_ms",
                "1..1000 ms",
            ),
            (
                |c| c.protection.overload_margin = Ratio::lit("2.01"),
                "protect.overload_margin",
                "0.05..2",
            ),
            (
                |c| c.protection.overload_ms = u32::MAX,
                "protect.overload_ms",
                "10..5000 ms",
            ),
            (
                |c| c.protection.runaway_travel = Metres::lit("0.011"),
                "protect.runaway_travel",
                "0.01..10 mm",
            ),
            (
                |c| c.sensing.current_zero_code = 4096,
                "sense.current_zero",
                "0..4095 codes",
            ),
            (
                |c| c.sensing.current_ua_per_code = 0,
                "sense.current_ua_per_code",
                "1..1000000 uA",
            ),
            (
                |c| c.sensing.supply_uv_per_code = 100_001,
                "sense.supply_uv_per_code",
                "1..100000 uV",
            ),
        ];
        for (edit, field, range) in cases {
            let mut c = ControlConfig::DEFAULT;
            edit(&mut c);
            assert_eq!(
                c.validate(&geometry()),
                Err(ConfigError::OutOfRange { field, range }),
                "{field}"
            );
        }
    }

    /// A law in τ on a lead screw (the `ball` preset, or `friction.variable = tau` under
    /// another law): the estimator would read its |θ̇| bits as τ. The ball-screw build refuses
    /// it as needing a ball screw, the lead-screw build as needing the ball-screw firmware
    /// (`check_variant`, unchanged), on every path that builds a controller.
    #[test]
    fn tau_law_on_a_lead_screw_is_refused() {
        use crate::model::friction::{FrictionLaw, LawVariable};
        let mut preset = ControlConfig::DEFAULT;
        preset.estimator.law = FrictionLaw::BALL_SCREW;
        let mut variable = ControlConfig::DEFAULT;
        variable.estimator.law.variable = LawVariable::Lubrication;
        #[cfg(feature = "ball-screw")]
        let reason = TAU_NEEDS_BALL;
        #[cfg(not(feature = "ball-screw"))]
        let reason = NEEDS_BALL_SCREW;
        let want = ConfigError::Conflict {
            field: "friction.variable",
            reason,
        };
        for c in [preset, variable] {
            assert_eq!(c.screw, ScrewKind::Lead);
            assert_eq!(c.validate(&geometry()), Err(want));
            assert_eq!(crate::config::ValidatedConfig::new(c).err(), Some(want));
            assert_eq!(crate::control::Controller::new(&c, 0).err(), Some(want));
            // The same law in |θ̇| is taken: only the variable is refused.
            let mut rate = c;
            rate.estimator.law.variable = LawVariable::ScrewRate;
            rate.validate(&geometry()).unwrap();
        }
    }

    /// With `drive.screw = ball` the ball-screw build takes a law in τ (the `ball` preset) and
    /// gives it to the estimator as the equivalent thread law in the screw rate at the rated
    /// load's axial force: the estimator's μ equals the float64 equivalent law's
    /// (`BallScrewConfig::equivalent_thread_law`) within the conversion's 10⁻⁶ relative plus
    /// the law's own evaluation error (e^(−y)'s argument in Q16: |amp|·2^-15; μ in Q28). Before,
    /// the estimator read |θ̇| as τ = |θ̇|/4096: μ at the 4008's cruise was 5.1× low (0.00304
    /// for 0.01552).
    #[cfg(feature = "ball-screw")]
    #[test]
    fn tau_law_on_a_ball_screw_runs_as_the_equivalent_thread_law() {
        use crate::model::friction::{FrictionLaw, LawVariable};
        let mut c = ControlConfig::ball_screw_4008().unwrap();
        c.estimator.law = FrictionLaw::BALL_SCREW;
        crate::config::ValidatedConfig::new(c).unwrap();
        let ctrl = crate::control::Controller::new(&c, 0).unwrap();
        // The configuration keeps the law as given; the estimator runs it in the screw rate.
        assert_eq!(ctrl.config().estimator.law, FrictionLaw::BALL_SCREW);
        let est = ctrl.estimator().law();
        // The float64 equivalent law at the same force, evaluated in float64.
        let bs = BallScrewConfig {
            law: FrictionLaw::BALL_SCREW,
            ..c.ball_screw
        };
        let f = c.ball_screw.preload.sat_add(Geometry::weight(c.rated_load));
        let twin = bs.equivalent_thread_law(f).unwrap();
        assert_eq!(twin.s_max, fixed::types::I32F32::MAX);
        let want = |w: f64| {
            twin.base.to_f64()
                + twin.amp.to_f64() * (-twin.rate.to_num::<f64>() * w).exp()
                + twin.slope.to_num::<f64>() * w
        };
        let bound =
            |w: f64| 1e-6 * want(w) + twin.amp.to_f64() * 2f64.powi(-15) + 3.0 * 2f64.powi(-28);
        for w in [
            c.motion.cruise_speed.to_f64(),
            0.01,
            0.1,
            0.5,
            1.0,
            3.0,
            20.0,
            200.0,
        ] {
            let got = est.mu(RadiansPerSecond::from_f64(w)).to_f64();
            let want = want(RadiansPerSecond::from_f64(w).to_f64());
            assert!(
                (got - want).abs() <= bound(w),
                "{w} rad/s: estimator μ {got:e}, equivalent law {want:e}"
            );
        }
        assert_eq!(est.law().variable, LawVariable::ScrewRate);
        // The controller's law is the one `ball_screw_4008` gives its estimator (the same
        // reference force up to g's rounding).
        let factory = ControlConfig::ball_screw_4008().unwrap().estimator.law;
        let (a, b) = (
            est.law().slope.to_num::<f64>(),
            factory.slope.to_num::<f64>(),
        );
        assert!((a / b - 1.0).abs() < 1e-4, "{a:e} vs {b:e}");
    }

    /// `reconfigure` rebuilds the estimator's law when only the ball screw's reference force
    /// changes (the rated load): the estimator's own settings are the same, its law is not.
    #[cfg(feature = "ball-screw")]
    #[test]
    fn reconfigure_follows_the_equivalent_thread_law() {
        use crate::control::Controller;
        use crate::model::friction::FrictionLaw;
        let mut c = ControlConfig::ball_screw_4008().unwrap();
        c.estimator.law = FrictionLaw::BALL_SCREW;
        let mut ctrl = Controller::new(&c, 0).unwrap();
        let before = *ctrl.estimator().law().law();
        let mut lighter = c;
        lighter.rated_load = Kilograms::lit("500");
        ctrl.reconfigure(&lighter).unwrap();
        let want = *Controller::new(&lighter, 0)
            .unwrap()
            .estimator()
            .law()
            .law();
        assert_ne!(want, before);
        assert_eq!(*ctrl.estimator().law().law(), want);
    }

    #[test]
    fn run_threshold_above_start_threshold_is_refused() {
        let mut c = ControlConfig::DEFAULT;
        c.protection.supply_run_min = Volts::lit("12");
        assert!(matches!(
            c.validate(&geometry()),
            Err(ConfigError::Conflict {
                field: "protect.supply_run_min",
                ..
            })
        ));
    }
}
