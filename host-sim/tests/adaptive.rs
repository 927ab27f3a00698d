//! The adaptive-step option (embedded RK23 error control, paper mode) against the fixed step
//! of the convergence study: the same results within the criterion of docs/plant.md, the
//! energy balance, far fewer evaluations, and stops on the record times.

// A failed expectation is a failed test: panicking is the point here.
#![allow(clippy::expect_used)]

mod common;
use common::*;
use host_sim::physics::Lubricant;
use host_sim::plant::{Dir, Phase};
use host_sim::sim::{ConfigError, Driver, Sim, Stepping, DEFAULT_DT, DEFAULT_TOL};

fn adaptive(tol: f64) -> Stepping {
    Stepping::Adaptive {
        tol,
        h_max: host_sim::sim::ADAPTIVE_H_MAX,
    }
}

#[test]
fn adaptive_steps_agree_with_the_fixed_step_within_the_criterion() {
    // Stick-slip lifting and lowering (dry) and steady sliding (lubricated), 0.1 s: the window
    // 0.099–0.1 s and the constant-speed mean against the fixed step dt/2 = 1 µs.
    for (lube, mu_pin, deg, cruise) in [
        (Lubricant::Dry, 0.3, 15.0, 15.0),
        (Lubricant::Dry, 0.3, 65.0, -15.0),
        (Lubricant::Ptfe, 0.3, 45.0, 15.0),
        (Lubricant::Lithium, 0.0, 15.0, 15.0),
    ] {
        let mut fixed = paper_cfg(lube, mu_pin, deg, 0.1, 0.5 * DEFAULT_DT);
        fixed.record_rate = 0.0;
        let mut cfg = fixed;
        cfg.dt = DEFAULT_DT;
        cfg.stepping = adaptive(DEFAULT_TOL);
        let (f, _) = paper(fixed, cruise);
        let (a, _) = paper(cfg, cruise);
        let rel = |x: f64, y: f64| (x - y).abs() / y.abs();
        let (fw, aw) = (f.window.expect("window"), a.window.expect("window"));
        let (fc, ac) = (f.cruise.expect("cruise"), a.cruise.expect("cruise"));
        let case = format!("{lube:?} {deg}° {cruise}");
        assert!(
            rel(aw.mean_friction_torque, fw.mean_friction_torque) < 0.01,
            "{case}: window {} vs {}",
            aw.mean_friction_torque,
            fw.mean_friction_torque
        );
        assert!(
            rel(ac.mean_friction_torque, fc.mean_friction_torque) < 0.01,
            "{case}: cruise {} vs {}",
            ac.mean_friction_torque,
            fc.mean_friction_torque
        );
        assert_eq!(a.sticks, f.sticks, "{case}: the same stick-slip history");
        assert!(a.energy.balance_error() < 0.01, "{case}: {:?}", a.energy);
        assert!(
            a.evaluations * 10 < f.evaluations,
            "{case}: {} vs {} evaluations",
            a.evaluations,
            f.evaluations
        );
    }
}

#[test]
fn tighter_tolerance_is_closer_to_the_converged_result() {
    let mut fixed = paper_cfg(Lubricant::Dry, 0.3, 15.0, 0.1, 0.5 * DEFAULT_DT);
    fixed.record_rate = 0.0;
    let reference = paper(fixed, 15.0).0.window.expect("window");
    let err = |tol: f64| {
        let mut cfg = fixed;
        cfg.stepping = adaptive(tol);
        let s = paper(cfg, 15.0).0;
        let w = s.window.expect("window");
        (
            (w.mean_friction_torque - reference.mean_friction_torque).abs(),
            s.evaluations,
        )
    };
    let (loose, n_loose) = err(1e-2);
    let (tight, n_tight) = err(1e-5);
    assert!(tight < loose, "{tight} vs {loose}");
    assert!(
        tight < 1e-3 * reference.mean_friction_torque.abs(),
        "{tight}"
    );
    assert!(n_tight > n_loose);
}

#[test]
fn adaptive_trace_lands_on_the_record_times_and_stuck_stays_stuck() {
    // The lift breaks away at ≈ 62 ms and sticks again ≈ 0.5 ms later.
    let mut cfg = paper_cfg(Lubricant::Dry, 0.3, 15.0, 0.08, DEFAULT_DT);
    cfg.record_rate = 1000.0;
    cfg.stepping = adaptive(DEFAULT_TOL);
    let (s, trace) = paper(cfg, 15.0);
    let times: Vec<f64> = trace.records.iter().map(|r| r.t).collect();
    assert_eq!(times.len(), 81, "{times:?}");
    for (k, t) in times.iter().enumerate() {
        assert!((t - k as f64 * 1e-3).abs() < 1e-12, "{k}: {t}");
    }
    assert!(s.sticks >= 1);
    let has = |p: Phase| trace.records.iter().any(|r| r.phase == p);
    assert!(has(Phase::Stick) && has(Phase::Slip(Dir::Up)));
    for r in trace.records.iter().filter(|r| r.phase == Phase::Stick) {
        assert_eq!(r.theta_dot, 0.0);
    }
}

#[test]
fn adaptive_steps_are_for_paper_mode_only() {
    let mut cfg = paper_cfg(Lubricant::Dry, 0.3, 15.0, 0.01, DEFAULT_DT);
    cfg.stepping = adaptive(DEFAULT_TOL);
    let duty = host_sim::sim::OpenLoopDuty {
        duty: 0.5,
        ramp: 0.1,
    };
    let err = Sim::new(cfg, Driver::OpenLoop(duty)).err();
    assert_eq!(err, Some(ConfigError::AdaptiveNeedsPaperMode));
    cfg.stepping = adaptive(0.0);
    let err = Sim::new(
        cfg,
        Driver::Paper(host_sim::plant::SpeedProfile::paper(15.0)),
    )
    .err();
    assert_eq!(err, Some(ConfigError::NonPositive));
}
