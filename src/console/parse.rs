//! The parser: one line in, a [`Request`] or a [`ParseError`] out.

use super::{value, ValueError, Words, MAX_LINE};
use crate::config::settings::{self, Kind, SettingId};
use crate::text;
use crate::units::Metres;

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
    /// [`super::write_set`].
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
    /// `version`: the protocol version, for host tools ([`super::service::write_version`]).
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
    /// A control byte other than tab (NUL, ESC, BEL, CR or LF inside the line…): the whole
    /// line is refused, so nothing a terminal or a script slipped in runs half a command.
    Control(u8),
    /// Longer than [`MAX_LINE`].
    TooLong,
    /// The first word is no command.
    UnknownCommand(Words<'a>),
    /// A command that needs a key got none.
    MissingKey(&'static str),
    /// No setting has this key.
    UnknownKey(Words<'a>),
    /// `set <key>` without a value.
    MissingValue(SettingId),
    /// The value for a key was not understood.
    BadValue(SettingId, ValueError),
    /// `goto` without a height or with a bad one.
    BadHeight(ValueError),
    /// Words left over after a complete command.
    Trailing(Words<'a>),
}

/// The unit and range the `goto` height takes.
pub(super) const HEIGHT: Kind = Kind::Number {
    frac: 24,
    pow10: 3,
    unit: settings::MILLIMETRES,
    none_at_max: false,
};

/// Split off the first word (ASCII whitespace separated; all trimming here is ASCII: a
/// person's terminal sends no other whitespace, and Unicode's would link its table).
/// An ASCII byte never splits a UTF-8 sequence: both parts stay valid UTF-8.
fn word(s: &[u8]) -> (&[u8], &[u8]) {
    let s = s.trim_ascii_start();
    match s
        .iter()
        .position(|b| b.is_ascii_whitespace())
        .and_then(|i| s.split_at_checked(i))
    {
        Some((w, rest)) => (w, rest.trim_ascii_start()),
        None => (s, &[]),
    }
}

fn no_more(rest: &[u8], r: Request) -> Result<Option<Request>, ParseError<'_>> {
    let rest = rest.trim_ascii();
    if rest.is_empty() {
        Ok(Some(r))
    } else {
        Err(ParseError::Trailing(Words(rest)))
    }
}

fn key<'a>(cmd: &'static str, rest: &'a [u8]) -> Result<(SettingId, &'a [u8]), ParseError<'a>> {
    let (k, rest) = word(rest);
    if k.is_empty() {
        return Err(ParseError::MissingKey(cmd));
    }
    settings::find(k)
        .map(|id| (id, rest))
        .ok_or(ParseError::UnknownKey(Words(k)))
}

/// Parse one line (without its line end). `Ok(None)`: an empty line or a `#` comment.
/// Commands, keys, units and choices are case-insensitive.
pub fn parse(line: &[u8]) -> Result<Option<Request>, ParseError<'_>> {
    if line.len() > MAX_LINE {
        return Err(ParseError::TooLong);
    }
    // Checked, then parsed as bytes (see `Words`): every word cut from it at ASCII whitespace
    // is valid UTF-8 too.
    if !text::is_utf8(line) {
        return Err(ParseError::NotText);
    }
    if let Some(&b) = line
        .iter()
        .find(|&&b| (b < 0x20 && b != b'\t') || b == 0x7F)
    {
        return Err(ParseError::Control(b));
    }
    let line = line.trim_ascii();
    if line.is_empty() || line.first() == Some(&b'#') {
        return Ok(None);
    }
    let (cmd, rest) = word(line);
    // One search of a table instead of a compare per command.
    let Some(i) = COMMAND_WORDS
        .iter()
        .position(|name| cmd.eq_ignore_ascii_case(name.as_bytes()))
    else {
        return Err(ParseError::UnknownCommand(Words(cmd)));
    };
    let simple = match i {
        0 => Request::Status,
        1 => Request::Save,
        2 => Request::Limits,
        3 => Request::Up,
        4 => Request::Down,
        5 => Request::Stop,
        6 => Request::Version,
        7 => {
            let (id, rest) = key("get", rest)?;
            return no_more(rest, Request::Get(id));
        }
        8 => {
            let (id, rest) = key("set", rest)?;
            if rest.is_empty() {
                return Err(ParseError::MissingValue(id));
            }
            let raw =
                value::parse(&id.setting().kind, rest).map_err(|e| ParseError::BadValue(id, e))?;
            return Ok(Some(Request::Set(id, raw)));
        }
        9 => {
            let raw = value::parse(&HEIGHT, rest).map_err(ParseError::BadHeight)?;
            let bits =
                i32::try_from(raw).map_err(|_| ParseError::BadHeight(ValueError::TooLarge))?;
            return Ok(Some(Request::Goto(Metres::from_bits(bits))));
        }
        10 => {
            let (sub, rest) = word(rest);
            return if sub.is_empty() {
                Ok(Some(Request::Fault))
            } else if sub.eq_ignore_ascii_case(b"clear") {
                no_more(rest, Request::FaultClear)
            } else {
                Err(ParseError::Trailing(Words(sub)))
            };
        }
        // `help` and `?`.
        _ => {
            let (topic, rest) = word(rest);
            return if topic.is_empty() {
                Ok(Some(Request::Help(HelpTopic::Commands)))
            } else if topic.eq_ignore_ascii_case(b"keys") {
                no_more(rest, Request::Help(HelpTopic::Keys))
            } else {
                let id = settings::find(topic).ok_or(ParseError::UnknownKey(Words(topic)))?;
                no_more(rest, Request::Help(HelpTopic::Key(id)))
            };
        }
    };
    no_more(rest, simple)
}

/// The command words [`parse`] knows, by the position it dispatches on.
const COMMAND_WORDS: [&str; 13] = [
    "status", "save", "limits", "up", "down", "stop", "version", "get", "set", "goto", "fault",
    "help", "?",
];
