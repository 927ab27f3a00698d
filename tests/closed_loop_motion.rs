//! Motion in closed loop: the core's supervisor, ramp, speed loop and halt planner driving
//! host-sim's plant. Every test runs the same `Controller::step` the board runs.
#![allow(clippy::expect_used, clippy::unwrap_used)]

mod support;
use host_sim::physics::Lubricant;
use liftfw::control::{Command, State};
use liftfw::units::Metres;
use support::{command_at, run, Scenario};

#[test]
fn explore_goto() {
    for &(lub, load, start, dh) in &[
        (Lubricant::Dry, 1000.0, 15.0, 0.015),
        (Lubricant::Ptfe, 1000.0, 15.0, 0.015),
        (Lubricant::Lithium, 0.0, 15.0, 0.015),
        (Lubricant::Dry, 1000.0, 45.0, -0.004),
        (Lubricant::Ptfe, 500.0, 65.0, -0.002),
    ] {
        let s = Scenario::new(lub, load, start, 6.0);
        let h0 = host_sim::physics::Geometry::paper().height(f64::to_radians(start));
        let target = h0 + dh;
        let r = run(
            &s,
            command_at(0.05, Command::GoTo(Metres::from_f64(target))),
        );
        let fin = r.final_height();
        let ext = r.extreme_height(dh > 0.0);
        println!(
            "{lub:?} {load} {start} target {:.2} mm final {:.3} mm err {:+.3} mm extreme {:+.3} state {:?} events {:?} peak {:.1} A",
            target * 1e3,
            fin * 1e3,
            (fin - target) * 1e3,
            (ext - target) * 1e3,
            r.controller.state(),
            r.events.iter().map(|(t, e)| format!("{t:.3}:{e:?}")).collect::<Vec<_>>(),
            r.summary.peak_current
        );
        assert_ne!(r.controller.state(), State::Fault);
    }
}

