//! The replies: each `write_*` formats one into any [`core::fmt::Write`] sink, most through one
//! template ([`fill`]).

use super::{value, HelpTopic, ParseError, MAX_LINE};
use crate::config::settings::{self, Kind, SettingId};
use crate::config::ValidatedConfig;
use crate::text::{escape, fill, height_arg, Arg};
use crate::units::{Amperes, Angle, Metres, NewtonMetres, RadiansPerSecond, Ratio};
use crate::ConfigError;
use core::fmt::{self, Write};
use fixed::types::I16F16;

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
            // The spec's parts in one pass: display unit, what it is, `suffix=power`s.
            let mut parts = unit.parts();
            let display = parts.next().unwrap_or("");
            out.write_str(parts.next().unwrap_or(""))?;
            if !display.is_empty() {
                out.write_str(" in ")?;
                out.write_str(display)?;
            }
            // The other ASCII spellings, once each (the accepted suffixes repeat no display
            // unit).
            let mut n = 0;
            for a in parts {
                // The suffix: the part before its `=` (ASCII, so a char boundary).
                let s = a
                    .bytes()
                    .position(|b| b == b'=')
                    .and_then(|i| a.get(..i))
                    .unwrap_or(a);
                // (One byte test for both, instead of `is_ascii`'s word-wise loop as well.)
                if s.bytes().any(|b| !b.is_ascii() || b == b'*') {
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
    // Shared pieces: the prefix, and the two endings that point to `help`.
    const COMMANDS: &str = "; type `help` for the commands";
    const KEYS: &str = "; `help keys` lists them";
    out.write_str("error: ")?;
    let (template, args): (&str, &[Arg<'_>]) = match e {
        ParseError::NotText => ("line is not text (UTF-8); type `help`", &[]),
        ParseError::Control(b) => {
            out.write_str("control character ")?;
            escape(out, *b)?;
            return out.write_str(" in the line, ignored; type `help`");
        }
        ParseError::TooLong => (
            "line longer than \x01 characters, ignored; type `help`",
            &[Arg::Uint(MAX_LINE as u32)],
        ),
        // The user's words and a pointer to `help` (one argument list for the three).
        ParseError::UnknownCommand(w) | ParseError::UnknownKey(w) | ParseError::Trailing(w) => {
            let (template, ending) = match e {
                ParseError::UnknownCommand(_) => ("unknown command '\x01'\x01", COMMANDS),
                ParseError::UnknownKey(_) => (settings::unknown_key_template(w.as_bytes()), KEYS),
                _ => ("unexpected '\x01'\x01", COMMANDS),
            };
            return fill(out, template, &[Arg::Clip(*w), Arg::Str(ending)]);
        }
        ParseError::MissingKey(cmd) => (
            "`\x01` needs a key, e.g. `\x01 limits.upper`\x01",
            &[Arg::Str(cmd), Arg::Str(cmd), Arg::Str(KEYS)],
        ),
        // Both end with what the key takes (one `fill` and one `write_expected` for both).
        ParseError::MissingValue(id) | ParseError::BadValue(id, _) => {
            let (template, why) = match e {
                ParseError::BadValue(_, v) => ("bad value for \x01: \x01; ", v.message()),
                _ => ("`set \x01` needs a value: ", ""),
            };
            fill(out, template, &[Arg::Str(id.key()), Arg::Str(why)])?;
            return write_expected(out, *id);
        }
        ParseError::BadHeight(v) => (
            "bad height for goto: \x01; expected a length in mm (or m, cm), e.g. `goto 300mm`",
            &[Arg::Str(v.message())],
        ),
    };
    fill(out, template, args)
}

/// "expected a length in mm (or m, cm, um), range …".
fn write_expected(out: &mut dyn Write, id: SettingId) -> fmt::Result {
    let s = id.setting();
    out.write_str("expected ")?;
    write_unit(out, &s.kind)?;
    out.write_str(", range ")?;
    out.write_str(s.range)
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
    fill(out, "error: set \x01 refused: ", &[Arg::Str(id.key())])?;
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

/// "mechanism 133.5..416.4 mm" (α₀ … α_max of the geometry).
fn write_mechanism(out: &mut dyn Write, cfg: &ValidatedConfig) -> fmt::Result {
    let g = &cfg.get().estimator.geometry;
    fill(
        out,
        "mechanism \x01..\x01 mm",
        &[
            Arg::Mm(height_at(cfg, g.alpha0_deg)),
            Arg::Mm(height_at(cfg, g.alpha_max_deg)),
        ],
    )
}

/// The reply to `limits`.
pub fn write_limits(out: &mut dyn Write, cfg: &ValidatedConfig) -> fmt::Result {
    let l = &cfg.get().limits;
    fill(
        out,
        "limits.lower = \x01 mm, limits.upper = \x01 mm, limits.switch_lower = \x01 mm; ",
        &[Arg::Mm(l.lower), Arg::Mm(l.upper), Arg::Mm(l.switch_lower)],
    )?;
    write_mechanism(out, cfg)
}

/// The reply to `help <key>`: the key, its help line (builds with the `help-text` feature:
/// liftctl, host-sim) and what it takes. The firmware has no help lines and points to
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

/// The reply to `help`: each command with a line of description (builds with the `help-text`
/// feature: liftctl, host-sim); the firmware lists the commands' forms only ([`COMMANDS_BRIEF`])
/// and points to docs/console.md.
#[cfg(feature = "help-text")]
const COMMANDS: &str = "commands (case-insensitive):\r\n\
             \x20 status              state, height, speed, current, T_r, stick-slip (flag, last drop, episodes), fault, ball screw: f, f_law\r\n\
             \x20 up | down | stop    move (hold-to-run unless motion.buttons = latched)\r\n\
             \x20 goto <height>       drive the head to a height, e.g. goto 300mm\r\n\
             \x20 limits              limit stops and the mechanism's range\r\n\
             \x20 get <key>           show a setting\r\n\
             \x20 set <key> <value>   change a setting (validated; e.g. set limits.upper 400mm)\r\n\
             \x20 save                store the settings in flash\r\n\
             \x20 fault | fault clear show or clear the fault\r\n\
             \x20 version             protocol version (for host tools such as liftctl)\r\n\
             \x20 help keys | help <key>";

/// The firmware's `help`: every command's form, without the descriptions.
#[cfg_attr(feature = "help-text", allow(dead_code))]
const COMMANDS_BRIEF: &str = "commands (case-insensitive; docs/console.md describes them):\r\n\
     \x20 status | up | down | stop | goto <height> | limits | save | version\r\n\
     \x20 get <key> | set <key> <value> | fault | fault clear | help keys | help <key>";

#[cfg(not(feature = "help-text"))]
const COMMANDS: &str = COMMANDS_BRIEF;

/// The reply to `help`.
pub fn write_help(out: &mut dyn Write, topic: HelpTopic) -> fmt::Result {
    match topic {
        HelpTopic::Commands => out.write_str(COMMANDS),
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
                    Kind::Number { unit, .. } => {
                        let display = unit.display();
                        out.write_str(if display.is_empty() { "-" } else { display })?
                    }
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
    /// The position is known; unhomed, `height` shows as `unknown` and `homed=no`.
    pub homed: bool,
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
    /// The identified load (or the prior), its interval, whether it was identified, and the
    /// friction scale on the configured law (`crate::ident`).
    pub load: crate::ident::LoadReport,
    /// The motion's cruise speed when the motor cannot reach `motion.cruise_speed`
    /// (` cruise_limit=4.41rad/s` at the end of the line).
    pub cruise_limit: Option<RadiansPerSecond>,
    /// Ball screw: identified friction coefficient and the law's f(τ), once identified.
    #[cfg(feature = "ball-screw")]
    pub ball_f: Option<(Ratio, Ratio)>,
}

/// The reply to `status`: one line, `key=value` pairs a person and a script can read (a fault
/// name's spaces are written as `-`, so every value is one word).
pub fn write_status(out: &mut dyn Write, s: &StatusView) -> fmt::Result {
    fill(
        out,
        "state=\x01 height=\x01\x01 speed=\x01rad/s current=\x01A T_r=\x01Nm stick_slip=\x01 \
         ss_amp=\x01Nm ss_episodes=\x01 fault=\x01 homed=\x01",
        &[
            Arg::Str(s.state),
            height_arg(s.height, s.homed),
            Arg::Str(if s.homed { "mm" } else { "" }),
            Arg::Fixed(s.screw_speed.to_bits(), 16, 2),
            Arg::Fixed(s.current.to_bits(), 16, 2),
            Arg::Fixed(s.friction_torque.to_bits(), 16, 3),
            Arg::Str(if s.stick_slip { "yes" } else { "no" }),
            Arg::Fixed(s.stick_slip_amplitude.to_bits(), 16, 2),
            Arg::Uint(s.stick_slip_episodes),
            Arg::Word(s.fault.unwrap_or("none")),
            Arg::Str(if s.homed { "yes" } else { "no" }),
        ],
    )?;
    let l = &s.load;
    fill(
        out,
        " load=\x01kg load_range=\x01..\x01kg load_src=\x01 mu_scale=\x01\x01",
        &[
            Arg::Fixed(l.load.to_bits(), 12, 0),
            Arg::Fixed(l.load_lo.to_bits(), 12, 0),
            Arg::Fixed(l.load_hi.to_bits(), 12, 0),
            Arg::Str(load_src(l.identified)),
            Arg::Fixed(l.scale.to_bits(), 28, 3),
            Arg::Str(if l.scale_known { "" } else { "(assumed)" }),
        ],
    )?;
    if let Some(w) = s.cruise_limit {
        fill(
            out,
            " cruise_limit=\x01rad/s",
            &[Arg::Fixed(w.to_bits(), 16, 2)],
        )?;
    }
    #[cfg(not(feature = "ball-screw"))]
    return Ok(());
    #[cfg(feature = "ball-screw")]
    match s.ball_f {
        Some((f, law)) => fill(
            out,
            " f=\x01 f_law=\x01",
            &[
                Arg::Fixed(f.to_bits(), 28, 5),
                Arg::Fixed(law.to_bits(), 28, 5),
            ],
        ),
        None => Ok(()),
    }
}

/// The console warning of a lift/lowering pair that found the thread drier than configured
/// (`crate::ident`), one line.
pub fn write_thread_dry_warning(out: &mut dyn Write, r: &crate::ident::LoadReport) -> fmt::Result {
    fill(
        out,
        "warning: the thread runs \x01x the configured friction law (identified load \x01 kg): \
         check lubrication",
        &[
            Arg::Fixed(r.scale.to_bits(), 28, 2),
            Arg::Fixed(r.load.to_bits(), 12, 0),
        ],
    )
}

/// Where a load came from, as `status` and the `fault` snapshot say it (`load_src=`): the
/// motor current, or the prior.
pub(crate) fn load_src(identified: bool) -> &'static str {
    if identified {
        "current"
    } else {
        "prior"
    }
}

/// ` at an identified load of N kg`, or ` at the prior load of N kg (not identified)` (an
/// overload's notice).
pub fn write_load(
    out: &mut dyn Write,
    load: crate::units::Kilograms,
    identified: bool,
) -> fmt::Result {
    fill(
        out,
        if identified {
            " at an identified load of \x01 kg"
        } else {
            " at the prior load of \x01 kg (not identified)"
        },
        &[Arg::Fixed(load.to_bits(), 12, 0)],
    )
}

/// The console warning of a ball screw whose identified friction coefficient left the band
/// around the law (`control::lube`), one line.
pub fn write_lube_warning(out: &mut dyn Write, f: Ratio, law: Ratio) -> fmt::Result {
    fill(
        out,
        "warning: ball-screw friction f=\x01\x01 the law's \x01 beyond ballscrew.lube_band \
         (check lubrication and wear)",
        &[
            Arg::Fixed(f.to_bits(), 28, 5),
            Arg::Str(if f > law { " above" } else { " below" }),
            Arg::Fixed(law.to_bits(), 28, 5),
        ],
    )
}

/// The console warning of a motion whose cruise the motor cannot reach
/// ([`crate::control::Event::CruiseLimited`]), one line.
pub fn write_cruise_warning(out: &mut dyn Write, speed: RadiansPerSecond) -> fmt::Result {
    fill(
        out,
        "warning: cruise limited to \x01 rad/s: the motor's speed at this load and supply \
         (motion.cruise_speed is more)",
        &[Arg::Fixed(speed.to_bits(), 16, 2)],
    )
}

/// The console warning of the stick-slip reactions `warn` and `speed`, one line.
pub fn write_stick_slip_warning(
    out: &mut dyn Write,
    episode: u32,
    amplitude: NewtonMetres,
    speed_changed: bool,
) -> fmt::Result {
    fill(
        out,
        "warning: stick-slip (episode \x01, torque drop \x01 Nm per slip)",
        &[Arg::Uint(episode), Arg::Fixed(amplitude.to_bits(), 16, 2)],
    )?;
    if speed_changed {
        out.write_str(", cruise changed to stickslip.escape_speed")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::super::parse::HEIGHT;
    use super::super::{parse, service, ValueError};
    use super::*;
    extern crate std;
    use crate::control::protect::FaultKind;
    use crate::control::{Fault, State};
    use crate::units::{Instant, Volts};
    use std::format;
    use std::string::String;

    /// The `write!` forms the replies had before [`fill`], kept as twins.
    mod reference {
        use super::*;

        pub fn fixed(bits: i32, frac: u32, dec: u32) -> String {
            let scale = 10i64.pow(dec);
            let v = i64::from(bits) * scale;
            let half = 1i64 << (frac - 1);
            let q = if v >= 0 {
                (v + half) >> frac
            } else {
                -((-v + half) >> frac)
            };
            let sign = if q < 0 { "-" } else { "" };
            let m = q.unsigned_abs();
            let s = scale.unsigned_abs();
            if dec == 0 {
                format!("{sign}{m}")
            } else {
                format!("{sign}{}.{:0w$}", m / s, m % s, w = dec as usize)
            }
        }

        /// (Before [`write_decimal`], heights between −1 and 0 mm lost their sign: `-0.3`
        /// was written `0.3`.)
        pub fn mm(m: Metres) -> String {
            let tenths = (i64::from(m.to_bits()) * 10_000 + (1 << 23)) >> 24;
            let sign = if tenths < 0 { "-" } else { "" };
            let t = tenths.unsigned_abs();
            format!("{sign}{}.{}", t / 10, t % 10)
        }

        pub fn word(name: &str) -> String {
            name.chars()
                .map(|c| if c.is_whitespace() { '-' } else { c })
                .collect()
        }

        pub fn status(s: &StatusView) -> String {
            #[cfg(not(feature = "ball-screw"))]
            let ball = "";
            #[cfg(feature = "ball-screw")]
            let ball = match s.ball_f {
                Some((f, law)) => format!(
                    " f={} f_law={}",
                    fixed(f.to_bits(), 28, 5),
                    fixed(law.to_bits(), 28, 5)
                ),
                None => String::new(),
            };
            let l = &s.load;
            let load = format!(
                " load={}kg load_range={}..{}kg load_src={} mu_scale={}{}",
                fixed(l.load.to_bits(), 12, 0),
                fixed(l.load_lo.to_bits(), 12, 0),
                fixed(l.load_hi.to_bits(), 12, 0),
                if l.identified { "current" } else { "prior" },
                fixed(l.scale.to_bits(), 28, 3),
                if l.scale_known { "" } else { "(assumed)" }
            );
            format!(
                "state={} height={} speed={}rad/s current={}A T_r={}Nm stick_slip={} \
                 ss_amp={}Nm ss_episodes={} fault={} homed={}{load}{}{ball}",
                s.state,
                if s.homed {
                    mm(s.height) + "mm"
                } else {
                    "unknown".into()
                },
                fixed(s.screw_speed.to_bits(), 16, 2),
                fixed(s.current.to_bits(), 16, 2),
                fixed(s.friction_torque.to_bits(), 16, 3),
                if s.stick_slip { "yes" } else { "no" },
                fixed(s.stick_slip_amplitude.to_bits(), 16, 2),
                s.stick_slip_episodes,
                word(s.fault.unwrap_or("none")),
                if s.homed { "yes" } else { "no" },
                s.cruise_limit
                    .map(|w| format!(" cruise_limit={}rad/s", fixed(w.to_bits(), 16, 2)))
                    .unwrap_or_default()
            )
        }

        pub fn fault(f: &Fault) -> String {
            let ms = f.at.0 / 1000;
            let permille =
                (i32::from(f.duty) * 1000 + if f.duty < 0 { -16384 } else { 16384 }) / 32768;
            let p = permille.unsigned_abs();
            format!(
                "fault={} t={}.{:03}s state={} height={} speed={}rad/s current={}A supply={}V \
                 duty={}{}.{}% torque={}Nm model_torque={}Nm load={}kg load_src={}",
                word(f.kind.name()),
                ms / 1000,
                ms % 1000,
                f.state.name(),
                if f.homed {
                    mm(f.height) + "mm"
                } else {
                    "unknown".into()
                },
                fixed(f.screw_speed.to_bits(), 16, 2),
                fixed(f.current.to_bits(), 16, 2),
                fixed(f.supply.to_bits(), 16, 2),
                if permille < 0 { "-" } else { "" },
                p / 10,
                p % 10,
                fixed(f.measured_torque.to_bits(), 16, 3),
                fixed(f.model_torque.to_bits(), 16, 3),
                fixed(f.load.to_bits(), 12, 0),
                if f.load_identified {
                    "current"
                } else {
                    "prior"
                }
            )
        }
    }

    /// Values over the whole range of each field (xorshift), with the edges.
    fn samples() -> impl Iterator<Item = u64> {
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        [
            0,
            1,
            u64::MAX,
            1 << 63,
            (1 << 63) - 1,
            1 << 31,
            (1 << 31) - 1,
        ]
        .into_iter()
        .chain(core::iter::from_fn(move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            Some(x >> (x % 48))
        }))
        .take(3000)
    }

    #[test]
    fn parse_errors_are_those_of_the_write_forms() {
        let id = settings::find("limits.upper").unwrap();
        let mut expected = String::new();
        write_expected(&mut expected, id).unwrap();
        let long = "a-very-long-word-that-is-clipped-after-24-chars";
        let cases = [
            (
                ParseError::NotText,
                String::from("error: line is not text (UTF-8); type `help`"),
            ),
            (
                ParseError::TooLong,
                format!("error: line longer than {MAX_LINE} characters, ignored; type `help`"),
            ),
            (
                ParseError::UnknownCommand(long.into()),
                format!(
                    "error: unknown command '{}...'; type `help` for the commands",
                    &long[..24]
                ),
            ),
            (
                ParseError::MissingKey("get"),
                String::from(
                    "error: `get` needs a key, e.g. `get limits.upper`; `help keys` lists them",
                ),
            ),
            (
                ParseError::UnknownKey("x".into()),
                String::from("error: unknown key 'x'; `help keys` lists them"),
            ),
            (
                ParseError::MissingValue(id),
                format!("error: `set limits.upper` needs a value: {expected}"),
            ),
            (
                ParseError::BadValue(id, ValueError::WrongUnit),
                format!("error: bad value for limits.upper: unit not accepted; {expected}"),
            ),
            (
                ParseError::BadHeight(ValueError::NotANumber),
                String::from(
                    "error: bad height for goto: not a number; expected a length in mm (or m, \
                     cm), e.g. `goto 300mm`",
                ),
            ),
            (
                ParseError::Trailing("now".into()),
                String::from("error: unexpected 'now'; type `help` for the commands"),
            ),
        ];
        for (e, want) in cases {
            let mut out = String::new();
            write_parse_error(&mut out, &e).unwrap();
            assert_eq!(out, want);
        }
    }

    #[test]
    fn status_and_fault_lines_are_those_of_the_write_forms() {
        let kinds = [
            FaultKind::OverCurrent,
            FaultKind::EncoderLost,
            FaultKind::LimitSwitch,
        ];
        for (i, v) in samples().enumerate() {
            let b = |k: u32| (v.rotate_left(k) as u32) as i32;
            let s = StatusView {
                state: ["idle", "lifting", "fault"][i % 3],
                height: Metres::from_bits(b(0)),
                homed: i % 5 != 3,
                screw_speed: RadiansPerSecond::from_bits(b(7)),
                current: Amperes::from_bits(b(13)),
                friction_torque: NewtonMetres::from_bits(b(21)),
                stick_slip: i % 2 == 0,
                stick_slip_amplitude: NewtonMetres::from_bits(b(29)),
                stick_slip_episodes: b(37) as u32,
                fault: [None, Some("encoder lost"), Some("over-current")][i % 3],
                load: crate::ident::LoadReport {
                    load: crate::units::Kilograms::from_bits(b(45)),
                    load_lo: crate::units::Kilograms::from_bits(b(49)),
                    load_hi: crate::units::Kilograms::from_bits(b(51)),
                    identified: i % 2 == 1,
                    scale: Ratio::from_bits(b(55)),
                    scale_known: i % 3 == 1,
                    pairs: 0,
                },
                cruise_limit: (i % 4 == 2).then(|| RadiansPerSecond::from_bits(b(45))),
                #[cfg(feature = "ball-screw")]
                ball_f: (i % 4 == 1).then(|| (Ratio::from_bits(b(47)), Ratio::from_bits(b(53)))),
            };
            let mut out = String::new();
            write_status(&mut out, &s).unwrap();
            assert_eq!(out, reference::status(&s));
            let f = Fault {
                kind: kinds[i % 3],
                at: Instant(b(3) as u32),
                state: [State::Lifting, State::Lowering, State::Idle][i % 3],
                position: b(5),
                height: Metres::from_bits(b(11)),
                homed: i % 7 != 2,
                screw_speed: RadiansPerSecond::from_bits(b(17)),
                current: Amperes::from_bits(b(19)),
                supply: Volts::from_bits(b(23)),
                duty: b(31) as i16,
                measured_torque: NewtonMetres::from_bits(b(41)),
                model_torque: NewtonMetres::from_bits(b(43)),
                load: crate::units::Kilograms::from_bits(b(57)),
                load_identified: i % 5 == 1,
            };
            let mut out = String::new();
            service::write_fault(&mut out, Some(&f)).unwrap();
            assert_eq!(out, reference::fault(&f));
            let (lf, law) = (Ratio::from_bits(b(59)), Ratio::from_bits(b(61)));
            let mut out = String::new();
            write_lube_warning(&mut out, lf, law).unwrap();
            assert_eq!(
                out,
                format!(
                    "warning: ball-screw friction f={} {} the law's {} beyond \
                     ballscrew.lube_band (check lubrication and wear)",
                    reference::fixed(lf.to_bits(), 28, 5),
                    if lf > law { "above" } else { "below" },
                    reference::fixed(law.to_bits(), 28, 5)
                )
            );
        }
    }

    /// A number's unit text (one pass over the unit's spec) is the one its `Unit` accessors
    /// spell, for every setting and the goto height.
    #[test]
    fn unit_texts_are_those_of_the_unit_accessors() {
        fn twin(kind: &Kind) -> String {
            let Kind::Number {
                unit, none_at_max, ..
            } = kind
            else {
                unreachable!()
            };
            let mut t = String::from(unit.what());
            if !unit.display().is_empty() {
                t += " in ";
                t += unit.display();
            }
            let others: Vec<&str> = unit
                .accepts()
                .map(|(s, _)| s)
                .filter(|s| s.is_ascii() && !s.contains('*'))
                .collect();
            if !others.is_empty() {
                t += &format!(" (or {})", others.join(", "));
            }
            if *none_at_max {
                t += ", or none";
            }
            t
        }
        let kinds = settings::all()
            .map(|id| &id.setting().kind)
            .chain([&HEIGHT])
            .filter(|k| matches!(k, Kind::Number { .. }));
        let mut n = 0;
        for kind in kinds {
            let mut got = String::new();
            write_unit(&mut got, kind).unwrap();
            assert_eq!(got, twin(kind));
            n += 1;
        }
        assert!(n > 40);
    }

    /// Each choice setting's names (by their id in the registry) are the ones its range
    /// text lists.
    #[test]
    fn choice_names_are_those_of_the_range_text() {
        let mut n = 0;
        for id in settings::all() {
            let s = id.setting();
            if let Kind::Choice(_) = s.kind {
                let mut names = String::new();
                write_unit(&mut names, &s.kind).unwrap();
                assert_eq!(names, s.range, "{}", s.key);
                n += 1;
            }
        }
        assert_eq!(n, 7);
    }

    /// The firmware's `help` (no descriptions) names every command form the described one
    /// does, in its lines of at most 80 characters.
    #[test]
    fn brief_commands_help_names_every_command() {
        for form in [
            "status",
            "up",
            "down",
            "stop",
            "goto <height>",
            "limits",
            "get <key>",
            "set <key> <value>",
            "save",
            "fault",
            "fault clear",
            "version",
            "help keys",
            "help <key>",
        ] {
            assert!(COMMANDS_BRIEF.contains(form), "{form}");
            #[cfg(feature = "help-text")]
            assert!(COMMANDS.contains(form), "{form}");
        }
        assert_eq!(COMMANDS_BRIEF.lines().count(), 3);
        assert!(COMMANDS_BRIEF.lines().all(|l| l.trim_end().len() <= 80));
        // Every command word the parser knows is listed.
        for line in COMMANDS_BRIEF.lines().skip(1) {
            for form in line.split('|') {
                let w = form.split_whitespace().next().unwrap();
                assert!(
                    !matches!(parse(w.as_bytes()), Err(ParseError::UnknownCommand(_))),
                    "{w}"
                );
            }
        }
    }

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
