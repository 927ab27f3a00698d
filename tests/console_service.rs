//! The console service (`liftfw::console::service`): every command's reply against a real
//! `Controller`, `set` refused while moving and accepted at rest, set-then-get, refused values
//! leave everything untouched, `save` handed to the caller and reported, and no input panics or
//! changes the configuration unless it is a valid `set`.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use liftfw::config::settings;
use liftfw::config::sim_flash::{SimFlash, ERASE_SIZE};
use liftfw::config::store::{ConfigStore, Source, StoreError};
use liftfw::config::ValidatedConfig;
use liftfw::console::service::{self, Action, Outcome, PROTOCOL_VERSION};
use liftfw::console::{parse, LineBuffer, Request};
use liftfw::control::config::ControlConfig;
use liftfw::control::{Command, Controller, FaultKind, Inputs, Refusal, State};
use liftfw::units::{Instant, Metres};
use proptest::prelude::*;

/// 12.6 V at 4.468 mV per code; 0 A at code 2048.
const SUPPLY_OK: u16 = 2820;
/// 17.9 V: above `protect.supply_max`.
const SUPPLY_HIGH: u16 = 4000;

struct Bench {
    c: Controller,
    cfg: ValidatedConfig,
    t: u32,
    inputs: Inputs,
}

impl Bench {
    /// A controller at rest at 250 mm with a healthy supply, a few ticks in.
    fn new() -> Bench {
        let cfg = ValidatedConfig::factory();
        let probe = Controller::new(cfg.get(), 0).unwrap();
        let pos = probe
            .estimator()
            .geometry()
            .counts_for_height(Metres::lit("0.25"))
            .unwrap();
        let mut b = Bench {
            c: Controller::new(cfg.get(), pos).unwrap(),
            cfg,
            t: 0,
            inputs: Inputs {
                encoder_count: 0,
                encoder_edge_age: 0,
                current_raw: 2048,
                supply_raw: SUPPLY_OK,
                switches: Default::default(),
            },
        };
        b.ticks(10);
        b
    }

    fn ticks(&mut self, n: u32) {
        for _ in 0..n {
            self.t += 1000;
            self.c.step(Instant(self.t), &self.inputs);
        }
    }

    fn line(&mut self, line: &str) -> (String, Outcome) {
        let mut out = String::new();
        let o = service::handle(line.as_bytes(), &mut self.c, &mut self.cfg, &mut out);
        (out, o)
    }

    fn reply(&mut self, line: &str) -> String {
        let (out, o) = self.line(line);
        assert_eq!(o.reply, Ok(()), "{line}");
        out
    }
}

#[test]
fn version_names_the_protocol_and_the_schema() {
    let mut b = Bench::new();
    let r = b.reply("version");
    assert!(r.starts_with("liftfw console v2 firmware="), "{r}");
    let schema = format!("schema={:08x}", liftfw::config::record::schema());
    assert!(r.ends_with(&schema), "{r}");
    assert_eq!(PROTOCOL_VERSION, 2);
    assert_eq!(parse(b"VERSION"), Ok(Some(Request::Version)));
    assert!(b.reply("version 2").starts_with("error: unexpected '2'"));
}

#[test]
fn status_reports_the_controller() {
    let mut b = Bench::new();
    let r = b.reply("status");
    assert!(
        r.starts_with("state=idle height=250.0mm speed=0.00rad/s current=0.00A T_r="),
        "{r}"
    );
    assert!(
        r.contains(
            " stick_slip=no ss_amp=0.00Nm ss_episodes=0 fault=none homed=yes load=1000kg \
             load_range=0..2000kg load_src=prior mu_scale=1.000(assumed)"
        ),
        "{r}"
    );
    let s = b.c.status();
    assert_eq!(
        service::status_view(&s).state,
        "idle",
        "the view maps the controller's state"
    );
}

#[test]
fn set_then_get_changes_running_and_controller() {
    let mut b = Bench::new();
    assert_eq!(b.reply("get limits.upper"), "limits.upper = 410 mm");
    let (r, o) = b.line("set limits.upper 400mm");
    assert_eq!(r, "ok: limits.upper = 400 mm (not saved; `save` stores it)");
    assert_eq!(o.action, Action::Reconfigured);
    assert_eq!(b.reply("get limits.upper"), "limits.upper = 400 mm");
    assert_eq!(b.cfg.get().limits.upper, Metres::lit("0.4"));
    assert_eq!(b.c.config().limits.upper, Metres::lit("0.4"));
    assert_eq!(
        b.reply("limits"),
        "limits.lower = 145.0 mm, limits.upper = 400.0 mm, limits.switch_lower = 140.3 mm; mechanism 133.5..416.4 mm"
    );
    // The controller's stop moved with it.
    let want =
        b.c.estimator()
            .geometry()
            .counts_for_height(Metres::lit("0.4"))
            .unwrap();
    assert_eq!(b.c.limit_counts().1, want);
    // The same value again: ok, nothing to reconfigure.
    let (r, o) = b.line("set limits.upper 0.4 m");
    assert!(r.starts_with("ok: limits.upper = 400 mm"), "{r}");
    assert_eq!(o.action, Action::None);
}

#[test]
fn refused_values_change_nothing() {
    let mut b = Bench::new();
    let before = b.cfg;
    let cases = [
        (
            "set protect.overcurrent 80A",
            "error: set protect.overcurrent refused: protect.overcurrent out of range (allowed 1..60 A)",
        ),
        (
            "set limits.lower 405mm",
            "error: set limits.lower refused: limits.lower: must be at least 10 mm below \
             limits.upper; mechanism 133.5..416.4 mm",
        ),
        (
            "set limits.upper 41 kg",
            "error: bad value for limits.upper: unit not accepted; expected a length in mm (or m, \
             cm, um), range the mechanism's height range (see `limits`)",
        ),
        ("set limits.middle 3", "error: unknown key 'limits.middle'; `help keys` lists them"),
    ];
    for (line, want) in cases {
        let (r, o) = b.line(line);
        assert_eq!(r, want, "{line}");
        assert_eq!(o.action, Action::None);
        assert_eq!(b.cfg, before, "{line}");
        assert_eq!(b.c.config(), before.get(), "{line}");
    }
}

#[test]
fn set_is_refused_while_moving_and_accepted_at_rest() {
    let mut b = Bench::new();
    let pos = b.c.position_counts();
    assert_eq!(b.reply("up"), "ok: lifting to limits.upper");
    b.ticks(5);
    assert_eq!(b.c.state(), State::Lifting);
    let before = b.cfg;
    let (r, o) = b.line("set limits.upper 380mm");
    assert_eq!(
        r,
        "error: set limits.upper refused: the lift is moving; `stop` and let it come to rest \
         first; nothing changed"
    );
    assert_eq!(o.action, Action::None);
    assert_eq!(b.cfg, before);
    assert_eq!(b.c.config(), before.get());
    // Reading is fine while moving; a set that changes nothing is too.
    assert_eq!(b.reply("get limits.upper"), "limits.upper = 410 mm");
    assert!(b.reply("set limits.upper 410mm").starts_with("ok: "));
    assert!(b.reply("status").starts_with("state=lifting "));
    // The encoder never moves here, so the lift ends at rest (holding, or a stall fault).
    assert_eq!(b.reply("stop"), "ok: stop");
    b.ticks(3000);
    assert!(
        matches!(b.c.state(), State::Holding | State::Fault),
        "{:?}",
        b.c.state()
    );
    let state = b.c.state();
    let fault = b.c.fault().copied();
    let (r, o) = b.line("set limits.upper 380mm");
    assert_eq!(r, "ok: limits.upper = 380 mm (not saved; `save` stores it)");
    assert_eq!(o.action, Action::Reconfigured);
    // Position, state and fault survive the reconfiguration.
    assert_eq!(b.c.position_counts(), pos);
    assert_eq!(b.c.state(), state);
    assert_eq!(b.c.fault().copied(), fault);
}

#[test]
fn motion_commands_reply_and_refuse() {
    let mut b = Bench::new();
    assert_eq!(b.reply("stop"), "ok: stop");
    assert_eq!(b.reply("goto 300mm"), "ok: going to 300.0 mm");
    assert_eq!(b.c.state(), State::Lifting);
    assert_eq!(
        b.reply("down"),
        "error: down refused: moving the other way, stop first"
    );
    let mut b = Bench::new();
    assert_eq!(
        b.reply("goto 500mm"),
        "error: goto refused: target outside the limit stops"
    );
    assert_eq!(b.reply("down"), "ok: lowering to limits.lower");
    let mut b = Bench::new();
    b.inputs.supply_raw = 1000; // 4.5 V
    b.ticks(5);
    assert_eq!(
        b.reply("up"),
        "error: up refused: supply below the start threshold"
    );
}

#[test]
fn fault_is_shown_kept_by_set_and_cleared() {
    let mut b = Bench::new();
    assert_eq!(b.reply("fault"), "fault=none");
    assert_eq!(b.reply("fault clear"), "ok: no fault latched");
    b.inputs.supply_raw = SUPPLY_HIGH;
    b.ticks(100);
    assert_eq!(b.c.fault().map(|f| f.kind), Some(FaultKind::OverVoltage));
    let r = b.reply("fault");
    assert!(r.starts_with("fault=over-voltage t=0."), "{r}");
    assert!(
        r.contains(" state=idle height=250.0mm speed=0.00rad/s current=0.00A supply=17.8"),
        "{r}"
    );
    // Nothing weighed yet: the load is the prior, and the snapshot says so.
    assert!(r.ends_with("Nm load=1000kg load_src=prior"), "{r}");
    assert!(b
        .reply("status")
        .contains("fault=over-voltage homed=yes load="));
    assert_eq!(
        b.reply("up"),
        "error: up refused: a fault is latched (see `fault`, then `fault clear`)"
    );
    // At rest in a fault, settings may change; the fault stays latched.
    assert!(b.reply("set motion.ramp_ms 300").starts_with("ok: "));
    assert_eq!(b.c.fault().map(|f| f.kind), Some(FaultKind::OverVoltage));
    assert_eq!(b.c.config().motion.ramp_ms, 300);
    b.inputs.supply_raw = SUPPLY_OK;
    b.ticks(30);
    assert_eq!(b.reply("fault clear"), "ok: fault cleared");
    assert_eq!(b.reply("fault"), "fault=none");
    assert_eq!(b.c.state(), State::Idle);
}

#[test]
fn help_and_errors_go_through() {
    let mut b = Bench::new();
    let h = b.reply("help");
    assert!(h.contains("version"), "{h}");
    assert!(b.reply("help limits.upper").starts_with("limits.upper: "));
    assert_eq!(
        b.reply("lift"),
        "error: unknown command 'lift'; type `help` for the commands"
    );
    assert_eq!(b.reply(""), "");
    assert_eq!(b.reply("# comment"), "");
}

type Flash = SimFlash<{ 4 * ERASE_SIZE }>;

#[test]
fn save_is_handed_to_the_caller_and_reported() {
    let mut store = ConfigStore::new(Flash::new(), 0..(4 * ERASE_SIZE) as u32).unwrap();
    assert_eq!(store.load().source, Source::Missing);
    let mut b = Bench::new();
    b.reply("set limits.upper 395mm");
    let (r, o) = b.line("save");
    assert_eq!((r.as_str(), o.action), ("", Action::Save));
    let res = store.save(&b.cfg);
    let mut out = String::new();
    service::write_saved(&mut out, res).unwrap();
    assert_eq!(out, "ok: saved as configuration #1");
    // A power cycle: the flash holds what was saved.
    let flash = store.into_flash();
    let mut store = ConfigStore::new(flash, 0..(4 * ERASE_SIZE) as u32).unwrap();
    let loaded = store.load();
    assert_eq!(loaded.config, b.cfg);
    assert_eq!(loaded.config.get().limits.upper, Metres::lit("0.395"));
    let mut out = String::new();
    service::write_saved(&mut out, Err(StoreError::Full)).unwrap();
    assert_eq!(
        out,
        "error: save failed (store is full); flash holds the previous configuration or this one, \
         never a mix; the running settings are unchanged"
    );
}

#[test]
fn overlong_lines_and_short_sinks() {
    let mut b = Bench::new();
    let mut lb = LineBuffer::new();
    let mut out = String::new();
    for &byte in [b'x'; 120].iter().chain(b"\r") {
        let o = service::handle_feed(lb.feed(byte), &mut b.c, &mut b.cfg, &mut out);
        assert_eq!(o.action, Action::None);
    }
    assert_eq!(
        out,
        "error: line longer than 96 characters, ignored; type `help`"
    );
    // A sink too small for the reply: the request is still executed, the reply says it was cut.
    let mut small: heapless::String<8> = heapless::String::new();
    let o = service::handle(b"set limits.upper 390mm", &mut b.c, &mut b.cfg, &mut small);
    assert_eq!(o.action, Action::Reconfigured);
    assert!(o.reply.is_err());
    assert_eq!(b.c.config().limits.upper, Metres::lit("0.39"));
}

#[test]
fn reconfigure_directly() {
    let mut b = Bench::new();
    let mut cfg = ControlConfig::DEFAULT;
    cfg.limits.lower = Metres::lit("0.2");
    assert_eq!(b.c.reconfigure(&cfg), Ok(()));
    assert_eq!(b.c.config(), &cfg);
    b.c.command(Command::Up).unwrap();
    let mut other = cfg;
    other.limits.lower = Metres::lit("0.15");
    assert_eq!(b.c.reconfigure(&other), Err(Refusal::InMotion));
    assert_eq!(b.c.config(), &cfg);
    let mut b = Bench::new();
    let mut bad = ControlConfig::DEFAULT;
    bad.limits.lower = Metres::lit("0.5");
    assert_eq!(b.c.reconfigure(&bad), Err(Refusal::BadConfig));
    assert_eq!(b.c.config(), &ControlConfig::DEFAULT);
}

/// Lines a person (or a fuzzer) might send: commands, keys, values and noise.
fn line_strategy() -> impl Strategy<Value = Vec<u8>> {
    let key =
        proptest::sample::select(settings::SETTINGS.iter().map(|s| s.key).collect::<Vec<_>>());
    let word = proptest::sample::select(vec![
        "set",
        "get",
        "status",
        "save",
        "limits",
        "up",
        "down",
        "stop",
        "goto",
        "fault",
        "fault clear",
        "help",
        "version",
        "SET",
    ]);
    let value = proptest::sample::select(vec![
        "", "0", "1", "-1", "400mm", "150 mm", "0.3m", "1e9", "none", "dry", "ptfe", "scurve",
        "latched", "12", "45A", "0.5", "50%", "x", "1_000",
    ]);
    prop_oneof![
        proptest::collection::vec(any::<u8>(), 0..130),
        (word, key, value).prop_map(|(w, k, v)| format!("{w} {k} {v}").into_bytes()),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    /// Any sequence of lines: no panic, and the configuration changes exactly when a line is a
    /// `set` that validates (and the lift is at rest); the controller always runs the running
    /// configuration.
    #[test]
    fn arbitrary_lines_never_panic_or_change_config_unless_valid_set(
        lines in proptest::collection::vec(line_strategy(), 1..12)
    ) {
        let mut b = Bench::new();
        for line in &lines {
            let before = b.cfg;
            let moving = matches!(b.c.state(), State::Lifting | State::Lowering);
            let expect = match parse(line) {
                Ok(Some(Request::Set(id, raw))) => match settings::apply(&before, id, raw) {
                    Ok(next) if !moving || next == before => next,
                    _ => before,
                },
                _ => before,
            };
            let mut out = String::new();
            let o = service::handle(line, &mut b.c, &mut b.cfg, &mut out);
            prop_assert_eq!(o.reply, Ok(()));
            prop_assert_eq!(b.cfg, expect);
            prop_assert_eq!(b.c.config(), b.cfg.get());
            prop_assert_eq!(o.action == Action::Reconfigured, expect != before);
            b.ticks(3);
        }
    }
}

#[test]
fn status_fault_names_are_one_word() {
    let v = liftfw::console::StatusView {
        state: "fault",
        height: Metres::lit("0.2"),
        homed: true,
        screw_speed: Default::default(),
        current: Default::default(),
        friction_torque: Default::default(),
        stick_slip: false,
        stick_slip_amplitude: Default::default(),
        stick_slip_episodes: 0,
        fault: Some(FaultKind::LimitSwitch.name()),
        load: Default::default(),
        cruise_limit: None,
        #[cfg(feature = "ball-screw")]
        ball_f: None,
    };
    let mut s = String::new();
    liftfw::console::write_status(&mut s, &v).unwrap();
    assert!(
        s.contains(" fault=limit-switch-before-soft-limit-missed homed=yes load="),
        "{s}"
    );
}

/// The ball-screw image's console refuses a law in τ on a lead screw (the estimator would read
/// its |θ̇| as τ), as the `ball` preset or as the variable, and changes nothing; on a ball screw
/// the law is taken and the screw can then not go back to lead under it.
#[cfg(feature = "ball-screw")]
#[test]
fn tau_law_needs_drive_screw_ball() {
    let mut b = Bench::new();
    let before = b.cfg;
    assert_eq!(b.reply("get drive.screw"), "drive.screw = lead");
    for (line, key) in [
        ("set friction.law ball", "friction.law"),
        ("set friction.variable tau", "friction.variable"),
    ] {
        let (r, o) = b.line(line);
        assert_eq!(
            r,
            format!(
                "error: set {key} refused: friction.variable: tau (the ball-screw law) needs \
                 drive.screw = ball"
            ),
            "{line}"
        );
        assert_eq!(o.action, Action::None);
        assert_eq!(b.cfg, before, "{line}");
        assert_eq!(b.c.config(), before.get(), "{line}");
    }
    let r = b.reply("set drive.screw ball");
    assert!(r.starts_with("ok: drive.screw = ball"), "{r}");
    let r = b.reply("set friction.law ball");
    assert!(r.starts_with("ok: friction.law = ball"), "{r}");
    let with_tau = b.cfg;
    let (r, _) = b.line("set drive.screw lead");
    assert!(
        r.starts_with("error: set drive.screw refused: friction.variable: tau"),
        "{r}"
    );
    assert_eq!(b.cfg, with_tau);
    assert_eq!(b.c.config(), with_tau.get());
}
