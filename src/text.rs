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

/// ASCII text (digits) as it is.
pub(crate) fn ascii(out: &mut dyn Write, digits: &[u8]) -> fmt::Result {
    out.write_str(core::str::from_utf8(digits).map_err(|_| fmt::Error)?)
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

    #[test]
    fn a_full_sink_is_an_error() {
        let mut s = heapless::String::<3>::new();
        assert!(uint(&mut s, 1234).is_err());
        assert!(uint(&mut s, 123).is_ok());
        assert_eq!(s.as_str(), "123");
    }
}
