//! The board's console over a serial port or TCP (host-sim): one line out, one reply line in,
//! every reply checked for its form.
//!
//! A reply that does not arrive within the timeout, that is not text, or that does not have the
//! form the command's reply has is an error ([`Error::Timeout`], [`Error::Garbled`]); a board
//! that answers `version` with another protocol is [`Error::Protocol`] and nothing else is sent.

use liftfw::console::service::{PROTOCOL_VERSION, VERSION_PREFIX};
use std::collections::BTreeMap;
use std::fmt;
use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The longest wait for a reply `--timeout` takes, s (an hour: longer is a typo).
pub const MAX_TIMEOUT_S: f64 = 3600.0;

/// A wait for a reply reads in slices this long, so that Ctrl-C ends it soon.
const SLICE: Duration = Duration::from_millis(50);

/// Refuse text with a control character (CR, LF, NUL, ESC, tab…) before it reaches the board:
/// the board ends a line at CR or LF, so `32\rmA` would arrive as the value `32` and a second
/// line `mA`, and a `get` key could carry a whole second command. `what` names the argument.
pub fn check_text(what: &str, text: &str) -> Result<(), Error> {
    match text.chars().find(|c| c.is_control()) {
        None => Ok(()),
        Some(c) => Err(Error::Invalid(format!(
            "liftctl: refused: {what} {:?} contains the control character {:?}; nothing was \
             sent",
            text, c
        ))),
    }
}

/// What went wrong talking to the board.
#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// The port or address could not be opened.
    Connect(String),
    /// No complete reply within the timeout.
    Timeout {
        /// The line sent.
        sent: String,
        /// Seconds waited.
        secs: f64,
    },
    /// A reply that is not text or not of the expected form.
    Garbled {
        /// The line sent.
        sent: String,
        /// What came back (lossy text).
        got: String,
    },
    /// The connection closed or the port failed.
    Lost(String),
    /// The board speaks another console protocol (its `version` reply).
    Protocol(String),
    /// The board's settings list differs from this liftctl's.
    Schema {
        /// The board's schema.
        board: String,
        /// Ours.
        ours: String,
    },
    /// The board refused: its `error:` line, unchanged.
    Board(String),
    /// liftctl refused before sending anything (the firmware's own rules and message).
    Invalid(String),
    /// A local file or argument problem.
    Local(String),
    /// Ctrl-C while waiting for a reply.
    Interrupted {
        /// The line sent.
        sent: String,
    },
    /// A change failed part-way (`cause`); `note` says what liftctl did about the ones before.
    Undone {
        /// Why it stopped.
        cause: Box<Error>,
        /// What became of the earlier changes.
        note: String,
    },
}

impl Error {
    /// The message for the terminal: the board's (and the firmware's) words unchanged, liftctl's
    /// own prefixed with `liftctl:`.
    pub fn report(&self) -> String {
        match self {
            Error::Board(m) | Error::Invalid(m) => m.clone(),
            Error::Undone { cause, note } => format!("{}\nliftctl: {note}", cause.report()),
            e => format!("liftctl: {e}"),
        }
    }

    /// Exit code: 1 refused (by the board or by liftctl's checks), 2 no or bad reply (and a
    /// wait for one interrupted by Ctrl-C), 3 local (files, arguments).
    pub fn exit_code(&self) -> u8 {
        match self {
            Error::Board(_) | Error::Invalid(_) => 1,
            Error::Local(_) => 3,
            Error::Undone { cause, .. } => cause.exit_code(),
            _ => 2,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Connect(m) => write!(f, "cannot open the board's console: {m}"),
            Error::Timeout { sent, secs } => write!(
                f,
                "no reply to `{sent}` within {secs} s (a lost line, a board that is off, or the \
                 wrong port/baud rate)"
            ),
            Error::Garbled { sent, got } => write!(
                f,
                "garbled reply to `{sent}`: {got:?} (noise on the line, the wrong baud rate, or \
                 not a liftfw console)"
            ),
            Error::Lost(m) => write!(f, "connection to the board lost: {m}"),
            Error::Protocol(v) => write!(
                f,
                "the board answers `version` with {v:?}; this liftctl speaks \
                 {VERSION_PREFIX}{PROTOCOL_VERSION}: update liftctl or the firmware (nothing was \
                 sent)"
            ),
            Error::Schema { board, ours } => write!(
                f,
                "the board's settings list (schema {board}) differs from this liftctl's (schema \
                 {ours}): it cannot check settings for this firmware; use a liftctl built from \
                 the same sources (nothing was sent)"
            ),
            Error::Board(m) | Error::Invalid(m) => f.write_str(m),
            Error::Local(m) => f.write_str(m),
            Error::Interrupted { sent } => write!(
                f,
                "interrupted (Ctrl-C) while waiting for the reply to `{sent}`; the board may \
                 have executed it"
            ),
            Error::Undone { cause, note } => write!(f, "{cause}\n{note}"),
        }
    }
}

impl std::error::Error for Error {}

/// A byte stream with a settable read timeout.
pub trait Link: Read + Write + Send {
    /// Reads block at most this long.
    fn set_timeout(&mut self, d: Duration) -> io::Result<()>;
}

impl Link for TcpStream {
    fn set_timeout(&mut self, d: Duration) -> io::Result<()> {
        self.set_read_timeout(Some(d.max(Duration::from_millis(1))))
    }
}

impl Link for Box<dyn serialport::SerialPort> {
    fn set_timeout(&mut self, d: Duration) -> io::Result<()> {
        serialport::SerialPort::set_timeout(self.as_mut(), d.max(Duration::from_millis(1)))
            .map_err(io::Error::other)
    }
}

/// What `version` said.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Version {
    /// The whole reply.
    pub line: String,
    /// `firmware=`.
    pub firmware: String,
    /// `schema=`.
    pub schema: String,
}

/// A board's console.
pub struct Board {
    link: Box<dyn Link>,
    buf: Vec<u8>,
    timeout: Duration,
    /// Set by Ctrl-C: a wait for a reply ends with [`Error::Interrupted`].
    stop: Option<Arc<AtomicBool>>,
    /// The `version` reply of the handshake.
    pub version: Version,
}

/// This liftctl's settings schema, as `version` prints it.
pub fn our_schema() -> String {
    format!("{:08x}", liftfw::config::record::schema())
}

/// Open `target`: `tcp://host:port` (host-sim serve) or a serial port (`/dev/ttyUSB0`, `COM3`)
/// at `baud` 8N1, and check the protocol version.
/// `stop` (Ctrl-C) ends any wait for a reply, the handshake's included.
pub fn open(
    target: &str,
    baud: u32,
    timeout: Duration,
    stop: Option<Arc<AtomicBool>>,
) -> Result<Board, Error> {
    let link: Box<dyn Link> = if let Some(addr) = target.strip_prefix("tcp://") {
        let sa = addr
            .to_socket_addrs()
            .map_err(|e| Error::Connect(format!("{target}: {e}")))?
            .next()
            .ok_or_else(|| Error::Connect(format!("{target}: no address")))?;
        let s = TcpStream::connect_timeout(&sa, timeout)
            .map_err(|e| Error::Connect(format!("{target}: {e}")))?;
        let _ = s.set_nodelay(true);
        Box::new(s)
    } else {
        let p = serialport::new(target, baud)
            .timeout(timeout)
            .open()
            .map_err(|e| Error::Connect(format!("{target}: {e}")))?;
        Box::new(p)
    };
    Board::handshake(link, timeout, stop)
}

impl Board {
    /// Over any link: end whatever partial line the board holds, then `version`.
    pub fn handshake(
        link: Box<dyn Link>,
        timeout: Duration,
        stop: Option<Arc<AtomicBool>>,
    ) -> Result<Board, Error> {
        let mut b = Board {
            link,
            buf: Vec::new(),
            timeout,
            stop,
            version: Version {
                line: String::new(),
                firmware: String::new(),
                schema: String::new(),
            },
        };
        b.send("")?;
        b.drain(Duration::from_millis(30));
        b.version = b.query_version()?;
        Ok(b)
    }

    fn query_version(&mut self) -> Result<Version, Error> {
        let deadline = Instant::now() + self.timeout;
        self.drain(Duration::from_millis(1));
        self.send("version")?;
        loop {
            let line = self.read_line("version", deadline)?;
            let t = line.trim();
            // Blank lines, the echo, and a stale error for the line the handshake ended.
            if t.is_empty() || t == "version" || t.starts_with("error:") {
                continue;
            }
            let Some(rest) = t.strip_prefix(VERSION_PREFIX) else {
                return Err(Error::Protocol(t.to_string()));
            };
            let n: String = rest.chars().take_while(char::is_ascii_digit).collect();
            if n != PROTOCOL_VERSION.to_string() {
                return Err(Error::Protocol(t.to_string()));
            }
            let kv = words(t);
            return Ok(Version {
                line: t.to_string(),
                firmware: kv.get("firmware").cloned().unwrap_or_default(),
                schema: kv.get("schema").cloned().unwrap_or_default(),
            });
        }
    }

    /// Ctrl-C sets `stop`: from then on a wait for a reply ends at once with
    /// [`Error::Interrupted`] (`None`: waits run to their timeout).
    pub fn set_interrupt(&mut self, stop: Option<Arc<AtomicBool>>) {
        self.stop = stop;
    }

    /// The Ctrl-C flag ([`Self::set_interrupt`]).
    pub fn interrupt(&self) -> Option<Arc<AtomicBool>> {
        self.stop.clone()
    }

    /// Whether the board's settings list is this liftctl's.
    pub fn check_schema(&self) -> Result<(), Error> {
        if self.version.schema == our_schema() {
            Ok(())
        } else {
            Err(Error::Schema {
                board: self.version.schema.clone(),
                ours: our_schema(),
            })
        }
    }

    fn send(&mut self, line: &str) -> Result<(), Error> {
        check_text("the line", line)?;
        self.link
            .write_all(format!("{line}\r\n").as_bytes())
            .and_then(|()| self.link.flush())
            .map_err(|e| Error::Lost(e.to_string()))
    }

    /// Discard whatever arrives within `quiet` (stale replies of an earlier timeout).
    fn drain(&mut self, quiet: Duration) {
        self.buf.clear();
        let _ = self.link.set_timeout(quiet);
        let mut tmp = [0u8; 256];
        for _ in 0..64 {
            match self.link.read(&mut tmp) {
                Ok(n) if n > 0 => {}
                _ => break,
            }
        }
    }

    fn read_line(&mut self, sent: &str, deadline: Instant) -> Result<String, Error> {
        let mut tmp = [0u8; 256];
        loop {
            if let Some(i) = self.buf.iter().position(|&b| b == b'\n') {
                let raw: Vec<u8> = self.buf.drain(..=i).collect();
                let text = std::str::from_utf8(&raw[..i])
                    .ok()
                    .map(|s| s.trim_end_matches('\r'));
                return match text {
                    Some(s) if !s.chars().any(char::is_control) => Ok(s.to_string()),
                    _ => Err(Error::Garbled {
                        sent: sent.to_string(),
                        got: String::from_utf8_lossy(&raw).trim_end().to_string(),
                    }),
                };
            }
            if self.buf.len() > 4096 {
                let got = String::from_utf8_lossy(&self.buf[..80]).to_string();
                self.buf.clear();
                return Err(Error::Garbled {
                    sent: sent.to_string(),
                    got,
                });
            }
            if self.stop.as_ref().is_some_and(|s| s.load(Ordering::SeqCst)) {
                return Err(Error::Interrupted {
                    sent: sent.to_string(),
                });
            }
            let now = Instant::now();
            if now >= deadline {
                return Err(Error::Timeout {
                    sent: sent.to_string(),
                    secs: self.timeout.as_secs_f64(),
                });
            }
            self.link
                .set_timeout((deadline - now).min(SLICE))
                .map_err(|e| Error::Lost(e.to_string()))?;
            match self.link.read(&mut tmp) {
                Ok(0) => return Err(Error::Lost("the board closed the connection".into())),
                Ok(n) => self.buf.extend_from_slice(&tmp[..n]),
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock
                            | io::ErrorKind::TimedOut
                            | io::ErrorKind::Interrupted
                    ) => {}
                Err(e) => return Err(Error::Lost(e.to_string())),
            }
        }
    }

    /// Send one command and return its reply line (blank lines and an echo of the command are
    /// skipped; a `warning:` line the board sends of its own accord is shown on stderr, as
    /// it came, and skipped).
    pub fn ask(&mut self, cmd: &str) -> Result<String, Error> {
        self.drain(Duration::from_millis(1));
        self.send(cmd)?;
        let deadline = Instant::now() + self.timeout;
        loop {
            let line = self.read_line(cmd, deadline)?;
            let t = line.trim();
            if t.is_empty() || t == cmd.trim() {
                continue;
            }
            if t.starts_with("warning:") {
                eprintln!("{t}");
                continue;
            }
            return Ok(t.to_string());
        }
    }

    /// A command whose reply is `ok: …` or `error: …`; `Ok` carries the reply, an `error:`
    /// line is [`Error::Board`] unchanged, anything else [`Error::Garbled`].
    pub fn ask_ok(&mut self, cmd: &str) -> Result<String, Error> {
        let r = self.ask(cmd)?;
        if ok_form(cmd, &r) {
            Ok(r)
        } else if r.starts_with("error:") {
            Err(Error::Board(r))
        } else {
            Err(Error::Garbled {
                sent: cmd.to_string(),
                got: r,
            })
        }
    }

    /// `status` as its `key=value` pairs (all seven keys checked present).
    pub fn status(&mut self) -> Result<Status, Error> {
        let r = self.ask("status")?;
        Status::parse(&r).ok_or(Error::Garbled {
            sent: "status".into(),
            got: r,
        })
    }

    /// `get key` → the value text (`410 mm`), which `set` takes back exactly.
    pub fn get(&mut self, key: &str) -> Result<String, Error> {
        let cmd = format!("get {key}");
        let r = self.ask(&cmd)?;
        if r.starts_with("error:") {
            return Err(Error::Board(r));
        }
        match r.strip_prefix(key).and_then(|s| s.strip_prefix(" = ")) {
            Some(v) if !v.is_empty() => Ok(v.to_string()),
            _ => Err(Error::Garbled { sent: cmd, got: r }),
        }
    }

    /// `set key text` → the value the board now runs with.
    pub fn set(&mut self, key: &str, text: &str) -> Result<String, Error> {
        let cmd = format!("set {key} {text}");
        let r = self.ask_ok(&cmd)?;
        let prefix = format!("ok: {key} = ");
        match r.strip_prefix(&prefix) {
            Some(v) => Ok(v.split(" (").next().unwrap_or(v).to_string()),
            None => Err(Error::Garbled { sent: cmd, got: r }),
        }
    }

    /// `limits` (the stops and the mechanism's range).
    pub fn limits(&mut self) -> Result<String, Error> {
        let r = self.ask("limits")?;
        if r.starts_with("limits.lower = ") && r.contains("limits.upper = ") {
            Ok(r)
        } else {
            Err(Error::Garbled {
                sent: "limits".into(),
                got: r,
            })
        }
    }

    /// `fault` as its `key=value` pairs.
    pub fn fault(&mut self) -> Result<BTreeMap<String, String>, Error> {
        let r = self.ask("fault")?;
        let kv = words(&r);
        if r.starts_with("fault=") && kv.contains_key("fault") {
            Ok(kv)
        } else {
            Err(Error::Garbled {
                sent: "fault".into(),
                got: r,
            })
        }
    }
}

/// Whether `reply` is the board's `ok:` reply to `cmd` (docs/console.md "Commands"), not
/// just any line starting `ok:` (`ok: sure` to `up` is garbage, not a lift going up).
pub fn ok_form(cmd: &str, reply: &str) -> bool {
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    let height = |s: &str| {
        s.strip_suffix(" mm").is_some_and(|n| {
            let n = n.strip_prefix('-').unwrap_or(n);
            matches!(n.split_once('.'), Some((a, b)) if digits(a) && digits(b))
        })
    };
    // An accepted motion may say its cruise speed was limited: ` (cruise limited to …)`.
    let motion = |r: &str, head: &str| {
        r.strip_prefix(head)
            .is_some_and(|rest| rest.is_empty() || rest.starts_with(" (cruise limited to "))
    };
    let word = cmd
        .split_whitespace()
        .next()
        .unwrap_or("")
        .to_ascii_lowercase();
    match word.as_str() {
        "up" => motion(reply, "ok: lifting to limits.upper"),
        "down" => motion(reply, "ok: lowering to limits.lower"),
        "stop" => reply == "ok: stop",
        "goto" => reply.strip_prefix("ok: going to ").is_some_and(|r| {
            let h = r.split(" (cruise limited to ").next().unwrap_or(r);
            height(h) && motion(r, h)
        }),
        "save" => reply
            .strip_prefix("ok: saved as configuration #")
            .is_some_and(digits),
        "fault" => reply == "ok: fault cleared" || reply == "ok: no fault latched",
        // `set` checks the rest of its reply itself (`Board::set`).
        _ => reply.starts_with("ok: ") && reply.len() > 4,
    }
}

/// `key=value` words of a line.
pub fn words(line: &str) -> BTreeMap<String, String> {
    line.split_whitespace()
        .filter_map(|w| w.split_once('='))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

/// A `status` reply.
#[derive(Clone, Debug, PartialEq)]
pub struct Status {
    /// `idle`, `lifting`, `lowering`, `holding`, `fault`.
    pub state: String,
    /// Head height, mm; `None` while the board is unhomed (`height=unknown homed=no`: it
    /// does not know where the head is).
    pub height_mm: Option<f64>,
    /// Screw speed, rad/s.
    pub speed: f64,
    /// Motor current, A.
    pub current: f64,
    /// Estimated thread friction torque T_r, N·m.
    pub friction_torque: f64,
    /// Stick-slip detected.
    pub stick_slip: bool,
    /// `none` or the fault's name.
    pub fault: String,
    /// The board knows the position (`homed=yes`).
    pub homed: bool,
}

impl Status {
    /// Parse `state=… height=…mm speed=…rad/s current=…A T_r=…Nm stick_slip=… fault=…
    /// homed=yes|no` (`height=unknown` with `homed=no`). Every number must be finite.
    pub fn parse(line: &str) -> Option<Status> {
        let kv = words(line);
        let num = |k: &str, unit: &str| -> Option<f64> {
            // Digits, sign and point only: Rust's parser also takes `nan`, `inf`, `1e5`.
            let v = kv.get(k)?.strip_suffix(unit)?;
            if v.is_empty()
                || !v
                    .bytes()
                    .all(|b| b.is_ascii_digit() || b == b'.' || b == b'-')
            {
                return None;
            }
            v.parse::<f64>().ok().filter(|x| x.is_finite())
        };
        let homed = match kv.get("homed")?.as_str() {
            "yes" => true,
            "no" => false,
            _ => return None,
        };
        let state = kv.get("state")?.clone();
        let known = ["idle", "lifting", "lowering", "holding", "fault"];
        if !known.contains(&state.as_str()) {
            return None;
        }
        Some(Status {
            state,
            height_mm: match (homed, kv.get("height")?.as_str()) {
                (false, "unknown") => None,
                (true, _) => Some(num("height", "mm")?),
                _ => return None,
            },
            speed: num("speed", "rad/s")?,
            current: num("current", "A")?,
            friction_torque: num("T_r", "Nm")?,
            stick_slip: match kv.get("stick_slip")?.as_str() {
                "yes" => true,
                "no" => false,
                _ => return None,
            },
            fault: kv.get("fault")?.clone(),
            homed,
        })
    }

    /// At rest (not lifting or lowering).
    pub fn at_rest(&self) -> bool {
        !matches!(self.state.as_str(), "lifting" | "lowering")
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn status_parses_and_refuses_garbage() {
        let s = Status::parse(
            "state=lifting height=212.4mm speed=3.00rad/s current=12.35A T_r=0.851Nm \
             stick_slip=no fault=none homed=yes",
        );
        assert_eq!(
            s,
            Some(Status {
                state: "lifting".into(),
                height_mm: Some(212.4),
                speed: 3.0,
                current: 12.35,
                friction_torque: 0.851,
                stick_slip: false,
                fault: "none".into(),
                homed: true,
            })
        );
        let unhomed = Status::parse(
            "state=idle height=unknown speed=0.00rad/s current=0.00A T_r=0.000Nm stick_slip=no \
             fault=none homed=no",
        )
        .unwrap();
        assert_eq!((unhomed.height_mm, unhomed.homed), (None, false));
        for bad in [
            "",
            "state=lifting height=212.4mm",
            "state=lifxing height=212.4mm speed=3.00rad/s current=12.35A T_r=0.851Nm stick_slip=no fault=none homed=yes",
            "state=lifting height=21#.4mm speed=3.00rad/s current=12.35A T_r=0.851Nm stick_slip=no fault=none homed=yes",
            "state=lifting height=212.4 speed=3.00rad/s current=12.35A T_r=0.851Nm stick_slip=no fault=none homed=yes",
            // Numbers Rust's parser takes but the board never writes, and a lost `homed`.
            "state=idle height=nanmm speed=0.00rad/s current=0.00A T_r=0.000Nm stick_slip=no fault=none homed=yes",
            "state=idle height=infmm speed=0.00rad/s current=0.00A T_r=0.000Nm stick_slip=no fault=none homed=yes",
            "state=idle height=1e3mm speed=0.00rad/s current=0.00A T_r=0.000Nm stick_slip=no fault=none homed=yes",
            "state=idle height=212.4mm speed=0.00rad/s current=0.00A T_r=0.000Nm stick_slip=no fault=none",
            "state=idle height=unknown speed=0.00rad/s current=0.00A T_r=0.000Nm stick_slip=no fault=none homed=yes",
        ] {
            assert_eq!(Status::parse(bad), None, "{bad}");
        }
    }
}
