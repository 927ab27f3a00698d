//! `host-sim lift`, the README's main job: the board's core halts a loaded lift at the set
//! height and its friction-torque estimate follows the plant.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use host_sim::apps::lift::{main as lift, LiftArgs};
use host_sim::physics::Lubricant;

#[test]
fn the_main_job_lifts_to_the_set_height_and_estimates_the_friction_torque() {
    for (lubricant, from_mm, to_mm) in [
        (Lubricant::Ptfe, 150.0, 156.0),
        (Lubricant::Lithium, 200.0, 195.0),
    ] {
        let out = lift(&LiftArgs {
            lubricant,
            load_kg: 1000.0,
            from_mm,
            to_mm,
            seed: 3,
            plot: None,
            faults: Vec::new(),
        })
        .expect("runs without a fault");
        assert!(out.error_mm.abs() <= 0.5, "{lubricant:?}: {out:?}");
        assert!(out.overshoot_mm <= 0.5, "{lubricant:?}: {out:?}");
        let rel = (out.tr_core - out.tr_plant).abs() / out.tr_plant.abs();
        assert!(
            rel < 0.02,
            "{lubricant:?}: T_r estimate off by {:.1} %",
            rel * 100.0
        );
    }
}
