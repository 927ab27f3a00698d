//! Numbers as text for the console and the messages, without `core::fmt`'s formatting
//! machinery.
//!
//! Every reply and message of the core is written with `write_str` and these few functions
//! into a [`core::fmt::Write`] sink, never with `write!`: `write!` builds `fmt::Arguments` at
//! each call site and links `core::fmt::write`, `Formatter::pad_integral`, the `Display` impls
//! of the integer types and their padding code, much code on the board for what is
//! only integers in decimal and one hex word. The output is the same as `write!`'s
//! (`{}`, `{:0w$}`, `{:08x}`); the tests below compare them.

use crate::units::Metres;
use core::fmt::{self, Write};

/// `v` in decimal, zero-padded to at least `width` digits (`{v:0width$}` for `width ≤ 20`;
/// a larger `width` pads to 20 only).
pub fn uint_padded(out: &mut dyn Write, mut v: u64, width: usize) -> fmt::Result {
    // u64::MAX has 20 digits; a wider `width` is never asked for (the widths are 1…12).
    let mut buf = [0u8; 20];
    let mut n = 0;
    for slot in buf.iter_mut().rev() {
        // `v % 10 < 10`: the cast is exact.
        *slot = b'0' + (v % 10) as u8;
        v /= 10;
        n += 1;
        if v == 0 && n >= width {
            break;
        }
    }
    ascii(out, buf.get(buf.len() - n..).unwrap_or(&[]))
}

/// `v` in decimal (`{v}`).
pub fn uint(out: &mut dyn Write, v: u64) -> fmt::Result {
    decimal(out, v, 0)
}

/// `v·10^−dec` in decimal: the whole part, and for `dec > 0` a point and `dec` digits
/// (`{}.{:0dec$}` of `v / 10^dec` and `v % 10^dec`, for `dec ≤ 19`). One digit loop for both
/// parts: no division by `10^dec`.
pub fn decimal(out: &mut dyn Write, mut v: u64, dec: usize) -> fmt::Result {
    let mut buf = [0u8; 20];
    let mut n = 0;
    for slot in buf.iter_mut().rev() {
        // `v % 10 < 10`: the cast is exact.
        *slot = b'0' + (v % 10) as u8;
        v /= 10;
        n += 1;
        if v == 0 && n > dec {
            break;
        }
    }
    let digits = buf.get(buf.len() - n..).unwrap_or(&[]);
    let (whole, frac) = digits
        .split_at_checked(n.saturating_sub(dec))
        .unwrap_or((digits, &[]));
    ascii(out, whole)?;
    if dec == 0 {
        return Ok(());
    }
    out.write_char('.')?;
    ascii(out, frac)
}

/// `v` in decimal with a `-` when negative (`{v}`).
pub fn int(out: &mut dyn Write, v: i64) -> fmt::Result {
    if v < 0 {
        out.write_char('-')?;
    }
    uint(out, v.unsigned_abs())
}

/// `v` as 8 lower-case hex digits (`{v:08x}`).
pub fn hex8(out: &mut dyn Write, v: u32) -> fmt::Result {
    let mut buf = [0u8; 8];
    for (i, slot) in buf.iter_mut().enumerate() {
        // A nibble: the cast is exact.
        let d = ((v >> (28 - 4 * i)) & 0xF) as u8;
        *slot = if d < 10 { b'0' + d } else { b'a' + d - 10 };
    }
    ascii(out, &buf)
}

/// ASCII text (digits, at most 20) as it is, in one `write_str` (a sink that is full takes
/// none of it). Copied char by char into a string rather than checked by `core::str::from_utf8`:
/// the firmware links no `from_utf8` (and its table; see [`is_utf8`]).
pub(crate) fn ascii(out: &mut dyn Write, digits: &[u8]) -> fmt::Result {
    let mut s = heapless::String::<20>::new();
    for &d in digits {
        // Masked to ASCII, so each char is one byte (no UTF-8 encoding linked).
        s.push(char::from(d & 0x7F)).map_err(|_| fmt::Error)?;
    }
    out.write_str(&s)
}

/// The first char of `b` and the bytes after it, if `b` starts with a well-formed UTF-8
/// sequence, by the rules `core::str::from_utf8` checks (no overlong form, no surrogate, at
/// most U+10FFFF; the tests compare the two on every short sequence).
pub fn next_char(b: &[u8]) -> Option<(char, &[u8])> {
    let (&first, mut rest) = b.split_first()?;
    // Continuation bytes after the first, and the least value that needs that many.
    let (n, min) = match first {
        0x00..=0x7F => return Some((char::from(first), rest)),
        0xC2..=0xDF => (1, 0x80),
        0xE0..=0xEF => (2, 0x800),
        0xF0..=0xF4 => (3, 0x1_0000),
        _ => return None,
    };
    let mut v = u32::from(first) & (0x3F >> n);
    for _ in 0..n {
        let (&c, tail) = rest.split_first()?;
        if c & 0xC0 != 0x80 {
            return None;
        }
        v = v << 6 | u32::from(c & 0x3F);
        rest = tail;
    }
    if v < min {
        return None;
    }
    // Refuses surrogates and values above U+10FFFF.
    char::from_u32(v).map(|c| (c, rest))
}

/// Whether `b` is valid UTF-8 (`core::str::from_utf8(b).is_ok()`, without linking it: the
/// console checks its lines with this and parses them as bytes).
pub fn is_utf8(mut b: &[u8]) -> bool {
    while !b.is_empty() {
        match next_char(b) {
            Some((_, rest)) => b = rest,
            None => return false,
        }
    }
    true
}

/// Words of a line as the user typed them, for messages: UTF-8 kept as bytes. The console's parser checks
/// a line with [`is_utf8`] and then works on its bytes, so the firmware links no
/// `core::str::from_utf8` (and its table). Made only from a checked line or
/// a `&str` (`From`), so it is always valid UTF-8; `Debug` shows it as the `&str` it is.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Words<'a>(pub(crate) &'a [u8]);

impl<'a> Words<'a> {
    /// The bytes (valid UTF-8).
    pub fn as_bytes(self) -> &'a [u8] {
        self.0
    }
}

impl<'a> From<&'a str> for Words<'a> {
    fn from(s: &'a str) -> Self {
        Words(s.as_bytes())
    }
}

impl fmt::Debug for Words<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match core::str::from_utf8(self.0) {
            Ok(s) => fmt::Debug::fmt(s, f),
            // Not made by this module (its words are checked): shown as bytes.
            Err(_) => fmt::Debug::fmt(self.0, f),
        }
    }
}

/// At most 24 characters of user text in a message (the rest as `...`), char by char (the
/// words are bytes, see [`Words`]).
fn clip(out: &mut dyn Write, s: Words<'_>) -> fmt::Result {
    let mut rest = s.0;
    let mut n = 0;
    while let Some((c, tail)) = next_char(rest) {
        if n == 24 {
            return out.write_str("...");
        }
        // A control character is shown, not sent: a terminal would act on ESC, BEL, NUL.
        match u8::try_from(c) {
            Ok(b) if b < 0x20 || (0x7F..0xA0).contains(&b) => escape(out, b)?,
            _ => out.write_char(c)?,
        }
        n += 1;
        rest = tail;
    }
    Ok(())
}

/// A byte as `\xNN` (upper-case hex), for control characters in replies.
pub(crate) fn escape(out: &mut dyn Write, b: u8) -> fmt::Result {
    const HEX: &[u8; 16] = b"0123456789ABCDEF";
    out.write_str("\\x")?;
    out.write_char(char::from(HEX[usize::from(b >> 4)]))?;
    out.write_char(char::from(HEX[usize::from(b & 15)]))
}

/// A height for a reply: in mm (the caller writes the unit) if the position is known, else
/// `unknown` (an unhomed board's height is its homing assumption, not the head's).
pub(crate) fn height_arg(h: Metres, homed: bool) -> Arg<'static> {
    if homed {
        Arg::Mm(h)
    } else {
        Arg::Str("unknown")
    }
}

/// One value in a reply template ([`fill`]).
#[derive(Clone, Copy, Debug)]
pub(crate) enum Arg<'a> {
    /// Text as it is.
    Str(&'a str),
    /// A name as one `key=value` word ([`write_word`]).
    Word(&'a str),
    /// User text, at most 24 characters of it ([`clip`]).
    Clip(Words<'a>),
    /// An unsigned integer in decimal.
    Uint(u32),
    /// A fixed-point value: its bits, fractional bits and the decimals shown
    /// ([`fixed_decimal`]).
    Fixed(i32, u8, u8),
    /// A height in mm with one decimal.
    Mm(Metres),
    /// An integer count of 10^−d units with `d` decimals (`Deci(-5, 1)`: `-0.5`).
    Deci(i32, u8),
}

/// The placeholder in a [`fill`] template.
pub(crate) const SLOT: u8 = 0x01;

/// `template` with each [`SLOT`] byte replaced by the next of `args` (a slot without an
/// argument writes nothing). One call with one string per reply instead of a `write_str` per
/// piece: a reply is data (its template and arguments), not a sequence of calls.
pub(crate) fn fill(out: &mut dyn Write, template: &str, args: &[Arg<'_>]) -> fmt::Result {
    let mut args = args.iter();
    let mut rest = template;
    loop {
        // SLOT is ASCII: the split is at a char boundary (checked, so that no panic is linked).
        let Some((piece, tail)) = rest
            .bytes()
            .position(|b| b == SLOT)
            .and_then(|i| rest.split_at_checked(i))
        else {
            return out.write_str(rest);
        };
        out.write_str(piece)?;
        // A number as its count of 10^−dec and dec.
        let number = match args.next() {
            Some(Arg::Str(t)) => out.write_str(t).map(|_| None)?,
            Some(Arg::Word(t)) => write_word(out, t).map(|_| None)?,
            Some(&Arg::Clip(t)) => clip(out, t).map(|_| None)?,
            Some(&Arg::Uint(v)) => Some((i64::from(v), 0)),
            Some(&Arg::Fixed(bits, frac, dec)) => Some((
                fixed_decimal(bits, u32::from(frac), u32::from(dec)),
                u32::from(dec),
            )),
            // 0.1 mm is the resolution a person reads heights in (rounded half up).
            Some(Arg::Mm(m)) => Some(((i64::from(m.to_bits()) * 10_000 + (1 << 23)) >> 24, 1)),
            Some(&Arg::Deci(v, d)) => Some((i64::from(v), u32::from(d))),
            None => None,
        };
        if let Some((q, dec)) = number {
            write_decimal(out, q, dec)?;
        }
        rest = tail.get(1..).unwrap_or("");
    }
}

/// A name as one `key=value` word: spaces become `-` ("encoder lost" → `encoder-lost`).
fn write_word(out: &mut dyn Write, name: &str) -> fmt::Result {
    // Piece by piece between ASCII whitespace bytes (char boundaries; no char decoding).
    let mut rest = name;
    while let Some((piece, tail)) = rest
        .bytes()
        .position(|b| b.is_ascii_whitespace())
        .and_then(|i| rest.split_at_checked(i))
    {
        out.write_str(piece)?;
        out.write_char('-')?;
        rest = tail.get(1..).unwrap_or("");
    }
    out.write_str(rest)
}

/// A fixed-point value `bits·2^−frac` rounded to `dec` decimals (ties away from zero), as a
/// count of `10^−dec` ([`write_decimal`] prints it), for status lines.
fn fixed_decimal(bits: i32, frac: u32, dec: u32) -> i64 {
    // dec ≤ 5 in every reply: fits.
    let scale = ten_to(dec).unwrap_or(1) as i64;
    let v = i64::from(bits) * scale;
    let half = 1i64 << (frac - 1);
    if v >= 0 {
        (v + half) >> frac
    } else {
        -((-v + half) >> frac)
    }
}

/// `q·10^−dec` in decimal: the sign, the whole part, and `dec` digits after the point (no
/// point for 0). Every number of the replies goes through here.
fn write_decimal(out: &mut dyn Write, q: i64, dec: u32) -> fmt::Result {
    if q < 0 {
        out.write_char('-')?;
    }
    decimal(out, q.unsigned_abs(), dec as usize)
}

/// `10^k`, `None` above `u64::MAX` (one small loop in place of `u64::pow` and
/// `u64::checked_pow`, for both uses; at most 20 rounds).
pub(crate) fn ten_to(k: u32) -> Option<u64> {
    let mut p = 1u64;
    for _ in 0..k {
        p = p.checked_mul(10)?;
    }
    Some(p)
}

#[cfg(test)]
mod tests {
    use super::*;
    extern crate std;
    use std::format;
    use std::string::String;

    fn text(f: impl Fn(&mut dyn Write) -> fmt::Result) -> String {
        let mut s = String::new();
        f(&mut s).unwrap();
        s
    }

    #[test]
    fn integers_print_as_core_fmt_prints_them() {
        let mut samples = std::vec![0u64, 1, 9, 10, 99, 100, 12_345, u64::from(u32::MAX)];
        samples.extend([u64::MAX, u64::MAX - 1, 10u64.pow(19), 10u64.pow(19) - 1]);
        // A spread over the whole range.
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..2000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            samples.push(x >> (x % 64));
        }
        for &v in &samples {
            assert_eq!(text(|o| uint(o, v)), format!("{v}"));
            for w in 0..=20 {
                assert_eq!(
                    text(|o| uint_padded(o, v, w)),
                    format!("{v:0w$}"),
                    "{v} {w}"
                );
            }
            let s = v as i64;
            assert_eq!(text(|o| int(o, s)), format!("{s}"));
            assert_eq!(
                text(|o| int(o, s.wrapping_neg())),
                format!("{}", s.wrapping_neg())
            );
            for dec in 0..=19usize {
                let p = 10u64.pow(dec as u32);
                let want = if dec == 0 {
                    format!("{v}")
                } else {
                    format!("{}.{:0dec$}", v / p, v % p)
                };
                assert_eq!(text(|o| decimal(o, v, dec)), want, "{v} {dec}");
            }
            let h = v as u32;
            assert_eq!(text(|o| hex8(o, h)), format!("{h:08x}"));
        }
        assert_eq!(text(|o| int(o, i64::MIN)), format!("{}", i64::MIN));
    }

    /// Every sequence of up to three bytes, and many longer ones, is judged as
    /// `core::str::from_utf8` judges it; `next_char` decodes what `chars` decodes.
    #[test]
    fn utf8_is_checked_as_core_checks_it() {
        let check = |b: &[u8]| {
            let want = core::str::from_utf8(b);
            assert_eq!(is_utf8(b), want.is_ok(), "{b:02x?}");
            if let Ok(s) = want {
                let mut rest = b;
                for c in s.chars() {
                    let (got, tail) = next_char(rest).unwrap();
                    assert_eq!(got, c);
                    rest = tail;
                }
                assert!(rest.is_empty());
            }
        };
        check(&[]);
        for x in 0..=0xFFFFu16 {
            let [a, b] = x.to_be_bytes();
            check(&[b]);
            check(&[a, b]);
        }
        // Longer sequences: every non-ASCII lead byte with every second byte and the bytes
        // where the continuation ranges change after it, and a pseudo-random spread of lines.
        let edges = [
            0x00, 0x41, 0x7F, 0x80, 0x8F, 0x90, 0x9F, 0xA0, 0xBF, 0xC0, 0xFF,
        ];
        for a in 0x80..=0xFFu8 {
            for b in 0..=0xFFu8 {
                for &c in &edges {
                    check(&[a, b, c]);
                }
            }
        }
        for a in 0xE0..=0xFFu8 {
            for &b in &edges {
                for &c in &edges {
                    for &d in &edges {
                        check(&[a, b, c, d]);
                    }
                }
            }
        }
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        for _ in 0..20_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let len = (x % 9) as usize;
            let bytes: std::vec::Vec<u8> = (0..len)
                .map(|i| {
                    let v = (x >> (8 * i)) as u8;
                    // Mostly ASCII and lead/continuation bytes.
                    if v & 1 == 0 {
                        v | 0x80
                    } else {
                        v >> 1
                    }
                })
                .collect();
            check(&bytes);
        }
    }

    #[test]
    fn a_full_sink_is_an_error() {
        let mut s = heapless::String::<3>::new();
        assert!(uint(&mut s, 1234).is_err());
        assert!(uint(&mut s, 123).is_ok());
        assert_eq!(s.as_str(), "123");
    }

    /// User text in messages is cut after 24 characters (not bytes), as `char_indices` cut it.
    #[test]
    fn clip_cuts_after_24_characters() {
        let twin = |s: &str| match s.char_indices().nth(24) {
            Some((i, _)) => format!("{}...", &s[..i]),
            None => String::from(s),
        };
        for s in [
            "",
            "short",
            "exactly-twenty-four-char",
            "exactly-twenty-five-chars",
            "äöüäöüäöüäöüäöüäöüäöüäöüäöü",
            "°°°°°°°°°°°°°°°°°°°°°°°°",
            "°°°°°°°°°°°°°°°°°°°°°°°°x",
            "a𝄞b𝄞c𝄞d𝄞e𝄞f𝄞g𝄞h𝄞i𝄞j𝄞k𝄞l𝄞m𝄞",
        ] {
            let mut out = String::new();
            clip(&mut out, s.into()).unwrap();
            assert_eq!(out, twin(s), "{s}");
        }
    }

    /// Names become one word: each ASCII whitespace character a `-` (the `chars` form's twin).
    #[test]
    fn words_replace_ascii_whitespace() {
        for name in [
            "",
            "idle",
            "encoder lost",
            " a  b\tc\n",
            "ü ö",
            "limit switch before x ",
        ] {
            let mut out = String::new();
            write_word(&mut out, name).unwrap();
            assert_eq!(
                out,
                name.chars()
                    .map(|c| if c.is_whitespace() { '-' } else { c })
                    .collect::<String>(),
                "{name:?}"
            );
        }
    }

    /// Heights keep their sign below one millimetre (they lost it before `write_decimal`).
    #[test]
    fn small_negative_heights_keep_their_sign() {
        let text = |mm: f64| {
            let mut s = String::new();
            fill(&mut s, "\x01", &[Arg::Mm(Metres::from_f64(mm / 1000.0))]).unwrap();
            s
        };
        assert_eq!(text(-0.3), "-0.3");
        assert_eq!(text(-12.34), "-12.3");
        assert_eq!(text(0.04), "0.0");
        assert_eq!(text(416.44), "416.4");
    }
}
