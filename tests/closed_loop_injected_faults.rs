//! Faults injected the way a user injects them (`host_sim::inject`: a kind, a time and a
//! size, applied by the simulation to the plant or to what the board reads), for the cases no
//! other test covered: a dead lower limit switch during homing, a current sensor with an
//! offset or a wrong scale, lowering faster than commanded (the runaway monitor's overspeed
//! branch) and over-voltage at rest.
#![allow(clippy::expect_used, clippy::unwrap_used)]

mod support;
use host_sim::inject::{parse_list, Plan};
use host_sim::physics::{Geometry, Lubricant};
use liftfw::control::{Bridge, Command, Event, FaultKind, State, Switches};
use support::{run, Scenario, Tick};

fn plan(s: &str) -> Plan {
    Plan::new(&parse_list(s).unwrap()).unwrap()
}

fn height_at(deg: f64) -> f64 {
    Geometry::paper().height(deg.to_radians())
}

#[test]
fn a_dead_lower_switch_during_homing_ends_in_a_fault_not_a_false_home() {
    // Unhomed at 17.5°, DOWN held from 0.1 s; the lower switch (16°) never closes. host-sim's
    // plant has no end stop under the mechanism: the lift's bottom is a jam from 6 s, by when
    // the head is ≈ 10 mm under the switch's height.
    let mut s = Scenario::new(Lubricant::Dry, 1000.0, 17.5, 8.0);
    s.unhomed = true;
    s.faults = plan("lower-switch-dead@0, jam@6:2000");
    let r = run(
        &s,
        Box::new(|k: &mut Tick<'_>| {
            if k.t >= 0.1 {
                k.inputs.switches.0 |= Switches::BUTTON_DOWN;
            }
        }),
    );
    assert!(
        !r.events
            .iter()
            .any(|(_, e)| matches!(e, Event::Homed { .. })),
        "homed without a switch"
    );
    assert!(!r.controller.homed());
    // The lift went past the switch's height; the mechanism's end stalls the motor and a
    // protection stops it: overload (the drive pushing the lift down against an obstruction,
    // the current held at its limit: 6.22 s), stall, or over-current.
    let (t, f) = r.first_fault().unwrap_or_else(|| {
        panic!(
            "no fault: lowest {:.2} mm (switch {:.2}), state {:?}",
            r.extreme_height(false) * 1e3,
            height_at(16.0) * 1e3,
            r.controller.state()
        )
    });
    assert!(
        matches!(
            f.kind,
            FaultKind::Overload | FaultKind::Stall | FaultKind::OverCurrent
        ) && t > 6.0
            && t < 7.0,
        "{:?} at {t:.2} s",
        f.kind
    );
    // Still unhomed: a height move stays refused.
    assert!(!r.controller.status().homed);
    assert!(r.extreme_height(false) < height_at(16.0));
    let last = r.ticks.last().unwrap();
    assert!(!matches!(last.bridge, Bridge::Drive(_)), "still driving");
}

/// Lift 1000 kg from 20° with `faults`; the first fault.
fn lift_with(faults: &str) -> support::Run {
    let mut s = Scenario::new(Lubricant::Dry, 1000.0, 20.0, 3.0);
    s.wide_stops();
    s.faults = plan(faults);
    run(&s, support::command_at(0.02, Command::Up))
}

#[test]
fn a_current_sensor_reading_high_trips_overload_while_lifting() {
    // Reading double (scale 2), or 15 A too much (offset), from 1.2 s into a lift at
    // 1000 kg: the measured torque exceeds the model's at rated load beyond the margin.
    for faults in ["current-scale@1.2:2", "current-offset@1.2:25"] {
        let r = lift_with(faults);
        let (t, f) = r.first_fault().expect(faults);
        assert!(
            matches!(f.kind, FaultKind::Overload | FaultKind::OverCurrent),
            "{faults}: {:?}",
            f.kind
        );
        assert!((1.2..1.8).contains(&t), "{faults}: tripped at {t:.3} s");
        assert_eq!(f.state, State::Lifting);
        assert!(r
            .ticks
            .iter()
            .filter(|k| k.t > t + 0.002)
            .all(|k| !matches!(k.bridge, Bridge::Drive(_))));
    }
}

#[test]
fn a_current_sensor_reading_low_still_lets_the_overcurrent_limit_stop_a_jam() {
    // Reading half (scale 0.5) hides half the current; a jam at 1.5 s then makes the motor
    // push until the stall monitor (no count, high duty, no back-EMF) stops it.
    let r = lift_with("current-scale@1:0.5, jam@1.5:400");
    let (t, f) = r.first_fault().expect("the jam is caught");
    assert!(
        matches!(
            f.kind,
            FaultKind::Stall | FaultKind::OverCurrent | FaultKind::Overload
        ),
        "{:?}",
        f.kind
    );
    assert!(t > 1.5 && t < 2.5, "tripped at {t:.3} s");
    // The true current (the plant's, not the sensor's) stayed within the bridge's rating.
    let peak = r.peak_current();
    assert!(peak < 80.0, "true current {peak:.1} A");
}

#[test]
fn lowering_faster_than_commanded_trips_runaway() {
    // A failed bridge drives down at full duty from 0.8 s into a lowering: the screw runs
    // faster than the reference and the overspeed branch of the runaway monitor trips.
    let mut s = Scenario::new(Lubricant::Ptfe, 1000.0, 30.0, 2.0);
    s.wide_stops();
    // Cruise 1.5 rad/s: the monitor's limit is 1.5 × 1.5 + 25 % × 1.5 = 2.6 rad/s, well under
    // what the motor reaches at full duty lowering (≈ 5 rad/s).
    s.control.motion.cruise_speed = liftfw::units::RadiansPerSecond::from_f64(1.5);
    let mut sent = false;
    let r = run(
        &s,
        Box::new(move |k: &mut Tick<'_>| {
            if !sent && k.t >= 0.02 {
                sent = true;
                k.controller.command(Command::Down).unwrap();
            }
            if k.t >= 0.8 {
                // 60 % down: faster than the reference, under the over-current trip.
                k.force = Some(Bridge::Drive(-(i16::MAX / 5 * 3)));
            }
        }),
    );
    let (t, f) = r.first_fault().expect("runaway");
    assert_eq!(f.kind, FaultKind::Runaway);
    assert_eq!(
        f.state,
        State::Lowering,
        "tripped while lowering (overspeed branch)"
    );
    // 100 ms of too-fast lowering, after the speed filter sees the rise.
    assert!(t > 0.85 && t < 1.1, "tripped at {t:.3} s");
}

#[test]
fn over_voltage_at_rest_latches() {
    // At rest, the battery surges to 17 V (above protect.supply_max, 16 V) from 0.3 s.
    let mut s = Scenario::new(Lubricant::Dry, 1000.0, 25.0, 0.8);
    s.faults = plan("supply-surge@0.3:17");
    let r = run(&s, Box::new(|_: &mut Tick<'_>| {}));
    let (t, f) = r.first_fault().expect("over-voltage");
    assert_eq!(f.kind, FaultKind::OverVoltage);
    assert_eq!(f.state, State::Idle);
    assert!(t > 0.3 && t < 0.45, "tripped at {t:.3} s");
    // Nothing moved.
    assert!((r.final_height() - height_at(25.0)).abs() < 0.05e-3);
}
