//! The settings registry: every field of [`ControlConfig`] by its console key.
//!
//! Each [`Setting`] reads and writes its field as raw bits in an `i64` (the Q format's bits, an
//! integer, or a choice index), knows its unit for parsing and display and its accepted range
//! for messages. Range checks themselves stay where they are defined
//! ([`ControlConfig::validate`], [`crate::estimator::Estimator::new`]): [`apply`] changes one
//! field of a copy and re-validates the whole configuration, so a refused change leaves the
//! running one untouched. The flash record ([`crate::config::record`]) stores the `stored`
//! settings in this table's order.

use crate::config::ValidatedConfig;
use crate::control::config::{ButtonMode, ControlConfig, RampShape, ScrewKind};
use crate::detect::stickslip::Reaction;
use crate::model::friction::{FrictionLaw, LawVariable};
use crate::units::{
    Amperes, Kilograms, Metres, NewtonMetres, Newtons, RadiansPerSecond, Ratio, Volts,
};
use crate::ConfigError;
use fixed::types::{I16F16, I32F32};

/// A unit a value is typed and shown in: its display unit, what it measures and the other
/// suffixes it accepts, packed in one text (`display|what|suffix=power|…`; one reference per
/// unit instead of three, and no table of (suffix, power) pairs: ≈ 0.4 KiB less flash).
#[derive(Debug, PartialEq, Eq)]
pub struct Unit {
    spec: &'static str,
}

impl Unit {
    /// The spec's `|`-separated parts: the display unit, what it measures, then each accepted
    /// suffix as `suffix=power`.
    pub(crate) fn parts(&self) -> Parts {
        Parts(Some(self.spec))
    }

    /// The unit values are shown in (empty: a plain number).
    pub fn display(&self) -> &'static str {
        self.parts().next().unwrap_or("")
    }

    /// What the value is, for messages ("a length").
    pub fn what(&self) -> &'static str {
        self.parts().nth(1).unwrap_or("")
    }

    /// Accepted suffixes other than `display` (lower case) with their power of ten relative
    /// to `display`; `display` itself (any case) and a bare number are always read in
    /// `display`.
    pub fn accepts(&self) -> impl Iterator<Item = (&'static str, i32)> {
        self.parts().skip(2).map(|a| {
            // `suffix=power`, the power one digit with an optional `-` (`units!` checks that
            // at compile time; a test reads every unit back).
            let b = a.as_bytes();
            let digit = b.last().map_or(0, |d| i32::from(d.wrapping_sub(b'0')));
            let neg = b.get(b.len().wrapping_sub(2)) == Some(&b'-');
            let cut = b.len().saturating_sub(if neg { 3 } else { 2 });
            (a.get(..cut).unwrap_or(""), if neg { -digit } else { digit })
        })
    }
}

/// The `|`-separated parts of a [`Unit`]'s spec (an empty part included).
pub(crate) struct Parts(Option<&'static str>);

impl Iterator for Parts {
    type Item = &'static str;

    fn next(&mut self) -> Option<&'static str> {
        let rest = self.0?;
        // `|` is ASCII: the split is at a char boundary (checked: no panic linked).
        match rest
            .bytes()
            .position(|b| b == b'|')
            .and_then(|i| rest.split_at_checked(i))
        {
            Some((part, tail)) => {
                self.0 = tail.get(1..);
                Some(part)
            }
            None => {
                self.0 = None;
                Some(rest)
            }
        }
    }
}

/// The units ([`UNITS`]) and a [`UnitId`] constant for each (`NAME, display, what,
/// [accepted suffixes]`).
macro_rules! units {
    ($($(#[$doc:meta])* $name:ident, $display:literal, $what:literal, [$(($s:literal, $p:literal)),* $(,)?];)*) => {
        /// Positions in [`UNITS`].
        #[allow(non_camel_case_types, clippy::upper_case_acronyms)]
        #[repr(u8)]
        enum UnitIndex { $($name),* }

        $(
            $(#[$doc])*
            pub const $name: UnitId = UnitId(UnitIndex::$name as u8);
        )*

        /// Every unit, in [`UnitId`] order.
        pub static UNITS: [Unit; [$(UnitIndex::$name),*].len()] = [$(
            Unit { spec: concat!($display, "|", $what $(, "|", $s, "=", $p)*) },
        )*];

        // `Unit::accepts` reads a power of one digit.
        const _: () = {
            $($(assert!($p >= -9 && $p <= 9, "a suffix's power of ten must be one digit");)*)*
        };

        /// The units as the macro was given them, for the test that reads the specs back.
        #[cfg(test)]
        static UNITS_GIVEN: [(&str, &str, &[(&str, i32)]); UNITS.len()] = [$(
            ($display, $what, &[$(($s, $p)),*]),
        )*];
    };
}

/// A unit by its position in [`UNITS`]; reads as the [`Unit`] (`Deref`). One byte instead of a
/// reference keeps each registry entry 4 bytes smaller on the board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UnitId(u8);

impl core::ops::Deref for UnitId {
    type Target = Unit;

    fn deref(&self) -> &Unit {
        // Ids are only the constants below: the index is in bounds; `get` keeps it total.
        UNITS.get(usize::from(self.0)).unwrap_or(&UNITS[0])
    }
}

units! {
    /// Lengths, shown in mm.
    MILLIMETRES, "mm", "a length", [("m", 3), ("cm", 1), ("um", -3)];
    /// Screw or motor speeds.
    RAD_PER_S, "rad/s", "an angular speed", [];
    /// Durations in ms.
    MILLIS, "ms", "a duration", [("s", 3)];
    /// Durations in µs.
    MICROS, "us", "a duration", [("ms", 3), ("s", 6)];
    /// Currents.
    AMPS, "A", "a current", [("ma", -3)];
    /// Voltages.
    VOLTS, "V", "a voltage", [("mv", -3)];
    /// Masses.
    KILOGRAMS, "kg", "a mass", [("t", 3), ("g", -3)];
    /// Dimensionless ratios (a percentage is accepted).
    RATIO, "", "a ratio", [("%", -2)];
    /// Plain numbers (gear ratio, law parameters).
    NUMBER, "", "a number", [];
    /// Counts and ADC codes.
    COUNTS, "", "a whole number", [("counts", 0), ("codes", 0)];
    /// Angles in degrees.
    DEGREES, "deg", "an angle", [("°", 0)];
    /// Torques.
    NEWTON_METRES, "Nm", "a torque", [("n*m", 0), ("n.m", 0), ("n·m", 0), ("mnm", -3)];
    /// Torque constants.
    NM_PER_AMP, "Nm/A", "a torque constant", [("n*m/a", 0), ("n·m/a", 0)];
    /// Frequencies.
    HERTZ, "Hz", "a frequency", [];
    /// ADC scalings of current, per code.
    MICROAMPS, "uA", "a current per ADC code", [("ma", 3)];
    /// ADC scalings of voltage, per code.
    MICROVOLTS, "uV", "a voltage per ADC code", [("mv", 3)];
    /// Torsional stiffness.
    NM_PER_RAD, "Nm/rad", "a torsional stiffness", [("n*m/rad", 0), ("n·m/rad", 0)];
    /// Resistances.
    OHMS, "ohm", "a resistance", [("mohm", -3), ("Ω", 0), ("mΩ", -3)];
    /// Screw inertia in µkg·m².
    MICRO_KGM2, "ukgm2", "an inertia", [("ukg*m2", 0)];
    /// Forces.
    NEWTONS, "N", "a force", [("kn", 3)];
    /// Dynamic viscosity.
    PASCAL_SECONDS, "Pa.s", "a viscosity", [("mpa.s", -3)];
    /// Screw support damping in µN·m·s/rad.
    MICRO_NMS, "uNms/rad", "a rotational damping", [("unms", 0)];
}

/// A choice setting's names, by position in [`CHOICES`]; reads as the names (`Deref`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChoiceId(u8);

impl core::ops::Deref for ChoiceId {
    type Target = [&'static str];

    fn deref(&self) -> &[&'static str] {
        // Ids are only the ones of the registry: the index is in bounds; `get` keeps it total.
        CHOICES.get(usize::from(self.0)).copied().unwrap_or(&[])
    }
}

/// The names of every choice setting, in [`ChoiceId`] order (a test checks each against its
/// setting's range text).
static CHOICES: [&[&str]; 7] = [
    &["trapezoid", "scurve"],
    &["hold", "latched"],
    &["lead", "ball"],
    &["none", "spring"],
    &["dry", "ptfe", "lithium", "ball"],
    &["rate", "speed", "tau"],
    &["log", "warn", "speed"],
];

/// How a setting's raw bits read as a value.
#[derive(Debug, PartialEq, Eq)]
pub enum Kind {
    /// `raw / 2^frac` in the field's base unit, shown as that times `10^pow10` in `unit.display`.
    Number {
        /// Fractional bits of the field's Q format (0 for integers). (`u8`/`i8` keep each
        /// registry entry 4 bytes smaller on the board.)
        frac: u8,
        /// Display unit per base unit as a power of ten (mm per m: 3).
        pow10: i8,
        /// Unit for parsing and display.
        unit: UnitId,
        /// The field's largest value means "no limit" (typed and shown as `none`).
        none_at_max: bool,
    },
    /// An index into the names. (Ids of one byte: the kind is then 4 bytes instead of 8, 4
    /// bytes less per registry entry on the board.)
    Choice(ChoiceId),
}

/// One configurable field.
#[non_exhaustive]
pub struct Setting {
    /// Console key (lower case, as [`ConfigError`] names it).
    pub key: &'static str,
    /// Raw-bits interpretation.
    pub kind: Kind,
    /// Accepted range, for messages (the text of the validation that checks it).
    pub range: &'static str,
    /// One line of help, for a person on a host: only with the `help-text` feature (liftctl
    /// and host-sim turn it on; the firmware leaves the ≈ 3 KiB of text and this field out and
    /// its `help <key>` gives unit and range). Read it through [`Setting::about`].
    #[cfg(feature = "help-text")]
    about: &'static str,
    // No other field: 20 bytes per setting on the board. Whether it is stored
    // ([`Setting::stored`]) and its position (the field [`Setting::get`] and [`Setting::set`]
    // reach) come from where it is in [`SETTINGS`].
}

impl core::fmt::Debug for Setting {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Setting").field("key", &self.key).finish()
    }
}

impl Setting {
    /// The one line of help, if this build has the help texts (feature `help-text`).
    #[cfg(feature = "help-text")]
    pub fn about(&self) -> Option<&'static str> {
        Some(self.about)
    }

    /// The one line of help, if this build has the help texts (feature `help-text`).
    #[cfg(not(feature = "help-text"))]
    pub fn about(&self) -> Option<&'static str> {
        None
    }

    /// Its position in [`SETTINGS`]. Every `Setting` is one of that table's (it is
    /// `#[non_exhaustive]`, so no other crate can make one, this crate makes them only there,
    /// and it is not `Clone`): the position is its address's distance from the table's start.
    pub fn index(&self) -> usize {
        let at = core::ptr::from_ref(self).addr();
        at.wrapping_sub(SETTINGS.as_ptr().addr()) / core::mem::size_of::<Setting>()
    }

    /// Part of the flash record (false only for derived settings such as `friction.law`).
    pub fn stored(&self) -> bool {
        stored_at(self.index())
    }

    /// The field's raw bits in `cfg`. (Through a copy: the registry reaches its fields by one
    /// `&mut` access ([`slot`]) for both directions.)
    pub fn get(&self, cfg: &ControlConfig) -> i64 {
        let mut c = *cfg;
        slot(self.index(), &mut c).read()
    }

    /// Write raw bits into the field; false (and `cfg` unchanged) if they do not fit its type.
    /// No range check: see [`apply`].
    pub fn set(&self, cfg: &mut ControlConfig, raw: i64) -> bool {
        slot(self.index(), cfg).write(raw)
    }
}

/// Index of a setting in [`SETTINGS`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SettingId(u8);

impl SettingId {
    /// The setting.
    pub fn setting(self) -> &'static Setting {
        // Ids are only made by `find`/`all`, so the index is in bounds; `get` keeps it total.
        SETTINGS.get(usize::from(self.0)).unwrap_or(&SETTINGS[0])
    }

    /// Its console key.
    pub fn key(self) -> &'static str {
        self.setting().key
    }

    /// Position in [`SETTINGS`].
    pub fn index(self) -> usize {
        usize::from(self.0)
    }
}

/// The setting with this key (ASCII case-insensitive), given as text or bytes (the console
/// parses lines as bytes).
pub fn find(key: &(impl AsRef<[u8]> + ?Sized)) -> Option<SettingId> {
    find_bytes(key.as_ref())
}

fn find_bytes(key: &[u8]) -> Option<SettingId> {
    SETTINGS
        .iter()
        .position(|s| s.key.as_bytes().eq_ignore_ascii_case(key))
        .map(|i| SettingId(i as u8))
}

/// Every setting, in registry order.
pub fn all() -> impl Iterator<Item = SettingId> {
    (0..SETTINGS.len()).map(|i| SettingId(i as u8))
}

/// Change one setting of a copy of `cfg` and validate the whole copy; the copy is returned
/// only if it is valid. Raw bits that do not fit the field's type are refused with the
/// setting's own range.
pub fn apply(
    cfg: &ValidatedConfig,
    id: SettingId,
    raw: i64,
) -> Result<ValidatedConfig, ConfigError> {
    let s = id.setting();
    let mut next = *cfg.get();
    if !s.set(&mut next, raw) {
        return Err(ConfigError::OutOfRange {
            field: s.key,
            range: s.range,
        });
    }
    ValidatedConfig::new(next)
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
    let field = if cfg.screw == ScrewKind::Ball {
        "drive.screw"
    } else if cfg.estimator.law.variable == LawVariable::Lubrication {
        "friction.variable"
    } else {
        return Ok(());
    };
    Err(ConfigError::Conflict {
        field,
        reason: NEEDS_BALL_SCREW,
    })
}

/// The console's message template for a key [`find`] does not know (`\x01`: the key, then the
/// pointer to `help keys`): without the `ball-screw` feature a `ballscrew.*` key is not unknown
/// but needs the other image.
pub fn unknown_key_template(key: &[u8]) -> &'static str {
    let ball = key
        .get(..BALL_PREFIX.len())
        .is_some_and(|p| p.eq_ignore_ascii_case(BALL_PREFIX.as_bytes()));
    if ball && !cfg!(feature = "ball-screw") {
        "'\x01' needs the ball-screw firmware (this is the lead-screw image)\x01"
    } else {
        "unknown key '\x01'\x01"
    }
}

/// The ball-screw variant's keys' common prefix.
const BALL_PREFIX: &str = "ballscrew.";

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

/// The configuration fields as the registry reaches them, and [`Slot`]'s two directions.
/// (`q32` names the 32-bit fixed-point types, `choice` the fieldless enum and bool fields'
/// types and `preset` the other chosen ones, with a variant name each.)
macro_rules! slots {
    (q32: $($q:ident),*;
     choice: $($c:ident($ct:ty) = $cv:expr),*;
     preset: $($p:ident($pt:ty) = $pv:expr),* $(,)?) => {
        /// A configuration field as the registry reaches it: a mutable reference typed by how
        /// its raw bits read and write (a choice by its type's list of values,
        /// [`ChoiceValue::VALUES`]). [`slot`] maps a setting's index to its field once for both
        /// directions: on the board each setting costs one address and tag in one `match`,
        /// instead of a load in a reading and a store in a writing one. (A reference and a tag
        /// only: 8 bytes, returned in registers.)
        enum Slot<'a> {
            $($q(&'a mut $q),)*
            Q64(&'a mut I32F32),
            I32(&'a mut i32),
            U32(&'a mut u32),
            U16(&'a mut u16),
            $($c(&'a mut $ct),)*
            $($p(&'a mut $pt),)*
        }

        $(impl<'a> From<&'a mut $q> for Slot<'a> {
            fn from(f: &'a mut $q) -> Self {
                Slot::$q(f)
            }
        })*

        $(impl ChoiceValue for $ct {
            const VALUES: &'static [Self] = &$cv;
        }

        impl<'a> From<&'a mut $ct> for Slot<'a> {
            fn from(f: &'a mut $ct) -> Self {
                Slot::$c(f)
            }
        })*

        $(impl ChoiceValue for $pt {
            const VALUES: &'static [Self] = &$pv;
        }

        impl<'a> From<&'a mut $pt> for Slot<'a> {
            fn from(f: &'a mut $pt) -> Self {
                Slot::$p(f)
            }
        })*

        // A choice type's list is its values in declaration order: `Slot::read` takes the
        // position to be the discriminant.
        const _: () = {
            $({
                let values = <$ct as ChoiceValue>::VALUES;
                let mut i = 0;
                while i < values.len() {
                    assert!(values[i] as usize == i, "a choice lists its type's values in order");
                    i += 1;
                }
            })*
        };

        impl Slot<'_> {
            /// The raw bits (a choice whose value is none of its list's: −1).
            fn read(&self) -> i64 {
                match self {
                    $(Slot::$q(f) => i64::from(f.to_bits()),)*
                    Slot::Q64(f) => f.to_bits(),
                    Slot::I32(f) => i64::from(**f),
                    Slot::U32(f) => i64::from(**f),
                    Slot::U16(f) => i64::from(**f),
                    // A choice's list is its type's values in declaration order (checked at
                    // compile time): the position is the value's discriminant, one load for
                    // every choice type instead of a search loop each.
                    $(Slot::$c(f) => i64::from(**f as u8),)*
                    $(Slot::$p(f) => index_of(&**f, <$pt as ChoiceValue>::VALUES),)*
                }
            }

            /// Store raw bits; false (the field unchanged) if its type or list cannot hold
            /// them.
            fn write(self, raw: i64) -> bool {
                match self {
                    $(Slot::$q(f) => i32::try_from(raw).map(|b| *f = <$q>::from_bits(b)).is_ok(),)*
                    Slot::Q64(f) => {
                        *f = I32F32::from_bits(raw);
                        true
                    }
                    Slot::I32(f) => put(f, raw),
                    Slot::U32(f) => put(f, raw),
                    Slot::U16(f) => put(f, raw),
                    $(Slot::$c(f) => choose(f, <$ct as ChoiceValue>::VALUES, raw),)*
                    $(Slot::$p(f) => choose(f, <$pt as ChoiceValue>::VALUES, raw),)*
                }
            }
        }
    };
}

slots! {
    q32: Metres, Ratio, Amperes, Volts, Kilograms, NewtonMetres, RadiansPerSecond, Newtons,
        I16F16;
    choice: Ramp(RampShape) = [RampShape::Trapezoid, RampShape::SCurve],
        Buttons(ButtonMode) = [ButtonMode::HoldToRun, ButtonMode::Latched],
        Screw(ScrewKind) = [ScrewKind::Lead, ScrewKind::Ball],
        Flag(bool) = [false, true],
        Variable(LawVariable) =
            [LawVariable::ScrewRate, LawVariable::SlidingSpeed, LawVariable::Lubrication],
        Reaction(Reaction) = [Reaction::Log, Reaction::Warn, Reaction::ChangeSpeed];
    preset: Law(FrictionLaw) = LAW_PRESETS,
}

impl<'a> From<&'a mut I32F32> for Slot<'a> {
    fn from(f: &'a mut I32F32) -> Self {
        Slot::Q64(f)
    }
}

impl<'a> From<&'a mut i32> for Slot<'a> {
    fn from(f: &'a mut i32) -> Self {
        Slot::I32(f)
    }
}

impl<'a> From<&'a mut u32> for Slot<'a> {
    fn from(f: &'a mut u32) -> Self {
        Slot::U32(f)
    }
}

impl<'a> From<&'a mut u16> for Slot<'a> {
    fn from(f: &'a mut u16) -> Self {
        Slot::U16(f)
    }
}

/// An enum (or bool) field's type, or a preset's: the values its setting chooses from, in
/// choice order (one setting per type).
trait ChoiceValue: Sized + 'static {
    const VALUES: &'static [Self];
}

/// An integer field takes `raw` if its type holds it.
fn put<T: TryFrom<i64>>(f: &mut T, raw: i64) -> bool {
    T::try_from(raw).map(|v| *f = v).is_ok()
}

/// The position of `f`'s value in `values`, −1 if none.
fn index_of<T: PartialEq>(f: &T, values: &[T]) -> i64 {
    values.iter().position(|x| x == f).map_or(-1, |i| i as i64)
}

/// Set `f` to the value at position `raw` of `values`; false if there is none.
fn choose<T: Copy>(f: &mut T, values: &[T], raw: i64) -> bool {
    match usize::try_from(raw).ok().and_then(|i| values.get(i)) {
        Some(x) => {
            *f = *x;
            true
        }
        None => false,
    }
}

/// The [`Slot`] of one setting, by its accessor form:
/// - `q32 path`: a fixed-point field stored as its 32 raw bits;
/// - `q64 path`: an I32F32 field stored as its 64 raw bits;
/// - `int T, path`: an integer field of type `T`;
/// - `choice path`: an enum (or bool) field stored as the index of its value in its type's
///   list (`slots!`);
/// - `preset path`: like `choice`, but derived (not in the flash record; reads −1 when the
///   field matches no preset of its type's list).
macro_rules! field_slot {
    ($c:ident, choice $($f:ident).+) => { Slot::from(&mut $c.$($f).+) };
    ($c:ident, preset $($f:ident).+) => { Slot::from(&mut $c.$($f).+) };
    ($c:ident, int $t:ty, $($f:ident).+) => { Slot::from(&mut $c.$($f).+) };
    ($c:ident, $form:ident $($f:ident).+) => { Slot::from(&mut $c.$($f).+) };
}

/// Whether an accessor form is part of the flash record.
macro_rules! field_stored {
    (preset $($rest:tt)*) => {
        false
    };
    ($($rest:tt)*) => {
        true
    };
}

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
        fn slot(index: usize, c: &mut ControlConfig) -> Slot<'_> {
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

    /// A choice setting's list holds every value of its type (`Slot::read` takes a value's
    /// discriminant for its position, `slots!` checks the order): each type's values from
    /// an exhaustive `match` (a new variant breaks this test's build until it is listed) read
    /// back as their positions, and every position writes and reads back.
    #[test]
    fn choice_lists_hold_every_value_of_their_type() {
        fn ramp(v: RampShape) -> i64 {
            match v {
                RampShape::Trapezoid => 0,
                RampShape::SCurve => 1,
            }
        }
        fn buttons(v: ButtonMode) -> i64 {
            match v {
                ButtonMode::HoldToRun => 0,
                ButtonMode::Latched => 1,
            }
        }
        fn screw(v: ScrewKind) -> i64 {
            match v {
                ScrewKind::Lead => 0,
                ScrewKind::Ball => 1,
            }
        }
        fn variable(v: LawVariable) -> i64 {
            match v {
                LawVariable::ScrewRate => 0,
                LawVariable::SlidingSpeed => 1,
                LawVariable::Lubrication => 2,
            }
        }
        fn reaction(v: Reaction) -> i64 {
            match v {
                Reaction::Log => 0,
                Reaction::Warn => 1,
                Reaction::ChangeSpeed => 2,
            }
        }
        let mut c = ControlConfig::DEFAULT;
        let mut seen = 0;
        for s in SETTINGS.iter() {
            let Kind::Choice(names) = s.kind else {
                continue;
            };
            if s.key == "friction.law" {
                continue; // a preset (`Slot` searches its list)
            }
            for raw in 0..names.len() as i64 {
                assert!(s.set(&mut c, raw), "{} {raw}", s.key);
                assert_eq!(s.get(&c), raw, "{}", s.key);
                // The value written is the one at that position of its type.
                let at = match s.key {
                    "motion.ramp_shape" => ramp(c.motion.ramp_shape),
                    "motion.buttons" => buttons(c.motion.buttons),
                    "drive.screw" => screw(c.screw),
                    "drive.brake" => i64::from(c.brake.present),
                    "friction.variable" => variable(c.estimator.law.variable),
                    "stickslip.reaction" => reaction(c.stick_slip.reaction),
                    k => panic!("a choice setting this test does not know: {k}"),
                };
                assert_eq!(at, raw, "{}", s.key);
            }
            // As many names as the type has values.
            let count = match s.key {
                "friction.variable" | "stickslip.reaction" => 3,
                _ => 2,
            };
            assert_eq!(names.len(), count, "{}", s.key);
            assert!(!s.set(&mut c, count as i64), "{}", s.key);
            seen += 1;
        }
        assert_eq!(seen, 6);
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

    /// The display unit is accepted without an entry: `accepts` repeats none (the messages'
    /// "(or …)" list relies on it).
    #[test]
    fn accepted_suffixes_do_not_repeat_the_display_unit() {
        for u in UNITS.iter() {
            for (s, _) in u.accepts() {
                assert!(!s.eq_ignore_ascii_case(u.display()), "{}", u.display());
                assert_eq!(s, s.to_ascii_lowercase());
            }
        }
    }

    /// Each unit's packed spec reads back as the display unit, description and suffixes the
    /// `units!` list gives.
    #[test]
    fn unit_specs_read_back_as_given() {
        for (u, (display, what, accepts)) in UNITS.iter().zip(UNITS_GIVEN.iter()) {
            assert_eq!(u.display(), *display);
            assert_eq!(u.what(), *what);
            assert!(!display.contains(['|', '=']) && !what.contains('|'));
            let read: std::vec::Vec<(&str, i32)> = u.accepts().collect();
            assert_eq!(read, *accepts, "{display}");
        }
        assert_eq!(RATIO.display(), "");
        assert_eq!(
            MICROS.accepts().collect::<std::vec::Vec<_>>(),
            [("ms", 3), ("s", 6)]
        );
        assert_eq!(MILLIMETRES.accepts().last(), Some(("um", -3)));
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

    #[test]
    fn every_setting_writes_back_what_it_reads() {
        let c = ControlConfig::DEFAULT;
        for s in SETTINGS.iter() {
            let mut d = c;
            assert!(s.set(&mut d, s.get(&c)), "{}", s.key);
            assert_eq!(d, c, "{}", s.key);
        }
    }

    /// Raw bits the field's type cannot hold are refused and change nothing (32-bit fields
    /// take `i32`, integer fields their own type, choices an index of their list; I32F32
    /// fields take any `i64`).
    #[test]
    fn raw_bits_outside_the_field_type_are_refused() {
        let c = ControlConfig::DEFAULT;
        let fits = |s: &Setting, raw: i64| {
            let mut d = c;
            let ok = s.set(&mut d, raw);
            if !ok {
                assert_eq!(d, c, "{}", s.key);
            } else {
                assert_eq!(s.get(&d), raw, "{}", s.key);
            }
            ok
        };
        let key = |k: &str| find(k).unwrap().setting();
        for k in [
            "limits.upper",
            "motor.kt",
            "load.rated",
            // (The lead-screw build has no ball-screw keys; `opaque_set` is checked against
            // `Setting::set` in the ball-screw build.)
            if cfg!(feature = "ball-screw") {
                "ballscrew.preload"
            } else {
                "motion.cruise_speed"
            },
        ] {
            assert!(fits(key(k), i64::from(i32::MIN)) && fits(key(k), i64::from(i32::MAX)));
            assert!(
                !fits(key(k), i64::from(i32::MAX) + 1) && !fits(key(k), i64::from(i32::MIN) - 1)
            );
        }
        let ramp = key("motion.ramp_ms");
        assert!(fits(ramp, i64::from(u32::MAX)) && !fits(ramp, -1) && !fits(ramp, 1 << 32));
        let zero = key("sense.current_zero");
        assert!(fits(zero, 65535) && !fits(zero, 65536) && !fits(zero, -1));
        let inertia = key("mech.inertia");
        assert!(fits(inertia, -1) && !fits(inertia, 1 << 31));
        let rate = key("friction.rate");
        assert!(fits(rate, i64::MAX) && fits(rate, i64::MIN));
        let shape = key("motion.ramp_shape");
        assert!(fits(shape, 1) && !fits(shape, 2) && !fits(shape, -1));
        let law = key("friction.law");
        assert!(fits(law, 3) && !fits(law, 4));
    }

    #[test]
    fn brake_settings_are_validated() {
        let cfg = ValidatedConfig::factory();
        assert!(!cfg.get().brake.present);
        let brake = find("drive.brake").unwrap();
        let on = apply(&cfg, brake, 1).unwrap();
        assert!(on.get().brake.present);
        assert!(apply(&cfg, brake, 2).is_err());
        let ms = find("drive.brake_ms").unwrap();
        assert_eq!(apply(&on, ms, 5).unwrap().get().brake.delay_ms, 5);
        assert_eq!(apply(&on, ms, 1000).unwrap().get().brake.delay_ms, 1000);
        for bad in [0, 4, 1001] {
            assert_eq!(
                apply(&on, ms, bad).unwrap_err(),
                ConfigError::OutOfRange {
                    field: "drive.brake_ms",
                    range: "5..1000 ms"
                }
            );
        }
    }

    #[test]
    fn refused_change_names_the_field_and_keeps_the_config() {
        let cfg = ValidatedConfig::factory();
        let lower = find("limits.lower").unwrap();
        let e = apply(&cfg, lower, Metres::lit("0.405").to_bits().into()).unwrap_err();
        assert_eq!(
            e,
            ConfigError::Conflict {
                field: "limits.lower",
                reason: "must be at least 10 mm below limits.upper"
            }
        );
        let ramp = find("motion.ramp_ms").unwrap();
        let e = apply(&cfg, ramp, -1).unwrap_err();
        assert_eq!(
            e,
            ConfigError::OutOfRange {
                field: "motion.ramp_ms",
                range: "10..2000 ms"
            }
        );
    }
}
