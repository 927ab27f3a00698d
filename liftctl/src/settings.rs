//! Settings on the PC side: the board's running configuration mirrored through `get`, changes
//! checked with the core's own parser and registry (`liftfw::console::parse`,
//! `liftfw::config::settings`) before anything is sent, sent in an order in which every step
//! is valid, and undone if the board refuses one or a reply is lost. TOML export and import.

use crate::board::{Board, Error};
use liftfw::config::settings::{self, SettingId};
use liftfw::config::ValidatedConfig;
use liftfw::console::{self, Request};
use std::fmt::Write as _;

/// One change: the setting, its raw bits, and the text sent to the board.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Change {
    /// The setting.
    pub id: SettingId,
    /// Raw bits (as the core parses the text).
    pub raw: i64,
    /// The text the user gave, sent as is.
    pub text: String,
}

/// Parse `key value` exactly as the firmware would; its message if it would refuse.
pub fn parse_change(key: &str, value: &str) -> Result<Change, Error> {
    let line = format!("set {key} {value}");
    match console::parse(line.as_bytes()) {
        Ok(Some(Request::Set(id, raw))) => Ok(Change {
            id,
            raw,
            text: value.trim().to_string(),
        }),
        Ok(_) => Err(Error::Invalid(format!("error: `set {key}` needs a value"))),
        Err(e) => {
            let mut s = String::new();
            let _ = console::write_parse_error(&mut s, &e);
            Err(Error::Invalid(s))
        }
    }
}

/// The ball-screw variant's keys (`BALL_PREFIX`): liftctl knows them (it is built with them), a
/// board running the default lead-screw image refuses them. That image's refusal of one
/// (`liftfw::config::settings::unknown_key_template`).
const NEEDS_BALL_IMAGE: &str = "needs the ball-screw firmware";

/// The board's running configuration, read key by key, and the text of each stored value.
pub struct Mirror {
    /// As validated here (the board's configuration passes the same validation).
    pub config: ValidatedConfig,
    /// `(key, value text)` for every setting the board has, in registry order
    /// (`friction.law` included).
    pub texts: Vec<(&'static str, String)>,
    /// The board runs the lead-screw image: it has no `ballscrew.*` settings. They keep their
    /// factory values in `config` and are not in `texts`.
    pub lead_image: bool,
}

impl Mirror {
    /// Read every setting with `get`.
    pub fn read(board: &mut Board) -> Result<Mirror, Error> {
        let mut cfg = *ValidatedConfig::factory().get();
        let mut texts = Vec::new();
        let mut lead_image = false;
        for id in settings::all() {
            let s = id.setting();
            let text = match board.get(s.key) {
                Ok(text) => text,
                Err(Error::Board(r))
                    if s.key.starts_with(settings::BALL_PREFIX) && r.contains(NEEDS_BALL_IMAGE) =>
                {
                    lead_image = true;
                    continue;
                }
                Err(e) => return Err(e),
            };
            if s.stored() {
                let c = parse_change(s.key, &text).map_err(|_| Error::Garbled {
                    sent: format!("get {}", s.key),
                    got: text.clone(),
                })?;
                s.set(&mut cfg, c.raw);
            }
            texts.push((s.key, text));
        }
        let config = ValidatedConfig::new(cfg).map_err(|e| {
            Error::Local(format!(
                "the board's settings do not pass this liftctl's validation ({e}); is it built \
                 from the same sources?"
            ))
        })?;
        Ok(Mirror {
            config,
            texts,
            lead_image,
        })
    }

    /// The value text of `id`.
    pub fn text(&self, id: SettingId) -> &str {
        self.texts
            .iter()
            .find(|(k, _)| *k == id.key())
            .map_or("", |(_, t)| t.as_str())
    }
}

fn refused(id: SettingId, e: &liftfw::ConfigError, running: &ValidatedConfig) -> Error {
    let mut s = String::new();
    let _ = console::write_refused(&mut s, id, e, running);
    Error::Invalid(s)
}

/// Order `changes` so that each one validates on the configuration the ones before it leave
/// (e.g. raise the upper stop before the lower one), after checking the whole result. Changes
/// to the value already in force are dropped.
pub fn plan(running: &ValidatedConfig, changes: &[Change]) -> Result<Vec<Change>, Error> {
    let mut target = *running.get();
    for c in changes {
        if !c.id.setting().set(&mut target, c.raw) {
            return Err(refused(
                c.id,
                &liftfw::ConfigError::OutOfRange {
                    field: c.id.key(),
                    range: c.id.setting().range,
                },
                running,
            ));
        }
    }
    if let Err(e) = ValidatedConfig::new(target) {
        let field = match e {
            liftfw::ConfigError::OutOfRange { field, .. }
            | liftfw::ConfigError::Conflict { field, .. } => field,
        };
        return Err(
            match settings::find(field).or(changes.first().map(|c| c.id)) {
                Some(id) => refused(id, &e, running),
                None => Error::Invalid(format!("error: {e}")),
            },
        );
    }
    let mut cur = *running;
    let mut pending: Vec<Change> = changes
        .iter()
        .filter(|c| c.id.setting().get(running.get()) != c.raw)
        .cloned()
        .collect();
    let mut out = Vec::new();
    while !pending.is_empty() {
        let step = pending
            .iter()
            .position(|c| settings::apply(&cur, c.id, c.raw).is_ok());
        match step {
            Some(i) => {
                let c = pending.remove(i);
                if let Ok(next) = settings::apply(&cur, c.id, c.raw) {
                    cur = next;
                }
                out.push(c);
            }
            None => {
                let c = &pending[0];
                let e = settings::apply(&cur, c.id, c.raw).err();
                let why = e.map(|e| e.to_string()).unwrap_or_default();
                return Err(Error::Invalid(format!(
                    "error: these changes cannot be made one at a time without passing through \
                     a refused configuration ({why}); change them in smaller steps"
                )));
            }
        }
    }
    Ok(out)
}

/// Apply `changes` to the board: checked and ordered here first ([`plan`]), then `set` one by
/// one; if the board refuses one, or a reply is lost or garbled, the ones already made are set
/// back to their previous values. Returns the `ok:` values the board reported.
pub fn apply(board: &mut Board, changes: &[Change]) -> Result<Vec<String>, Error> {
    board.check_schema()?;
    let mirror = Mirror::read(board)?;
    let changes = for_image(&mirror, changes)?;
    let steps = plan(&mirror.config, &changes)?;
    let mut done: Vec<SettingId> = Vec::new();
    let mut report = Vec::new();
    for c in &steps {
        match board.set(c.id.key(), &c.text) {
            Ok(v) => {
                done.push(c.id);
                report.push(format!("{} = {v}", c.id.key()));
            }
            Err(e) => {
                // The failed one too: a lost reply may hide a change the board made.
                done.push(c.id);
                // Setting back runs to its end even after Ctrl-C (which may be why we stopped).
                let stop = board.interrupt();
                board.set_interrupt(None);
                let undo = undo(board, &mirror, &done);
                board.set_interrupt(stop);
                return Err(Error::Undone {
                    cause: Box::new(e),
                    note: match undo {
                        Ok(()) => "nothing changed: what this command had changed was set back"
                            .to_string(),
                        Err(u) => format!(
                            "setting back what this command had changed failed too ({u}): the \
                             board may run with some of it; none of it is saved, so restarting \
                             the lift restores the saved settings"
                        ),
                    },
                });
            }
        }
    }
    Ok(report)
}

/// The changes this board can take. On the lead-screw image a ball-screw value equal to the
/// factory one (a file exported from a ball-screw board that never changed it) is nothing to
/// change; any other ball-screw value is refused before anything is sent.
fn for_image(mirror: &Mirror, changes: &[Change]) -> Result<Vec<Change>, Error> {
    if !mirror.lead_image {
        return Ok(changes.to_vec());
    }
    let mut out = Vec::new();
    for c in changes {
        let s = c.id.setting();
        if !s.key.starts_with(settings::BALL_PREFIX) {
            out.push(c.clone());
        } else if s.get(mirror.config.get()) != c.raw {
            return Err(Error::Invalid(format!(
                "error: '{}' needs the ball-screw firmware: the board runs the lead-screw \
                 image; nothing was changed",
                s.key
            )));
        }
    }
    Ok(out)
}

fn undo(board: &mut Board, mirror: &Mirror, done: &[SettingId]) -> Result<(), Error> {
    for &id in done.iter().rev() {
        let old = mirror.text(id);
        match board.get(id.key()) {
            Ok(now) if now == old => continue,
            _ => {}
        }
        board.set(id.key(), old)?;
    }
    Ok(())
}

/// The running settings as TOML: one table per key prefix, every value as the text `set`
/// takes back exactly.
pub fn export_toml(mirror: &Mirror, header: &str) -> String {
    let mut s = String::new();
    for l in header.lines() {
        let _ = writeln!(s, "# {l}");
    }
    let mut group = "";
    for (key, text) in &mirror.texts {
        let (g, k) = key.split_once('.').unwrap_or(("", key));
        let stored = settings::find(key).is_some_and(|id| id.setting().stored());
        if g != group {
            let _ = writeln!(s, "\n[{g}]");
            group = g;
        }
        let v = toml::Value::String(text.clone());
        if stored {
            let _ = writeln!(s, "{k} = {v}");
        } else {
            let _ = writeln!(
                s,
                "# {k} = {v}  (derived from the values below, not stored; import ignores it)"
            );
        }
    }
    s
}

/// Read a TOML export into changes (every stored key it names), each checked with the core's
/// parser. Unknown keys and values the firmware would refuse are errors, and nothing is sent.
pub fn import_toml(text: &str) -> Result<Vec<Change>, Error> {
    let table: toml::Table = text
        .parse()
        .map_err(|e| Error::Local(format!("not a TOML settings file: {e}")))?;
    let mut changes: Vec<Change> = Vec::new();
    // `friction.law` loads a preset of the friction.* values: applied first, and only when the
    // file does not give those values itself (which of the two would win is not obvious).
    let mut presets: Vec<Change> = Vec::new();
    for (group, v) in &table {
        let toml::Value::Table(t) = v else {
            return Err(Error::Local(format!(
                "`{group}` is not a table of settings; `liftctl config export` shows the layout"
            )));
        };
        for (k, v) in t {
            let key = format!("{group}.{k}");
            crate::board::check_text("key", &key)?;
            let Some(id) = settings::find(&key) else {
                return Err(Error::Invalid(format!(
                    "error: unknown key '{key}'; `liftctl config get` lists them"
                )));
            };
            let value = match v {
                toml::Value::String(s) => s.clone(),
                toml::Value::Integer(i) => i.to_string(),
                toml::Value::Float(f) => f.to_string(),
                _ => {
                    return Err(Error::Local(format!(
                        "{key}: a value is text, e.g. \"410 mm\", or a number"
                    )))
                }
            };
            crate::board::check_text(&key, &value)?;
            // Keys are case-insensitive (`[LIMITS]` is `[limits]`) and TOML's are not: a key
            // given twice, whatever its case, is refused rather than applied twice.
            if changes.iter().chain(&presets).any(|c| c.id == id) {
                return Err(Error::Local(format!(
                    "{key} is given twice (keys are case-insensitive: [{group}] and another \
                     table of that name differing only in case); keep one"
                )));
            }
            if !id.setting().stored() {
                // A derived key (`friction.law`): its preset, checked by `plan` like any value.
                presets.push(parse_change(&key, &value)?);
                continue;
            }
            changes.push(parse_change(&key, &value)?);
        }
    }
    for p in &presets {
        let (group, _) = p.id.key().split_once('.').unwrap_or(("", ""));
        if let Some(c) = changes
            .iter()
            .find(|c| c.id.key().split_once('.').is_some_and(|(g, _)| g == group))
        {
            return Err(Error::Local(format!(
                "{} and {} in one file: the preset would replace the values given; keep one \
                 (an export gives the values and leaves {} as a comment)",
                p.id.key(),
                c.id.key(),
                p.id.key()
            )));
        }
    }
    presets.extend(changes);
    Ok(presets)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    fn ch(k: &str, v: &str) -> Change {
        parse_change(k, v).unwrap()
    }

    #[test]
    fn values_are_checked_like_the_firmware() {
        assert_eq!(
            parse_change("limits.upper", "41 kg")
                .unwrap_err()
                .to_string(),
            "error: bad value for limits.upper: unit not accepted; expected a length in mm (or \
             m, cm, um), range the mechanism's height range (see `limits`)"
        );
        assert_eq!(
            parse_change("limits.middle", "3").unwrap_err().to_string(),
            "error: unknown key 'limits.middle'; `help keys` lists them"
        );
    }

    #[test]
    fn plan_orders_stops_and_refuses_out_of_range() {
        let run = ValidatedConfig::factory();
        // Both stops above the current upper one: the upper must go first.
        let p = plan(
            &run,
            &[ch("limits.lower", "405mm"), ch("limits.upper", "415mm")],
        )
        .unwrap();
        let keys: Vec<&str> = p.iter().map(|c| c.id.key()).collect();
        assert_eq!(keys, ["limits.upper", "limits.lower"]);
        // Stops past both ends of the mechanism (133.5..416.4 mm): refused with the firmware's
        // words.
        let e = plan(
            &run,
            &[ch("limits.upper", "450mm"), ch("limits.lower", "120mm")],
        );
        let msg = e.unwrap_err().to_string();
        assert!(
            msg.starts_with("error: set limits.") && msg.ends_with("; mechanism 133.5..416.4 mm"),
            "{msg}"
        );
        // Values already in force are not sent.
        assert!(plan(&run, &[ch("limits.upper", "410mm")])
            .unwrap()
            .is_empty());
    }

    #[test]
    fn toml_round_trip() {
        let run = ValidatedConfig::factory();
        let texts = settings::all()
            .map(|id| {
                let mut s = String::new();
                console::write_get(&mut s, &run, id).unwrap();
                let v = s.split_once(" = ").unwrap().1.to_string();
                (id.key(), v)
            })
            .collect();
        let m = Mirror {
            config: run,
            texts,
            lead_image: false,
        };
        let t = export_toml(&m, "test");
        let changes = import_toml(&t).unwrap();
        let stored = settings::all().filter(|id| id.setting().stored()).count();
        assert_eq!(changes.len(), stored);
        let mut cfg = *run.get();
        for c in &changes {
            assert!(c.id.setting().set(&mut cfg, c.raw));
        }
        assert_eq!(&cfg, run.get());
        assert!(import_toml("[limits]\nmiddle = \"3 mm\"").is_err());
        assert!(import_toml("[limits]\nupper = \"3 kg\"").is_err());
    }
}
