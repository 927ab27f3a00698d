//! Units and choices: how a setting's raw bits read as a value, and what a person types.

/// A unit a value is typed and shown in: its display unit, what it measures and the other
/// suffixes it accepts, packed in one text (`display|what|suffix=power|…`; one reference per
/// unit instead of three, and no table of (suffix, power) pairs).
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
/// reference keeps the registry's entries small.
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

/// A choice setting's names, by position in `CHOICES`; reads as the names (`Deref`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChoiceId(pub(super) u8);

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
        /// Fractional bits of the field's Q format (0 for integers). (`u8`/`i8` keep the
        /// registry's entries small.)
        frac: u8,
        /// Display unit per base unit as a power of ten (mm per m: 3).
        pow10: i8,
        /// Unit for parsing and display.
        unit: UnitId,
        /// The field's largest value means "no limit" (typed and shown as `none`).
        none_at_max: bool,
    },
    /// An index into the names. (An id of one byte keeps the kind,
    /// and so each registry entry, small.)
    Choice(ChoiceId),
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
