//! The fixed-point ball-screw friction (`liftfw::model::ballscrew`, seed 002) against its
//! float64 twin (`host_sim::physics::ballscrew`) over the envelope: screw rate −400…400 rad/s,
//! axial load 0…80 kN (twice the lift's 36.6 kN at 15°), f 0…0.1, torque −200…200 N·m.
//! Budgets: τ 10⁻⁶ relative or 10⁻⁸; f 10⁻⁷; friction torque 0.01 % or 0.5 mN·m; Eq 2 1 % of
//! 10⁻⁵ … (see each test); the lift/lowering pair solve (`control::lube::solve_pair`) against a
//! float64 bisection. Arbitrary bit patterns must not panic.
// The ball-screw variant only (cargo feature `ball-screw`; `cargo test --workspace` has it).
#![cfg(feature = "ball-screw")]
#![allow(clippy::unwrap_used, clippy::expect_used)]

use host_sim::physics::ballscrew::BallScrewFriction;
use liftfw::model::ballscrew::{BallScrew, BallScrewConfig, FrictionIdentifier};
use liftfw::units::{NewtonMetres, Newtons, RadiansPerSecond, Ratio};
use proptest::prelude::*;

fn core() -> BallScrew {
    BallScrewConfig::SEED_001_4008.compile().unwrap()
}

/// The twin with the core's quantised configuration (r_m, r_b, lead in Q24), so that the
/// comparison measures the arithmetic, not the 10⁻⁶ rounding of the inputs.
fn twin() -> BallScrewFriction {
    let c = BallScrewConfig::SEED_001_4008;
    BallScrewFriction {
        r_m: c.r_m.to_f64(),
        r_b: c.r_b.to_f64(),
        lead: c.lead.to_f64(),
        ..BallScrewFriction::seed_001_4008()
    }
}

#[test]
fn preset_law_is_seed_002_eq_3() {
    // f = 0.0026 + 0.9117·τ + 0.0028·e^(−0.08863·10⁵·τ).
    let l = liftfw::model::friction::FrictionLaw::BALL_SCREW;
    assert_eq!(l.base, Ratio::lit("0.0026"));
    assert_eq!(l.amp, Ratio::lit("0.0028"));
    assert!((l.slope.to_num::<f64>() - 0.9117).abs() < 1e-9);
    assert_eq!(l.rate.to_num::<f64>(), 0.08863e5);
    let b = core();
    for tau in [0.0f64, 1e-5, 1e-4, 3.7e-4, 1e-3, 1e-2, 0.1] {
        let want = 0.0026 + 0.9117 * tau + 0.0028 * (-8863.0 * tau).exp();
        let got = b.coefficient(Ratio::from_f64(tau)).to_f64();
        assert!((got - want).abs() < 1e-7, "τ {tau}: {got} vs {want}");
    }
}

/// The law's refusals name the `ballscrew.f_*` keys (the estimator's own law names
/// `friction.*`), each with the law's range.
#[test]
fn law_refusals_name_the_ball_screw_keys() {
    use fixed::types::I32F32;
    use liftfw::ConfigError;
    type Law = liftfw::model::friction::FrictionLaw;
    /// A change that puts one term of the law out of its range, its key suffix and range.
    type Case = (fn(&mut Law), &'static str, &'static str);
    let bad = |f: fn(&mut Law)| {
        let mut c = BallScrewConfig::SEED_001_4008;
        f(&mut c.law);
        let e = c.compile().unwrap_err();
        let mut l = c.law;
        l.variable = liftfw::model::friction::LawVariable::ScrewRate;
        f(&mut l);
        (
            e,
            l.compile(liftfw::units::Metres::lit("0.004"), Ratio::ONE)
                .unwrap_err(),
        )
    };
    let cases: [Case; 5] = [
        (|l| l.base = Ratio::lit("1.5"), "f_base", "0..1"),
        (|l| l.amp = Ratio::lit("-1.5"), "f_amp", "-1..1"),
        (|l| l.rate = I32F32::lit("-1"), "f_rate", "0..1e6"),
        (|l| l.slope = I32F32::lit("2000"), "f_slope", "-1000..1000"),
        (|l| l.s_max = I32F32::ZERO, "f_s_max", ">0..1e6"),
    ];
    for (f, key, range) in cases {
        let (ball, own) = bad(f);
        let want = |field: &'static str| ConfigError::OutOfRange { field, range };
        assert_eq!(ball, want(format!("ballscrew.{key}").leak()), "{key}");
        let own_key = format!("friction.{}", &key[2..]);
        assert_eq!(own, want(own_key.leak()), "{key}");
    }
}

#[test]
fn turning_point_matches_the_closed_form() {
    // d f/dτ = 0.9117 − 0.0028·8863·e^(−8863τ) = 0 ⇒ τ* = ln(0.0028·8863/0.9117)/8863.
    let tau_star = (0.0028f64 * 8863.0 / 0.9117).ln() / 8863.0;
    let f_star = 0.0026 + 0.9117 * tau_star + 0.0028 * (-8863.0 * tau_star).exp();
    let (t, f) = core().turning_point();
    assert!(
        (f.to_f64() - f_star).abs() < 2e-8,
        "{} vs {f_star}",
        f.to_f64()
    );
    // The minimum is flat: f moves by < 1 LSB (3.7e-9) over ±1.5e-6 of τ around it, so τ* is
    // located to that width.
    assert!(
        (t.to_f64() - tau_star).abs() < 2e-6,
        "{} vs {tau_star}",
        t.to_f64()
    );
    assert!((twin().law.turning_point() - tau_star).abs() < 1e-15);
    // Mixed regime below (falling), hydrodynamic above (rising).
    let b = core();
    let at = |x: f64| b.coefficient(Ratio::from_f64(x)).to_f64();
    assert!(at(tau_star * 0.5) > f_star && at(tau_star * 2.0) > f_star);
    assert!(at(1e-5) > at(1e-4) && at(1e-2) > at(1e-3));
}

#[test]
fn eq_2_is_the_inverse_of_eq_1_in_the_twin_and_the_core() {
    let (b, t) = (core(), twin());
    for (f, fa) in [(0.003, 500.0), (0.0054, 20_000.0), (0.05, 80_000.0)] {
        let torque = t.friction_torque(f, fa);
        let tf = t.coefficient_from_torque(torque, fa);
        assert!((tf - f).abs() < 1e-15);
        let cf = b
            .coefficient_from_torque(NewtonMetres::from_f64(torque), Newtons::from_f64(fa))
            .unwrap()
            .to_f64();
        assert!((cf - f).abs() < 1e-5 * f + 5e-8, "{cf} vs {f}");
    }
}

#[test]
fn ball_screw_is_not_self_locking_at_any_lift_load() {
    let b = core();
    for kn in [1, 5, 10, 20, 36, 60] {
        let fa = Newtons::from_int(kn * 1000);
        for w in [0.05, 1.0, 5.0] {
            let f = b.coefficient(b.tau(RadiansPerSecond::from_f64(w), fa));
            assert!(b.friction_torque(f, fa) < b.load_torque(fa));
        }
    }
}

#[test]
fn identifier_converges_to_the_plant_coefficient() {
    let (b, t) = (core(), twin());
    let mut id = FrictionIdentifier::new(Ratio::lit("0.01"), 5, Newtons::lit("500"));
    // A plant whose lubrication made f 40 % higher than the law: lifting and lowering samples.
    let load = 15_000.0;
    let f_true = 1.4 * t.coefficient(t.tau(1.0, load));
    for i in 0..200 {
        let lifting = i % 2 == 0;
        let mf = t.friction_torque(f_true, load);
        let tl = t.load_torque(load);
        let torque = if lifting { tl + mf } else { tl - mf };
        assert!(id.update(
            &b,
            NewtonMetres::from_f64(torque),
            Newtons::from_f64(load),
            lifting
        ));
    }
    let e = id.estimate().to_f64();
    // The torque is quantised to 1.5e-5 N·m: f to ≈ 2.5e-7 at 15 kN.
    assert!(
        (e - f_true).abs() < 2e-5 * f_true.max(0.01),
        "{e} vs {f_true}"
    );
    // Below the minimum force nothing is used.
    assert!(!id.update(&b, NewtonMetres::lit("1"), Newtons::lit("10"), true));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn tau_matches_the_twin(w in -400.0f64..400.0, fa in 1.0f64..80_000.0) {
        let (b, t) = (core(), twin());
        let wq = RadiansPerSecond::from_f64(w);
        let fq = Newtons::from_f64(fa);
        let want = t.tau(wq.to_f64(), fq.to_f64()).min(8.0 - 4e-9);
        let got = b.tau(wq, fq).to_f64();
        prop_assert!((got - want).abs() <= 1e-6 * want + 1e-8, "{got} vs {want}");
    }

    #[test]
    fn coefficient_matches_the_twin(tau in 0.0f64..0.05) {
        let (b, t) = (core(), twin());
        let tq = Ratio::from_f64(tau);
        let got = b.coefficient(tq).to_f64();
        let want = t.coefficient(tq.to_f64());
        prop_assert!((got - want).abs() <= 1e-7, "{got} vs {want}");
    }

    #[test]
    fn friction_torque_matches_the_twin(f in 0.0f64..0.1, load in -80_000.0f64..80_000.0, w in -400.0f64..400.0) {
        let (b, t) = (core(), twin());
        let fa = b.axial_force(Newtons::from_f64(load));
        let fq = Ratio::from_f64(f);
        let got = b.friction_torque(fq, fa).to_f64();
        let want = t.friction_torque(fq.to_f64(), fa.to_f64());
        prop_assert!((got - want).abs() <= (1e-4 * want).max(5e-4), "{got} vs {want}");
        // And the whole chain from the speed: law at the core's own τ. τ saturates at its
        // Q-format's top (8, as in `tau_matches_the_twin`): a near-zero axial force makes the
        // twin's τ unbounded, so the twin is evaluated at the saturated τ too.
        let wq = RadiansPerSecond::from_f64(w);
        let fc = b.coefficient(b.tau(wq, fa));
        let ft = t.coefficient(t.tau(wq.to_f64(), fa.to_f64()).min(8.0 - 4e-9));
        prop_assert!((fc.to_f64() - ft).abs() <= 1e-6 * ft + 2e-7, "{} vs {ft}", fc.to_f64());
    }

    #[test]
    fn load_torque_and_eq_2_match_the_twin(fa in 1.0f64..80_000.0, torque in -200.0f64..200.0) {
        let (b, t) = (core(), twin());
        let fq = Newtons::from_f64(fa);
        let tl = b.load_torque(fq).to_f64();
        let want = t.load_torque(fq.to_f64());
        prop_assert!((tl - want).abs() <= (1e-6 * want).max(3e-5), "{tl} vs {want}");
        let tq = NewtonMetres::from_f64(torque);
        let want = t.coefficient_from_torque(tq.to_f64(), fq.to_f64());
        let got = b.coefficient_from_torque(tq, fq).unwrap().to_f64();
        let want_sat = want.clamp(-8.0, 8.0 - 4e-9);
        prop_assert!((got - want_sat).abs() <= 1e-5 * want_sat.abs() + 8e-9, "{got} vs {want}");
    }

    #[test]
    fn steady_torque_identifies_the_law_both_ways(w in 0.05f64..20.0, load in 500.0f64..80_000.0, up in any::<bool>()) {
        // The motor's steady torque from the twin, fed back through Eq 2: the law's own f.
        let (b, t) = (core(), twin());
        let wq = if up { w } else { -w };
        let torque = t.steady_screw_torque(wq, load);
        let f = b.identify(NewtonMetres::from_f64(torque), Newtons::from_f64(load), up).unwrap().to_f64();
        let want = t.coefficient(t.tau(wq, load));
        // Torque rounding (input ½ LSB, load torque 1 LSB, Eq 2's quotient: ≤ 4e-5 N·m) over
        // F·arm: ≤ 1.3e-6 of f at the lightest load, plus 10⁻⁵ relative.
        let tol = 4e-5 / (load * t.arm()) + 1e-5 * want;
        prop_assert!((f - want).abs() <= tol, "{f} vs {want} (tol {tol:e})");
    }

    #[test]
    fn arbitrary_bits_never_panic(w in any::<i32>(), fa in any::<i32>(), f in any::<i32>(), tq in any::<i32>(), up in any::<bool>()) {
        let b = core();
        let (w, fa, f, tq) = (
            RadiansPerSecond::from_bits(w),
            Newtons::from_bits(fa),
            Ratio::from_bits(f),
            NewtonMetres::from_bits(tq),
        );
        let tau = b.tau(w, fa);
        prop_assert!(tau >= Ratio::ZERO);
        let _ = b.coefficient(tau);
        let _ = b.friction_torque(f, b.axial_force(fa));
        let _ = b.coefficient_from_torque(tq, fa);
        let _ = b.load_torque(b.axial_force(fa));
        let _ = b.identify(tq, fa, up);
        let mut id = FrictionIdentifier::new(f, 4, Newtons::lit("1"));
        let _ = id.update(&b, tq, fa, up);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 500, ..ProptestConfig::default() })]

    /// The ball screw seen as a thread (the estimator's law in ball-screw mode) against the
    /// twin's (the plant's): both are μ_eq = (arm/r_m)·f(τ(θ̇)) at the reference force.
    #[test]
    fn equivalent_thread_law_matches_the_twin(fa in 1000.0f64..80_000.0, w in -400.0f64..400.0) {
        let t = twin();
        let fq = Newtons::from_f64(fa);
        let law = BallScrewConfig::SEED_001_4008.equivalent_thread_law(fq).unwrap().compile(BallScrewConfig::SEED_001_4008.r_m, Ratio::ONE).unwrap();
        let tl = t.equivalent_law(fq.to_f64());
        let wq = RadiansPerSecond::from_f64(w);
        let got = law.mu(wq).to_f64();
        let want = tl.mu_of(wq.to_f64());
        prop_assert!((got - want).abs() <= 2e-6 * want + 2e-7, "{got} vs {want}");
        // Not self-locking at rest.
        prop_assert!(law.mu(RadiansPerSecond::ZERO).to_f64() < t.helix().tan());
    }
}

#[test]
fn ball_screw_preset_is_a_valid_controller_configuration() {
    let c = liftfw::control::config::ControlConfig::ball_screw_4008().unwrap();
    assert_eq!(c.screw, liftfw::control::config::ScrewKind::Ball);
    assert!(liftfw::control::Controller::new(&c, 1000).is_ok());
}

#[test]
fn configuration_is_validated_once() {
    let ok = BallScrewConfig::SEED_001_4008;
    assert!(ok.compile().is_ok());
    let bad = [
        BallScrewConfig { r_b: ok.r_m, ..ok },
        BallScrewConfig {
            loaded_balls: 0,
            ..ok
        },
        BallScrewConfig {
            contact_angle_deg: fixed::types::I16F16::lit("10"),
            ..ok
        },
        BallScrewConfig {
            law: liftfw::model::friction::FrictionLaw::DRY,
            ..ok
        },
        BallScrewConfig {
            viscosity: fixed::types::I32F32::ZERO,
            ..ok
        },
    ];
    for c in bad {
        assert!(c.compile().is_err(), "{c:?}");
    }
}

/// Float64 twin of `control::lube::solve_pair`: the x where Eq 2 gives a lift and a lowering
/// the same f, by bisection to 10⁻¹⁵, and that f.
fn twin_pair(t: &BallScrewFriction, up: (f64, f64), down: (f64, f64)) -> (f64, f64) {
    let lever = t.lead / (2.0 * std::f64::consts::PI);
    let f_up = |x: f64| (up.0 - x * up.1 * lever) / (t.arm() * (t.preload + x * up.1));
    let f_down = |x: f64| (x * down.1 * lever - down.0) / (t.arm() * (t.preload + x * down.1));
    let (mut lo, mut hi) = (0.02, 4.0);
    while hi - lo > 1e-15 {
        let mid = 0.5 * (lo + hi);
        if f_up(mid) >= f_down(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (lo, 0.5 * (f_up(lo) + f_down(lo)))
}

proptest! {
    #[test]
    fn lift_and_lowering_pair_matches_the_twin(
        f in 0.001f64..0.05,
        x in 0.05f64..3.0,
        w_up in 2_000.0f64..40_000.0,
        down_share in 0.13f64..1.0,
        preload in 0.0f64..5_000.0,
    ) {
        // Means a lift and a lowering of load fraction x at friction f would give (Eq 1), fed
        // through the core's quantisation; the twin solves the same quantised means.
        let mut c = BallScrewConfig::SEED_001_4008;
        c.preload = Newtons::from_f64(preload);
        let b = c.compile().unwrap();
        let t = BallScrewFriction { preload: c.preload.to_f64(), ..twin() };
        let lever = t.lead / (2.0 * std::f64::consts::PI);
        let w_down = w_up * down_share;
        let (ru, rd) = (x * w_up, x * w_down);
        let tu = ru * lever + f * t.arm() * (t.preload + ru);
        let td = rd * lever - f * t.arm() * (t.preload + rd);
        let q = |tq: f64, w: f64| (NewtonMetres::from_f64(tq), Newtons::from_f64(w));
        let (up, down) = (q(tu, w_up), q(td, w_down));
        let (xt, ft) = twin_pair(
            &t,
            (up.0.to_f64(), up.1.to_f64()),
            (down.0.to_f64(), down.1.to_f64()),
        );
        let got = liftfw::control::lube::solve_pair(&b, up, down);
        if td <= 0.0 {
            // The lowering needs torque to drive down: no load-driven pair (either answer is
            // allowed, but it must not panic).
            return Ok(());
        }
        let (xc, fu, fd) = got.expect("a consistent pair is solved");
        // The core rounds x·W to 1/256 N and torques to 1/65536 N·m: x to a few force LSB over
        // the lowering's demand (its torque is the one the friction hardly changes); f to those
        // roundings (load torque lever·4/256 N, 2 torque LSB) over the lowering's F·arm, plus
        // 10⁻⁵ relative.
        let x_tol = 1e-5 * xt + 4.0 / (256.0 * w_down);
        prop_assert!((xc.to_f64() - xt).abs() <= x_tol, "x {} vs {xt}", xc.to_f64());
        let tol = (3e-5 + lever * 4.0 / 256.0) / ((t.preload + rd) * t.arm()) + 1e-5 * ft;
        for g in [fu, fd] {
            prop_assert!((g.to_f64() - ft).abs() <= tol, "f {} vs {ft} (tol {tol:e})", g.to_f64());
        }
        prop_assert!((ft - f).abs() <= 1e-3 * f + 1e-5, "twin {ft} vs true {f}");
    }
}
