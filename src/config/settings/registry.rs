//! The registry: every setting's key and range ([`crate::keys`]), kind, help line and field,
//! in the order the flash record stores them.

use super::slot::{field_slot, field_stored, Slot};
use super::*;
use crate::keys;

const fn num(frac: u8, unit: UnitId) -> Kind {
    Kind::Number {
        frac,
        pow10: 0,
        unit,
        none_at_max: false,
    }
}

/// Metres (I8F24) shown in mm.
const LEN: Kind = Kind::Number {
    frac: 24,
    pow10: 3,
    unit: MILLIMETRES,
    none_at_max: false,
};

/// [`SETTINGS`] and the function that reaches a setting's field by its index (`index => key,
/// kind, help line, [accessor]`; the key names the [`crate::keys`] constant that holds the
/// console key and the range text). One `match` for both directions instead of a `get`
/// and a `set` function per setting (or a `match` per direction): the table stays small
/// and each setting's field access is one address and tag.
///
/// The `ball_screw:` group is the ball-screw variant's (cargo feature `ball-screw`). Its entries
/// come last, so the flash record holds their values last in either build: without the
/// feature they are no settings (no keys, no console access), but [`slot`] still reaches their
/// fields at the same positions and the record carries their raw words through
/// ([`BALL_KEYS`], [`opaque_get`]).
macro_rules! registry {
    ($($n:literal => $key:ident, $kind:expr, $about:literal, [$($acc:tt)+];)*
     ball_screw: $($bn:literal => $bkey:ident, $bkind:expr, $babout:literal, [$($bacc:tt)+];)*) => {
        /// Every setting. The flash record's layout follows this order (the `stored` ones):
        /// changing it changes the record's schema fingerprint (see [`crate::config::record`]).
        pub static SETTINGS: [Setting; SETTINGS_LEN] = [$(
            Setting {
                key: keys::$key.name,
                kind: $kind,
                range: keys::$key.range,
                #[cfg(feature = "help-text")]
                about: $about,
            },
        )* $(
            #[cfg(feature = "ball-screw")]
            Setting {
                key: keys::$bkey.name,
                kind: $bkind,
                range: keys::$bkey.range,
                #[cfg(feature = "help-text")]
                about: $babout,
            },
        )*];

        /// Number of [`SETTINGS`].
        const SETTINGS_LEN: usize = BALL_FIRST + if cfg!(feature = "ball-screw") {
            BALL_KEYS.len()
        } else {
            0
        };

        /// Position of the first ball-screw setting: in the ball-screw build its place in
        /// [`SETTINGS`], in the other the first opaque word's [`slot`].
        const BALL_FIRST: usize = [$($n),*].len();

        /// The ball-screw variant's settings' keys, in registry order (all stored). Without the
        /// feature only the record's schema word uses them (at compile time: no flash).
        pub const BALL_KEYS: [&str; [$($bn),*].len()] = [$(keys::$bkey.name),*];

        /// Bit `i`: setting `i` is stored in the flash record.
        /// (One statement per setting, so that an entry can carry attributes such as `cfg`.)
        const STORED: u128 = {
            let mut mask = 0;
            $(mask |= (field_stored!($($acc)+) as u128) << $n;)*
            $(
                #[cfg(feature = "ball-screw")]
                {
                    mask |= (field_stored!($($bacc)+) as u128) << $bn;
                }
            )*
            mask
        };

        // The indices written in the registry are the positions (`slot` finds a setting's
        // field by its position), the ball screw's following the others'; all of the ball
        // screw's are stored (the record's opaque words).
        const _: () = {
            let mut i = 0;
            $(
                assert!($n == i, "registry indices must count 0, 1, 2, …");
                i += 1;
            )*
            $(
                assert!($bn == i, "registry indices must count 0, 1, 2, …");
                assert!(field_stored!($($bacc)+), "the ball screw's settings are all stored");
                i += 1;
            )*
            assert!(SETTINGS.len() <= i && i <= 128);
        };

        /// The field of the setting at `index` (out of range: the first's). Without the
        /// `ball-screw` feature the ball screw's fields are still reached here, past
        /// [`SETTINGS`]' end ([`opaque_get`], [`opaque_set`]).
        #[inline(never)]
        pub(super) fn slot(index: usize, c: &mut ControlConfig) -> Slot<'_> {
            match index {
                $($n => field_slot!(c, $($acc)+),)*
                $($bn => field_slot!(c, $($bacc)+),)*
                // Not reached: `index` is a registry position.
                _ => field_slot!(c, q32 limits.lower),
            }
        }
    };
}

/// Whether the setting at `index` of [`SETTINGS`] is stored in the flash record
/// ([`Setting::stored`]; `const` for the record's compile-time layout tables).
pub const fn stored_at(index: usize) -> bool {
    index < SETTINGS.len() && STORED >> index & 1 == 1
}

/// Number of the ball-screw variant's values the record holds after [`SETTINGS`]' own: the
/// opaque words a build without the `ball-screw` feature carries through (0 with it).
pub const OPAQUE_COUNT: usize = if cfg!(feature = "ball-screw") {
    0
} else {
    BALL_KEYS.len()
};

/// The raw bits of the `i`-th ball-screw value (`i < BALL_KEYS.len()`; 0 otherwise): the
/// record's word for it. The same bits as the setting's in the ball-screw build.
#[cfg_attr(feature = "ball-screw", allow(dead_code))]
pub(crate) fn opaque_get(i: usize, cfg: &ControlConfig) -> i64 {
    if i < BALL_KEYS.len() {
        let mut c = *cfg;
        slot(BALL_FIRST + i, &mut c).read()
    } else {
        0
    }
}

/// Store a record's raw word into the `i`-th ball-screw value, unvalidated (this build never
/// uses it; the ball-screw build validates it). False (`cfg` unchanged) if it does not fit the
/// field's type.
#[cfg_attr(feature = "ball-screw", allow(dead_code))]
pub(crate) fn opaque_set(i: usize, cfg: &mut ControlConfig, raw: i64) -> bool {
    i < BALL_KEYS.len() && slot(BALL_FIRST + i, cfg).write(raw)
}

/// The friction-law presets `friction.law` selects, in its choice order.
pub const LAW_PRESETS: [FrictionLaw; 4] = [
    FrictionLaw::DRY,
    FrictionLaw::PTFE,
    FrictionLaw::LITHIUM,
    FrictionLaw::BALL_SCREW,
];

registry! {
    0 => LIMITS_LOWER, LEN,
        "lowest head height the lift drives to",
        [q32 limits.lower];
    1 => LIMITS_UPPER, LEN,
        "highest head height the lift drives to",
        [q32 limits.upper];
    2 => LIMITS_SWITCH_LOWER, LEN,
        "head height where the lower limit switch closes (the homing reference)",
        [q32 limits.switch_lower];
    3 => LOAD_RATED, num(12, KILOGRAMS),
        "rated load of the lift",
        [q32 rated_load];
    4 => MOTION_CRUISE_SPEED, num(16, RAD_PER_S),
        "cruise screw speed",
        [q32 motion.cruise_speed];
    5 => MOTION_RAMP_MS, num(0, MILLIS),
        "time from rest to cruise speed (and back)",
        [int u32, motion.ramp_ms];
    6 => MOTION_RAMP_SHAPE, Kind::Choice(ChoiceId(0)),
        "speed ramp: constant acceleration or jerk-limited",
        [choice motion.ramp_shape];
    7 => MOTION_BUTTONS, Kind::Choice(ChoiceId(1)),
        "UP/DOWN buttons: hold-to-run or latched until STOP",
        [choice motion.buttons];
    8 => PROTECT_OVERCURRENT, num(16, AMPS),
        "motor current that trips the over-current fault",
        [q32 protection.overcurrent];
    9 => PROTECT_CURRENT_LIMIT, num(16, AMPS),
        "current the speed loop never asks for (at most protect.overcurrent)",
        [q32 protection.current_limit];
    10 => PROTECT_STALL_DUTY, num(28, RATIO),
        "duty at or above which no encoder motion counts as a stall",
        [q32 protection.stall_duty];
    11 => PROTECT_STALL_MS, num(0, MILLIS),
        "time stalled before the fault",
        [int u32, protection.stall_ms];
    12 => PROTECT_MAX_MOTOR_SPEED, num(16, RAD_PER_S),
        "fastest plausible motor-shaft speed",
        [q32 protection.max_motor_speed];
    13 => PROTECT_SUPPLY_START_MIN, num(16, VOLTS),
        "refuse to start below this supply voltage",
        [q32 protection.supply_start_min];
    14 => PROTECT_SUPPLY_RUN_MIN, num(16, VOLTS),
        "stop while moving below this supply voltage",
        [q32 protection.supply_run_min];
    15 => PROTECT_SUPPLY_MAX, num(16, VOLTS),
        "stop above this supply voltage",
        [q32 protection.supply_max];
    16 => PROTECT_SUPPLY_MS, num(0, MILLIS),
        "supply out of range this long trips the fault",
        [int u32, protection.supply_ms];
    17 => PROTECT_OVERLOAD_MARGIN, num(28, RATIO),
        "overload: measured torque above the rated-load model by this fraction",
        [q32 protection.overload_margin];
    18 => PROTECT_OVERLOAD_MS, num(0, MILLIS),
        "overload held this long trips the fault",
        [int u32, protection.overload_ms];
    19 => PROTECT_RUNAWAY_TRAVEL, LEN,
        "uncommanded nut travel before the runaway fault",
        [q32 protection.runaway_travel];
    20 => SENSE_CURRENT_ZERO, num(0, COUNTS),
        "current-sense ADC code at 0 A (refined at rest, within 16 codes)",
        [int u16, sensing.current_zero_code];
    21 => SENSE_CURRENT_UA_PER_CODE, num(0, MICROAMPS),
        "motor current per ADC code",
        [int u32, sensing.current_ua_per_code];
    22 => SENSE_SUPPLY_UV_PER_CODE, num(0, MICROVOLTS),
        "supply voltage per ADC code",
        [int u32, sensing.supply_uv_per_code];
    23 => GEOMETRY_LENGTH, LEN,
        "Eq 1's length L (twice the arm length)",
        [q32 estimator.geometry.length];
    24 => GEOMETRY_ALPHA0, num(16, DEGREES),
        "arm angle fully down",
        [q32 estimator.geometry.alpha0_deg];
    25 => GEOMETRY_ALPHA_MAX, num(16, DEGREES),
        "largest arm angle of the mechanism",
        [q32 estimator.geometry.alpha_max_deg];
    26 => GEOMETRY_H0, LEN,
        "head height with the arms collapsed",
        [q32 estimator.geometry.h0];
    27 => GEOMETRY_MU_PIN, num(28, RATIO),
        "pin friction coefficient (Eq 6)",
        [q32 estimator.geometry.mu_pin];
    28 => DRIVE_COUNTS_PER_REV, num(0, COUNTS),
        "encoder counts per motor turn",
        [int u32, estimator.drive.counts_per_rev];
    29 => DRIVE_GEAR_RATIO, num(16, NUMBER),
        "motor turns per screw turn",
        [q32 estimator.drive.gear_ratio];
    30 => DRIVE_PITCH_RADIUS, LEN,
        "screw pitch radius r_m",
        [q32 estimator.drive.pitch_radius];
    31 => DRIVE_LEAD_ANGLE, num(16, DEGREES),
        "screw lead angle",
        [q32 estimator.drive.lead_angle_deg];
    32 => DRIVE_SCREW, Kind::Choice(ChoiceId(2)),
        "screw type: lead (self-locking) or ball (held actively at rest)",
        [choice screw];
    33 => DRIVE_BRAKE, Kind::Choice(ChoiceId(3)),
        "holding brake: none, or spring-applied (engaged unless the brake output is on)",
        [choice brake.present];
    34 => DRIVE_BRAKE_MS, num(0, MILLIS),
        "time the brake takes to release or engage",
        [int u32, brake.delay_ms];
    35 => MECH_INERTIA, num(0, MICRO_KGM2),
        "screw inertia I",
        [int i32, estimator.mechanics.inertia_ukgm2];
    36 => MECH_DAMPING, num(0, MICRO_NMS),
        "screw support damping c",
        [int i32, estimator.mechanics.damping_unms];
    37 => MECH_SUPPORT_TORQUE, num(16, NEWTON_METRES),
        "support friction torque T0",
        [q32 estimator.mechanics.support_torque];
    38 => MECH_NUT_MASS, num(12, KILOGRAMS),
        "translating (nut) mass m",
        [q32 estimator.mechanics.nut_mass];
    39 => MECH_COUPLING_STIFFNESS, num(16, NM_PER_RAD),
        "torsional stiffness k of the coupling",
        [q32 estimator.mechanics.coupling_stiffness];
    40 => FRICTION_LAW, Kind::Choice(ChoiceId(4)),
        "load a preset friction law (shows `custom` after edits)",
        [preset estimator.law];
    41 => FRICTION_VARIABLE, Kind::Choice(ChoiceId(5)),
        "law variable: screw rate |w| rad/s, sliding speed m/s, or tau",
        [choice estimator.law.variable];
    42 => FRICTION_BASE, num(28, RATIO),
        "law: constant term",
        [q32 estimator.law.base];
    43 => FRICTION_AMP, num(28, RATIO),
        "law: exponential (Stribeck) amplitude",
        [q32 estimator.law.amp];
    44 => FRICTION_RATE, num(32, NUMBER),
        "law: exponential rate per unit of the variable",
        [q64 estimator.law.rate];
    45 => FRICTION_SLOPE, num(32, NUMBER),
        "law: viscous slope per unit of the variable",
        [q64 estimator.law.slope];
    46 => FRICTION_S_MAX, Kind::Number { frac: 32, pow10: 0, unit: NUMBER, none_at_max: true },
        "law: viscous term flat beyond this (none: never)",
        [q64 estimator.law.s_max];
    47 => MOTOR_KT, num(28, NM_PER_AMP),
        "motor torque constant",
        [q32 estimator.motor.torque_constant];
    48 => MOTOR_GEAR_EFFICIENCY, num(28, RATIO),
        "gearbox efficiency",
        [q32 estimator.motor.gear_efficiency];
    49 => MOTOR_RESISTANCE, num(28, OHMS),
        "motor loop resistance (armature, bridge, battery)",
        [q32 estimator.motor.resistance];
    50 => MOTOR_INERTIA, num(0, MICRO_KGM2),
        "inertia of the motor's rotor and gearbox input, at the motor shaft",
        [int i32, estimator.motor.inertia_ukgm2];
    51 => CONTROL_TICK_US, num(0, MICROS),
        "control tick period",
        [int u32, estimator.tick_us];
    52 => CONTROL_SPEED_BANDWIDTH, num(0, HERTZ),
        "speed filter bandwidth",
        [int u32, estimator.speed_bandwidth_hz];
    53 => CONTROL_REST_SPEED, num(16, RAD_PER_S),
        "screw speed below which the screw counts as at rest",
        [q32 estimator.rest_speed];
    54 => STICKSLIP_REACTION, Kind::Choice(ChoiceId(6)),
        "on stick-slip: log it, also warn on the console, or also change to the escape speed",
        [choice stick_slip.reaction];
    55 => STICKSLIP_DROP, num(16, NEWTON_METRES),
        "smallest fall of the measured screw torque that counts as a slip",
        [q32 stick_slip.drop_threshold];
    56 => STICKSLIP_WINDOW_MS, num(0, MILLIS),
        "slips further apart start a new chain",
        [int u32, stick_slip.window_ms];
    57 => STICKSLIP_ESCAPE_SPEED, num(16, RAD_PER_S),
        "cruise speed for the rest of a motion after stick-slip (reaction speed)",
        [q32 stick_slip.escape_speed];
    ball_screw:
    58 => BALLSCREW_R_M, LEN,
        "ball screw: ball-centre circle radius r_m",
        [q32 ball_screw.r_m];
    59 => BALLSCREW_R_B, LEN,
        "ball screw: ball radius r_b (less than r_m)",
        [q32 ball_screw.r_b];
    60 => BALLSCREW_CONTACT_ANGLE, num(16, DEGREES),
        "ball screw: contact angle alpha",
        [q32 ball_screw.contact_angle_deg];
    61 => BALLSCREW_LEAD, LEN,
        "ball screw: lead (nut travel per screw turn)",
        [q32 ball_screw.lead];
    62 => BALLSCREW_BALLS, num(0, COUNTS),
        "ball screw: number of loaded balls M",
        [int u16, ball_screw.loaded_balls];
    63 => BALLSCREW_PRELOAD, num(8, NEWTONS),
        "ball screw: preload F_p",
        [q32 ball_screw.preload];
    64 => BALLSCREW_VISCOSITY, num(32, PASCAL_SECONDS),
        "ball screw: lubricant dynamic viscosity eta0",
        [q64 ball_screw.viscosity];
    65 => BALLSCREW_F_BASE, num(28, RATIO),
        "ball screw f(tau): constant term",
        [q32 ball_screw.law.base];
    66 => BALLSCREW_F_AMP, num(28, RATIO),
        "ball screw f(tau): exponential amplitude",
        [q32 ball_screw.law.amp];
    67 => BALLSCREW_F_RATE, num(32, NUMBER),
        "ball screw f(tau): exponential rate per unit of tau",
        [q64 ball_screw.law.rate];
    68 => BALLSCREW_F_SLOPE, num(32, NUMBER),
        "ball screw f(tau): slope per unit of tau",
        [q64 ball_screw.law.slope];
    69 => BALLSCREW_F_S_MAX, Kind::Number { frac: 32, pow10: 0, unit: NUMBER, none_at_max: true },
        "ball screw f(tau): flat beyond this tau (none: never)",
        [q64 ball_screw.law.s_max];
    70 => BALLSCREW_LUBE_BAND, num(28, RATIO),
        "warn when the identified f leaves law*(1 +- band)",
        [q32 lube.band];
    71 => BALLSCREW_IDENT_MIN_SPEED, num(16, RAD_PER_S),
        "slowest cruise whose motor current identifies f",
        [q32 lube.min_speed];
    72 => BALLSCREW_NO_LOAD_CURRENT, num(16, AMPS),
        "motor current at cruise speed with the gearbox output free (drive friction)",
        [q32 lube.no_load_current];
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_are_unique_lower_case_and_findable() {
        for (i, s) in SETTINGS.iter().enumerate() {
            assert_eq!(s.key, s.key.to_ascii_lowercase());
            assert_eq!(find(s.key).map(SettingId::index), Some(i));
            assert_eq!(
                find(&s.key.to_ascii_uppercase()).map(SettingId::index),
                Some(i)
            );
        }
        assert_eq!(find("limits.middle"), None);
    }

    /// Compile-time guard: this destructuring lists every field of the configuration without
    /// `..`, so a new field breaks this test's build until it has a key in [`SETTINGS`] (and so
    /// in the flash record, whose schema word then changes).
    #[test]
    fn registry_covers_every_field() {
        use crate::control::config::{BrakeConfig, LubeConfig};
        use crate::control::config::{LimitStops, MotionConfig, ProtectionConfig, SensingConfig};
        use crate::detect::stickslip::StickSlipConfig;
        use crate::estimator::{EstimatorConfig, MotorConfig};
        use crate::model::ballscrew::BallScrewConfig;
        use crate::model::geometry::{DriveConfig, GeometryConfig};
        use crate::model::screw::MechanicsConfig;
        let ControlConfig {
            estimator:
                EstimatorConfig {
                    geometry:
                        GeometryConfig {
                            length: _,
                            alpha0_deg: _,
                            alpha_max_deg: _,
                            h0: _,
                            mu_pin: _,
                        },
                    drive:
                        DriveConfig {
                            counts_per_rev: _,
                            gear_ratio: _,
                            pitch_radius: _,
                            lead_angle_deg: _,
                        },
                    mechanics:
                        MechanicsConfig {
                            inertia_ukgm2: _,
                            damping_unms: _,
                            support_torque: _,
                            nut_mass: _,
                            coupling_stiffness: _,
                        },
                    law:
                        FrictionLaw {
                            base: _,
                            amp: _,
                            rate: _,
                            slope: _,
                            s_max: _,
                            variable: _,
                        },
                    motor:
                        MotorConfig {
                            torque_constant: _,
                            gear_efficiency: _,
                            resistance: _,
                            inertia_ukgm2: _,
                        },
                    tick_us: _,
                    speed_bandwidth_hz: _,
                    rest_speed: _,
                },
            rated_load: _,
            motion:
                MotionConfig {
                    cruise_speed: _,
                    ramp_ms: _,
                    ramp_shape: _,
                    buttons: _,
                },
            limits:
                LimitStops {
                    lower: _,
                    upper: _,
                    switch_lower: _,
                },
            protection:
                ProtectionConfig {
                    overcurrent: _,
                    current_limit: _,
                    stall_duty: _,
                    stall_ms: _,
                    max_motor_speed: _,
                    supply_start_min: _,
                    supply_run_min: _,
                    supply_max: _,
                    supply_ms: _,
                    overload_margin: _,
                    overload_ms: _,
                    runaway_travel: _,
                },
            sensing:
                SensingConfig {
                    current_zero_code: _,
                    current_ua_per_code: _,
                    supply_uv_per_code: _,
                },
            stick_slip:
                StickSlipConfig {
                    reaction: _,
                    drop_threshold: _,
                    window_ms: _,
                    escape_speed: _,
                },
            screw: _,
            ball_screw:
                BallScrewConfig {
                    r_m: _,
                    r_b: _,
                    contact_angle_deg: _,
                    lead: _,
                    loaded_balls: _,
                    preload: _,
                    viscosity: _,
                    law:
                        FrictionLaw {
                            base: _,
                            amp: _,
                            rate: _,
                            slope: _,
                            s_max: _,
                            // Always `Lubrication` (validation refuses any other): no key.
                            variable: _,
                        },
                },
            lube:
                LubeConfig {
                    band: _,
                    min_speed: _,
                    no_load_current: _,
                },
            brake:
                BrakeConfig {
                    present: _,
                    delay_ms: _,
                },
        } = ControlConfig::DEFAULT;
        // 72 fields above, one key each (the ball screw's law variable is fixed), plus the
        // `friction.law` preset selector.
        // (Without the `ball-screw` feature the ball screw's 15 are opaque record words.)
        assert_eq!(
            SETTINGS.iter().filter(|s| s.stored()).count() + OPAQUE_COUNT,
            72
        );
    }

    /// The ball screw's values are the registry's last stored settings (so a build without the
    /// feature appends them to the record in the same place), and the opaque accessors read and
    /// write the very bits the settings do.
    #[cfg(feature = "ball-screw")]
    #[test]
    fn opaque_words_are_the_ball_screw_settings_bits() {
        let stored: std::vec::Vec<&Setting> = SETTINGS.iter().filter(|s| s.stored()).collect();
        let tail = &stored[stored.len() - BALL_KEYS.len()..];
        let mut cfg = ControlConfig::ball_screw_4008().unwrap();
        cfg.ball_screw.preload = Newtons::lit("1234.5");
        cfg.lube.band = Ratio::lit("0.7");
        for (j, s) in tail.iter().enumerate() {
            assert_eq!(s.key, BALL_KEYS[j]);
            assert!(s.key.starts_with(BALL_PREFIX));
            assert_eq!(opaque_get(j, &cfg), s.get(&cfg), "{}", s.key);
            for raw in [s.get(&cfg) ^ 1, 0, 1, i64::from(i32::MAX) + 1, -1, i64::MIN] {
                let (mut a, mut b) = (cfg, cfg);
                assert_eq!(
                    opaque_set(j, &mut a, raw),
                    s.set(&mut b, raw),
                    "{} {raw}",
                    s.key
                );
                assert_eq!(a, b, "{} {raw}", s.key);
            }
        }
        assert_eq!(opaque_get(BALL_KEYS.len(), &cfg), 0);
        assert!(!opaque_set(BALL_KEYS.len(), &mut cfg, 0));
        // Nothing else of the registry is the ball screw's.
        assert!(stored[..stored.len() - BALL_KEYS.len()]
            .iter()
            .all(|s| !s.key.starts_with(BALL_PREFIX)));
        assert_eq!(OPAQUE_COUNT, 0);
        // The feature's checks are off.
        assert_eq!(crate::control::config::check_variant(&cfg), Ok(()));
        assert_eq!(
            unknown_key_template(b"ballscrew.x"),
            "unknown key '\x01'\x01"
        );
    }

    #[test]
    fn every_setting_accesses_its_own_field() {
        // A setting's position is found from its address (the registry's indices are the
        // positions: a compile-time check).
        for (i, s) in SETTINGS.iter().enumerate() {
            assert_eq!(s.index(), i, "{}", s.key);
            assert_eq!(find(s.key).map(|id| id.setting().index()), Some(i));
        }
        // Only the preset selector is left out of the record.
        let derived: std::vec::Vec<&str> = SETTINGS
            .iter()
            .filter(|s| !s.stored())
            .map(|s| s.key)
            .collect();
        assert_eq!(derived, ["friction.law"]);
        assert!(!stored_at(SETTINGS.len()) && !stored_at(200));
        // Each stored setting's field is its own: changing one leaves every other reading.
        let c = ControlConfig::DEFAULT;
        for s in SETTINGS.iter().filter(|s| s.stored()) {
            let raw = s.get(&c);
            let Some(d) = [raw ^ 1, raw.wrapping_add(2), 0, 1]
                .into_iter()
                .find_map(|v| {
                    let mut d = c;
                    (v != raw && s.set(&mut d, v)).then_some(d)
                })
            else {
                panic!("{} takes no other value", s.key)
            };
            for t in SETTINGS.iter().filter(|t| t.stored()) {
                assert_eq!(
                    t.get(&d) == t.get(&c),
                    !core::ptr::eq(s, t),
                    "{} {}",
                    s.key,
                    t.key
                );
            }
        }
    }
}
