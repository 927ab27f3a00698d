//! Values with units as a person types them (`410mm`, `0.41 m`, `45A`, `50%`), converted exactly
//! to a setting's raw bits and back, in integers only (no float code on the board).
//!
//! A number is `[+-]digits[.digits][e[+-]digits]`, at most 24 significant digits; the unit
//! follows, with or without a space, case-insensitive. Conversion rounds to the nearest
//! raw value (ties away from zero); integer settings refuse fractions. Formatting prints the
//! shortest decimal that converts back to the same bits, so `get` → `set` is exact.

use crate::config::settings::{Kind, Unit};
use core::fmt::{self, Write};

/// Why a value was refused before any range check.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ValueError {
    /// Nothing given.
    Missing,
    /// Not a number.
    NotANumber,
    /// A unit this setting does not take.
    WrongUnit,
    /// A fraction for a whole-number setting.
    NotWhole,
    /// Too large or too precise to represent at all.
    TooLarge,
    /// Not one of the setting's choices.
    NotAChoice,
}

impl fmt::Display for ValueError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ValueError::Missing => "no value given",
            ValueError::NotANumber => "not a number",
            ValueError::WrongUnit => "unit not accepted",
            ValueError::NotWhole => "must be a whole number",
            ValueError::TooLarge => "far outside the range",
            ValueError::NotAChoice => "not one of the choices",
        })
    }
}

/// A decimal `mant·10^exp`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Decimal {
    mant: i128,
    exp: i32,
}

/// Split `text` into a decimal and the unit text after it.
fn parse_decimal(text: &str) -> Result<(Decimal, &str), ValueError> {
    let b = text.as_bytes();
    let mut i = 0;
    let neg = match b.first() {
        Some(b'-') => {
            i += 1;
            true
        }
        Some(b'+') => {
            i += 1;
            false
        }
        _ => false,
    };
    let mut mant: i128 = 0;
    let mut digits = 0u32;
    let mut exp: i32 = 0;
    let mut seen_digit = false;
    let mut seen_point = false;
    while let Some(&c) = b.get(i) {
        match c {
            b'0'..=b'9' => {
                seen_digit = true;
                if mant != 0 || c != b'0' {
                    digits += 1;
                }
                if digits > 24 {
                    return Err(ValueError::TooLarge);
                }
                mant = mant * 10 + i128::from(c - b'0');
                if seen_point {
                    exp -= 1;
                }
            }
            b'.' if !seen_point => seen_point = true,
            b'_' => {}
            _ => break,
        }
        i += 1;
    }
    if !seen_digit {
        return Err(ValueError::NotANumber);
    }
    // Exponent, only if digits follow the `e` (so "1em" is not swallowed; no unit starts with e).
    if matches!(b.get(i), Some(b'e' | b'E')) {
        let mut j = i + 1;
        let eneg = match b.get(j) {
            Some(b'-') => {
                j += 1;
                true
            }
            Some(b'+') => {
                j += 1;
                false
            }
            _ => false,
        };
        let start = j;
        let mut e: i32 = 0;
        while let Some(&c) = b.get(j) {
            if !c.is_ascii_digit() {
                break;
            }
            e = e.saturating_mul(10).saturating_add(i32::from(c - b'0'));
            j += 1;
        }
        if j > start {
            if e > 60 {
                return Err(ValueError::TooLarge);
            }
            exp += if eneg { -e } else { e };
            i = j;
        }
    }
    let unit = text.get(i..).ok_or(ValueError::NotANumber)?.trim();
    Ok((
        Decimal {
            mant: if neg { -mant } else { mant },
            exp,
        },
        unit,
    ))
}

/// `v·10^p`, rounded to nearest (ties away from zero) when `p < 0`; `None` on overflow.
fn scale10(v: i128, p: i32) -> Option<(i128, bool)> {
    if p >= 0 {
        let f = 10i128.checked_pow(p as u32)?;
        return v.checked_mul(f).map(|r| (r, true));
    }
    let Some(f) = 10i128.checked_pow(p.unsigned_abs()) else {
        // Divisor beyond i128: |v| < 10^25 so the quotient rounds to zero.
        return Some((0, v == 0));
    };
    Some(div_round(v, f))
}

/// `n/d` rounded to nearest, ties away from zero, and whether it was exact (`d > 0`).
fn div_round(n: i128, d: i128) -> (i128, bool) {
    let q = n / d;
    let r = n % d;
    let exact = r == 0;
    if r.unsigned_abs() * 2 >= d.unsigned_abs() {
        (if n < 0 { q - 1 } else { q + 1 }, exact)
    } else {
        (q, exact)
    }
}

fn unit_pow(unit: &Unit, text: &str) -> Option<i32> {
    if text.is_empty() || text.eq_ignore_ascii_case(unit.display) {
        return Some(0);
    }
    unit.accepts
        .iter()
        .find(|(s, _)| s.eq_ignore_ascii_case(text))
        .map(|&(_, p)| p)
}

fn is_none_word(text: &str) -> bool {
    ["none", "off", "inf", "never"]
        .iter()
        .any(|w| w.eq_ignore_ascii_case(text))
}

/// Parse `text` as a value of `kind` into raw bits (no range check beyond the raw type's
/// magnitude: [`crate::config::settings::apply`] checks the field's type and range).
pub fn parse(kind: &Kind, text: &str) -> Result<i64, ValueError> {
    let text = text.trim();
    if text.is_empty() {
        return Err(ValueError::Missing);
    }
    match kind {
        Kind::Choice(names) => names
            .iter()
            .position(|n| n.eq_ignore_ascii_case(text))
            .map(|i| i as i64)
            .ok_or(ValueError::NotAChoice),
        Kind::Number {
            frac,
            pow10,
            unit,
            none_at_max,
        } => {
            if *none_at_max && is_none_word(text) {
                return Ok(i64::MAX);
            }
            let (d, unit_text) = parse_decimal(text)?;
            let p = unit_pow(unit, unit_text).ok_or(ValueError::WrongUnit)?;
            // raw = mant·10^(exp + p − pow10)·2^frac
            let k = d.exp + p - pow10;
            let shifted = d
                .mant
                .checked_mul(1i128 << frac)
                .ok_or(ValueError::TooLarge)?;
            let (raw, exact) = scale10(shifted, k).ok_or(ValueError::TooLarge)?;
            if *frac == 0 && !exact {
                return Err(ValueError::NotWhole);
            }
            i64::try_from(raw).map_err(|_| ValueError::TooLarge)
        }
    }
}

/// Write `raw` of `kind` as a person reads it (`410 mm`, `0.218`, `trapezoid`, `none`).
pub fn format(out: &mut dyn Write, kind: &Kind, raw: i64) -> fmt::Result {
    match kind {
        Kind::Choice(names) => match usize::try_from(raw).ok().and_then(|i| names.get(i)) {
            Some(n) => out.write_str(n),
            None => out.write_str("custom"),
        },
        Kind::Number {
            frac,
            pow10,
            unit,
            none_at_max,
        } => {
            if *none_at_max && raw == i64::MAX {
                return out.write_str("none");
            }
            write_shortest(out, raw, *frac, *pow10)?;
            if !unit.display.is_empty() {
                out.write_char(' ')?;
                out.write_str(unit.display)?;
            }
            Ok(())
        }
    }
}

/// The shortest decimal (0…12 fractional digits) that parses back to `raw`.
fn write_shortest(out: &mut dyn Write, raw: i64, frac: u32, pow10: i32) -> fmt::Result {
    let raw = i128::from(raw);
    let one = 1i128 << frac;
    let mut best = None;
    for n in 0..=12i32 {
        // q = round(raw·10^(pow10+n)/2^frac), back = round(q·2^frac/10^(pow10+n)).
        let Some((scaled, _)) = scale10(raw, pow10 + n) else {
            break;
        };
        let (q, _) = div_round(scaled, one);
        let Some(qs) = q.checked_mul(one) else {
            break;
        };
        let Some((back, _)) = scale10(qs, -(pow10 + n)) else {
            break;
        };
        best = Some((q, n));
        if back == raw {
            break;
        }
    }
    let Some((q, n)) = best else {
        return out.write_str("?");
    };
    if q < 0 {
        out.write_char('-')?;
    }
    let mag = q.unsigned_abs();
    let div = 10u128.pow(n as u32);
    write!(out, "{}", mag / div)?;
    if n > 0 {
        let mut f = mag % div;
        let mut digits = [b'0'; 12];
        for k in (0..n as usize).rev() {
            digits[k] = b'0' + (f % 10) as u8;
            f /= 10;
        }
        let mut len = n as usize;
        while len > 0 && digits[len - 1] == b'0' {
            len -= 1;
        }
        if len > 0 {
            out.write_char('.')?;
            for &d in &digits[..len] {
                out.write_char(char::from(d))?;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::settings::{find, SETTINGS};
    use crate::control::config::ControlConfig;
    extern crate std;
    use std::string::String;

    fn kind(key: &str) -> &'static Kind {
        &find(key).unwrap().setting().kind
    }

    fn show(key: &str, raw: i64) -> String {
        let mut s = String::new();
        format(&mut s, kind(key), raw).unwrap();
        s
    }

    #[test]
    fn lengths_take_mm_m_and_cm_in_any_case_with_or_without_space() {
        let k = kind("limits.upper");
        let want = crate::units::Metres::lit("0.41").to_bits() as i64;
        for t in [
            "410mm", "410 mm", "0.41m", "0.41 M", "41cm", "410", "4.1e2mm", " 410MM ",
        ] {
            assert_eq!(parse(k, t), Ok(want), "{t}");
        }
        assert_eq!(parse(k, "410 kg"), Err(ValueError::WrongUnit));
        assert_eq!(parse(k, "mm"), Err(ValueError::NotANumber));
        assert_eq!(parse(k, ""), Err(ValueError::Missing));
    }

    #[test]
    fn integer_settings_refuse_fractions_and_take_seconds() {
        let k = kind("motion.ramp_ms");
        assert_eq!(parse(k, "200ms"), Ok(200));
        assert_eq!(parse(k, "0.2 s"), Ok(200));
        assert_eq!(parse(k, "200.5ms"), Err(ValueError::NotWhole));
        assert_eq!(parse(k, "1e30"), Err(ValueError::TooLarge));
    }

    #[test]
    fn defaults_print_as_typed() {
        let c = ControlConfig::DEFAULT;
        let get = |key: &str| show(key, find(key).unwrap().setting().get(&c));
        assert_eq!(get("limits.upper"), "410 mm");
        assert_eq!(get("motion.cruise_speed"), "3 rad/s");
        assert_eq!(get("protect.overcurrent"), "45 A");
        assert_eq!(get("protect.supply_run_min"), "9.5 V");
        assert_eq!(get("friction.base"), "0.218");
        assert_eq!(get("friction.slope"), "-0.000447");
        assert_eq!(get("friction.s_max"), "none");
        assert_eq!(get("motion.ramp_shape"), "trapezoid");
        assert_eq!(get("friction.law"), "dry");
        assert_eq!(get("drive.pitch_radius"), "4.265 mm");
    }

    #[test]
    fn every_default_formats_and_parses_back_exactly() {
        let c = ControlConfig::DEFAULT;
        for s in SETTINGS.iter() {
            let raw = s.get(&c);
            let mut t = String::new();
            format(&mut t, &s.kind, raw).unwrap();
            assert_eq!(parse(&s.kind, &t), Ok(raw), "{} {t}", s.key);
        }
    }
}
