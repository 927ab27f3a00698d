//! The configuration's fields as the registry reaches them: one `&mut` access, typed by how
//! its raw bits read and write, for both directions.

use super::*;

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
        pub(super) enum Slot<'a> {
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
            pub(super) fn read(&self) -> i64 {
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
            pub(super) fn write(self, raw: i64) -> bool {
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

pub(super) use {field_slot, field_stored};

#[cfg(test)]
mod tests {
    use super::*;

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
    fn every_setting_writes_back_what_it_reads() {
        let c = ControlConfig::DEFAULT;
        for s in SETTINGS.iter() {
            let mut d = c;
            assert!(s.set(&mut d, s.get(&c)), "{}", s.key);
            assert_eq!(d, c, "{}", s.key);
        }
    }
}
