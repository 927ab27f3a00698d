//! Closed-loop regression tests of what a hostile user found (the console, the buttons and
//! the settings driven against host-sim's plant): a direction command never moves the other
//! way, an accepted cruise speed never makes a move stop short while claiming arrival nor
//! trips a runaway while lowering, and a drive or geometry change at rest leaves no false
//! height behind.
#![allow(clippy::expect_used, clippy::unwrap_used)]

mod support;
use host_sim::physics::{Geometry, Lubricant};
use liftfw::config::ValidatedConfig;
use liftfw::control::{Command, Refusal, State, Switches};
use liftfw::units::Metres;
use support::{run, Scenario, Tick};

/// The arm angle (degrees) of a head height (m) on the paper's lift.
fn deg_at(h: f64) -> f64 {
    Geometry::paper().alpha_of_height(h).to_degrees()
}

/// A lift resting at `from` m with `change` applied to its configuration at rest (as the
/// console's `set` does, `Controller::reconfigure`) at 0.05 s, then `then` at 0.1 s (console
/// command or a held button): the refusal, and the run.
fn after_set(
    from: f64,
    change: fn(&mut liftfw::control::config::ControlConfig),
    then: Then,
) -> (Option<Result<(), Refusal>>, support::Run) {
    let mut s = Scenario::new(Lubricant::Dry, 1000.0, deg_at(from), 3.0);
    let mut next = s.control;
    change(&mut next);
    let answer = std::sync::Arc::new(std::sync::Mutex::new(None));
    let a = std::sync::Arc::clone(&answer);
    s.seed = 3;
    let mut set = false;
    let r = run(
        &s,
        Box::new(move |k: &mut Tick<'_>| {
            if !set && k.t >= 0.05 {
                set = true;
                k.controller.reconfigure(&next).expect("accepted at rest");
            }
            match then {
                Then::Command(c) if k.t >= 0.1 && a.lock().unwrap().is_none() => {
                    *a.lock().unwrap() = Some(k.controller.command(c));
                }
                Then::Hold(b) if k.t >= 0.1 => k.inputs.switches.0 |= b,
                _ => {}
            }
        }),
    );
    let got = *answer.lock().unwrap();
    (got, r)
}

#[derive(Clone, Copy)]
enum Then {
    Command(Command),
    Hold(u8),
}

/// Highest and lowest true head height over a run, m.
fn span(r: &support::Run) -> (f64, f64) {
    (r.extreme_height(false), r.extreme_height(true))
}

#[test]
fn down_never_lifts_and_up_never_lowers_when_the_head_is_beyond_the_stop() {
    let from = 0.230;
    let raise_lower = |c: &mut liftfw::control::config::ControlConfig| {
        c.limits.lower = Metres::from_f64(0.260);
    };
    let drop_upper = |c: &mut liftfw::control::config::ControlConfig| {
        c.limits.upper = Metres::from_f64(0.200);
    };
    // Console `down` under a raised lower stop, and `up` over a lowered upper stop: refused.
    for (change, cmd) in [
        (raise_lower as fn(&mut _), Command::Down),
        (drop_upper as fn(&mut _), Command::Up),
    ] {
        let (answer, r) = after_set(from, change, Then::Command(cmd));
        assert_eq!(answer, Some(Err(Refusal::AtLimit)), "{cmd:?}");
        let (lo, hi) = span(&r);
        assert!(
            hi - from < 0.1e-3 && from - lo < 0.1e-3,
            "{cmd:?} moved the head: {:.2}..{:.2} mm",
            lo * 1e3,
            hi * 1e3
        );
        assert!(r.first_fault().is_none());
    }
    // The buttons share the command: DOWN under a raised lower stop does not lift, UP over a
    // lowered upper stop does not lower.
    for (change, button) in [
        (raise_lower as fn(&mut _), Switches::BUTTON_DOWN),
        (drop_upper as fn(&mut _), Switches::BUTTON_UP),
    ] {
        let (_, r) = after_set(from, change, Then::Hold(button));
        let (lo, hi) = span(&r);
        assert!(
            hi - from < 0.1e-3 && from - lo < 0.1e-3,
            "button {button:#x} moved the head: {:.2}..{:.2} mm",
            lo * 1e3,
            hi * 1e3
        );
        assert!(matches!(r.controller.state(), State::Idle | State::Holding));
    }
    // The right direction still works: `up` under a raised lower stop lifts.
    let (answer, r) = after_set(from, raise_lower, Then::Command(Command::Up));
    assert_eq!(answer, Some(Ok(())));
    assert!(r.final_height() > from + 1e-3);
}

/// Console lines through the board's service (`liftfw::console::service::handle`, as the
/// firmware's console task runs them) at the given times; their replies.
fn console_hook(
    lines: Vec<(f64, String)>,
    cfg: liftfw::control::config::ControlConfig,
    replies: std::sync::Arc<std::sync::Mutex<Vec<String>>>,
) -> support::Hook {
    let mut running = ValidatedConfig::new(cfg).expect("valid");
    let mut next = 0;
    Box::new(move |k: &mut Tick<'_>| {
        while next < lines.len() && k.t >= lines[next].0 {
            let mut out = String::new();
            liftfw::console::service::handle(
                lines[next].1.as_bytes(),
                k.controller,
                &mut running,
                &mut out,
            );
            replies.lock().unwrap().push(out);
            next += 1;
        }
    })
}

/// Every `motion.cruise_speed` the console accepts at rated load: a `goto` ends at its target
/// (never `holding` short of it), lowering never trips a runaway, and a speed the motor
/// cannot reach is limited, with a warning event and the limit in `status`.
#[test]
fn an_accepted_cruise_speed_never_stops_short_nor_runs_away() {
    let from = 0.230;
    for (speed, to) in [(6.0, 0.260), (20.0, 0.260), (6.0, 0.200), (20.0, 0.200)] {
        let mut s = Scenario::new(Lubricant::Dry, 1000.0, deg_at(from), 0.0);
        // Nut 0.955 mm/s at 3 rad/s, head ≈ nut × cot α: at least that fast, plus settling.
        let mid = 0.5 * (deg_at(from) + deg_at(to));
        s.duration = (to - from).abs() * 1e3 / (0.955 / mid.to_radians().tan()) + 2.0;
        let replies = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let lines = vec![
            (0.05, format!("set motion.cruise_speed {speed}")),
            (0.1, format!("goto {}mm", to * 1e3)),
        ];
        let r = run(
            &s,
            console_hook(lines, s.control, std::sync::Arc::clone(&replies)),
        );
        let replies = replies.lock().unwrap().clone();
        assert!(
            replies[0].starts_with("ok: motion.cruise_speed = "),
            "{replies:?}"
        );
        assert!(
            replies[1].starts_with("ok: going to"),
            "{speed}: {replies:?}"
        );
        if speed >= 20.0 {
            // Beyond the motor at 1000 kg either way (≈ 5 rad/s unloaded at 12.6 V).
            let limited = r.events.iter().find_map(|(_, e)| match e {
                liftfw::control::Event::CruiseLimited { speed } => Some(speed.to_f64()),
                _ => None,
            });
            let first = limited.expect("limited, with a warning event");
            assert!(first < speed, "{first}");
            // Where the limit settled: what the motor reached.
            let w = r
                .controller
                .status()
                .cruise_limit
                .expect("limited")
                .to_f64();
            assert!(
                w > 1.0 && w < 6.0,
                "{speed} to {to}: limited to {w:.2} rad/s"
            );
            println!("{speed} rad/s to {to}: limited to {w:.2} rad/s");
        }
        assert!(
            r.first_fault().is_none(),
            "{speed} to {to}: {:?}",
            r.first_fault()
        );
        assert_eq!(r.controller.state(), State::Holding, "{speed} to {to}");
        let err = r.final_height() - to;
        assert!(
            err.abs() < 0.3e-3,
            "{speed} rad/s to {to}: ends at {:.2} mm ({:+.2} mm)",
            r.final_height() * 1e3,
            err * 1e3
        );
    }
}

/// A drive or geometry `set` at rest: the counts mean another height, so the board forgets
/// the position, says so wherever it shows a height (`status`, `fault`), refuses the moves
/// that need a height, and `status` tells whether it is homed.
#[test]
fn a_drive_or_geometry_set_at_rest_marks_the_board_unhomed_everywhere() {
    let from = 0.230;
    for change in ["set drive.gear_ratio 61", "set geometry.mu_pin 0.25"] {
        let s = Scenario::new(Lubricant::Dry, 1000.0, deg_at(from), 0.6);
        let replies = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let lines = vec![
            (0.05, "status".to_string()),
            (0.1, change.to_string()),
            (0.2, "status".to_string()),
            (0.25, "goto 250mm".to_string()),
            (0.3, "up".to_string()),
            (0.35, "limits".to_string()),
        ];
        let r = run(
            &s,
            console_hook(lines, s.control, std::sync::Arc::clone(&replies)),
        );
        let replies = replies.lock().unwrap().clone();
        assert!(replies[0].contains(" height=230.0mm ") && replies[0].contains(" homed=yes "));
        assert!(replies[1].starts_with("ok: "), "{change}: {replies:?}");
        assert!(
            replies[2].contains(" height=unknown ") && replies[2].contains(" homed=no "),
            "{change}: {}",
            replies[2]
        );
        for (i, cmd) in [(3, "goto"), (4, "up")] {
            assert_eq!(
                replies[i],
                format!("error: {cmd} {}", Refusal::NotHomed.message()),
                "{change}"
            );
        }
        assert!(!r.controller.homed());
        assert!((r.final_height() - from).abs() < 0.1e-3, "the head stayed");
    }
}
