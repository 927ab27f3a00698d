//! Closed-loop mode: the liftfw core in the loop, the open-loop duty driver, the motor path,
//! the sensors and determinism.

// A failed expectation is a failed test: panicking is the point here.
#![allow(clippy::expect_used)]

mod common;
use host_sim::physics::Lubricant;
use host_sim::plant::sensors::current_of_code;
use host_sim::sim::{Driver, OpenLoopDuty, Sim, SimConfig, Summary};
use host_sim::trace::Trace;
use liftfw::control::config::ControlConfig;
use liftfw::control::{Bridge, Controller, Inputs};
use std::sync::{Arc, Mutex};

fn cfg(load: f64, duration: f64, seed: u64) -> SimConfig {
    let mut c = SimConfig::paper(Lubricant::Dry.law(), 0.3, 15.0);
    c.plant.load = load;
    c.duration = duration;
    c.dt = 4e-6;
    c.record_rate = 1000.0;
    c.seed = seed;
    c
}

fn run(c: SimConfig, driver: Driver) -> (Summary, Trace) {
    let mut sim = Sim::new(c, driver).expect("valid config");
    let s = sim.run();
    (s, sim.trace)
}

#[test]
fn lower_limit_switch_stops_the_open_loop_driver_at_the_bottom() {
    let duty = OpenLoopDuty {
        duty: -0.5,
        ramp: 0.1,
    };
    let (s, trace) = run(cfg(1000.0, 0.2, 1), Driver::OpenLoop(duty));
    assert_eq!(s.height.0, s.height.1);
    assert!(trace.records.iter().all(|r| r.duty == 0.0));
}

#[test]
fn coasting_core_leaves_the_self_locking_lift_where_it_is() {
    let (s, trace) = run(
        cfg(1000.0, 0.2, 1),
        Driver::Core(Box::new(
            Controller::new(&ControlConfig::DEFAULT, 0).expect("default config"),
        )),
    );
    assert_eq!(s.height.0, s.height.1);
    assert!(trace
        .records
        .iter()
        .all(|r| r.current == 0.0 && r.duty == 0.0));
    assert!((s.stick_fraction - 1.0).abs() < 1e-12);
}

#[test]
fn open_loop_duty_lifts_rated_load_within_forty_amps() {
    let duty = OpenLoopDuty {
        duty: 1.0,
        ramp: 0.2,
    };
    let (s, _) = run(cfg(1000.0, 0.8, 1), Driver::OpenLoop(duty));
    assert!(s.height.1 > s.height.0 + 1e-3, "{:?}", s.height);
    assert!(s.peak_current < 40.0, "{} A", s.peak_current);
    // Power-limited: ≈ 4 rad/s at the screw with 1000 kg at 15° (docs/plant.md).
    assert!(
        (3.0..5.5).contains(&s.late_screw_speed),
        "{}",
        s.late_screw_speed
    );
    assert!(
        s.energy.drive_balance_error() < 0.01 && s.energy.balance_error() < 0.01,
        "{:?}",
        s.energy
    );
    let (light, _) = run(cfg(0.0, 0.8, 1), Driver::OpenLoop(duty));
    assert!(light.late_screw_speed > s.late_screw_speed && light.peak_current < 10.0);
}

#[test]
fn lowering_by_duty_runs_the_motor_backwards() {
    let duty = OpenLoopDuty {
        duty: -0.5,
        ramp: 0.1,
    };
    // From 45°: at 15° the lift is fully down and the lower limit switch stops the driver.
    let mut c = cfg(1000.0, 0.5, 1);
    c.start_alpha = 45f64.to_radians();
    let (s, _) = run(c, Driver::OpenLoop(duty));
    assert!(s.height.1 < s.height.0 - 1e-4, "{:?}", s.height);
    assert!(s.late_screw_speed < -1.0, "{}", s.late_screw_speed);
}

/// A duty driver that also logs what the board saw: the log and the driver.
fn logging_duty() -> (Arc<Mutex<Vec<Inputs>>>, Driver) {
    let log = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&log);
    let duty = OpenLoopDuty {
        duty: 0.6,
        ramp: 0.05,
    };
    let driver = Driver::Custom(Box::new(move |t, inputs: &Inputs| -> Bridge {
        sink.lock().expect("log").push(*inputs);
        duty.command(t, inputs)
    }));
    (log, driver)
}

/// Runs a duty driver that also logs what the board saw.
fn logged(seed: u64) -> (Vec<Inputs>, Trace) {
    let (log, driver) = logging_duty();
    let (_, trace) = run(cfg(1000.0, 0.15, seed), driver);
    let inputs = log.lock().expect("log").clone();
    (inputs, trace)
}

#[test]
fn runs_are_deterministic_for_a_seed() {
    let (a, ta) = logged(7);
    let (b, tb) = logged(7);
    assert_eq!(a, b);
    assert_eq!(ta.records, tb.records);
    let (c, _) = logged(8);
    assert_ne!(
        a.iter().map(|i| i.current_raw).collect::<Vec<_>>(),
        c.iter().map(|i| i.current_raw).collect::<Vec<_>>()
    );
}

#[test]
fn the_board_sees_the_motor_through_encoder_and_current_sense() {
    let (inputs, trace) = logged(3);
    // The 16-bit counter moved forward (lifting) by the motor's turns × 48.
    let last = trace.records.last().expect("records");
    let counts = (
        last.motor_speed.signum() > 0.0,
        inputs.last().expect("ticks").encoder_count,
    );
    assert!(counts.0 && counts.1 > 100, "{counts:?}");
    // Mid-run, the current code decodes to the true current within noise + quantisation.
    let k = inputs.len() - 1;
    let rec = trace
        .records
        .iter()
        .min_by(|a, b| (a.t - 0.149).abs().total_cmp(&(b.t - 0.149).abs()))
        .expect("record");
    let seen = current_of_code(inputs[k].current_raw);
    assert!(
        (seen - rec.current).abs() < 1.0,
        "{seen} vs {}",
        rec.current
    );
}

/// What the board sees, tick by tick, from a duty driver stepped by `run` (`pieces` = 0) or
/// live by `step_n`, `pieces` base steps a call (host-sim serve, lift and estimate).
fn seen(pieces: u64) -> Vec<Inputs> {
    let (log, driver) = logging_duty();
    let mut c = cfg(1000.0, 0.15, 5);
    c.record_rate = 0.0;
    let steps = (c.duration / c.dt).round() as u64;
    let mut sim = Sim::new(c, driver).expect("valid config");
    if pieces == 0 {
        sim.run();
    } else {
        let mut done = 0;
        while done < steps {
            let n = pieces.min(steps - done);
            sim.step_n(n);
            done += n;
        }
    }
    let seen = log.lock().expect("log").clone();
    seen
}

/// Live stepping is `run` cut in pieces: the board sees the same encoder edges (their times
/// feed its speed loop), currents and supply on every tick. `step_n` once skipped the
/// sensors' observation after each step: the edge times went stale, the board's speed loop
/// saw whole counts and rang (±0.5 A at 3 rad/s), and the stick-slip detector flagged every
/// smooth run of `host-sim estimate`.
#[test]
fn live_stepping_shows_the_board_what_a_whole_run_shows() {
    let whole = seen(0);
    assert!(whole.len() >= 149, "{} ticks", whole.len());
    for pieces in [1, 250, 997] {
        assert_eq!(seen(pieces), whole, "step_n({pieces}) a call");
    }
}
