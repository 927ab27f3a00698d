//! The step-size criterion of docs/plant.md on a short horizon: halving the default step
//! changes the mean friction torque over the last millisecond by less than 1 %.

// A failed expectation is a failed test: panicking is the point here.
#![allow(clippy::expect_used)]

use host_sim::physics::FrictionLaw;
use host_sim::sim::DEFAULT_DT;
use host_sim::studies::convergence::convergence_to;

#[test]
fn halving_the_default_step_changes_mean_friction_torque_by_less_than_one_percent() {
    for (law, mu_pin, deg, cruise) in [
        (FrictionLaw::dry(), 0.3, 15.0, 15.0),
        (FrictionLaw::dry(), 0.3, 65.0, -15.0),
    ] {
        let study = convergence_to(law, mu_pin, deg, cruise, 0.1, DEFAULT_DT, 2);
        let change = study.levels[1].change.expect("two levels");
        assert!(change < 0.01, "{deg}°: {study}");
    }
}
