//! Homing in closed loop: after a power cut while moving the board does not know where the
//! head is. The core then refuses every motion but lowering, which runs to the lower limit
//! switch and takes the switch's configured height as the position; after that the lift halts
//! at set heights as usual. The plant's lower switch closes at α = 16° (140.3 mm), the
//! factory `limits.switch_lower`.
#![allow(clippy::expect_used, clippy::unwrap_used)]

mod support;
use host_sim::physics::{Geometry, Lubricant};
use liftfw::control::{Command, Event, Refusal, State, Switches};
use liftfw::units::Metres;
use support::{run, Scenario, Tick};

fn height_at(deg: f64) -> f64 {
    Geometry::paper().height(deg.to_radians())
}

/// Boot unhomed at `start_deg`, hold DOWN from 0.1 s until homed, then go to `target` m
/// `delay` s after the tick that homed.
fn home_then_goto(
    lub: Lubricant,
    load: f64,
    start_deg: f64,
    target: f64,
    delay: f64,
) -> support::Run {
    let mut s = Scenario::new(lub, load, start_deg, 0.0);
    s.unhomed = true;
    // Head speed at the 3 rad/s cruise: 0.955 mm/s of nut travel × cot α.
    let head_speed = |a: f64, b: f64| 0.955 / (0.5 * (a + b)).to_radians().tan();
    let down = (height_at(start_deg) - height_at(16.0)) * 1e3 / head_speed(start_deg, 16.0);
    let up = (target - height_at(16.0)).abs() * 1e3 / head_speed(16.0, 20.0);
    s.duration = down + up + 3.0;
    let mut homed_at: Option<f64> = None;
    let mut checked = false;
    let mut sent = false;
    run(
        &s,
        Box::new(move |k: &mut Tick<'_>| {
            if !checked && k.t >= 0.05 {
                checked = true;
                assert_eq!(k.controller.command(Command::Up), Err(Refusal::NotHomed));
                assert_eq!(
                    k.controller
                        .command(Command::GoTo(Metres::from_f64(target))),
                    Err(Refusal::NotHomed)
                );
                assert!(!k.controller.homed());
            }
            if homed_at.is_none() && k.controller.homed() {
                homed_at = Some(k.t);
            }
            match homed_at {
                // A person holds DOWN (released at boot, so the button is armed).
                None if k.t >= 0.1 => k.inputs.switches.0 |= Switches::BUTTON_DOWN,
                Some(t) if !sent && k.t > t + delay => {
                    sent = true;
                    k.controller
                        .command(Command::GoTo(Metres::from_f64(target)))
                        .expect("homed: goto accepted");
                }
                _ => {}
            }
        }),
    )
}

#[test]
fn an_unhomed_lift_homes_on_the_lower_switch_then_halts_at_a_set_height() {
    for (lub, load, start) in [
        (Lubricant::Ptfe, 500.0, 18.0),
        (Lubricant::Dry, 1000.0, 17.5),
        (Lubricant::Lithium, 0.0, 18.5),
    ] {
        let target = 0.152;
        let r = home_then_goto(lub, load, start, target, 0.5);
        assert!(r.first_fault().is_none(), "{lub:?}: {:?}", r.first_fault());
        let homed = r
            .events
            .iter()
            .find(|(_, e)| matches!(e, Event::Homed { .. }));
        assert!(homed.is_some(), "{lub:?}: never homed");
        assert!(r.controller.homed());
        // The lowest true height is the switch (it stops at once, within the debounce).
        let lowest = r.extreme_height(false);
        assert!(
            (lowest - height_at(16.0)).abs() < 0.5e-3,
            "{lub:?}: lowest {:.3} mm vs switch {:.3} mm",
            lowest * 1e3,
            height_at(16.0) * 1e3
        );
        let err = (r.final_height() - target) * 1e3;
        eprintln!("{lub:?} {load} kg from {start}°: homed, goto error {err:+.3} mm");
        assert!(err.abs() < 0.5, "{lub:?}: final error {err} mm");
        assert_eq!(r.controller.state(), State::Holding);
    }
}

/// A `goto` sent right after the homing notice, while the screw still turns down (the lift
/// stopped on the switch a tick ago): the drive must not start against the back-EMF. It
/// tripped the over-current limit at 56–66 A, on every lubricant, before the drive waited for
/// the screw to slow (`Motion::reversing`) and the re-home kept the speed filter's speed.
#[test]
fn a_goto_on_the_tick_after_homing_waits_for_the_screw_to_stop_turning_down() {
    for delay in [0.0005, 0.001] {
        for (lub, load, start) in [
            (Lubricant::Ptfe, 500.0, 18.0),
            (Lubricant::Dry, 1000.0, 17.5),
            (Lubricant::Lithium, 0.0, 18.5),
        ] {
            let target = 0.152;
            let r = home_then_goto(lub, load, start, target, delay);
            assert!(
                r.first_fault().is_none(),
                "{lub:?} {load} kg, goto {delay} s after homing: {:?}",
                r.first_fault()
            );
            let err = (r.final_height() - target) * 1e3;
            assert!(err.abs() < 0.5, "{lub:?}: final error {err} mm");
            assert_eq!(r.controller.state(), State::Holding);
        }
    }
}

#[test]
fn a_lift_parked_on_the_lower_switch_homes_by_creeping_up_until_it_opens() {
    // Start at 15.5°, below the switch (16°): DOWN is refused (switch closed), UP creeps up.
    let mut s = Scenario::new(Lubricant::Ptfe, 500.0, 15.5, 3.0);
    s.unhomed = true;
    let mut sent = false;
    let r = run(
        &s,
        Box::new(move |k: &mut Tick<'_>| {
            if !sent && k.t >= 0.05 {
                sent = true;
                assert_eq!(k.controller.command(Command::Down), Err(Refusal::AtLimit));
                k.controller
                    .command(Command::Up)
                    .expect("homing up accepted");
            }
        }),
    );
    assert!(r.first_fault().is_none(), "{:?}", r.first_fault());
    assert!(r.controller.homed(), "never homed");
    let at_switch = height_at(16.0);
    let h = r.final_height();
    assert!(
        h >= at_switch - 0.1e-3 && h < at_switch + 0.5e-3,
        "stopped at {:.3} mm, switch {:.3} mm",
        h * 1e3,
        at_switch * 1e3
    );
    // The position the core now holds matches the true height.
    let est = r.controller.status().height.to_f64();
    assert!((est - h).abs() < 0.3e-3, "core {est} vs true {h}");
}

#[test]
fn a_geometry_change_at_rest_forgets_the_position_and_other_changes_keep_it() {
    use liftfw::control::{config::ControlConfig, Controller};
    let cfg = ControlConfig::DEFAULT;
    let mut c = Controller::new(&cfg, 9_000).unwrap();
    let mut faster = cfg;
    faster.motion.ramp_ms = 120;
    c.reconfigure(&faster).unwrap();
    assert!(c.homed());
    assert_eq!(c.position_counts(), 9_000);
    let mut geared = faster;
    geared.estimator.drive.gear_ratio = fixed::types::I16F16::from_num(50);
    c.reconfigure(&geared).unwrap();
    assert!(!c.homed());
    assert_eq!(c.command(Command::Up), Err(Refusal::NotHomed));
}

#[test]
fn a_change_outside_the_model_keeps_the_estimators_state() {
    use liftfw::control::{config::ControlConfig, Controller, Inputs};
    use liftfw::units::Instant;
    let cfg = ControlConfig::DEFAULT;
    let mut c = Controller::new(&cfg, 9_000).unwrap();
    // A few ticks at rest: the speed filter has a state a fresh estimator does not (the
    // time of its last tick, the count it holds).
    for k in 0..20u32 {
        let inputs = Inputs {
            encoder_count: 9_003,
            encoder_edge_age: 0,
            current_raw: 2048,
            supply_raw: 2_800,
            switches: Switches(0),
        };
        c.step(Instant(1_000 + k * 1_000), &inputs);
    }
    let running = format!("{:?}", c.estimator());
    let fresh = format!("{:?}", Controller::new(&cfg, 9_000).unwrap().estimator());
    assert_ne!(running, fresh);
    let mut faster = cfg;
    faster.motion.ramp_ms = 120;
    c.reconfigure(&faster).unwrap();
    assert_eq!(format!("{:?}", c.estimator()), running);
    // A model change starts it afresh.
    let mut stiffer = faster;
    stiffer.estimator.mechanics.inertia_ukgm2 += 10;
    c.reconfigure(&stiffer).unwrap();
    assert_ne!(format!("{:?}", c.estimator()), running);
}
