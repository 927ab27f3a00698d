//! Paper mode (θ_i prescribed by Fig. 2): stick-slip, energy, the power-screw limit and the
//! paper's qualitative results.

// A failed expectation is a failed test: panicking is the point here.
#![allow(clippy::expect_used)]

mod common;
use common::*;
use host_sim::physics::Lubricant;
use host_sim::plant::{Dir, Flank, Phase};

#[test]
fn dry_lifting_from_15_deg_shows_stick_slip() {
    let (s, trace) = paper(paper_cfg(Lubricant::Dry, 0.3, 15.0, 0.12, 4e-6), 15.0);
    let cruise = s.cruise.expect("cruise window");
    assert!(s.sticks >= 2, "{} sticks", s.sticks);
    // The coupling winds up to the breakaway torque (≈ 77 N·m, 0.48 rad) and unwinds in a slip.
    assert!(
        cruise.twist_peak_to_peak > 0.3,
        "{}",
        cruise.twist_peak_to_peak
    );
    let has = |p: Phase| trace.records.iter().any(|r| r.phase == p);
    assert!(has(Phase::Stick) && has(Phase::Slip(Dir::Up)));
    // Stuck means stuck: the screw does not creep.
    for r in trace.records.iter().filter(|r| r.phase == Phase::Stick) {
        assert_eq!(r.theta_dot, 0.0);
    }
    // The screw advances on average at the input's speed.
    let net = trace
        .records
        .last()
        .map(|r| r.theta_i - r.theta)
        .unwrap_or(f64::NAN);
    assert!(net.abs() < 0.6, "twist stays bounded: {net}");
}

#[test]
fn energy_balances_within_one_percent() {
    for (deg, cruise, mu_pin) in [(15.0, 15.0, 0.3), (65.0, -15.0, 0.3), (15.0, 15.0, 0.0)] {
        let (s, _) = paper(paper_cfg(Lubricant::Dry, mu_pin, deg, 0.15, 4e-6), cruise);
        let e = s.energy;
        assert!(
            e.input.abs() > 1.0,
            "{deg}°: some work was done ({} J)",
            e.input
        );
        assert!(e.balance_error() < 0.01, "{deg}° {cruise}: {e:?}");
    }
}

#[test]
fn constant_speed_torque_matches_power_screw_formula() {
    // In steady sliding the coupling carries T₀ + c·θ̇ + r_m·W·tan(λ + φ) lifting and
    // −T₀ + c·θ̇ − r_m·W·tan(φ − λ) lowering, W = R ± F₀ + c_x·ẋ, tan φ = μ (DESIGN.md, checks).
    let cases = [
        (Lubricant::Dry, 15.0, 15.0, 0.3, 1e6),
        (Lubricant::Ptfe, 45.0, -15.0, 0.3, 0.0),
        (Lubricant::Ptfe, 45.0, -15.0, 0.0, 0.0),
    ];
    for (lube, deg, cruise, mu_pin, c_x) in cases {
        let (_, trace) = steady_cx(lube, mu_pin, deg, 0.3, cruise, c_x);
        let s = host_sim::physics::Screw::paper();
        for r in between(&trace, 0.2, 0.3) {
            let d = r.theta_dot.signum();
            let xd = s.lead_per_rad() * r.theta_dot;
            let w = r.r + r.f0 * d + r.c_x * xd;
            let phi = r.mu.atan();
            let thread = if d > 0.0 {
                s.r_m * w * (s.lambda + phi).tan()
            } else {
                -s.r_m * w * (phi - s.lambda).tan()
            };
            let expect = s.support_torque * d + s.damping * r.theta_dot + thread;
            assert!(r.phase == Phase::Slip(if d > 0.0 { Dir::Up } else { Dir::Down }));
            assert!(
                (r.coupling_torque - expect).abs() < 0.005 * expect.abs(),
                "{deg}° t={}: {} vs {expect}",
                r.t,
                r.coupling_torque
            );
        }
    }
}

#[test]
fn lubricated_torque_lower_than_dry() {
    // Compared in steady sliding (c_x = 10⁶), where T_r is the kinetic friction torque.
    let t = |l| {
        let (s, _) = steady(l, 0.3, 15.0, 0.3, 15.0);
        s.cruise.expect("cruise").mean_friction_torque
    };
    let (dry, ptfe, lith) = (t(Lubricant::Dry), t(Lubricant::Ptfe), t(Lubricant::Lithium));
    assert!(
        ptfe < 0.5 * dry,
        "PTFE less than half of dry: {ptfe} vs {dry}"
    );
    assert!(
        lith < 0.95 * dry && lith > 0.7 * dry,
        "lithium ~ 20 % below dry: {lith} vs {dry}"
    );
}

#[test]
fn friction_torque_falls_while_lifting_and_rises_while_lowering() {
    let (_, up) = steady(Lubricant::Dry, 0.3, 15.0, 0.6, 15.0);
    let early = mean(&up, 0.1, 0.15, |r| r.friction_torque);
    let late = mean(&up, 0.55, 0.6, |r| r.friction_torque);
    assert!(late < early, "lifting: {early} → {late}");
    let (_, down) = steady_cx(Lubricant::Ptfe, 0.3, 45.0, 0.6, -15.0, 0.0);
    let early = mean(&down, 0.1, 0.15, |r| r.friction_torque.abs());
    let late = mean(&down, 0.55, 0.6, |r| r.friction_torque.abs());
    assert!(late > early, "lowering: {early} → {late}");
}

#[test]
fn lowering_near_65_deg_with_pin_friction_loads_the_other_flank() {
    let (s, trace) = paper(paper_cfg(Lubricant::Dry, 0.3, 65.0, 0.1, 4e-6), -15.0);
    let sliding: Vec<_> = between(&trace, 0.07, 0.1)
        .filter(|r| r.phase == Phase::Slip(Dir::Down))
        .collect();
    assert!(!sliding.is_empty());
    for r in sliding {
        assert_eq!(r.flank, Flank::Reversed, "t = {}", r.t);
        assert!(r.normal < 0.0 && r.f0 > r.r);
    }
    assert!(s.energy.balance_error() < 0.01);
}
