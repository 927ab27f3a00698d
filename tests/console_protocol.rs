//! The console's line protocol: requests, error messages, round trips, and no panics on any
//! input.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use liftfw::config::settings::{self, Kind, SETTINGS};
use liftfw::config::ValidatedConfig;
use liftfw::console::{
    self, parse, value, Feed, HelpTopic, LineBuffer, ParseError, Request, StatusView, ValueError,
};
use liftfw::control::config::ControlConfig;
use liftfw::units::{Amperes, Metres, NewtonMetres, RadiansPerSecond};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

fn reply(f: impl FnOnce(&mut String) -> core::fmt::Result) -> String {
    let mut s = String::new();
    f(&mut s).unwrap();
    s
}

fn err_text(line: &str) -> String {
    let e = parse(line.as_bytes()).unwrap_err();
    reply(|s| console::write_parse_error(s, &e))
}

fn id(key: &str) -> settings::SettingId {
    settings::find(key).unwrap()
}

fn mm(v: &str) -> Metres {
    Metres::from_f64(v.parse::<f64>().unwrap() / 1000.0)
}

#[test]
fn commands_parse_in_any_case() {
    let cases: [(&str, Request); 12] = [
        ("status", Request::Status),
        ("STATUS", Request::Status),
        ("save", Request::Save),
        ("Limits", Request::Limits),
        ("up", Request::Up),
        ("DOWN", Request::Down),
        ("  stop  ", Request::Stop),
        ("fault", Request::Fault),
        ("fault clear", Request::FaultClear),
        ("Fault CLEAR", Request::FaultClear),
        ("help", Request::Help(HelpTopic::Commands)),
        ("help keys", Request::Help(HelpTopic::Keys)),
    ];
    for (line, want) in cases {
        assert_eq!(parse(line.as_bytes()), Ok(Some(want)), "{line}");
    }
    assert_eq!(parse(b""), Ok(None));
    assert_eq!(parse(b"   # a comment"), Ok(None));
}

#[test]
fn set_takes_values_with_units() {
    let upper = id("limits.upper");
    let bits = |m: Metres| i64::from(m.to_bits());
    for line in [
        "set limits.upper 410mm",
        "SET LIMITS.UPPER 410 MM",
        "set limits.upper 0.41m",
        "set limits.upper 41cm",
    ] {
        assert_eq!(
            parse(line.as_bytes()),
            Ok(Some(Request::Set(upper, bits(Metres::lit("0.41"))))),
            "{line}"
        );
    }
    let cases: [(&str, &str, i64); 7] = [
        (
            "set motion.cruise_speed 3 rad/s",
            "motion.cruise_speed",
            RadiansPerSecond::lit("3").to_bits().into(),
        ),
        (
            "set protect.overcurrent 45A",
            "protect.overcurrent",
            Amperes::lit("45").to_bits().into(),
        ),
        (
            "set protect.supply_start_min 11.5V",
            "protect.supply_start_min",
            (23 << 15).into(),
        ),
        ("set motion.ramp_ms 200ms", "motion.ramp_ms", 200),
        ("set load.rated 1000kg", "load.rated", 1000 << 12),
        ("set load.rated 1 t", "load.rated", 1000 << 12),
        ("set motion.ramp_shape SCurve", "motion.ramp_shape", 1),
    ];
    for (line, key, raw) in cases {
        assert_eq!(
            parse(line.as_bytes()),
            Ok(Some(Request::Set(id(key), raw))),
            "{line}"
        );
    }
    assert_eq!(
        parse(b"goto 300 mm"),
        Ok(Some(Request::Goto(Metres::lit("0.3"))))
    );
    assert_eq!(
        parse(b"goto 0.3m"),
        Ok(Some(Request::Goto(Metres::lit("0.3"))))
    );
}

#[test]
fn unknown_command_points_to_help() {
    assert_eq!(
        err_text("lift"),
        "error: unknown command 'lift'; type `help` for the commands"
    );
    assert_eq!(
        err_text("up now"),
        "error: unexpected 'now'; type `help` for the commands"
    );
}

#[test]
fn bad_value_names_key_unit_and_range() {
    assert_eq!(
        err_text("set limits.upper 41 kg"),
        "error: bad value for limits.upper: unit not accepted; expected a length in mm \
         (or m, cm, um), range the mechanism's height range (see `limits`)"
    );
    assert_eq!(
        err_text("set protect.overcurrent lots"),
        "error: bad value for protect.overcurrent: not a number; expected a current in A \
         (or ma), range 1..60 A"
    );
    assert_eq!(
        err_text("set motion.ramp_ms 20.5ms"),
        "error: bad value for motion.ramp_ms: must be a whole number; expected a duration \
         in ms (or s), range 10..2000 ms"
    );
    assert_eq!(
        err_text("set motion.ramp_shape sine"),
        "error: bad value for motion.ramp_shape: not one of the choices; expected trapezoid \
         or scurve, range trapezoid or scurve"
    );
    assert_eq!(
        err_text("set motion.ramp_ms"),
        "error: `set motion.ramp_ms` needs a value: expected a duration in ms (or s), \
         range 10..2000 ms"
    );
    assert_eq!(
        err_text("get limits.middle"),
        "error: unknown key 'limits.middle'; `help keys` lists them"
    );
    assert_eq!(
        err_text("get"),
        "error: `get` needs a key, e.g. `get limits.upper`; `help keys` lists them"
    );
    assert!(err_text("goto high").starts_with("error: bad height for goto: not a number"));
    assert_eq!(parse(&[0xFF, 0xFE]).unwrap_err(), ParseError::NotText);
}

#[test]
fn out_of_range_set_is_refused_naming_field_and_range() {
    let cfg = ValidatedConfig::factory();
    let Ok(Some(Request::Set(k, raw))) = parse(b"set protect.overcurrent 80A") else {
        panic!()
    };
    let r = settings::apply(&cfg, k, raw);
    assert_eq!(
        reply(|s| console::write_set(s, k, &r, &cfg)),
        "error: set protect.overcurrent refused: protect.overcurrent out of range (allowed 1..60 A)"
    );
    let Ok(Some(Request::Set(k, raw))) = parse(b"set limits.lower 405mm") else {
        panic!()
    };
    let r = settings::apply(&cfg, k, raw);
    assert_eq!(
        reply(|s| console::write_set(s, k, &r, &cfg)),
        "error: set limits.lower refused: limits.lower: must be at least 10 mm below \
         limits.upper; mechanism 133.5..416.4 mm"
    );
    let Ok(Some(Request::Set(k, raw))) = parse(b"set limits.upper 450mm") else {
        panic!()
    };
    let r = settings::apply(&cfg, k, raw);
    assert!(reply(|s| console::write_set(s, k, &r, &cfg)).ends_with("mechanism 133.5..416.4 mm"));
    // A value far outside the field's type is refused with the key's range too.
    let Ok(Some(Request::Set(k, raw))) = parse(b"set motion.ramp_ms 5000000000") else {
        panic!()
    };
    assert!(settings::apply(&cfg, k, raw).is_err());
}

#[test]
fn accepted_set_shows_the_new_value_and_get_reads_it() {
    let cfg = ValidatedConfig::factory();
    let Ok(Some(Request::Set(k, raw))) = parse(b"set limits.upper 400 mm") else {
        panic!()
    };
    let r = settings::apply(&cfg, k, raw);
    assert_eq!(
        reply(|s| console::write_set(s, k, &r, &cfg)),
        "ok: limits.upper = 400 mm (not saved; `save` stores it)"
    );
    let new = r.unwrap();
    assert_eq!(new.get().limits.upper, mm("400"));
    assert_eq!(
        reply(|s| console::write_get(s, &new, k)),
        "limits.upper = 400 mm"
    );
    assert_eq!(
        reply(|s| console::write_limits(s, &new)),
        "limits.lower = 145.0 mm, limits.upper = 400.0 mm, limits.switch_lower = 140.3 mm; mechanism 133.5..416.4 mm"
    );
}

#[test]
fn friction_law_preset_switches_and_shows_custom_after_edits() {
    let cfg = ValidatedConfig::factory();
    let law = id("friction.law");
    let Ok(Some(Request::Set(k, raw))) = parse(b"set friction.law ptfe") else {
        panic!()
    };
    let ptfe = settings::apply(&cfg, k, raw).unwrap();
    assert_eq!(
        reply(|s| console::write_get(s, &ptfe, law)),
        "friction.law = ptfe"
    );
    let Ok(Some(Request::Set(k, raw))) = parse(b"set friction.base 0.2") else {
        panic!()
    };
    let custom = settings::apply(&ptfe, k, raw).unwrap();
    assert_eq!(
        reply(|s| console::write_get(s, &custom, law)),
        "friction.law = custom"
    );
}

#[test]
fn status_line_is_readable() {
    let v = StatusView {
        state: "lifting",
        height: mm("212.4"),
        homed: true,
        screw_speed: RadiansPerSecond::lit("3.004"),
        current: Amperes::lit("12.345"),
        friction_torque: NewtonMetres::lit("0.8512"),
        stick_slip: false,
        stick_slip_amplitude: NewtonMetres::ZERO,
        stick_slip_episodes: 0,
        fault: None,
        load: liftfw::ident::LoadReport {
            load: liftfw::units::Kilograms::lit("612.4"),
            load_lo: liftfw::units::Kilograms::lit("580"),
            load_hi: liftfw::units::Kilograms::lit("1150.6"),
            identified: true,
            scale: liftfw::units::Ratio::ONE,
            scale_known: false,
            pairs: 0,
        },
        cruise_limit: None,
        #[cfg(feature = "ball-screw")]
        ball_f: None,
    };
    assert_eq!(
        reply(|s| console::write_status(s, &v)),
        "state=lifting height=212.4mm speed=3.00rad/s current=12.35A T_r=0.851Nm \
         stick_slip=no ss_amp=0.00Nm ss_episodes=0 fault=none homed=yes load=612kg \
         load_range=580..1151kg load_src=current mu_scale=1.000(assumed)"
    );
    // Unhomed, the board does not know the height: it says so instead of its assumption.
    let u = StatusView { homed: false, ..v };
    assert_eq!(
        reply(|s| console::write_status(s, &u)),
        "state=lifting height=unknown speed=3.00rad/s current=12.35A T_r=0.851Nm \
         stick_slip=no ss_amp=0.00Nm ss_episodes=0 fault=none homed=no load=612kg \
         load_range=580..1151kg load_src=current mu_scale=1.000(assumed)"
    );
    let v = StatusView {
        screw_speed: RadiansPerSecond::lit("-2.5"),
        stick_slip: true,
        stick_slip_amplitude: NewtonMetres::lit("31.256"),
        stick_slip_episodes: 3,
        fault: Some("overcurrent"),
        #[cfg(feature = "ball-screw")]
        ball_f: None,
        ..v
    };
    let s = reply(|s| console::write_status(s, &v));
    assert!(s.contains("speed=-2.50rad/s"), "{s}");
    assert!(
        s.contains(
            "stick_slip=yes ss_amp=31.26Nm ss_episodes=3 fault=overcurrent homed=yes load=612kg"
        ),
        "{s}"
    );
}

#[test]
fn stick_slip_warning_names_the_episode_and_the_drop() {
    let s = reply(|s| console::write_stick_slip_warning(s, 2, NewtonMetres::lit("12.5"), true));
    assert_eq!(
        s,
        "warning: stick-slip (episode 2, torque drop 12.50 Nm per slip), cruise changed to \
         stickslip.escape_speed"
    );
}

#[test]
fn help_lists_every_command_and_key() {
    let h = reply(|s| console::write_help(s, HelpTopic::Commands));
    for c in [
        "status", "up", "down", "stop", "goto", "limits", "get", "set", "save", "fault", "help",
    ] {
        assert!(h.contains(c), "{c}");
    }
    let k = reply(|s| console::write_help(s, HelpTopic::Keys));
    for s in SETTINGS.iter() {
        assert!(k.contains(s.key), "{}", s.key);
    }
    assert_eq!(
        reply(|s| console::write_help(s, HelpTopic::Key(id("motion.ramp_ms")))),
        "motion.ramp_ms: time from rest to cruise speed (and back); expected a duration in ms \
         (or s), range 10..2000 ms"
    );
}

#[test]
fn line_buffer_edits_and_splits_lines() {
    let mut lb = LineBuffer::new();
    let mut lines = Vec::new();
    for &b in b"stpo\x08\x08op\r\nup\nsave\r" {
        match lb.feed(b) {
            Feed::Line(l) => lines.push(String::from_utf8(l.to_vec()).unwrap()),
            Feed::Overflow => lines.push("<overflow>".into()),
            Feed::Pending => {}
        }
    }
    assert_eq!(lines, ["stop", "up", "save"]);
    let mut long = vec![b'x'; console::MAX_LINE + 5];
    long.push(b'\n');
    long.extend_from_slice(b"stop\n");
    let mut out = Vec::new();
    for &b in &long {
        match lb.feed(b) {
            Feed::Line(l) => out.push(parse(l).map(|r| r.is_some()).unwrap_or(false)),
            Feed::Overflow => out.push(false),
            Feed::Pending => {}
        }
    }
    assert_eq!(out, [false, true]);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic(line in proptest::collection::vec(any::<u8>(), 0..200)) {
        let mut s = String::new();
        match parse(&line) {
            Ok(_) => {}
            Err(e) => console::write_parse_error(&mut s, &e).unwrap(),
        }
        let mut lb = LineBuffer::new();
        for &b in &line {
            if let Feed::Line(l) = lb.feed(b) {
                let _ = parse(l);
            }
        }
    }

    #[test]
    fn arbitrary_set_lines_never_panic(
        key in proptest::sample::select(SETTINGS.iter().map(|s| s.key).collect::<Vec<_>>()),
        value in "[-+0-9.eE_ a-zA-Z/%]{0,40}",
    ) {
        let line = format!("set {key} {value}");
        let cfg = ValidatedConfig::factory();
        let mut s = String::new();
        match parse(line.as_bytes()) {
            Ok(Some(Request::Set(k, raw))) => {
                let r = settings::apply(&cfg, k, raw);
                console::write_set(&mut s, k, &r, &cfg).unwrap();
            }
            Ok(_) => {}
            Err(e) => console::write_parse_error(&mut s, &e).unwrap(),
        }
    }

    #[test]
    fn every_key_round_trips_set_to_get(
        index in 0..SETTINGS.len(),
        bits in any::<i64>(),
        width in 0..3u8,
    ) {
        let s = &SETTINGS[index];
        // Any value the field can hold: 32-bit fields get i32 or u32 patterns, I32F32 any value
        // below 10⁷ (the console takes 18 significant digits: 7 integer and the 10 fractional
        // ones 2^−32 needs; every valid I32F32 setting is at most 10⁶ or `none`).
        let raw = match s.kind {
            Kind::Choice(names) => bits.rem_euclid(names.len() as i64),
            Kind::Number { .. } => match width {
                0 => i64::from(bits as i32),
                1 => i64::from(bits as u32),
                _ => bits % (10_000_000i64 << 32),
            },
        };
        let mut cfg = ControlConfig::DEFAULT;
        if s.set(&mut cfg, raw) {
            let held = s.get(&cfg);
            let mut text = String::new();
            value::format(&mut text, &s.kind, held).unwrap();
            let line = format!("set {} {}", s.key, text);
            let parsed = parse(line.as_bytes());
            prop_assert_eq!(parsed, Ok(Some(Request::Set(settings::find(s.key).unwrap(), held))), "{}", line);
        }
    }

    #[test]
    fn valid_values_round_trip_through_apply_and_get(
        index in 0..SETTINGS.len(),
        delta in -1000i64..1000,
    ) {
        let s = &SETTINGS[index];
        let cfg = ValidatedConfig::factory();
        let id = settings::find(s.key).unwrap();
        let raw = s.get(cfg.get()).saturating_add(delta);
        if let Ok(next) = settings::apply(&cfg, id, raw) {
            let shown = {
                let mut t = String::new();
                console::write_get(&mut t, &next, id).unwrap();
                t
            };
            let text = shown.split_once(" = ").unwrap().1;
            let line = format!("set {} {}", s.key, text);
            let Ok(Some(Request::Set(_, back))) = parse(line.as_bytes()) else {
                return Err(TestCaseError::fail(line));
            };
            prop_assert_eq!(settings::apply(&cfg, id, back), Ok(next), "{}", line);
        }
    }
}

#[test]
fn value_errors_have_messages() {
    for e in [
        ValueError::Missing,
        ValueError::NotANumber,
        ValueError::WrongUnit,
        ValueError::NotWhole,
        ValueError::TooLarge,
        ValueError::TooManyDigits,
        ValueError::NotAChoice,
    ] {
        assert!(!format!("{e}").is_empty());
    }
}
