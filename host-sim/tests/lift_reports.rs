//! `host-sim lift` says what happened when the lift does not arrive: a target outside the
//! stops is refused (not reported as a halt error), a fault prints the height, the board's
//! snapshot and the plot, and the time cap fits a full stroke.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use host_sim::apps::lift::{main as lift, time_cap, LiftArgs};
use host_sim::physics::{Geometry, Lubricant};

fn args(from_mm: f64, to_mm: f64, faults: &str) -> LiftArgs {
    LiftArgs {
        lubricant: Lubricant::Ptfe,
        load_kg: 1000.0,
        from_mm,
        to_mm,
        seed: 3,
        plot: None,
        faults: host_sim::inject::parse_list(faults).unwrap(),
    }
}

#[test]
fn a_target_outside_the_stops_is_reported_refused() {
    // 412 mm lies inside the mechanism (≤ 416.4 mm) but above the factory upper stop.
    let e = lift(&args(300.0, 412.0, "")).unwrap_err();
    assert!(
        e.starts_with("goto 412.0 mm refused: refused: target outside the limit stops"),
        "{e}"
    );
}

#[test]
fn a_fault_reports_the_height_and_the_boards_snapshot() {
    // The screw jams 0.5 s into a lift from 150 mm.
    let e = lift(&args(150.0, 160.0, "jam@0.5:2000")).unwrap_err();
    assert!(e.starts_with("stopped by a fault at "), "{e}");
    assert!(
        e.contains(" head at 15") && e.contains(" mm from the target"),
        "{e}"
    );
    assert!(e.contains("the board's snapshot: fault="), "{e}");
    assert!(e.contains(" height=15"), "{e}");
}

#[test]
fn the_time_cap_fits_a_full_stroke() {
    let g = Geometry::paper();
    let deg = |mm: f64| ((mm * 1e-3 - g.h0) / g.length).asin().to_degrees();
    // The factory stops at the factory cruise (3 rad/s): the old fixed cap was 120 s.
    let full = time_cap(deg(145.0), deg(410.0), 3.0);
    assert!(full > 240.0, "{full:.0} s");
    // Halfway up takes much less than the whole stroke.
    assert!(time_cap(deg(145.0), deg(200.0), 3.0) < full / 2.0);
}
