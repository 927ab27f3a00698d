//! The console service: one complete line in, the request executed against the running lift
//! and configuration, the reply out.
//!
//! [`handle`] parses a line with [`parse`], runs it against a [`Lift`] (the [`Controller`], or
//! whatever the firmware wraps it in) and the running [`ValidatedConfig`], and writes the reply
//! with the `write_*` functions of [`crate::console`] into any [`core::fmt::Write`]. It is
//! `no_std`, allocates nothing and never panics.
//!
//! Rules it keeps:
//! - `set` replaces the running configuration only when the whole changed copy validates
//!   ([`settings::apply`]) *and* the lift accepted it ([`Lift::reconfigure`]: at rest only).
//!   While the lift moves it is refused and nothing changes, so a motion never sees a
//!   half-applied change.
//! - `save` cannot finish here (the flash belongs to its owner, on the board the storage task):
//!   [`handle`] returns [`Action::Save`],
//!   the caller runs [`crate::config::store::ConfigStore::save`] on the running configuration
//!   and reports its result with [`write_saved`].
//! - `version` names the protocol ([`PROTOCOL_VERSION`]) so a host tool can refuse a board that
//!   speaks another one, and the settings schema so it knows whether its own registry matches.

use super::{
    parse, write_get, write_help, write_limits, write_parse_error, write_refused, write_status,
    Feed, ParseError, Request, StatusView,
};
use crate::config::store::StoreError;
use crate::config::{record, settings, ValidatedConfig};
use crate::control::config::ControlConfig;
use crate::control::{Command, Controller, Fault, Refusal, Status};
use crate::text::{self, fill, height_arg, Arg};
use crate::units::Metres;
use core::fmt::{self, Write};

/// The console protocol version `version` reports. Bump it when a reply a host tool parses
/// changes its form (not for new commands or keys).
pub const PROTOCOL_VERSION: u32 = 2;

/// The start of the `version` reply; the version number follows it directly.
pub const VERSION_PREFIX: &str = "liftfw console v";

/// What the service needs from the lift. [`Controller`] implements it; firmware that keeps the
/// controller in another task implements it on a handle that locks it for each call (each call
/// is short and none formats text).
pub trait Lift {
    /// A motion request ([`Controller::command`]).
    fn command(&mut self, cmd: Command) -> Result<(), Refusal>;
    /// A snapshot for `status`.
    fn status(&self) -> Status;
    /// The latched fault, if any.
    fn fault(&self) -> Option<Fault>;
    /// Run with `cfg` from the next tick on; refused while moving
    /// ([`Controller::reconfigure`]).
    fn reconfigure(&mut self, cfg: &ControlConfig) -> Result<(), Refusal>;
}

impl Lift for Controller {
    fn command(&mut self, cmd: Command) -> Result<(), Refusal> {
        Controller::command(self, cmd)
    }

    fn status(&self) -> Status {
        Controller::status(self)
    }

    fn fault(&self) -> Option<Fault> {
        Controller::fault(self).copied()
    }

    fn reconfigure(&mut self, cfg: &ControlConfig) -> Result<(), Refusal> {
        Controller::reconfigure(self, cfg)
    }
}

/// What the caller must do after [`handle`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Action {
    /// Nothing: the reply is complete.
    None,
    /// The running configuration changed (not saved); the reply is complete. Lets the caller
    /// log it or share the new configuration with other tasks.
    Reconfigured,
    /// `save`: store the running configuration (`ConfigStore::save`) and reply with
    /// [`write_saved`]. Nothing was written for this line yet.
    Save,
}

/// The result of one line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Outcome {
    /// What is left for the caller.
    pub action: Action,
    /// Whether the reply fit the sink (`Err`: it was cut short; the request was executed all
    /// the same).
    pub reply: fmt::Result,
}

impl Outcome {
    fn done(reply: fmt::Result) -> Outcome {
        Outcome {
            action: Action::None,
            reply,
        }
    }
}

/// The `status` view of a controller status.
pub fn status_view(s: &Status) -> StatusView {
    StatusView {
        state: s.state.name(),
        height: s.height,
        homed: s.homed,
        screw_speed: s.screw_speed,
        current: s.current,
        friction_torque: s.friction_torque,
        stick_slip: s.stick_slip,
        stick_slip_amplitude: s.stick_slip_amplitude,
        stick_slip_episodes: s.stick_slip_episodes,
        fault: s.fault.map(|f| f.name()),
        load: s.load,
        cruise_limit: s.cruise_limit,
        #[cfg(feature = "ball-screw")]
        ball_f: s.lube.map(|r| (r.f, r.law)),
    }
}

/// Handle what [`super::LineBuffer::feed`] returned: a line is [`handle`]d, an overlong line
/// gets its error, a pending one nothing.
pub fn handle_feed<L: Lift + ?Sized>(
    feed: Feed<'_>,
    lift: &mut L,
    running: &mut ValidatedConfig,
    out: &mut dyn Write,
) -> Outcome {
    match feed {
        Feed::Pending => Outcome::done(Ok(())),
        Feed::Overflow => Outcome::done(write_parse_error(out, &ParseError::TooLong)),
        Feed::Line(line) => handle(line, lift, running, out),
    }
}

/// Parse one complete line (without its end), execute it and write the reply (no line end:
/// the caller adds CRLF). An empty line or a comment writes nothing.
pub fn handle<L: Lift + ?Sized>(
    line: &[u8],
    lift: &mut L,
    running: &mut ValidatedConfig,
    out: &mut dyn Write,
) -> Outcome {
    let req = match parse(line) {
        Ok(Some(r)) => r,
        Ok(None) => return Outcome::done(Ok(())),
        Err(e) => return Outcome::done(write_parse_error(out, &e)),
    };
    match req {
        Request::Status => Outcome::done(write_status(out, &status_view(&lift.status()))),
        Request::Get(id) => Outcome::done(write_get(out, running, id)),
        Request::Set(id, raw) => set(id, raw, lift, running, out),
        Request::Save => Outcome {
            action: Action::Save,
            reply: Ok(()),
        },
        Request::Limits => Outcome::done(write_limits(out, running)),
        Request::Up => Outcome::done(motion(out, lift, Command::Up)),
        Request::Down => Outcome::done(motion(out, lift, Command::Down)),
        Request::Stop => Outcome::done(motion(out, lift, Command::Stop)),
        Request::Goto(h) => Outcome::done(motion(out, lift, Command::GoTo(h))),
        Request::Fault => Outcome::done(write_fault(out, lift.fault().as_ref())),
        Request::FaultClear => Outcome::done(match lift.command(Command::ClearFault) {
            Ok(()) => out.write_str("ok: fault cleared"),
            Err(Refusal::NoFault) => out.write_str("ok: no fault latched"),
            Err(r) => fill(out, "error: fault clear \x01", &[Arg::Str(r.message())]),
        }),
        Request::Help(topic) => Outcome::done(write_help(out, topic)),
        Request::Version => Outcome::done(write_version(out)),
    }
}

fn set<L: Lift + ?Sized>(
    id: settings::SettingId,
    raw: i64,
    lift: &mut L,
    running: &mut ValidatedConfig,
    out: &mut dyn Write,
) -> Outcome {
    let next = match settings::apply(running, id, raw) {
        Ok(next) => next,
        Err(e) => return Outcome::done(write_refused(out, id, &e, running)),
    };
    if next == *running {
        // Nothing changes: no need to disturb the controller (and fine while moving).
        return Outcome::done(write_set_ok(out, &next, id));
    }
    match lift.reconfigure(next.get()) {
        Ok(()) => {
            *running = next;
            Outcome {
                action: Action::Reconfigured,
                reply: write_set_ok(out, running, id),
            }
        }
        Err(r) => Outcome::done(write_set_refused(out, id, r)),
    }
}

fn write_set_refused(out: &mut dyn Write, id: settings::SettingId, r: Refusal) -> fmt::Result {
    fill(
        out,
        "error: set \x01 \x01; nothing changed",
        &[Arg::Str(id.key()), Arg::Str(r.message())],
    )
}

fn write_set_ok(
    out: &mut dyn Write,
    cfg: &ValidatedConfig,
    id: settings::SettingId,
) -> fmt::Result {
    out.write_str("ok: ")?;
    write_get(out, cfg, id)?;
    out.write_str(" (not saved; `save` stores it)")
}

fn motion<L: Lift + ?Sized>(out: &mut dyn Write, lift: &mut L, cmd: Command) -> fmt::Result {
    // The command's word for a refusal and its whole reply when accepted (one `fill` each way).
    let (word, ok) = match cmd {
        Command::Up => ("up", "ok: lifting to limits.upper"),
        Command::Down => ("down", "ok: lowering to limits.lower"),
        Command::Stop => ("stop", "ok: stop"),
        Command::GoTo(_) => ("goto", "ok: going to \x01 mm"),
        Command::ClearFault => ("fault clear", "ok: fault clear"),
    };
    let target = match cmd {
        Command::GoTo(h) => h,
        _ => Metres::ZERO,
    };
    match lift.command(cmd) {
        Ok(()) => fill(out, ok, &[Arg::Mm(target)]),
        Err(r) => fill(
            out,
            "error: \x01 \x01",
            &[Arg::Str(word), Arg::Str(r.message())],
        ),
    }
}

/// The reply to `version`: `liftfw console v2 firmware=0.1.0 schema=1a2b3c4d` (the schema is
/// the flash record's fingerprint of the settings list, [`record::schema`]).
pub fn write_version(out: &mut dyn Write) -> fmt::Result {
    out.write_str(VERSION_HEAD)?;
    text::hex8(out, record::schema())
}

/// The `version` reply up to the schema, one text: [`VERSION_PREFIX`], [`PROTOCOL_VERSION`]
/// and the firmware's version (a test checks it against the two constants).
const VERSION_HEAD: &str = concat!(
    "liftfw console v",
    "2",
    " firmware=",
    env!("CARGO_PKG_VERSION"),
    " schema="
);

/// The reply to `fault`, `key=value` like `status`: `fault=none`, or the fault and the state
/// of the lift when it tripped: `fault=over-current t=12.345s state=lifting height=212.4mm
/// speed=3.00rad/s current=61.20A supply=12.31V duty=85.0% torque=1.234Nm model_torque=1.100Nm
/// load=1000kg load_src=current` (the load when it tripped: identified from the current, or
/// the prior, as `status` says).
pub fn write_fault(out: &mut dyn Write, fault: Option<&Fault>) -> fmt::Result {
    let Some(f) = fault else {
        return out.write_str("fault=none");
    };
    // Milliseconds since boot: at most 2^32 µs / 1000, an i32.
    let ms = (f.at.0 / 1000) as i32;
    // The fault's name may contain spaces; `-` keeps the line `key=value`.
    fill(
        out,
        "fault=\x01 t=\x01s state=\x01 height=\x01\x01 speed=\x01rad/s current=\x01A supply=\x01V \
         duty=\x01% torque=\x01Nm model_torque=\x01Nm load=\x01kg load_src=\x01",
        &[
            Arg::Word(f.kind.name()),
            Arg::Deci(ms, 3),
            Arg::Str(f.state.name()),
            height_arg(f.height, f.homed),
            Arg::Str(if f.homed { "mm" } else { "" }),
            Arg::Fixed(f.screw_speed.to_bits(), 16, 2),
            Arg::Fixed(f.current.to_bits(), 16, 2),
            Arg::Fixed(f.supply.to_bits(), 16, 2),
            // Duty Q15 in percent with one decimal: duty·100 with 15 fractional bits, rounded
            // half away from zero (|duty| ≤ 32768: no overflow in i32).
            Arg::Fixed(i32::from(f.duty) * 100, 15, 1),
            Arg::Fixed(f.measured_torque.to_bits(), 16, 3),
            Arg::Fixed(f.model_torque.to_bits(), 16, 3),
            Arg::Fixed(f.load.to_bits(), 12, 0),
            Arg::Str(super::reply::load_src(f.load_identified)),
        ],
    )
}

/// The reply to `save`, once the caller has run `ConfigStore::save`: `ok: saved as
/// configuration #7`, or why it failed and what the flash holds.
pub fn write_saved(out: &mut dyn Write, result: Result<u32, StoreError>) -> fmt::Result {
    match result {
        Ok(seq) => fill(out, "ok: saved as configuration #\x01", &[Arg::Uint(seq)]),
        Err(e) => fill(
            out,
            "error: save failed (\x01); flash holds the previous configuration or this one, \
             never a mix; the running settings are unchanged",
            &[Arg::Str(e.message())],
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    extern crate std;
    use std::format;
    use std::string::String;

    /// A fault's duty (Q15) shows as the percentage rounded half away from zero to one
    /// decimal: the same text as the per-mille integer formula it replaced, for every duty.
    #[test]
    fn duty_percent_is_the_rounded_per_mille_for_every_duty() {
        for d in i16::MIN..=i16::MAX {
            let permille = (i32::from(d) * 1000 + if d < 0 { -16384 } else { 16384 }) / 32768;
            let (mut got, mut want) = (String::new(), String::new());
            fill(&mut got, "\x01", &[Arg::Fixed(i32::from(d) * 100, 15, 1)]).unwrap();
            fill(&mut want, "\x01", &[Arg::Deci(permille, 1)]).unwrap();
            assert_eq!(got, want, "{d}");
        }
    }

    /// The `version` reply's one text spells the two constants host tools read it by.
    #[test]
    fn the_version_reply_spells_the_protocol_constants() {
        let mut s = String::new();
        write_version(&mut s).unwrap();
        let head = format!(
            "{VERSION_PREFIX}{PROTOCOL_VERSION} firmware={} schema=",
            env!("CARGO_PKG_VERSION")
        );
        assert_eq!(VERSION_HEAD, head);
        assert_eq!(s, format!("{head}{:08x}", record::schema()));
    }
}
