//! Values with units as a person types them (`410mm`, `0.41 m`, `45A`, `50%`), converted exactly
//! to a setting's raw bits and back, in 64-bit integers only (no float or 128-bit code on the board).
//!
//! A number is `[+-]digits[.digits][e[+-]digits]`, at most 18 significant digits; the unit
//! follows, with or without a space, case-insensitive. Conversion rounds to the nearest
//! raw value (ties away from zero); integer settings refuse fractions. Formatting prints the
//! shortest decimal that converts back to the same bits, so `get` → `set` is exact.

use crate::config::settings::{Kind, Unit};
use crate::text::ten_to;
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
    /// More than [`MAX_DIGITS`] significant digits.
    TooManyDigits,
    /// Not one of the setting's choices.
    NotAChoice,
}

impl ValueError {
    /// The message (its `Display`).
    pub fn message(&self) -> &'static str {
        match self {
            ValueError::Missing => "no value given",
            ValueError::NotANumber => "not a number",
            ValueError::WrongUnit => "unit not accepted",
            ValueError::NotWhole => "must be a whole number",
            ValueError::TooLarge => "far outside the range",
            ValueError::TooManyDigits => "more than 18 significant digits",
            ValueError::NotAChoice => "not one of the choices",
        }
    }
}

impl fmt::Display for ValueError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.message())
    }
}

/// A decimal `±mant·10^exp`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Decimal {
    neg: bool,
    mant: u64,
    exp: i32,
}

/// Most significant digits a typed number may have (`10^18 − 1` fits the `u64` mantissa with
/// room for the conversion's doubling).
pub const MAX_DIGITS: u32 = 18;

/// `m·10^k`, `None` if it exceeds `u64` (checked steps of ×10: for `m ≥ 1` at most 20 rounds
/// before it overflows).
fn times_ten_to(m: u64, k: u32) -> Option<u64> {
    let mut v = m;
    for _ in 0..k {
        v = v.checked_mul(10)?;
    }
    Some(v)
}

/// Split `text` into a decimal and the unit text after it.
fn parse_decimal(text: &[u8]) -> Result<(Decimal, &[u8]), ValueError> {
    let b = text;
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
    let mut mant: u64 = 0;
    let mut digits = 0u32;
    // Zeros after the first significant digit, not yet in `mant` (trailing zeros of "400.000"
    // go to the exponent instead and do not count against MAX_DIGITS).
    let mut zeros = 0u32;
    let mut exp: i32 = 0;
    let mut seen_digit = false;
    let mut seen_point = false;
    while let Some(&c) = b.get(i) {
        match c {
            b'0'..=b'9' => {
                seen_digit = true;
                if seen_point {
                    exp -= 1;
                }
                if c == b'0' {
                    if mant != 0 {
                        zeros += 1;
                    }
                } else {
                    digits += zeros + 1;
                    if digits > MAX_DIGITS {
                        return Err(ValueError::TooManyDigits);
                    }
                    // < 10^18 by the digit count: no overflow.
                    mant = mant * ten_to(zeros + 1).unwrap_or(0) + u64::from(c - b'0');
                    zeros = 0;
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
    // At most 96 characters in a line: no overflow.
    exp += zeros as i32;
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
    let unit = b.get(i..).ok_or(ValueError::NotANumber)?.trim_ascii();
    Ok((Decimal { neg, mant, exp }, unit))
}

/// `floor(m·2^bits / 10^j)` and whether the division was exact, in `u64` (binary long division:
/// the remainder stays below `10^18`); `None` if the quotient does not fit.
fn shl_div_pow10(m: u64, bits: u32, j: u32) -> Option<(u64, bool)> {
    // ≤ 10^18: fits (and is never 0).
    let d = ten_to(j.min(18)).unwrap_or(1);
    let (mut q, mut r) = (m / d, m % d);
    for _ in 0..bits {
        q = q.checked_mul(2)?;
        r *= 2;
        if r >= d {
            r -= d;
            q += 1;
        }
    }
    if j <= 18 {
        return Some((q, r == 0));
    }
    // floor(floor(x/a)/b) = floor(x/(a·b)).
    Some(match ten_to(j - 18) {
        Some(d) => (q / d, r == 0 && q % d == 0),
        None => (0, r == 0 && q == 0),
    })
}

/// `m·10^k·2^frac`, rounded to nearest (ties away from zero) when `k < 0`, and whether that was
/// exact; `None` if it exceeds `u64`.
fn to_raw(m: u64, k: i32, frac: u32) -> Option<(u64, bool)> {
    if m == 0 {
        return Some((0, true));
    }
    if k >= 0 {
        // m ≥ 1: past 10^19 this overflows as `ten_to` did.
        let v = times_ten_to(m, k.unsigned_abs())?;
        // `v·2^frac` fits when no set bit is shifted out.
        if frac >= 64 || v.leading_zeros() < frac {
            return None;
        }
        return Some((v << frac, true));
    }
    // round(x) = floor((floor(2x) + 1)/2) for x ≥ 0; x is an integer iff 2x is an even one.
    let (t, exact) = shl_div_pow10(m, frac + 1, k.unsigned_abs())?;
    Some((t / 2 + (t & 1), exact && t & 1 == 0))
}

fn unit_pow(unit: &Unit, text: &[u8]) -> Option<i32> {
    if text.is_empty() || text.eq_ignore_ascii_case(unit.display().as_bytes()) {
        return Some(0);
    }
    unit.accepts()
        .find(|(s, _)| s.as_bytes().eq_ignore_ascii_case(text))
        .map(|(_, p)| p)
}

fn is_none_word(text: &[u8]) -> bool {
    ["none", "off", "inf", "never"]
        .iter()
        .any(|w| w.as_bytes().eq_ignore_ascii_case(text))
}

/// Parse `text` as a value of `kind` into raw bits (no range check beyond the raw type's
/// magnitude: [`crate::config::settings::apply`] checks the field's type and range). Text is
/// taken as bytes (a `&str` or a line's `&[u8]`): the console parses lines without converting
/// them to `str` (see [`crate::text::is_utf8`]).
pub fn parse(kind: &Kind, text: &(impl AsRef<[u8]> + ?Sized)) -> Result<i64, ValueError> {
    parse_bytes(kind, text.as_ref())
}

fn parse_bytes(kind: &Kind, text: &[u8]) -> Result<i64, ValueError> {
    let text = text.trim_ascii();
    if text.is_empty() {
        return Err(ValueError::Missing);
    }
    match kind {
        Kind::Choice(names) => names
            .iter()
            .position(|n| n.as_bytes().eq_ignore_ascii_case(text))
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
            let (mag, exact) = to_raw(d.mant, d.exp + p - i32::from(*pow10), u32::from(*frac))
                .ok_or(ValueError::TooLarge)?;
            if *frac == 0 && !exact {
                return Err(ValueError::NotWhole);
            }
            let raw = if d.neg {
                0i64.checked_sub_unsigned(mag)
            } else {
                i64::try_from(mag).ok()
            };
            raw.ok_or(ValueError::TooLarge)
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
            write_shortest(out, raw, u32::from(*frac), i32::from(*pow10))?;
            let display = unit.display();
            if !display.is_empty() {
                out.write_char(' ')?;
                out.write_str(display)?;
            }
            Ok(())
        }
    }
}

/// The shortest decimal (0…12 fractional digits) that parses back to `raw`, in `u64`: the
/// integer part, then fraction digits generated one by one from the remainder (`< 2^frac`).
///
/// With `s = |raw|·10^pow10` (the value in display units times `2^frac`) split into the integer
/// part `ip` and `fr < 2^frac`, `n` digits are `D = floor(fr·10^n/2^frac)` with remainder `rem`,
/// rounded up when `2·rem ≥ 2^frac`. Read back, that decimal is `|raw| + e` raw units with
/// `e = −rem/10^(n+pow10)` (down) or `(2^frac − rem)/10^(n+pow10)` (up), and the parser's
/// rounding returns `|raw|` exactly when `−½ ≤ e < ½`.
fn write_shortest(out: &mut dyn Write, raw: i64, frac: u32, pow10: i32) -> fmt::Result {
    // |raw|·10^pow10 by checked steps of ×10 (a 64-bit multiply by a variable with its
    // overflow check is more code on the board); `ten_to`'s limit, 10^19, kept.
    let Some(s) = u32::try_from(pow10)
        .ok()
        .filter(|&k| k < 20)
        .and_then(|k| times_ten_to(raw.unsigned_abs(), k))
        .filter(|_| frac <= 40)
    else {
        // No registry kind gets here (pow10 ≥ 0, small values): the tests cover every key.
        return out.write_str("?");
    };
    let one = 1u64 << frac;
    let mut ip = s >> frac;
    let mut rem = s & (one - 1);
    // The fraction digits as text (no 64-bit digit arithmetic, no division to strip zeros).
    let mut digits = [b'0'; 12];
    let mut n = 0usize;
    let mut up;
    loop {
        up = 2 * rem >= one;
        // n ≤ 12 and pow10 ≤ 3 here: fits.
        let tol = ten_to(n as u32 + pow10 as u32).unwrap_or(u64::MAX);
        let fits = if up {
            2 * (one - rem) < tol
        } else {
            2 * rem <= tol
        };
        let Some(d) = digits.get_mut(n).filter(|_| !fits) else {
            break;
        };
        // rem < 2^frac ≤ 2^40: rem·10 fits, and the digit is below 10.
        let t = rem * 10;
        *d = b'0' + (t >> frac) as u8;
        rem = t & (one - 1);
        n += 1;
    }
    if up {
        // Round the last digit up, carrying through nines into the integer part.
        let mut carry = true;
        for d in digits.iter_mut().take(n).rev() {
            if *d == b'9' {
                *d = b'0';
            } else {
                *d += 1;
                carry = false;
                break;
            }
        }
        if carry {
            ip += 1;
        }
    }
    while n > 0 && digits.get(n - 1) == Some(&b'0') {
        n -= 1;
    }
    if raw < 0 && (ip != 0 || n != 0) {
        out.write_char('-')?;
    }
    crate::text::uint(out, ip)?;
    if n > 0 {
        out.write_char('.')?;
        crate::text::ascii(out, digits.get(..n).unwrap_or(&[]))?;
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
    use std::vec::Vec;

    /// The i128 implementation this module had before it moved to 64-bit arithmetic (24
    /// significant digits), kept as the twin the 64-bit one is checked against.
    mod reference {
        use super::super::ValueError;
        use core::fmt::{self, Write};

        /// A decimal `mant·10^exp`.
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        pub struct Decimal {
            pub mant: i128,
            pub exp: i32,
        }

        /// Split `text` into a decimal and the unit text after it.
        pub fn parse_decimal(text: &str) -> Result<(Decimal, &str), ValueError> {
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
        pub fn scale10(v: i128, p: i32) -> Option<(i128, bool)> {
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
        pub fn div_round(n: i128, d: i128) -> (i128, bool) {
            let q = n / d;
            let r = n % d;
            let exact = r == 0;
            if r.unsigned_abs() * 2 >= d.unsigned_abs() {
                (if n < 0 { q - 1 } else { q + 1 }, exact)
            } else {
                (q, exact)
            }
        }

        pub fn write_shortest(out: &mut dyn Write, raw: i64, frac: u32, pow10: i32) -> fmt::Result {
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

        /// The old `parse` of a number (no `none` words).
        pub fn parse(frac: u32, pow10: i32, p: i32, d: Decimal) -> Result<i64, ValueError> {
            let k = d.exp + p - pow10;
            let shifted = d
                .mant
                .checked_mul(1i128 << frac)
                .ok_or(ValueError::TooLarge)?;
            let (raw, exact) = scale10(shifted, k).ok_or(ValueError::TooLarge)?;
            if frac == 0 && !exact {
                return Err(ValueError::NotWhole);
            }
            i64::try_from(raw).map_err(|_| ValueError::TooLarge)
        }
    }

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

    #[test]
    fn more_than_18_significant_digits_are_refused_but_zeros_do_not_count() {
        let k = kind("friction.rate");
        assert_eq!(
            parse(k, "1234567.890123456789"),
            Err(ValueError::TooManyDigits)
        );
        assert_eq!(
            parse(k, "1234567.8901234567"),
            reference_parse(k, "1234567.8901234567")
        );
        let up = kind("limits.upper");
        let want = crate::units::Metres::lit("0.41").to_bits() as i64;
        assert_eq!(parse(up, "410.000000000000000000000mm"), Ok(want));
        assert_eq!(parse(up, "0.000000000000000000000410e24mm"), Ok(want));
        assert_eq!(
            format!("{}", ValueError::TooManyDigits),
            "more than 18 significant digits"
        );
    }

    /// The i128 twin's result for `text` (same unit handling as [`parse`]).
    fn reference_parse(kind: &Kind, text: &str) -> Result<i64, ValueError> {
        let Kind::Number {
            frac, pow10, unit, ..
        } = kind
        else {
            return parse(kind, text);
        };
        let text = text.trim();
        if text.is_empty() {
            return Err(ValueError::Missing);
        }
        let (d, unit_text) = reference::parse_decimal(text)?;
        let p = unit_pow(unit, unit_text.as_bytes()).ok_or(ValueError::WrongUnit)?;
        reference::parse(u32::from(*frac), i32::from(*pow10), p, d)
    }

    /// Number settings only, by registry index.
    fn number_kinds() -> std::vec::Vec<usize> {
        SETTINGS
            .iter()
            .enumerate()
            .filter(|(_, s)| matches!(s.kind, Kind::Number { .. }))
            .map(|(i, _)| i)
            .collect()
    }

    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 3000, ..ProptestConfig::default() })]

        /// Any number of up to 18 significant digits (with a point anywhere, an exponent, any
        /// unit the setting takes) converts to the same raw bits, or the same refusal, as the
        /// i128 twin.
        #[test]
        fn parse_matches_the_i128_twin(
            index in proptest::sample::select(number_kinds()),
            neg in any::<bool>(),
            digits in "[0-9]{1,18}",
            point in 0usize..=18,
            exp in proptest::option::of(-45i32..45),
            unit in any::<proptest::sample::Index>(),
        ) {
            let k = &SETTINGS[index].kind;
            let Kind::Number { unit: u, .. } = k else { unreachable!() };
            let mut t = String::new();
            if neg {
                t.push('-');
            }
            let point = point.min(digits.len());
            t.push_str(&digits[..point]);
            t.push('.');
            t.push_str(&digits[point..]);
            if let Some(e) = exp {
                t.push_str(&format!("e{e}"));
            }
            // The display unit (empty: none) or one of the other accepted suffixes.
            let suffixes: Vec<&str> =
                core::iter::once(u.display()).chain(u.accepts().map(|a| a.0)).collect();
            t.push_str(suffixes[unit.index(suffixes.len())]);
            // Zero is zero at any exponent (the twin overflowed on 0e40).
            let want = if digits.bytes().all(|b| b == b'0') {
                Ok(0)
            } else {
                reference_parse(k, &t)
            };
            prop_assert_eq!(parse(k, &t), want, "{}", t);
        }

        /// Every value a setting can hold within the console's 18 digits prints as the i128
        /// twin printed it: 32-bit fields any pattern, the I32F32 ones below 10⁷ (7 integer
        /// digits and the 10 fractional ones 2^−32 needs), which bounds every valid setting.
        #[test]
        fn format_matches_the_i128_twin(
            index in proptest::sample::select(number_kinds()),
            bits in any::<i64>(),
            width in 0..3u8,
        ) {
            let s = &SETTINGS[index];
            let Kind::Number { frac, pow10, .. } = s.kind else { unreachable!() };
            let (frac, pow10) = (u32::from(frac), i32::from(pow10));
            let raw = match width {
                0 => i64::from(bits as i32),
                1 => i64::from(bits as u32),
                _ if frac == 32 => bits % (10_000_000i64 << 32),
                _ => i64::from(bits as i32),
            };
            let mut mine = String::new();
            write_shortest(&mut mine, raw, frac, pow10).unwrap();
            let mut twin = String::new();
            reference::write_shortest(&mut twin, raw, frac, pow10).unwrap();
            prop_assert_eq!(&mine, &twin, "{} raw {}", s.key, raw);
            prop_assert_eq!(parse(&s.kind, &mine), Ok(raw), "{} {}", s.key, mine);
        }
    }
}
