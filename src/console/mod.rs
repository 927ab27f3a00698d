//! The console: a line protocol a person types over the UART (115200 8N1).
//!
//! [`LineBuffer`] collects bytes into lines (backspace edits, CR/LF/CRLF end a line, overlong
//! lines are refused whole), [`parse`] turns a line into a [`Request`], and the `write_*`
//! functions format replies into any [`core::fmt::Write`] sink (a `heapless::String` on the
//! board). Nothing here allocates, and no input makes it panic (`tests/console_*.rs` and the
//! `fuzz/` target check that). docs/console.md is the user's reference.
//!
//! [`service`] puts it together: one complete line in, the request executed against the running
//! controller and configuration, the reply out (and `save` handed back to the caller, whose
//! flash store is async).

pub mod service;
pub mod value;

use crate::config::settings::{self, Kind, SettingId};
use crate::config::ValidatedConfig;
use crate::text;
use crate::units::{Amperes, Angle, Metres, NewtonMetres, RadiansPerSecond, Ratio};
use crate::ConfigError;
use core::fmt::{self, Write};
use fixed::types::I16F16;
pub use value::ValueError;

/// Longest line accepted, bytes (without the line end).
pub const MAX_LINE: usize = 96;

/// What the user asked for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Request {
    /// `status`: state, height, speed, current, T_r, stick-slip, fault.
    Status,
    /// `get <key>`.
    Get(SettingId),
    /// `set <key> <value>`: the value already converted to the field's raw bits; apply it with
    /// [`crate::config::settings::apply`] (range and geometry checks) and reply with
    /// [`write_set`].
    Set(SettingId, i64),
    /// `save`: store the running configuration in flash.
    Save,
    /// `limits`: the limit stops and the mechanism's range.
    Limits,
    /// `up`.
    Up,
    /// `down`.
    Down,
    /// `stop`.
    Stop,
    /// `goto <height>`: drive the head to a height.
    Goto(Metres),
    /// `fault`: the active or last fault.
    Fault,
    /// `fault clear`.
    FaultClear,
    /// `help`, `help keys`, `help <key>`.
    Help(HelpTopic),
    /// `version`: the protocol version, for host tools ([`service::write_version`]).
    Version,
}

/// What `help` explains.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum HelpTopic {
    /// The commands.
    Commands,
    /// Every key with unit and range.
    Keys,
    /// One key.
    Key(SettingId),
}

/// Why a line was not understood.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParseError<'a> {
    /// Not valid UTF-8.
    NotText,
    /// Longer than [`MAX_LINE`].
    TooLong,
    /// The first word is no command.
    UnknownCommand(&'a str),
    /// A command that needs a key got none.
    MissingKey(&'static str),
    /// No setting has this key.
    UnknownKey(&'a str),
    /// `set <key>` without a value.
    MissingValue(SettingId),
    /// The value for a key was not understood.
    BadValue(SettingId, ValueError),
    /// `goto` without a height or with a bad one.
    BadHeight(ValueError),
    /// Words left over after a complete command.
    Trailing(&'a str),
}

/// The unit and range the `goto` height takes.
const HEIGHT: Kind = Kind::Number {
    frac: 24,
    pow10: 3,
    unit: &settings::MILLIMETRES,
    none_at_max: false,
};

/// Split off the first word (ASCII whitespace separated).
fn word(s: &str) -> (&str, &str) {
    let s = s.trim_start();
    match s.find(|c: char| c.is_ascii_whitespace()) {
        // `split_at_checked`, not `[..i]`: `find` gives a char boundary, and the firmware then
        // links no slicing panic (whose message formatting costs ≈ 2 KiB of flash).
        Some(i) => match s.split_at_checked(i) {
            Some((w, rest)) => (w, rest.trim_start()),
            None => (s, ""),
        },
        None => (s, ""),
    }
}

fn no_more(rest: &str, r: Request) -> Result<Option<Request>, ParseError<'_>> {
    let rest = rest.trim();
    if rest.is_empty() {
        Ok(Some(r))
    } else {
        Err(ParseError::Trailing(rest))
    }
}

fn key<'a>(cmd: &'static str, rest: &'a str) -> Result<(SettingId, &'a str), ParseError<'a>> {
    let (k, rest) = word(rest);
    if k.is_empty() {
        return Err(ParseError::MissingKey(cmd));
    }
    settings::find(k)
        .map(|id| (id, rest))
        .ok_or(ParseError::UnknownKey(k))
}

/// Parse one line (without its line end). `Ok(None)`: an empty line or a `#` comment.
/// Commands, keys, units and choices are case-insensitive.
pub fn parse(line: &[u8]) -> Result<Option<Request>, ParseError<'_>> {
    if line.len() > MAX_LINE {
        return Err(ParseError::TooLong);
    }
    let line = core::str::from_utf8(line).map_err(|_| ParseError::NotText)?;
    let line = line.trim();
    if line.is_empty() || line.starts_with('#') {
        return Ok(None);
    }
    let (cmd, rest) = word(line);
    let is = |name: &str| cmd.eq_ignore_ascii_case(name);
    if is("status") {
        no_more(rest, Request::Status)
    } else if is("get") {
        let (id, rest) = key("get", rest)?;
        no_more(rest, Request::Get(id))
    } else if is("set") {
        let (id, rest) = key("set", rest)?;
        if rest.trim().is_empty() {
            return Err(ParseError::MissingValue(id));
        }
        let raw =
            value::parse(&id.setting().kind, rest).map_err(|e| ParseError::BadValue(id, e))?;
        Ok(Some(Request::Set(id, raw)))
    } else if is("save") {
        no_more(rest, Request::Save)
    } else if is("limits") {
        no_more(rest, Request::Limits)
    } else if is("up") {
        no_more(rest, Request::Up)
    } else if is("down") {
        no_more(rest, Request::Down)
    } else if is("stop") {
        no_more(rest, Request::Stop)
    } else if is("goto") {
        let raw = value::parse(&HEIGHT, rest).map_err(ParseError::BadHeight)?;
        let bits = i32::try_from(raw).map_err(|_| ParseError::BadHeight(ValueError::TooLarge))?;
        Ok(Some(Request::Goto(Metres::from_bits(bits))))
    } else if is("fault") {
        let (sub, rest) = word(rest);
        if sub.is_empty() {
            Ok(Some(Request::Fault))
        } else if sub.eq_ignore_ascii_case("clear") {
            no_more(rest, Request::FaultClear)
        } else {
            Err(ParseError::Trailing(sub))
        }
    } else if is("version") {
        no_more(rest, Request::Version)
    } else if is("help") || cmd == "?" {
        let (topic, rest) = word(rest);
        if topic.is_empty() {
            Ok(Some(Request::Help(HelpTopic::Commands)))
        } else if topic.eq_ignore_ascii_case("keys") {
            no_more(rest, Request::Help(HelpTopic::Keys))
        } else {
            let id = settings::find(topic).ok_or(ParseError::UnknownKey(topic))?;
            no_more(rest, Request::Help(HelpTopic::Key(id)))
        }
    } else {
        Err(ParseError::UnknownCommand(cmd))
    }
}

/// `unit` and the alternatives a key takes, for messages: "mm (or m, cm, um)".
fn write_unit(out: &mut dyn Write, kind: &Kind) -> fmt::Result {
    match kind {
        Kind::Choice(names) => {
            for (i, n) in names.iter().enumerate() {
                if i > 0 {
                    out.write_str(if i + 1 == names.len() { " or " } else { ", " })?;
                }
                out.write_str(n)?;
            }
            Ok(())
        }
        Kind::Number {
            unit, none_at_max, ..
        } => {
            out.write_str(unit.what)?;
            if !unit.display.is_empty() {
                out.write_str(" in ")?;
                out.write_str(unit.display)?;
            }
            // The ASCII spellings other than the display unit, once each.
            let mut n = 0;
            for (s, _) in unit.accepts {
                if s.eq_ignore_ascii_case(unit.display) || !s.is_ascii() || s.contains('*') {
                    continue;
                }
                out.write_str(if n == 0 { " (or " } else { ", " })?;
                out.write_str(s)?;
                n += 1;
            }
            if n > 0 {
                out.write_char(')')?;
            }
            if *none_at_max {
                out.write_str(", or none")?;
            }
            Ok(())
        }
    }
}

/// The reply to a line that was not understood.
pub fn write_parse_error(out: &mut dyn Write, e: &ParseError<'_>) -> fmt::Result {
    const HELP: &str = "; type `help` for the commands";
    match e {
        ParseError::NotText => out.write_str("error: line is not text (UTF-8); type `help`"),
        ParseError::TooLong => {
            out.write_str("error: line longer than ")?;
            text::uint(out, MAX_LINE as u64)?;
            out.write_str(" characters, ignored; type `help`")
        }
        ParseError::UnknownCommand(c) => {
            out.write_str("error: unknown command '")?;
            clip(out, c)?;
            out.write_char('\'')?;
            out.write_str(HELP)
        }
        ParseError::MissingKey(cmd) => {
            out.write_str("error: `")?;
            out.write_str(cmd)?;
            out.write_str("` needs a key, e.g. `")?;
            out.write_str(cmd)?;
            out.write_str(" limits.upper`; `help keys` lists them")
        }
        ParseError::UnknownKey(k) => {
            out.write_str("error: unknown key '")?;
            clip(out, k)?;
            out.write_str("'; `help keys` lists them")
        }
        ParseError::MissingValue(id) => {
            out.write_str("error: `set ")?;
            out.write_str(id.key())?;
            out.write_str("` needs a value: ")?;
            write_expected(out, *id)
        }
        ParseError::BadValue(id, v) => {
            out.write_str("error: bad value for ")?;
            out.write_str(id.key())?;
            out.write_str(": ")?;
            out.write_str(v.message())?;
            out.write_str("; ")?;
            write_expected(out, *id)
        }
        ParseError::BadHeight(v) => {
            out.write_str("error: bad height for goto: ")?;
            out.write_str(v.message())?;
            out.write_str("; expected a length in mm (or m, cm), e.g. `goto 300mm`")
        }
        ParseError::Trailing(t) => {
            out.write_str("error: unexpected '")?;
            clip(out, t)?;
            out.write_char('\'')?;
            out.write_str(HELP)
        }
    }
}

/// "expected a length in mm (or m, cm, um), range …".
fn write_expected(out: &mut dyn Write, id: SettingId) -> fmt::Result {
    let s = id.setting();
    out.write_str("expected ")?;
    write_unit(out, &s.kind)?;
    out.write_str(", range ")?;
    out.write_str(s.range)
}

/// At most 24 characters of user text in a message (the rest as `...`).
fn clip(out: &mut dyn Write, s: &str) -> fmt::Result {
    match s.char_indices().nth(24) {
        Some((i, _)) => {
            // A char boundary from `char_indices` (checked, so that no panic is linked).
            out.write_str(s.get(..i).unwrap_or(s))?;
            out.write_str("...")
        }
        None => out.write_str(s),
    }
}

/// `key = value` for `get`.
pub fn write_get(out: &mut dyn Write, cfg: &ValidatedConfig, id: SettingId) -> fmt::Result {
    let s = id.setting();
    out.write_str(s.key)?;
    out.write_str(" = ")?;
    value::format(out, &s.kind, s.get(cfg.get()))
}

/// The reply to `set`: the new value, or why it was refused (naming the field and its range).
/// `result` is what [`crate::config::settings::apply`] returned; `running` is the configuration
/// in force after it (for the mechanism's range in limit messages).
pub fn write_set(
    out: &mut dyn Write,
    id: SettingId,
    result: &Result<ValidatedConfig, ConfigError>,
    running: &ValidatedConfig,
) -> fmt::Result {
    match result {
        Ok(cfg) => {
            out.write_str("ok: ")?;
            write_get(out, cfg, id)?;
            out.write_str(" (not saved; `save` stores it)")
        }
        Err(e) => write_refused(out, id, e, running),
    }
}

/// Why a change was refused: "error: set limits.upper refused: limits.upper out of range
/// (allowed …); mechanism 133.5..416.4 mm".
pub fn write_refused(
    out: &mut dyn Write,
    id: SettingId,
    e: &ConfigError,
    running: &ValidatedConfig,
) -> fmt::Result {
    out.write_str("error: set ")?;
    out.write_str(id.key())?;
    out.write_str(" refused: ")?;
    e.write_to(out)?;
    let field = match e {
        ConfigError::OutOfRange { field, .. } | ConfigError::Conflict { field, .. } => *field,
    };
    if field.starts_with("limits.") {
        out.write_str("; ")?;
        write_mechanism(out, running)?;
    }
    Ok(())
}

/// Head height at an arm angle of the configured geometry.
fn height_at(cfg: &ValidatedConfig, deg: I16F16) -> Metres {
    let g = &cfg.get().estimator.geometry;
    let (_, sin) = Angle::from_degrees(deg).cos_sin();
    g.h0.sat_add(crate::units::qmul::<Metres, Ratio, Metres>(g.length, sin))
}

fn write_mm(out: &mut dyn Write, m: Metres) -> fmt::Result {
    // 0.1 mm is the resolution a person reads heights in.
    let tenths = (i64::from(m.to_bits()) * 10_000 + (1 << 23)) >> 24;
    // The whole millimetres (with their sign) and the tenth's digit.
    text::int(out, tenths / 10)?;
    out.write_char('.')?;
    text::uint(out, (tenths % 10).unsigned_abs())
}

/// "mechanism 133.5..416.4 mm" (α₀ … α_max of the geometry).
fn write_mechanism(out: &mut dyn Write, cfg: &ValidatedConfig) -> fmt::Result {
    let g = &cfg.get().estimator.geometry;
    out.write_str("mechanism ")?;
    write_mm(out, height_at(cfg, g.alpha0_deg))?;
    out.write_str("..")?;
    write_mm(out, height_at(cfg, g.alpha_max_deg))?;
    out.write_str(" mm")
}

/// The reply to `limits`.
pub fn write_limits(out: &mut dyn Write, cfg: &ValidatedConfig) -> fmt::Result {
    let l = &cfg.get().limits;
    out.write_str("limits.lower = ")?;
    write_mm(out, l.lower)?;
    out.write_str(" mm, limits.upper = ")?;
    write_mm(out, l.upper)?;
    out.write_str(" mm, limits.switch_lower = ")?;
    write_mm(out, l.switch_lower)?;
    out.write_str(" mm; ")?;
    write_mechanism(out, cfg)
}

/// The reply to `help <key>`: the key, its help line (builds with the `help-text` feature:
/// liftctl, host-sim) and what it takes. The firmware has no help lines (flash) and points to
/// the host tool that has them instead.
pub fn write_key_help(out: &mut dyn Write, id: SettingId) -> fmt::Result {
    key_help(out, id, id.setting().about())
}

fn key_help(out: &mut dyn Write, id: SettingId, about: Option<&str>) -> fmt::Result {
    out.write_str(id.key())?;
    out.write_str(": ")?;
    match about {
        Some(about) => {
            out.write_str(about)?;
            out.write_str("; ")?;
            write_expected(out, id)
        }
        None => {
            write_expected(out, id)?;
            out.write_str("; described by `liftctl config keys`")
        }
    }
}

/// The reply to `help`.
pub fn write_help(out: &mut dyn Write, topic: HelpTopic) -> fmt::Result {
    match topic {
        HelpTopic::Commands => out.write_str(
            "commands (case-insensitive):\r\n\
             \x20 status              state, height, speed, current, T_r, stick-slip (flag, last drop, episodes), fault, ball screw: f, f_law\r\n\
             \x20 up | down | stop    move (hold-to-run unless motion.buttons = latched)\r\n\
             \x20 goto <height>       drive the head to a height, e.g. goto 300mm\r\n\
             \x20 limits              limit stops and the mechanism's range\r\n\
             \x20 get <key>           show a setting\r\n\
             \x20 set <key> <value>   change a setting (validated; e.g. set limits.upper 400mm)\r\n\
             \x20 save                store the settings in flash\r\n\
             \x20 fault | fault clear show or clear the fault\r\n\
             \x20 version             protocol version (for host tools such as liftctl)\r\n\
             \x20 help keys | help <key>",
        ),
        HelpTopic::Keys => {
            for (i, id) in settings::all().enumerate() {
                if i > 0 {
                    out.write_str("\r\n")?;
                }
                let s = id.setting();
                out.write_str("  ")?;
                out.write_str(s.key)?;
                out.write_str(" [")?;
                match &s.kind {
                    Kind::Choice(_) => out.write_str("choice")?,
                    Kind::Number { unit, .. } => out.write_str(if unit.display.is_empty() {
                        "-"
                    } else {
                        unit.display
                    })?,
                }
                out.write_str("] ")?;
                out.write_str(s.range)?;
            }
            Ok(())
        }
        HelpTopic::Key(id) => write_key_help(out, id),
    }
}

/// What `status` shows; the controller fills it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StatusView {
    /// Supervisor state, e.g. `idle`, `lifting`, `lowering`, `fault`.
    pub state: &'static str,
    /// Head height.
    pub height: Metres,
    /// Screw speed θ̇ (+ lifting).
    pub screw_speed: RadiansPerSecond,
    /// Motor current.
    pub current: Amperes,
    /// Estimated friction torque T_r.
    pub friction_torque: NewtonMetres,
    /// Stick-slip episode under way.
    pub stick_slip: bool,
    /// Coupling-torque drop of the last detected slip.
    pub stick_slip_amplitude: NewtonMetres,
    /// Stick-slip episodes since boot.
    pub stick_slip_episodes: u32,
    /// The active fault's name, if any.
    pub fault: Option<&'static str>,
    /// Ball screw: identified friction coefficient and the law's f(τ), once identified.
    pub ball_f: Option<(Ratio, Ratio)>,
}

/// Fixed-point value with `dec` decimals (rounded), for status lines.
fn write_fixed(out: &mut dyn Write, bits: i32, frac: u32, dec: u32) -> fmt::Result {
    let scale = 10i64.pow(dec);
    let v = i64::from(bits) * scale;
    let half = 1i64 << (frac - 1);
    let q = if v >= 0 {
        (v + half) >> frac
    } else {
        -((-v + half) >> frac)
    };
    if q < 0 {
        out.write_char('-')?;
    }
    let m = q.unsigned_abs();
    let s = scale.unsigned_abs();
    text::uint(out, m / s)?;
    if dec != 0 {
        out.write_char('.')?;
        text::uint_padded(out, m % s, dec as usize)?;
    }
    Ok(())
}

/// The reply to `status`: one line, `key=value` pairs a person and a script can read (a fault
/// name's spaces are written as `-`, so every value is one word).
pub fn write_status(out: &mut dyn Write, s: &StatusView) -> fmt::Result {
    out.write_str("state=")?;
    out.write_str(s.state)?;
    out.write_str(" height=")?;
    write_mm(out, s.height)?;
    out.write_str("mm speed=")?;
    write_fixed(out, s.screw_speed.to_bits(), 16, 2)?;
    out.write_str("rad/s current=")?;
    write_fixed(out, s.current.to_bits(), 16, 2)?;
    out.write_str("A T_r=")?;
    write_fixed(out, s.friction_torque.to_bits(), 16, 3)?;
    out.write_str("Nm stick_slip=")?;
    out.write_str(if s.stick_slip { "yes" } else { "no" })?;
    out.write_str(" ss_amp=")?;
    write_fixed(out, s.stick_slip_amplitude.to_bits(), 16, 2)?;
    out.write_str("Nm ss_episodes=")?;
    text::uint(out, u64::from(s.stick_slip_episodes))?;
    out.write_str(" fault=")?;
    write_word(out, s.fault.unwrap_or("none"))?;
    if let Some((f, law)) = s.ball_f {
        out.write_str(" f=")?;
        write_fixed(out, f.to_bits(), 28, 5)?;
        out.write_str(" f_law=")?;
        write_fixed(out, law.to_bits(), 28, 5)?;
    }
    Ok(())
}

/// The console warning of a ball screw whose identified friction coefficient left the band
/// around the law (`control::lube`), one line.
pub fn write_lube_warning(out: &mut dyn Write, f: Ratio, law: Ratio) -> fmt::Result {
    out.write_str("warning: ball-screw friction f=")?;
    write_fixed(out, f.to_bits(), 28, 5)?;
    out.write_str(if f > law { " above" } else { " below" })?;
    out.write_str(" the law's ")?;
    write_fixed(out, law.to_bits(), 28, 5)?;
    out.write_str(" beyond ballscrew.lube_band (check lubrication and wear)")
}

/// A name as one `key=value` word: spaces become `-` ("encoder lost" → `encoder-lost`).
fn write_word(out: &mut dyn Write, name: &str) -> fmt::Result {
    for c in name.chars() {
        out.write_char(if c.is_whitespace() { '-' } else { c })?;
    }
    Ok(())
}

/// The console warning of the stick-slip reactions `warn` and `speed`, one line.
pub fn write_stick_slip_warning(
    out: &mut dyn Write,
    episode: u32,
    amplitude: NewtonMetres,
    speed_changed: bool,
) -> fmt::Result {
    out.write_str("warning: stick-slip (episode ")?;
    text::uint(out, u64::from(episode))?;
    out.write_str(", torque drop ")?;
    write_fixed(out, amplitude.to_bits(), 16, 2)?;
    out.write_str(" Nm per slip)")?;
    if speed_changed {
        out.write_str(", cruise changed to stickslip.escape_speed")?;
    }
    Ok(())
}

/// Collects UART bytes into lines. Backspace/DEL remove the last byte, CR, LF or CRLF end a
/// line, a line longer than [`MAX_LINE`] is dropped whole and reported as [`Feed::Overflow`]
/// once its end arrives.
#[derive(Clone, Debug, Default)]
pub struct LineBuffer {
    buf: heapless::Vec<u8, MAX_LINE>,
    overflow: bool,
    last_cr: bool,
    /// A line was handed out: clear before the next byte.
    done: bool,
}

/// What one byte did to the line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Feed<'a> {
    /// The line goes on.
    Pending,
    /// A complete line (without its end).
    Line(&'a [u8]),
    /// A line that was too long ended.
    Overflow,
}

impl LineBuffer {
    /// An empty buffer.
    pub const fn new() -> Self {
        LineBuffer {
            buf: heapless::Vec::new(),
            overflow: false,
            last_cr: false,
            done: false,
        }
    }

    /// Feed one byte.
    pub fn feed(&mut self, b: u8) -> Feed<'_> {
        if core::mem::replace(&mut self.done, false) {
            self.buf.clear();
        }
        let after_cr = core::mem::replace(&mut self.last_cr, b == b'\r');
        match b {
            b'\n' if after_cr => Feed::Pending,
            b'\r' | b'\n' => {
                self.done = true;
                if core::mem::replace(&mut self.overflow, false) {
                    Feed::Overflow
                } else {
                    Feed::Line(&self.buf)
                }
            }
            0x08 | 0x7F => {
                self.buf.pop();
                Feed::Pending
            }
            _ => {
                if self.buf.push(b).is_err() {
                    self.overflow = true;
                }
                Feed::Pending
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    extern crate std;
    use std::string::String;

    /// Host builds have the help lines (`help-text`, turned on by host-sim and liftctl); the
    /// firmware's `help <key>` without them still says what the key takes and where the
    /// description is.
    #[test]
    fn key_help_without_the_help_text_gives_unit_range_and_a_pointer() {
        let id = settings::find("motion.ramp_ms").unwrap();
        let mut s = String::new();
        key_help(&mut s, id, None).unwrap();
        assert_eq!(
            s,
            "motion.ramp_ms: expected a duration in ms (or s), range 10..2000 ms; described by \
             `liftctl config keys`"
        );
        let mut s = String::new();
        key_help(&mut s, id, Some("what it is")).unwrap();
        assert_eq!(
            s,
            "motion.ramp_ms: what it is; expected a duration in ms (or s), range 10..2000 ms"
        );
    }
}
