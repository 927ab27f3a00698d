//! The registry: every setting's key, kind, range text, help line and field, in the order
//! the flash record stores them.

use super::slot::{field_slot, field_stored, Slot};
use super::*;

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
/// kind, range, help line, [accessor]`). One `match` for both directions instead of a `get`
/// and a `set` function per setting (or a `match` per direction): on the board the table is 8
/// bytes per setting smaller and each setting's field access is one address and tag.
///
/// The `ball_screw:` group is the ball-screw variant's (cargo feature `ball-screw`). Its entries
/// come last, so the flash record holds their values last in either build: without the
/// feature they are no settings (no keys, no console access), but [`slot`] still reaches their
/// fields at the same positions and the record carries their raw words through
/// ([`BALL_KEYS`], [`opaque_get`]).
macro_rules! registry {
    ($($n:literal => $key:literal, $kind:expr, $range:literal, $about:literal, [$($acc:tt)+];)*
     ball_screw: $($bn:literal => $bkey:literal, $bkind:expr, $brange:literal, $babout:literal, [$($bacc:tt)+];)*) => {
        /// Every setting. The flash record's layout follows this order (the `stored` ones):
        /// changing it changes the record's schema fingerprint (see [`crate::config::record`]).
        pub static SETTINGS: [Setting; SETTINGS_LEN] = [$(
            Setting {
                key: $key,
                kind: $kind,
                range: $range,
                #[cfg(feature = "help-text")]
                about: $about,
            },
        )* $(
            #[cfg(feature = "ball-screw")]
            Setting {
                key: $bkey,
                kind: $bkind,
                range: $brange,
                #[cfg(feature = "help-text")]
                about: $babout,
            },
        )*];

        /// The keys of [`SETTINGS`]' own entries, for [`key_index`] at compile time (no flash).
        const KEYS: [&str; BALL_FIRST] = [$($key),*];

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
        pub const BALL_KEYS: [&str; [$($bn),*].len()] = [$($bkey),*];

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

/// The position in [`SETTINGS`] of the setting with this key (exact spelling); a compile-time
/// error in a `const` if there is none. For the range tables ([`crate::Bound`]) that name a
/// setting instead of carrying its key and range text.
pub(crate) const fn key_index(key: &str) -> u8 {
    let mut i = 0;
    while i < KEYS.len() {
        let (a, b) = (KEYS[i].as_bytes(), key.as_bytes());
        if a.len() == b.len() {
            let mut j = 0;
            while j < a.len() && a[j] == b[j] {
                j += 1;
            }
            if j == a.len() {
                return i as u8;
            }
        }
        i += 1;
    }
    panic!("no setting has this key")
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
    0 => "limits.lower", LEN, "the mechanism's height range (see `limits`)",
        "lowest head height the lift drives to",
        [q32 limits.lower];
    1 => "limits.upper", LEN, "the mechanism's height range (see `limits`)",
        "highest head height the lift drives to",
        [q32 limits.upper];
    2 => "limits.switch_lower", LEN, "the mechanism's height range, at least 0.5 mm below limits.lower",
        "head height where the lower limit switch closes (the homing reference)",
        [q32 limits.switch_lower];
    3 => "load.rated", num(12, KILOGRAMS), "10..5000 kg",
        "rated load of the lift",
        [q32 rated_load];
    4 => "motion.cruise_speed", num(16, RAD_PER_S), "0.2..20 rad/s",
        "cruise screw speed",
        [q32 motion.cruise_speed];
    5 => "motion.ramp_ms", num(0, MILLIS), "10..2000 ms",
        "time from rest to cruise speed (and back)",
        [int u32, motion.ramp_ms];
    6 => "motion.ramp_shape", Kind::Choice(ChoiceId(0)), "trapezoid or scurve",
        "speed ramp: constant acceleration or jerk-limited",
        [choice motion.ramp_shape];
    7 => "motion.buttons", Kind::Choice(ChoiceId(1)), "hold or latched",
        "UP/DOWN buttons: hold-to-run or latched until STOP",
        [choice motion.buttons];
    8 => "protect.overcurrent", num(16, AMPS), "1..60 A",
        "motor current that trips the over-current fault",
        [q32 protection.overcurrent];
    9 => "protect.current_limit", num(16, AMPS), "1..60 A",
        "current the speed loop never asks for (at most protect.overcurrent)",
        [q32 protection.current_limit];
    10 => "protect.stall_duty", num(28, RATIO), "0.05..1",
        "duty at or above which no encoder motion counts as a stall",
        [q32 protection.stall_duty];
    11 => "protect.stall_ms", num(0, MILLIS), "20..5000 ms",
        "time stalled before the fault",
        [int u32, protection.stall_ms];
    12 => "protect.max_motor_speed", num(16, RAD_PER_S), "10..5000 rad/s",
        "fastest plausible motor-shaft speed",
        [q32 protection.max_motor_speed];
    13 => "protect.supply_start_min", num(16, VOLTS), "8..16 V",
        "refuse to start below this supply voltage",
        [q32 protection.supply_start_min];
    14 => "protect.supply_run_min", num(16, VOLTS), "6..16 V",
        "stop while moving below this supply voltage",
        [q32 protection.supply_run_min];
    15 => "protect.supply_max", num(16, VOLTS), "12..20 V",
        "stop above this supply voltage",
        [q32 protection.supply_max];
    16 => "protect.supply_ms", num(0, MILLIS), "1..1000 ms",
        "supply out of range this long trips the fault",
        [int u32, protection.supply_ms];
    17 => "protect.overload_margin", num(28, RATIO), "0.05..2",
        "overload: measured torque above the rated-load model by this fraction",
        [q32 protection.overload_margin];
    18 => "protect.overload_ms", num(0, MILLIS), "10..5000 ms",
        "overload held this long trips the fault",
        [int u32, protection.overload_ms];
    19 => "protect.runaway_travel", LEN, "0.01..10 mm",
        "uncommanded nut travel before the runaway fault",
        [q32 protection.runaway_travel];
    20 => "sense.current_zero", num(0, COUNTS), "0..4095 codes",
        "current-sense ADC code at 0 A",
        [int u16, sensing.current_zero_code];
    21 => "sense.current_ua_per_code", num(0, MICROAMPS), "1..1000000 uA",
        "motor current per ADC code",
        [int u32, sensing.current_ua_per_code];
    22 => "sense.supply_uv_per_code", num(0, MICROVOLTS), "1..100000 uV",
        "supply voltage per ADC code",
        [int u32, sensing.supply_uv_per_code];
    23 => "geometry.length", LEN, "0.05..2 m",
        "Eq 1's length L (twice the arm length)",
        [q32 estimator.geometry.length];
    24 => "geometry.alpha0", num(16, DEGREES), "12..60 deg",
        "arm angle fully down",
        [q32 estimator.geometry.alpha0_deg];
    25 => "geometry.alpha_max", num(16, DEGREES), "alpha0+5..89 deg",
        "largest arm angle of the mechanism",
        [q32 estimator.geometry.alpha_max_deg];
    26 => "geometry.h0", LEN, "0..1 m",
        "head height with the arms collapsed",
        [q32 estimator.geometry.h0];
    27 => "geometry.mu_pin", num(28, RATIO), "0..1",
        "pin friction coefficient (Eq 6)",
        [q32 estimator.geometry.mu_pin];
    28 => "drive.counts_per_rev", num(0, COUNTS), "4..65536",
        "encoder counts per motor turn",
        [int u32, estimator.drive.counts_per_rev];
    29 => "drive.gear_ratio", num(16, NUMBER), "1..1000",
        "motor turns per screw turn",
        [q32 estimator.drive.gear_ratio];
    30 => "drive.pitch_radius", LEN, "1..50 mm",
        "screw pitch radius r_m",
        [q32 estimator.drive.pitch_radius];
    31 => "drive.lead_angle", num(16, DEGREES), "0.5..20 deg",
        "screw lead angle",
        [q32 estimator.drive.lead_angle_deg];
    32 => "drive.screw", Kind::Choice(ChoiceId(2)), "lead or ball",
        "screw type: lead (self-locking) or ball (held actively at rest)",
        [choice screw];
    33 => "drive.brake", Kind::Choice(ChoiceId(3)), "none or spring",
        "holding brake: none, or spring-applied (engaged unless the brake output is on)",
        [choice brake.present];
    34 => "drive.brake_ms", num(0, MILLIS), "5..1000 ms",
        "time the brake takes to release or engage",
        [int u32, brake.delay_ms];
    35 => "mech.inertia", num(0, MICRO_KGM2), "0..100000 ukgm2",
        "screw inertia I",
        [int i32, estimator.mechanics.inertia_ukgm2];
    36 => "mech.damping", num(0, MICRO_NMS), "0..1e6 uNms/rad",
        "screw support damping c",
        [int i32, estimator.mechanics.damping_unms];
    37 => "mech.support_torque", num(16, NEWTON_METRES), "0..10 Nm",
        "support friction torque T0",
        [q32 estimator.mechanics.support_torque];
    38 => "mech.nut_mass", num(12, KILOGRAMS), "0..5 kg",
        "translating (nut) mass m",
        [q32 estimator.mechanics.nut_mass];
    39 => "mech.coupling_stiffness", num(16, NM_PER_RAD), "1..10000 Nm/rad",
        "torsional stiffness k of the coupling",
        [q32 estimator.mechanics.coupling_stiffness];
    40 => "friction.law", Kind::Choice(ChoiceId(4)), "dry, ptfe, lithium or ball",
        "load a preset friction law (shows `custom` after edits)",
        [preset estimator.law];
    41 => "friction.variable", Kind::Choice(ChoiceId(5)), "rate, speed or tau",
        "law variable: screw rate |w| rad/s, sliding speed m/s, or tau",
        [choice estimator.law.variable];
    42 => "friction.base", num(28, RATIO), "0..1",
        "law: constant term",
        [q32 estimator.law.base];
    43 => "friction.amp", num(28, RATIO), "-1..1",
        "law: exponential (Stribeck) amplitude",
        [q32 estimator.law.amp];
    44 => "friction.rate", num(32, NUMBER), "0..1e6",
        "law: exponential rate per unit of the variable",
        [q64 estimator.law.rate];
    45 => "friction.slope", num(32, NUMBER), "-1000..1000",
        "law: viscous slope per unit of the variable",
        [q64 estimator.law.slope];
    46 => "friction.s_max", Kind::Number { frac: 32, pow10: 0, unit: NUMBER, none_at_max: true },
        ">0..1e6", "law: viscous term flat beyond this (none: never)",
        [q64 estimator.law.s_max];
    47 => "motor.kt", num(28, NM_PER_AMP), "0.001..1 Nm/A",
        "motor torque constant",
        [q32 estimator.motor.torque_constant];
    48 => "motor.gear_efficiency", num(28, RATIO), "0.1..1",
        "gearbox efficiency",
        [q32 estimator.motor.gear_efficiency];
    49 => "motor.resistance", num(28, OHMS), "0.001..4 ohm",
        "motor loop resistance (armature, bridge, battery)",
        [q32 estimator.motor.resistance];
    50 => "control.tick_us", num(0, MICROS), "100..10000 us",
        "control tick period",
        [int u32, estimator.tick_us];
    51 => "control.speed_bandwidth", num(0, HERTZ), "1..tick rate/10 Hz",
        "speed filter bandwidth",
        [int u32, estimator.speed_bandwidth_hz];
    52 => "control.rest_speed", num(16, RAD_PER_S), "0..50 rad/s",
        "screw speed below which the screw counts as at rest",
        [q32 estimator.rest_speed];
    53 => "stickslip.reaction", Kind::Choice(ChoiceId(6)), "log, warn or speed",
        "on stick-slip: log it, also warn on the console, or also change to the escape speed",
        [choice stick_slip.reaction];
    54 => "stickslip.drop", num(16, NEWTON_METRES), "0.2..50 Nm",
        "smallest fall of the measured screw torque that counts as a slip",
        [q32 stick_slip.drop_threshold];
    55 => "stickslip.window_ms", num(0, MILLIS), "100..10000 ms",
        "slips further apart start a new chain",
        [int u32, stick_slip.window_ms];
    56 => "stickslip.escape_speed", num(16, RAD_PER_S), "0.2..20 rad/s",
        "cruise speed for the rest of a motion after stick-slip (reaction speed)",
        [q32 stick_slip.escape_speed];
    ball_screw:
    57 => "ballscrew.r_m", LEN, "2..100 mm",
        "ball screw: ball-centre circle radius r_m",
        [q32 ball_screw.r_m];
    58 => "ballscrew.r_b", LEN, "0.5..20 mm",
        "ball screw: ball radius r_b (less than r_m)",
        [q32 ball_screw.r_b];
    59 => "ballscrew.contact_angle", num(16, DEGREES), "20..80 deg",
        "ball screw: contact angle alpha",
        [q32 ball_screw.contact_angle_deg];
    60 => "ballscrew.lead", LEN, "0.5..50 mm",
        "ball screw: lead (nut travel per screw turn)",
        [q32 ball_screw.lead];
    61 => "ballscrew.balls", num(0, COUNTS), "1..1000",
        "ball screw: number of loaded balls M",
        [int u16, ball_screw.loaded_balls];
    62 => "ballscrew.preload", num(8, NEWTONS), "0..100 kN",
        "ball screw: preload F_p",
        [q32 ball_screw.preload];
    63 => "ballscrew.viscosity", num(32, PASCAL_SECONDS), "1e-4..10 Pa.s",
        "ball screw: lubricant dynamic viscosity eta0",
        [q64 ball_screw.viscosity];
    64 => "ballscrew.f_base", num(28, RATIO), "0..1",
        "ball screw f(tau): constant term",
        [q32 ball_screw.law.base];
    65 => "ballscrew.f_amp", num(28, RATIO), "-1..1",
        "ball screw f(tau): exponential amplitude",
        [q32 ball_screw.law.amp];
    66 => "ballscrew.f_rate", num(32, NUMBER), "0..1e6",
        "ball screw f(tau): exponential rate per unit of tau",
        [q64 ball_screw.law.rate];
    67 => "ballscrew.f_slope", num(32, NUMBER), "-1000..1000",
        "ball screw f(tau): slope per unit of tau",
        [q64 ball_screw.law.slope];
    68 => "ballscrew.f_s_max", Kind::Number { frac: 32, pow10: 0, unit: NUMBER, none_at_max: true },
        ">0..1e6", "ball screw f(tau): flat beyond this tau (none: never)",
        [q64 ball_screw.law.s_max];
    69 => "ballscrew.lube_band", num(28, RATIO), "0.05..4",
        "warn when the identified f leaves law*(1 +- band)",
        [q32 lube.band];
    70 => "ballscrew.ident_min_speed", num(16, RAD_PER_S), "0.05..20 rad/s",
        "slowest cruise whose motor current identifies f",
        [q32 lube.min_speed];
    71 => "ballscrew.no_load_current", num(16, AMPS), "0..20 A",
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
        // 71 fields above, one key each (the ball screw's law variable is fixed), plus the
        // `friction.law` preset selector.
        // (Without the `ball-screw` feature the ball screw's 15 are opaque record words.)
        assert_eq!(
            SETTINGS.iter().filter(|s| s.stored()).count() + OPAQUE_COUNT,
            71
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
        assert_eq!(check_variant(&cfg), Ok(()));
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
