//! Numbers as text for the console and the messages, without `core::fmt`'s formatting
//! machinery.
//!
//! Every reply and message of the core is written with `write_str` and these few functions
//! into a [`core::fmt::Write`] sink, never with `write!`: `write!` builds `fmt::Arguments` at
//! each call site and links `core::fmt::write`, `Formatter::pad_integral`, the `Display` impls
//! of the integer types and their padding code, several KiB of flash on the board for
//! what is only integers in decimal and one hex word. The output is the same as `write!`'s
//! (`{}`, `{:0w$}`, `{:08x}`); the tests below compare them.

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
/// the firmware links no `from_utf8` (≈ 0.6 KiB with its table; see [`is_utf8`]).
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
}
