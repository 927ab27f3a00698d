//! Motion in closed loop: the core's supervisor, ramp, speed loop and halt planner driving
//! host-sim's plant (motor, bridge, battery, noisy quantised sensors). Every test runs the same
//! `Controller::step` the board runs, at the board's 1 kHz tick.
#![allow(clippy::expect_used, clippy::unwrap_used)]

mod support;
use host_sim::physics::{Geometry, Lubricant};
use liftfw::control::{Bridge, Command, Event, State, Switches};
use liftfw::units::Metres;
use support::{command_at, run, Scenario, Tick};

fn height_at(deg: f64) -> f64 {
    Geometry::paper().height(deg.to_radians())
}

/// Go to `start + dh` and return (final error, overshoot beyond the target), mm.
fn goto(lub: Lubricant, load: f64, start_deg: f64, dh: f64, seed: u64) -> (f64, f64) {
    held(goto_ending(lub, load, start_deg, dh, seed, |_| {}))
}

/// A [`goto_ending`] that must end holding: (final error, overshoot), mm.
fn held((state, err, over, events): (State, f64, f64, Vec<(f64, Event)>)) -> (f64, f64) {
    assert_eq!(state, State::Holding, "{events:?}");
    (err, over)
}

/// Go to `start + dh` with the scenario adjusted by `adjust` (e.g. another ramp shape), however
/// the move ends: the state it ends in, the final error and the overshoot beyond the target
/// (mm), and the core's events.
fn goto_ending(
    lub: Lubricant,
    load: f64,
    start_deg: f64,
    dh: f64,
    seed: u64,
    adjust: impl Fn(&mut Scenario),
) -> (State, f64, f64, Vec<(f64, Event)>) {
    let mut s = Scenario::new(lub, load, start_deg, 0.0);
    adjust(&mut s);
    s.seed = seed;
    // Head speed ≈ 0.95 mm/s per rad/s of screw × cot α: allow the move plus 1 s.
    let cot = 1.0 / start_deg.to_radians().tan();
    s.duration = dh.abs() * 1e3 / (3.0 * 0.3 * cot.min(3.0)) + 1.2;
    let target = height_at(start_deg) + dh;
    s.wide_stops();
    let r = run(
        &s,
        command_at(0.02, Command::GoTo(Metres::from_f64(target))),
    );
    let err = (r.final_height() - target) * 1e3;
    let over = ((r.extreme_height(dh > 0.0) - target) * dh.signum() * 1e3).max(0.0);
    (r.controller.state(), err, over, r.events)
}

fn halts_within_half_a_millimetre(lub: Lubricant) {
    let mut worst = (0.0f64, 0.0f64);
    for (i, &(load, start, dh)) in [
        (0.0, 15.0, 0.008),
        (500.0, 15.0, 0.008),
        (1000.0, 15.0, 0.008),
        (1000.0, 45.0, -0.003),
        (0.0, 45.0, -0.003),
        (1000.0, 65.0, -0.0015),
    ]
    .iter()
    .enumerate()
    {
        let (err, over) = goto(lub, load, start, dh, i as u64 + 1);
        println!(
            "{lub:?} {load} kg from {start}° by {dh} m: error {err:+.3} mm, overshoot {over:.3} mm"
        );
        assert!(err.abs() <= 0.5, "{lub:?} {load} {start}: error {err} mm");
        assert!(over <= 0.5, "{lub:?} {load} {start}: overshoot {over} mm");
        if err.abs() > worst.0.abs() {
            worst.0 = err;
        }
        worst.1 = worst.1.max(over);
    }
    println!(
        "{lub:?} worst: error {:+.3} mm, overshoot {:.3} mm",
        worst.0, worst.1
    );
}

#[test]
fn dry_lift_halts_within_half_a_millimetre_at_any_load_either_way() {
    halts_within_half_a_millimetre(Lubricant::Dry);
}

#[test]
fn ptfe_lift_halts_within_half_a_millimetre_at_any_load_either_way() {
    halts_within_half_a_millimetre(Lubricant::Ptfe);
}

#[test]
fn greased_lift_halts_within_half_a_millimetre_at_any_load_either_way() {
    halts_within_half_a_millimetre(Lubricant::Lithium);
}

#[test]
fn speed_tracks_the_cruise_reference() {
    // Mean and rms screw-speed error over the cruise phase (0.5 s after the start to 0.5 s
    // before the brake), from the plant's true gear-output speed.
    for lub in Lubricant::ALL {
        let mut s = Scenario::new(lub, 1000.0, 15.0, 3.0);
        s.seed = 7;
        let r = run(&s, command_at(0.02, Command::Up));
        let n = 60.0 / (2.0 * std::f64::consts::PI); // not used: speeds are at the screw
        let _ = n;
        let cruise: Vec<f64> = r
            .trace
            .records
            .windows(2)
            .filter(|w| w[0].t > 0.5 && w[1].t < 2.9)
            .map(|w| (w[1].theta_i - w[0].theta_i) / (w[1].t - w[0].t) - 3.0)
            .collect();
        let mean = cruise.iter().sum::<f64>() / cruise.len() as f64;
        let rms = (cruise.iter().map(|e| e * e).sum::<f64>() / cruise.len() as f64).sqrt();
        println!("{lub:?}: cruise speed error mean {mean:+.4} rad/s, rms {rms:.4} rad/s (reference 3 rad/s)");
        assert!(mean.abs() < 0.05 * 3.0, "{lub:?}: mean error {mean}");
    }
}

#[test]
fn stop_brakes_along_the_ramp_and_holds() {
    let s = Scenario::new(Lubricant::Ptfe, 1000.0, 15.0, 1.5);
    let mut step = 0;
    let r = run(
        &s,
        Box::new(move |k: &mut Tick<'_>| {
            if step == 0 && k.t >= 0.02 {
                k.controller.command(Command::Up).unwrap();
                step = 1;
            } else if step == 1 && k.t >= 1.0 {
                k.controller.command(Command::Stop).unwrap();
                step = 2;
            }
        }),
    );
    assert_eq!(r.controller.state(), State::Holding);
    // Driving stops within ramp + settle of the stop command.
    let last_drive = r
        .ticks
        .iter()
        .rev()
        .find(|t| matches!(t.bridge, Bridge::Drive(_)))
        .unwrap();
    assert!(
        last_drive.t < 1.0 + 0.06 + 0.3,
        "drove until {}",
        last_drive.t
    );
    let h_stop = r.trace.records.iter().find(|x| x.t >= 1.4).unwrap().height;
    assert!((r.final_height() - h_stop).abs() < 1e-5, "held still");
}

#[test]
fn hold_to_run_button_lifts_only_while_held() {
    let s = Scenario::new(Lubricant::Ptfe, 500.0, 15.0, 1.5);
    let r = run(
        &s,
        Box::new(|k: &mut Tick<'_>| {
            // Released at boot (arms the buttons), held 0.1–0.8 s.
            if (0.1..0.8).contains(&k.t) {
                k.inputs.switches.0 |= Switches::BUTTON_UP;
            }
        }),
    );
    let drives: Vec<f64> = r
        .ticks
        .iter()
        .filter(|t| matches!(t.bridge, Bridge::Drive(_)))
        .map(|t| t.t)
        .collect();
    assert!(drives.first().unwrap() > &0.1 && drives.first().unwrap() < &0.11);
    assert!(
        *drives.last().unwrap() < 0.8 + 0.4,
        "{}",
        drives.last().unwrap()
    );
    assert!(r.final_height() > r.summary.height.0 + 1e-3);
    assert_eq!(r.controller.state(), State::Holding);
}

#[test]
fn a_down_button_held_at_boot_does_not_lower_the_lift() {
    let s = Scenario::new(Lubricant::Ptfe, 1000.0, 45.0, 0.5);
    let r = run(
        &s,
        Box::new(|k: &mut Tick<'_>| {
            k.inputs.switches.0 |= Switches::BUTTON_DOWN; // stuck or held since power-up
        }),
    );
    assert!(r
        .ticks
        .iter()
        .all(|t| !matches!(t.bridge, Bridge::Drive(_))));
    assert_eq!(r.final_height(), r.summary.height.0);
}

#[test]
fn lowering_from_the_button_needs_a_fresh_press_and_stops_on_release() {
    let s = Scenario::new(Lubricant::Ptfe, 1000.0, 45.0, 1.2);
    let r = run(
        &s,
        Box::new(|k: &mut Tick<'_>| {
            if (0.1..0.6).contains(&k.t) {
                k.inputs.switches.0 |= Switches::BUTTON_DOWN;
            }
        }),
    );
    assert!(r.final_height() < r.summary.height.0 - 1e-4);
    let last = r
        .ticks
        .iter()
        .rev()
        .find(|t| matches!(t.bridge, Bridge::Drive(_)))
        .unwrap();
    assert!(last.t < 0.6 + 0.4);
    assert!(r.events.iter().any(|(_, e)| matches!(
        e,
        Event::State {
            to: State::Lowering,
            ..
        }
    )));
}

#[test]
fn up_stops_at_the_upper_limit_stop() {
    // Upper stop 10 mm above the start: `up` ends there, not at the mechanism's end.
    let mut s = Scenario::new(Lubricant::Ptfe, 1000.0, 15.0, 4.0);
    let h0 = height_at(15.0);
    s.control.limits.switch_lower = Metres::from_f64(h0 + 0.00005);
    s.control.limits.lower = Metres::from_f64(h0 + 0.0006);
    s.control.limits.upper = Metres::from_f64(h0 + 0.0107);
    let r = run(&s, command_at(0.02, Command::Up));
    let err = (r.final_height() - (h0 + 0.0107)) * 1e3;
    assert!(err.abs() < 0.5, "{err} mm");
    assert_eq!(r.controller.state(), State::Holding);
}

#[test]
fn s_curve_ramp_halts_within_half_a_millimetre_for_every_lubricant_either_way() {
    use liftfw::control::config::RampShape;
    let scurve = |s: &mut Scenario| {
        s.control.motion.ramp_shape = RampShape::SCurve;
        s.control.motion.ramp_ms = 120;
    };
    for lub in [Lubricant::Dry, Lubricant::Ptfe, Lubricant::Lithium] {
        for (load, start, dh) in [(1000.0, 15.0, 0.006), (1000.0, 45.0, -0.003)] {
            let (err, over) = held(goto_ending(lub, load, start, dh, 3, scurve));
            println!("S-curve {lub:?} {load} kg from {start}° by {dh} m: error {err:+.3} mm, overshoot {over:.3} mm");
            assert!(err.abs() <= 0.5, "{lub:?} {start}: error {err} mm");
            assert!(over <= 0.5, "{lub:?} {start}: overshoot {over} mm");
        }
    }
}

/// The gear output's speed against the reference over the start's ramp and the 100 ms after
/// it (the plant's truth, each tick): the worst excess over the reference after the ramp, and
/// the worst lag behind it during the ramp, rad/s at the screw.
fn start_tracking(lub: Lubricant, load: f64, up: bool) -> (f64, f64) {
    let mut s = Scenario::new(lub, load, 20.0, 0.6);
    s.seed = 3;
    let refs = std::sync::Arc::new(std::sync::Mutex::new(Vec::<(f64, f64)>::new()));
    let log = std::sync::Arc::clone(&refs);
    let mut go = command_at(0.02, if up { Command::Up } else { Command::Down });
    let r = run(
        &s,
        Box::new(move |k: &mut Tick<'_>| {
            go(k);
            let w = k.controller.reference().to_f64();
            log.lock().expect("log").push((k.t, w));
        }),
    );
    let refs = refs.lock().expect("log").clone();
    let dir = if up { 1.0 } else { -1.0 };
    // The ramp: from the first moving reference to the first at cruise.
    let start = refs.iter().position(|&(_, w)| w != 0.0).expect("moved");
    let cruise = refs
        .iter()
        .position(|&(_, w)| (w * dir - 3.0).abs() < 1e-3)
        .expect("cruised");
    let t_cruise = refs[cruise].0;
    let mut lag: f64 = 0.0;
    let mut excess: f64 = 0.0;
    for w in r.trace.records.windows(2) {
        let t = w[1].t;
        let i = match refs.iter().rposition(|&(tr, _)| tr <= t) {
            Some(i) if i >= start => i,
            _ => continue,
        };
        let speed = (w[1].theta_i - w[0].theta_i) / (w[1].t - w[0].t) * dir;
        let reference = refs[i].1 * dir;
        if t < t_cruise {
            lag = lag.max(reference - speed);
        } else if t < t_cruise + 0.1 {
            excess = excess.max(speed - reference);
        }
    }
    (lag, excess)
}

#[test]
fn the_rotor_follows_the_start_ramp() {
    // With the drive's acceleration torque in the speed loop's feed-forward
    // (`motor.inertia`), the rotor follows the ramp instead of lagging it until the
    // integrator has wound up. Measured without it: lowering lagged 0.117 (PTFE) and
    // 0.068 rad/s (lithium), and overshot the cruise by 0.34…0.42 rad/s; with it 0.045 and
    // 0.037, overshooting by 0.28…0.35. (Dry threads stick-slip at the start and creep down:
    // not this test's.)
    for lub in [Lubricant::Ptfe, Lubricant::Lithium] {
        for (load, up) in [
            (1000.0, true),
            (250.0, true),
            (1000.0, false),
            (250.0, false),
            (0.0, false),
        ] {
            let (lag, excess) = start_tracking(lub, load, up);
            let way = if up { "up" } else { "down" };
            println!("{lub:?} {load} kg {way}: ramp lag {lag:.3} rad/s, then over the cruise by {excess:.3} rad/s");
            assert!(
                lag < 0.05,
                "{lub:?} {load} kg {way}: the rotor lagged the ramp by {lag} rad/s"
            );
        }
    }
}

#[test]
fn a_wrong_motor_inertia_still_halts_or_stops_safely() {
    // `motor.inertia` feeds the speed loop's acceleration feed-forward and the load
    // identification's acceleration torque. Set to 0 (none) or up to 10 000 µkg·m² (≈ 170× the
    // drive's 60), the lift still halts where it was sent, without a fault (measured: within
    // 0.09 mm). At the range's top, 100 000 (a flywheel), the identification reads a PTFE
    // 1000 kg car as 2 637 kg and the overload trip stops the lift, naming that load: a safe
    // state, never a move past the target.
    for j in [0, 10_000, 100_000] {
        for (lub, load, start, dh) in [
            (Lubricant::Ptfe, 1000.0, 15.0, 0.008f64),
            (Lubricant::Lithium, 0.0, 45.0, -0.003),
            (Lubricant::Dry, 1000.0, 15.0, 0.008),
        ] {
            let (state, err, over, events) = goto_ending(lub, load, start, dh, 5, |s| {
                s.control.estimator.motor.inertia_ukgm2 = j
            });
            println!("inertia {j} µkg·m², {lub:?} {load} kg from {start}°: {state:?}, error {err:+.3} mm, overshoot {over:.3} mm");
            assert!(over <= 0.5, "inertia {j}, {lub:?}: overshoot {over} mm");
            if j <= 10_000 {
                assert_eq!(state, State::Holding, "inertia {j}, {lub:?}: {events:?}");
                assert!(err.abs() <= 0.5, "inertia {j}, {lub:?}: error {err} mm");
            } else {
                // Where it faults, it is the overload trip, naming the load it read.
                let overload = events.iter().any(|(_, e)| {
                    matches!(e, Event::Fault(f) if f.kind == liftfw::control::FaultKind::Overload)
                });
                assert!(
                    state == State::Holding || (state == State::Fault && overload),
                    "inertia {j}, {lub:?}: {state:?} {events:?}"
                );
            }
        }
    }
}
