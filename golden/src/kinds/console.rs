//! The console line parser: `console::parse`.

use crate::format::{Error, InputBuf, Kind, Reader, Sink, Text};
use crate::record;
use crate::rng::SplitMix64;

/// [`Kind::ConsoleParse`](crate::Kind::ConsoleParse): `console::parse` of one line.
pub(crate) fn eval(r: &mut Reader<'_>, out: &mut impl Sink) -> Result<(), Error> {
    // The whole input is the line; `Debug` spells every field of the result (variant,
    // setting, raw value bits, error kind, the offending words) and is the same code
    // on both sides.
    let line = r.take(r.b.len())?;
    let parsed = liftfw::console::parse(line);
    core::fmt::write(&mut Text(out), format_args!("{parsed:?}")).map_err(|_| Error::BadField(0))?;
    // The one field `Debug` shows in decimal rather than as raw bits.
    if let Ok(Some(liftfw::console::Request::Goto(h))) = parsed {
        out.put_i32(h.to_bits());
    }
    Ok(())
}

/// Console lines generated (a well-formed command, a damaged one, or noise).
pub const CONSOLE_LINES: u32 = 2400;

const COMMANDS: [&str; 14] = [
    "status", "get", "set", "save", "limits", "up", "down", "stop", "goto", "fault", "version",
    "help", "?", "clear",
];

const UNITS: [&str; 30] = [
    "", "mm", "m", "cm", "um", "rad/s", "ms", "s", "us", "A", "mA", "V", "mV", "kg", "t", "g", "%",
    "counts", "deg", "°", "Nm", "n*m", "n·m", "mNm", "Nm/A", "Hz", "ohm", "Ω", "N", "kN",
];

const WORDS: [&str; 20] = [
    "trapezoid",
    "scurve",
    "hold",
    "latched",
    "lead",
    "ball",
    "none",
    "spring",
    "dry",
    "ptfe",
    "lithium",
    "rate",
    "speed",
    "tau",
    "custom",
    "off",
    "inf",
    "never",
    "keys",
    "clear",
];

/// A number as a person might type it (or not): signs, decimals, exponents, huge, garbage.
fn number(rng: &mut SplitMix64, out: &mut LineBuf) {
    if rng.chance(1, 8) {
        out.push_str("-");
    } else if rng.chance(1, 16) {
        out.push_str("+");
    }
    match rng.range(0, 7) {
        0 => out.push_u64(rng.next_u64() >> rng.range(0, 63)),
        1 => {
            out.push_u64(rng.range(0, 100) as u64);
            out.push_str(".");
            out.push_u64(rng.range(0, 99_999) as u64);
        }
        2 => {
            out.push_str(".");
            out.push_u64(rng.range(0, 999) as u64);
        }
        3 => {
            out.push_u64(rng.range(0, 9) as u64);
            out.push_str(["e", "E", "e-", "e+"][rng.range(0, 3) as usize]);
            out.push_u64(rng.range(0, 30) as u64);
        }
        4 => out.push_str(
            ["1.", "..5", "1.2.3", "0x10", "1_000", "nan", "-", "1,5"][rng.range(0, 7) as usize],
        ),
        5 => {
            for _ in 0..rng.range(15, 40) {
                out.push_u64(rng.range(0, 9) as u64);
            }
        }
        _ => out.push_u64(rng.range(0, 2000) as u64),
    }
}

/// One console line, built on the stack.
struct LineBuf {
    b: [u8; 160],
    len: usize,
}

impl LineBuf {
    fn push(&mut self, c: u8) {
        if let Some(x) = self.b.get_mut(self.len) {
            *x = c;
            self.len += 1;
        }
    }
    fn push_str(&mut self, s: &str) {
        for c in s.bytes() {
            self.push(c);
        }
    }
    fn push_u64(&mut self, mut v: u64) {
        let mut d = [0u8; 20];
        let mut n = 0;
        loop {
            d[n] = b'0' + (v % 10) as u8;
            n += 1;
            v /= 10;
            if v == 0 {
                break;
            }
        }
        for i in (0..n).rev() {
            self.push(d[i]);
        }
    }
    fn space(&mut self, rng: &mut SplitMix64) {
        match rng.range(0, 9) {
            0 => self.push_str("  "),
            1 => self.push_str("\t"),
            2 => self.push_str(" \t "),
            _ => self.push_str(" "),
        }
    }
    /// A word, sometimes in another case.
    fn word(&mut self, w: &str, rng: &mut SplitMix64) {
        let mode = rng.range(0, 5);
        for c in w.bytes() {
            self.push(match mode {
                0 => c.to_ascii_uppercase(),
                1 if rng.chance(1, 2) => c.to_ascii_uppercase(),
                _ => c,
            });
        }
    }
}

/// One line: a well-formed command, a damaged one, or noise.
fn console_line(rng: &mut SplitMix64, k: u32) -> LineBuf {
    let mut l = LineBuf {
        b: [0; 160],
        len: 0,
    };
    let keys = liftfw::config::settings::all().count() as i64;
    let key = |rng: &mut SplitMix64| {
        liftfw::config::settings::all()
            .nth(rng.range(0, keys - 1) as usize)
            .map_or("?", |id| id.key())
    };
    if rng.chance(1, 6) {
        l.space(rng);
    }
    match k % 10 {
        // Every command alone, then with a word after it.
        0 => {
            l.word(COMMANDS[(k / 10) as usize % COMMANDS.len()], rng);
            if (k / 10) as usize / COMMANDS.len() % 2 == 1 {
                l.space(rng);
                l.word(WORDS[rng.range(0, 19) as usize], rng);
            }
        }
        // get/help of every key (walked in order), a few misspelt.
        1 => {
            l.word(["get", "help", "?"][rng.range(0, 2) as usize], rng);
            l.space(rng);
            let id = liftfw::config::settings::all().nth((k / 10) as usize % keys as usize);
            let w = id.map_or("?", |id| id.key());
            if rng.chance(1, 8) {
                l.word(w.get(..w.len() - 1).unwrap_or(w), rng);
            } else {
                l.word(w, rng);
            }
        }
        // set <every key> <number> [unit]
        2..=4 => {
            l.word("set", rng);
            l.space(rng);
            let id = liftfw::config::settings::all().nth((k / 3) as usize % keys as usize);
            l.word(id.map_or("?", |id| id.key()), rng);
            if rng.chance(9, 10) {
                l.space(rng);
                number(rng, &mut l);
                if rng.chance(2, 3) {
                    if rng.chance(1, 2) {
                        l.space(rng);
                    }
                    l.word(UNITS[rng.range(0, UNITS.len() as i64 - 1) as usize], rng);
                }
            }
        }
        // set <key> <choice word>
        5 => {
            l.word("set", rng);
            l.space(rng);
            l.word(key(rng), rng);
            l.space(rng);
            l.word(WORDS[rng.range(0, 19) as usize], rng);
        }
        // goto <height> [unit]
        6 => {
            l.word("goto", rng);
            if rng.chance(9, 10) {
                l.space(rng);
                number(rng, &mut l);
                l.word(
                    ["", "mm", "m", "cm", "um", "A", " mm", "mm mm"][rng.range(0, 7) as usize],
                    rng,
                );
            }
        }
        // Comments, blank lines, trailing words.
        7 => match rng.range(0, 4) {
            0 => l.push_str("# a comment: set x 1"),
            1 => l.space(rng),
            2 => {
                l.word(COMMANDS[rng.range(0, 13) as usize], rng);
                l.space(rng);
                l.word(key(rng), rng);
                l.space(rng);
                number(rng, &mut l);
                l.space(rng);
                l.word("extra", rng);
            }
            3 => l.push_str("fault clear now"),
            _ => l.word("fault clear", rng),
        },
        // Overlong lines around the limit (96 bytes).
        8 => {
            let n = 90 + (k / 10) % 20;
            l.word("set", rng);
            l.space(rng);
            l.word(key(rng), rng);
            l.space(rng);
            while l.len < n as usize {
                l.push(b'0' + rng.range(0, 9) as u8);
            }
        }
        // Random bytes: printable, then anything (invalid UTF-8 included).
        _ => {
            let any = rng.chance(1, 2);
            for _ in 0..rng.range(0, 40) {
                l.push(if any {
                    rng.bits() as u8
                } else {
                    rng.range(0x20, 0x7e) as u8
                });
            }
        }
    }
    if rng.chance(1, 6) {
        l.space(rng);
    }
    l
}

/// The parser's records: [`CONSOLE_LINES`] lines.
pub(crate) fn generate(rng: &mut SplitMix64, s: &mut impl Sink) -> Result<(), Error> {
    for k in 0..CONSOLE_LINES {
        let l = console_line(rng, k);
        let mut input = InputBuf::new();
        input.put(l.b.get(..l.len).unwrap_or(&l.b));
        record(s, Kind::ConsoleParse, &input)?;
    }
    Ok(())
}
