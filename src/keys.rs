//! The configuration's keys and the ranges they accept: one table, read by every validator
//! (`check_range`, `Bound`), by the settings registry (`config::settings`) and by the
//! messages, so that a key or a range is written once. Also the error that names them.
//!
//! A range here is the text a person reads (`help <key>`, a refusal); the check that enforces
//! it sits with the type it checks (`ControlConfig::validate`, `Estimator::new`, …) and takes
//! its [`Key`] from here.

use crate::text::{fill, Arg};

/// A setting's console key and the range it accepts, as messages show them.
#[derive(Debug, PartialEq, Eq)]
pub struct Key {
    /// The console key (lower case).
    pub name: &'static str,
    /// The accepted range with its unit (the text of the check that enforces it).
    pub range: &'static str,
}

impl Key {
    /// The refusal of a value outside [`Key::range`].
    pub const fn out_of_range(&self) -> ConfigError {
        ConfigError::OutOfRange {
            field: self.name,
            range: self.range,
        }
    }

    /// The refusal of a value that contradicts another setting.
    pub const fn conflict(&self, reason: &'static str) -> ConfigError {
        ConfigError::Conflict {
            field: self.name,
            reason,
        }
    }
}

/// A [`Key`] constant per setting (`NAME = "key", "range";`).
macro_rules! keys {
    ($($name:ident = $key:literal, $range:literal;)*) => {
        $(
            #[doc = concat!("`", $key, "`: ", $range, ".")]
            pub const $name: Key = Key { name: $key, range: $range };
        )*
    };
}

keys! {
    LIMITS_LOWER = "limits.lower", "the mechanism's height range (see `limits`)";
    LIMITS_UPPER = "limits.upper", "the mechanism's height range (see `limits`)";
    LIMITS_SWITCH_LOWER = "limits.switch_lower", "the mechanism's height range, at least 0.5 mm below limits.lower";

    LOAD_RATED = "load.rated", "10..5000 kg";

    MOTION_CRUISE_SPEED = "motion.cruise_speed", "0.2..20 rad/s";
    MOTION_RAMP_MS = "motion.ramp_ms", "10..2000 ms";
    MOTION_RAMP_SHAPE = "motion.ramp_shape", "trapezoid or scurve";
    MOTION_BUTTONS = "motion.buttons", "hold or latched";

    PROTECT_OVERCURRENT = "protect.overcurrent", "1..60 A";
    PROTECT_CURRENT_LIMIT = "protect.current_limit", "1..60 A";
    PROTECT_STALL_DUTY = "protect.stall_duty", "0.05..1";
    PROTECT_STALL_MS = "protect.stall_ms", "20..5000 ms";
    PROTECT_MAX_MOTOR_SPEED = "protect.max_motor_speed", "10..5000 rad/s";
    PROTECT_SUPPLY_START_MIN = "protect.supply_start_min", "8..16 V";
    PROTECT_SUPPLY_RUN_MIN = "protect.supply_run_min", "6..16 V";
    PROTECT_SUPPLY_MAX = "protect.supply_max", "12..20 V";
    PROTECT_SUPPLY_MS = "protect.supply_ms", "1..1000 ms";
    PROTECT_OVERLOAD_MARGIN = "protect.overload_margin", "0.05..2";
    PROTECT_OVERLOAD_MS = "protect.overload_ms", "10..5000 ms";
    PROTECT_RUNAWAY_TRAVEL = "protect.runaway_travel", "0.01..10 mm";

    SENSE_CURRENT_ZERO = "sense.current_zero", "0..4095 codes";
    SENSE_CURRENT_UA_PER_CODE = "sense.current_ua_per_code", "1..1000000 uA";
    SENSE_SUPPLY_UV_PER_CODE = "sense.supply_uv_per_code", "1..100000 uV";

    GEOMETRY_LENGTH = "geometry.length", "0.05..2 m";
    GEOMETRY_ALPHA0 = "geometry.alpha0", "12..60 deg";
    GEOMETRY_ALPHA_MAX = "geometry.alpha_max", "alpha0+5..89 deg";
    GEOMETRY_H0 = "geometry.h0", "0..1 m";
    GEOMETRY_MU_PIN = "geometry.mu_pin", "0..1";

    DRIVE_COUNTS_PER_REV = "drive.counts_per_rev", "4..65536";
    DRIVE_GEAR_RATIO = "drive.gear_ratio", "1..1000";
    DRIVE_PITCH_RADIUS = "drive.pitch_radius", "1..50 mm";
    DRIVE_LEAD_ANGLE = "drive.lead_angle", "0.5..20 deg";
    DRIVE_SCREW = "drive.screw", "lead or ball";
    DRIVE_BRAKE = "drive.brake", "none or spring";
    DRIVE_BRAKE_MS = "drive.brake_ms", "5..1000 ms";

    MECH_INERTIA = "mech.inertia", "0..100000 ukgm2";
    MECH_DAMPING = "mech.damping", "0..1e6 uNms/rad";
    MECH_SUPPORT_TORQUE = "mech.support_torque", "0..10 Nm";
    MECH_NUT_MASS = "mech.nut_mass", "0..5 kg";
    MECH_COUPLING_STIFFNESS = "mech.coupling_stiffness", "1..10000 Nm/rad";

    FRICTION_LAW = "friction.law", "dry, ptfe, lithium or ball";
    FRICTION_VARIABLE = "friction.variable", "rate, speed or tau";
    FRICTION_BASE = "friction.base", "0..1";
    FRICTION_AMP = "friction.amp", "-1..1";
    FRICTION_RATE = "friction.rate", "0..1e6";
    FRICTION_SLOPE = "friction.slope", "-1000..1000";
    FRICTION_S_MAX = "friction.s_max", ">0..1e6";

    MOTOR_KT = "motor.kt", "0.001..1 Nm/A";
    MOTOR_GEAR_EFFICIENCY = "motor.gear_efficiency", "0.1..1";
    MOTOR_RESISTANCE = "motor.resistance", "0.001..4 ohm";
    MOTOR_INERTIA = "motor.inertia", "0..100000 ukgm2";

    CONTROL_TICK_US = "control.tick_us", "100..10000 us";
    CONTROL_SPEED_BANDWIDTH = "control.speed_bandwidth", "1..tick rate/10 Hz";
    CONTROL_REST_SPEED = "control.rest_speed", "0..50 rad/s";

    STICKSLIP_REACTION = "stickslip.reaction", "log, warn or speed";
    STICKSLIP_DROP = "stickslip.drop", "0.2..50 Nm";
    STICKSLIP_WINDOW_MS = "stickslip.window_ms", "100..10000 ms";
    STICKSLIP_ESCAPE_SPEED = "stickslip.escape_speed", "0.2..20 rad/s";

    BALLSCREW_R_M = "ballscrew.r_m", "2..100 mm";
    BALLSCREW_R_B = "ballscrew.r_b", "0.5..20 mm";
    BALLSCREW_CONTACT_ANGLE = "ballscrew.contact_angle", "20..80 deg";
    BALLSCREW_LEAD = "ballscrew.lead", "0.5..50 mm";
    BALLSCREW_BALLS = "ballscrew.balls", "1..1000";
    BALLSCREW_PRELOAD = "ballscrew.preload", "0..100 kN";
    BALLSCREW_VISCOSITY = "ballscrew.viscosity", "1e-4..10 Pa.s";
    BALLSCREW_F_BASE = "ballscrew.f_base", "0..1";
    BALLSCREW_F_AMP = "ballscrew.f_amp", "-1..1";
    BALLSCREW_F_RATE = "ballscrew.f_rate", "0..1e6";
    BALLSCREW_F_SLOPE = "ballscrew.f_slope", "-1000..1000";
    BALLSCREW_F_S_MAX = "ballscrew.f_s_max", ">0..1e6";
    BALLSCREW_LUBE_BAND = "ballscrew.lube_band", "0.05..4";
    BALLSCREW_IDENT_MIN_SPEED = "ballscrew.ident_min_speed", "0.05..20 rad/s";
    BALLSCREW_NO_LOAD_CURRENT = "ballscrew.no_load_current", "0..20 A";
}

/// A configuration value was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConfigError {
    /// `field` lies outside `range`.
    OutOfRange {
        /// The setting's key, as the console names it.
        field: &'static str,
        /// Its accepted range with unit.
        range: &'static str,
    },
    /// `field` contradicts another setting.
    Conflict {
        /// The setting's key, as the console names it.
        field: &'static str,
        /// What it must satisfy.
        reason: &'static str,
    },
}

impl ConfigError {
    /// The message (its `Display`), written without `core::fmt`'s machinery (`text::fill`).
    pub fn write_to(&self, out: &mut dyn core::fmt::Write) -> core::fmt::Result {
        match self {
            ConfigError::OutOfRange { field, range } => fill(
                out,
                "\x01 out of range (allowed \x01)",
                &[Arg::Str(field), Arg::Str(range)],
            ),
            ConfigError::Conflict { field, reason } => {
                fill(out, "\x01: \x01", &[Arg::Str(field), Arg::Str(reason)])
            }
        }
    }
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        self.write_to(f)
    }
}

/// One row of a range table ([`check_bounds`]): `lo ≤ v ≤ hi` on a quantity's raw bits
/// (`to_bits`, or the integer itself), else the key's [`Key::out_of_range`].
pub(crate) struct Bound {
    pub lo: i32,
    pub hi: i32,
    pub key: &'static Key,
}

impl Bound {
    /// The row `lo ≤ v ≤ hi` of `key`.
    pub const fn new(lo: i32, hi: i32, key: &'static Key) -> Bound {
        Bound { lo, hi, key }
    }
}

/// [`check_range`] over a table, in order: the first value outside its row's bounds is the
/// error. One out-of-line loop over constant rows instead of one inlined check (with its own
/// error path and string loads) per setting.
pub(crate) fn check_bounds<const N: usize>(
    values: [i32; N],
    bounds: &'static [Bound; N],
) -> Result<(), ConfigError> {
    check_bounds_slice(&values, bounds)
}

/// [`check_bounds`]' one copy for every table length.
#[inline(never)]
fn check_bounds_slice(values: &[i32], bounds: &'static [Bound]) -> Result<(), ConfigError> {
    for (&v, b) in values.iter().zip(bounds) {
        if v < b.lo || v > b.hi {
            return Err(b.key.out_of_range());
        }
    }
    Ok(())
}

/// `Ok` if `lo ≤ v ≤ hi`, else `key`'s [`Key::out_of_range`]: a single range check (a run of
/// them on one configuration type is smaller as a [`check_bounds`] table).
pub(crate) fn check_range<T: PartialOrd>(v: T, lo: T, hi: T, key: &Key) -> Result<(), ConfigError> {
    if v >= lo && v <= hi {
        Ok(())
    } else {
        Err(key.out_of_range())
    }
}
