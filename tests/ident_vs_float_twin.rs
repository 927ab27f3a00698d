//! The load and friction identification (`liftfw::ident`) against its float64 twin, over the
//! operating envelope: arm angles α₀…75°, both directions, loads 0…2 t, every preset law's μ
//! range (0.05…0.4 at scale 1), friction scales 0.5…3, load-free demand ±200 N.
//!
//! The twin is the textbook form of docs/model.md "Load and friction identification":
//! ρ_d(μ) = r_m·(tan λ + d·μ)/(1 − d·μ·tan λ), M_d(s) = (T/ρ_d(s·μ) − D)/G_d, and the pair's s
//! where M_up(s) = M_down(s), found by float bisection.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use liftfw::ident::pair::{self, MotionMeans};
use liftfw::ident::{load_gain_q24, ratio_q12};
use liftfw::model::geometry::DriveConfig;
use liftfw::model::screw::{MechanicsConfig, ScrewModel};
use liftfw::units::{NewtonMetres, Newtons, Ratio};
use proptest::prelude::*;

const G: f64 = 9.80665;

fn screw() -> ScrewModel {
    ScrewModel::new(&DriveConfig::DEFAULT, &MechanicsConfig::DEFAULT).unwrap()
}

/// The twin's constants, from the paper's screw (host-sim's physics).
fn twin_screw() -> (f64, f64) {
    let s = host_sim::physics::Screw::paper();
    (s.r_m, s.lambda.tan())
}

fn rho(dir: f64, mu: f64) -> f64 {
    let (r, tan) = twin_screw();
    let mus = dir * mu;
    r * (tan + mus) / (1.0 - mus * tan)
}

fn g_per_kg(alpha_deg: f64, dir: f64, mu_pin: f64) -> f64 {
    let a = alpha_deg.to_radians();
    G * (a.cos() + 2.0 * mu_pin * dir) / a.sin()
}

/// The torque a motion of load `m` on a thread at scale `s` gives, as means at scale 1.
fn means(dir: i8, m: f64, s: f64, g: f64, d: f64, mu: f64) -> (MotionMeans, f64) {
    let t = rho(f64::from(dir), mu * s) * (m * g + d);
    (
        MotionMeans {
            dir,
            torque: NewtonMetres::from_f64(t),
            g_per_kg: (g * f64::from(1u32 << 23)).round() as i32,
            free: Newtons::from_f64(d),
            mu: Ratio::from_f64(mu),
            n: 1000,
            slipped: false,
        },
        t,
    )
}

/// The twin of `load_at_scale`.
fn twin_load(dir: i8, t: f64, g: f64, d: f64, mu: f64, s: f64) -> f64 {
    (t / rho(f64::from(dir), mu * s) - d) / g
}

/// The twin of `solve`: float bisection on s.
fn twin_solve(up: (f64, f64, f64, f64), dn: (f64, f64, f64, f64)) -> Option<(f64, f64)> {
    let h =
        |s: f64| twin_load(1, up.0, up.1, up.2, up.3, s) - twin_load(-1, dn.0, dn.1, dn.2, dn.3, s);
    let (_, tan) = twin_screw();
    let mut lo = (tan / dn.3 * 1025.0 / 1024.0).max(0.25);
    let mut hi = 4f64.min((1.0 / (3.0 * tan)).min(0.6) / up.3.max(dn.3));
    if h(lo) >= 0.0 {
        return None;
    }
    // The first crossing from below on a 32-step grid (as the core).
    let step = (hi - lo) / 32.0;
    let mut a = lo;
    let mut bracket = None;
    for k in 1..=32 {
        let b = if k == 32 {
            hi
        } else {
            lo + step * f64::from(k)
        };
        let v = h(b);
        match bracket {
            None if v > 0.0 => bracket = Some((a, b)),
            Some(_) if v < 0.0 => return None,
            _ => {}
        }
        a = b;
    }
    (lo, hi) = bracket?;
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if h(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let m = 0.5
        * (twin_load(1, up.0, up.1, up.2, up.3, lo) + twin_load(-1, dn.0, dn.1, dn.2, dn.3, lo));
    Some((lo, m))
}

/// A pair's solution within 0.2 % (scale) and 0.3 % + 0.5 kg (load) of the twin's `ts`, `tm`.
fn near_twin(sol: &pair::PairSolution, ts: f64, tm: f64) -> Result<(), TestCaseError> {
    prop_assert!(
        (sol.scale.to_f64() - ts).abs() <= 2e-3 * ts,
        "{:?} vs {}",
        sol,
        ts
    );
    prop_assert!(
        (sol.load.to_f64() - tm).abs() <= 3e-3 * tm + 0.5,
        "{:?} vs {}",
        sol,
        tm
    );
    Ok(())
}

/// A pair's solution within 1 % (+0.5 kg) of the truth `s`, `m` its means were made from.
fn near_truth(sol: &pair::PairSolution, s: f64, m: f64) -> Result<(), TestCaseError> {
    prop_assert!(
        (sol.scale.to_f64() - s).abs() <= 1e-2 * s,
        "{:?} vs truth {}",
        sol,
        s
    );
    prop_assert!(
        (sol.load.to_f64() - m).abs() <= 1e-2 * m + 0.5,
        "{:?} vs truth {}",
        sol,
        m
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    /// Σy/Σg within 2^-15 relative (+1 LSB) over sums of up to 2^20 samples of the envelope's
    /// torques and gains.
    #[test]
    fn the_load_ratio_follows_the_quotient(y in -(1i64 << 45)..(1i64 << 45), g0 in 1i64..(1i64 << 50), neg in any::<bool>()) {
        let g = if neg { -g0 } else { g0 };
        let want = (y as f64) * 2f64.powi(20) / (g as f64);
        match ratio_q12(y, g) {
            Some(got) => prop_assert!((f64::from(got) - want).abs() <= want.abs() * 3.1e-5 + 1.0,
                "{} vs {}", got, want),
            None => prop_assert!(want.abs() > 2f64.powi(30), "refused {}", want),
        }
    }

    /// `v·2^k/x` by the normalised reciprocal within 2^-15 relative (+1 LSB) of the float
    /// quotient, over the magnitudes the pair solve and the interval divide: numerators up to
    /// 2^44, divisors of 1…32 bits of either sign, scalings 16…32.
    #[test]
    fn the_scaled_division_follows_the_quotient(v in -(1i64 << 44)..(1i64 << 44), x0 in 1i64..(1i64 << 32), neg in any::<bool>(), k in 16i32..=32) {
        let x = if neg { -x0 } else { x0 };
        let want = (v as f64) * 2f64.powi(k) / (x as f64);
        match pair::div_scaled(v, x, k) {
            Some(got) => prop_assert!((got as f64 - want).abs() <= want.abs() * 3.1e-5 + 1.0,
                "{} vs {}", got, want),
            None => prop_assert!((v as f64).abs() * 2f64.powi(17) > 2f64.powi(63), "refused {}", want),
        }
    }

    /// The load gain r_m·ξ·G_d read from the model's thread torque and axial demand at a
    /// window's first sample (T/W·G_d): within 2^-13 relative (+2 LSB) of the twin's
    /// ρ_d(μ)·G_d, over the envelope's arm angles, both directions, loads and laws.
    #[test]
    fn the_load_gain_follows_the_twin(
        alpha in 15.0f64..75.0,
        up in any::<bool>(),
        m in 0.0f64..2000.0,
        mu in 0.05f64..0.6,
        d in -200.0f64..200.0,
    ) {
        let dir = if up { 1.0 } else { -1.0 };
        let g = g_per_kg(alpha, dir, 0.3);
        let w = m * g + d;
        prop_assume!(w.abs() >= 2.0);
        let t = rho(dir, mu) * w;
        let want = rho(dir, mu) * g;
        let got = f64::from(load_gain_q24(
            NewtonMetres::from_f64(t),
            Newtons::from_f64(w),
            (g * f64::from(1u32 << 23)).round() as i32,
        )) / f64::from(1u32 << 24);
        // T is quantised to 2^-16 N·m and W to 2^-8 N: their relative error grows as they
        // shrink.
        let tol = want.abs() * (1.3e-4 + 2f64.powi(-16) / t.abs().max(1e-9) + 2f64.powi(-8) / w.abs())
            + 2.0 * 2f64.powi(-24);
        prop_assert!((got - want).abs() <= tol, "{} vs {} (T {} W {})", got, want, t, w);
    }

    /// One motion's load at a friction scale: within 0.05 % or 0.1 kg of the twin.
    #[test]
    fn the_load_at_a_scale_follows_the_twin(
        alpha in 15.0f64..75.0,
        up in any::<bool>(),
        m in 0.0f64..2000.0,
        mu in 0.05f64..0.4,
        s_true in 0.5f64..3.0,
        s in 0.5f64..3.0,
        d in -200.0f64..200.0,
    ) {
        let dir: i8 = if up { 1 } else { -1 };
        let (_, tan) = twin_screw();
        // Lowering below self-locking, or a flank that reverses: not where the board samples.
        prop_assume!(up || (mu * s > tan * 1.05 && mu * s_true > tan * 1.05));
        let g = g_per_kg(alpha, f64::from(dir), 0.3);
        prop_assume!(g > 0.5 && m * g + d > 10.0);
        let (mm, t) = means(dir, m, s_true, g, d, mu);
        let want = twin_load(dir, mm.torque.to_f64(), f64::from(mm.g_per_kg) / f64::from(1u32 << 23), mm.free.to_f64(), mm.mu.to_f64(), s);
        let got = pair::load_at_scale(&screw(), &mm, Ratio::from_f64(s)).unwrap() as f64 / 4096.0;
        // The torque's own quantisation (15 µN·m) over ρ·G bounds the input's share.
        let q = 2f64.powi(-16) / (rho(f64::from(dir), mu * s).abs() * g);
        prop_assert!((got - want).abs() <= 5e-4 * want.abs() + 0.1 + q, "{} vs {} (t {})", got, want, t);
    }

    /// A lowering's load on the reversed flank (`pair::reversed_flank_load`): a head lighter
    /// than M* = −D/G_d carries on the other flank, whose ρ is lifting's, T = ρ_up·(M·G + D);
    /// the near branch's load is that M, within 0.5 % or 0.2 kg of the twin (M = (T/ρ_up − D)/G),
    /// 0 down to T = 1.5·ρ_up·D, and `None` beyond (only the loaded flank explains it) or where
    /// D ≥ 0.
    #[test]
    fn a_light_lowering_reads_the_near_branch_like_the_twin(
        alpha in 15.0f64..50.0,
        m_frac in 0.0f64..1.0,
        mu in 0.05f64..0.4,
        d in -200.0f64..-5.0,
        extra in 0.0f64..1.0,
    ) {
        // Lowering's G_d: 9.81·(cos α − 0.6)/sin α, positive below ≈ 53°.
        let g = g_per_kg(alpha, -1.0, 0.3);
        prop_assume!(g > 0.5);
        // A load on the reversed flank: 0 ≤ M ≤ M*.
        let m_star = -d / g;
        let m = m_frac * m_star;
        // `means` puts the torque on the loaded flank; on the reversed one ρ is lifting's.
        let (mut mm, _) = means(-1, m, 1.0, g, d, mu);
        mm.torque = NewtonMetres::from_f64(rho(1.0, mu) * (m * g + d));
        let (tq, gq, dq, muq) = (
            mm.torque.to_f64(),
            f64::from(mm.g_per_kg) / f64::from(1u32 << 23),
            mm.free.to_f64(),
            mm.mu.to_f64(),
        );
        let want = ((tq / rho(1.0, muq) - dq) / gq).max(0.0);
        let q = 2f64.powi(-16) / (rho(1.0, muq) * gq);
        match pair::reversed_flank_load(&screw(), &mm) {
            Some(got) => {
                let got = got as f64 / 4096.0;
                prop_assert!((got - want).abs() <= 5e-3 * want + 0.2 + q, "{} vs {}", got, want);
            }
            // Only at the range's quantised edges.
            None => prop_assert!(!(1e-3..=0.999).contains(&m_frac), "None for {} of {}", m, m_star),
        }
        // More downward torque than 1.5× an empty head's: the loaded flank's reading only.
        mm.torque = NewtonMetres::from_f64(rho(1.0, mu) * d * (1.52 + extra));
        prop_assert_eq!(pair::reversed_flank_load(&screw(), &mm), None);
        // Between 1× and 1.48× an empty head's: the near branch reads 0 (at 1× within the
        // torque's quantisation: a few 2^-12 kg).
        mm.torque = NewtonMetres::from_f64(rho(1.0, mu) * d * (1.0 + 0.48 * extra));
        let r = pair::reversed_flank_load(&screw(), &mm);
        prop_assert!(matches!(r, Some(v) if (0..=410).contains(&v)), "{:?}", r);
        // Lifting, or a positive load-free demand: not this reading.
        mm.dir = 1;
        prop_assert_eq!(pair::reversed_flank_load(&screw(), &mm), None);
        mm.dir = -1;
        mm.free = Newtons::from_f64(-d);
        prop_assert_eq!(pair::reversed_flank_load(&screw(), &mm), None);
    }

    /// A lift/lowering pair: the scale within 0.2 % and the load within 0.3 % or 0.5 kg of the
    /// twin's solution, and, where the load's push while lowering is at least 8× the load-free
    /// demand, both within 1 % (0.5 kg) of the truth the means were made from, and never
    /// refused at 12× (between 8× and 12× the twin itself may find the second crossing that
    /// makes a pair ambiguous: both refuse).
    #[test]
    fn a_pair_follows_the_twin(
        alpha in 16.0f64..40.0,
        m in 100.0f64..2000.0,
        mu in 0.08f64..0.3,
        s in 0.7f64..2.5,
        d in 5.0f64..60.0,
    ) {
        let (_, tan) = twin_screw();
        prop_assume!(mu * s > 1.1 * tan && mu * 0.7 > tan * 1.03 && mu * s < 0.55);
        let gu = g_per_kg(alpha, 1.0, 0.3);
        let gd = g_per_kg(alpha, -1.0, 0.3);
        prop_assume!(gd >= gu / 7.5);
        let (up, _) = means(1, m, s, gu, d, mu);
        let (dn, _) = means(-1, m, s, gd, -d, mu);
        let q = |x: &MotionMeans| (x.torque.to_f64(), f64::from(x.g_per_kg) / f64::from(1u32 << 23), x.free.to_f64(), x.mu.to_f64());
        let twin = twin_solve(q(&up), q(&dn));
        let got = pair::solve(&screw(), &up, &dn);
        match (twin, got) {
            (Some((ts, tm)), Some(sol)) => {
                near_twin(&sol, ts, tm)?;
                if m * gd >= 8.0 * d {
                    near_truth(&sol, s, m)?;
                }
            }
            (None, None) => {
                // Refused only where the pair is ambiguous: a light load whose load-free demand
                // rivals its weight's push while lowering.
                prop_assert!(m * gd < 12.0 * d, "refused a load-dominated pair");
            }
            (t, g) => prop_assert!(false, "twin {:?}, core {:?}", t, g),
        }
    }
}

/// The law scaled by `s` (base, amplitude, slope), as a friction scale scales it.
fn scaled(
    l: &liftfw::model::friction::FrictionLaw,
    s: f64,
) -> liftfw::model::friction::FrictionLaw {
    liftfw::model::friction::FrictionLaw {
        base: Ratio::from_f64(l.base.to_f64() * s),
        amp: Ratio::from_f64(l.amp.to_f64() * s),
        slope: fixed::types::I32F32::from_num(l.slope.to_num::<f64>() * s),
        ..*l
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 500, ..ProptestConfig::default() })]

    /// A friction scale put in force at rest (`CompiledLaw::rescaled` and
    /// `MuTable::rescale_nodes`, no compile and no law evaluations) against the float twin
    /// s'/s·μ(θ̇) of the law in force, and against the law compiled at the new scale and
    /// tabulated from scratch (what `Estimator::set_friction_scale` does at boot): within
    /// 2^-12 relative (+4 LSB of Q28), over the lead-screw presets, scales 0.5…3 in force and
    /// targets 0.5…3, speeds 0…2000 rad/s.
    #[test]
    fn a_rescaled_law_and_table_follow_the_twin(
        preset in 0usize..3,
        s0 in 0.5f64..3.0,
        s1 in 0.5f64..3.0,
        speeds in proptest::collection::vec(0.0f64..2000.0, 16),
    ) {
        use liftfw::model::friction::{FrictionLaw, MuTable};
        let law = [FrictionLaw::DRY, FrictionLaw::PTFE, FrictionLaw::LITHIUM][preset];
        let sc = screw();
        let compile = |l: &FrictionLaw| l.compile(sc.pitch_radius(), sc.cos_lambda());
        let (Ok(c0), Ok(c1)) = (compile(&scaled(&law, s0)), compile(&scaled(&law, s1))) else {
            return Ok(()); // A scale that takes the law out of its ranges is refused alike.
        };
        let ratio = Ratio::from_f64(s1 / s0);
        let fresh = MuTable::build(&c1);
        let Ok(r) = c0.rescaled(&scaled(&law, s1), ratio) else {
            return Ok(());
        };
        let mut table = MuTable::build(&c0);
        // In pieces, as the ticks at rest run it.
        for from in (0..200).step_by(24) {
            table.rescale_nodes(ratio.to_bits(), from, from + 24);
        }
        for v in speeds {
            let x = (v * 65536.0) as u32;
            let twin = f64::from(c0.mu_unfloored_call(x)) * (s1 / s0);
            let tol = |want: f64| want.abs() / 4096.0 + 4.0;
            let got = f64::from(r.mu_unfloored_call(x));
            prop_assert!((got - twin).abs() <= tol(twin), "law at {v}: {got} vs {twin}");
            // Each table is within its own bound of its law (`MuTable::build`: |μ|/8192, or
            // the law's own step |amp|·2^-16 + 2 LSB near μ = 0): the two within twice that.
            let want = f64::from(fresh.lookup(&c1, x));
            let step = (law.amp.to_f64() * s1).abs() * 2f64.powi(28 - 16) + 2.0;
            let bound = 2.0 * (want.abs() / 8192.0).max(step) + tol(want);
            let got = f64::from(table.lookup(&r, x));
            prop_assert!((got - want).abs() <= bound, "table at {v}: {got} vs {want}");
        }
    }
}

/// The twin of `ident::stick::lift` (docs/model.md "Stick-slip"): M = P/(ρ₁·G_up), refused
/// where the slips' fall is under half the span P − T₀, T₀ = P·(ρ₀/ρ₁)·(G_R/G_up).
fn twin_stick(p: f64, drop: f64, mu0: f64, g_up: f64, g_r: f64) -> Option<f64> {
    let (rho1, rho0) = (rho(1.0, mu0), rho(1.0, 0.0));
    let t0 = p * rho0 / rho1 * g_r / g_up;
    let span = p - t0;
    if span <= 0.0 || 2.0 * drop < span {
        return None;
    }
    Some(p / (rho1 * g_up))
}

/// One stick-slip case in fixed point: M kg of `ident::stick::lift`.
fn fixed_stick(p: f64, drop: f64, mu0: f64, g_up: f64, g_r: f64) -> Option<f64> {
    let sc = screw();
    let q16 = |x: f64| (x * 65536.0).round() as i64;
    let q23 = |x: f64| (x * f64::from(1u32 << 23)).round() as i64;
    let rho1 = pair::rho_q32(&sc, Ratio::from_f64(mu0), 1)?;
    let rho0 = pair::rho_q32(&sc, Ratio::ZERO, 1)?;
    liftfw::ident::stick::lift(q16(p), q16(drop), rho1, rho0, q23(g_up), q23(g_r))
        .map(|m| m.to_f64())
}

/// The mobilisation in [0, `hi`] where `below` turns false (bisection to f64 precision).
fn twin_bisect(hi: f64, below: impl Fn(f64) -> bool) -> f64 {
    let (mut lo, mut hi) = (0.0, hi);
    for _ in 0..60 {
        let mid = (lo + hi) / 2.0;
        if below(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (lo + hi) / 2.0
}

/// A stuck lift's thread torque per kilogram at mobilisation ρ: r_m·ξ_up(ρ·μ(0))·(G_R + ρ·G_F).
fn twin_tau_up(rho_: f64, mu0: f64, g_up: f64, g_dn: f64) -> f64 {
    let (g_r, g_f) = ((g_up + g_dn) / 2.0, (g_up - g_dn) / 2.0);
    rho(1.0, rho_ * mu0) * (g_r + rho_ * g_f)
}

/// The twin of `ident::stick::lift_friction`: ρ̄ where M·τ_up(ρ̄) = T̄ on [0, 1], then
/// T_r = M·r_m·ρ̄μ₀·(G_R + ρ̄G_F)/(1 − ρ̄μ₀·tan λ).
fn twin_lift_friction(m: f64, mean: f64, mu0: f64, g_up: f64, g_dn: f64) -> f64 {
    let r = twin_bisect(1.0, |mid| m * twin_tau_up(mid, mu0, g_up, g_dn) < mean);
    let (rm, tan) = twin_screw();
    let (g_r, g_f) = ((g_up + g_dn) / 2.0, (g_up - g_dn) / 2.0);
    m * rm * r * mu0 * (g_r + r * g_f) / (1.0 - r * mu0 * tan)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    /// A stick-slipping lift's load within 0.1 % (+0.5 kg) of the twin and its mean T_r within
    /// 0.2 % (+2 mN·m) over the envelope: α 20…70°, loads 50…2000 kg, μ(0) 0.05…0.4 (and 1.5×,
    /// 2× drier: up to 0.8), pins μ_b 0.05…0.4, mean mobilisation 0…1; refused alike where the
    /// slips' fall is under half the span.
    #[test]
    fn a_stick_slipping_lift_follows_the_twin(
        alpha in 20.0f64..70.0,
        m in 50.0f64..2000.0,
        mu0 in 0.05f64..0.8,
        mu_pin in 0.05f64..0.4,
        rho_bar in 0.0f64..1.0,
        fall in 0.0f64..1.0,
    ) {
        let (g_up, g_dn) = (g_per_kg(alpha, 1.0, mu_pin), g_per_kg(alpha, -1.0, mu_pin));
        let g_r = (g_up + g_dn) / 2.0;
        let p = rho(1.0, mu0) * m * g_up;
        let t0 = rho(1.0, 0.0) * m * g_r;
        // Away from the refusal's edge (the twin's and the fixed point's rounding differ there).
        let drop = if fall < 0.5 { fall * 0.9 } else { 0.55 + fall * 0.45 } * (p - t0);
        let want = twin_stick(p, drop, mu0, g_up, g_r);
        let got = fixed_stick(p, drop, mu0, g_up, g_r);
        match (want, got) {
            (Some(wm), Some(gm)) => {
                prop_assert!((gm - wm).abs() <= 1e-3 * wm + 0.5, "M {} vs {}", gm, wm);
            }
            (None, None) => {}
            (w, g) => prop_assert!(false, "twin {:?}, fixed {:?}", w, g),
        }
        // The mean T_r at a mean torque between the lead's alone (ρ = 0) and the breakaway.
        let mean = m * twin_tau_up(rho_bar, mu0, g_up, g_dn);
        let want = twin_lift_friction(m, mean, mu0, g_up, g_dn);
        let q23 = |x: f64| (x * f64::from(1u32 << 23)).round() as i64;
        let got = liftfw::ident::stick::lift_friction(
            &screw(),
            Ratio::from_f64(mu0),
            q23(g_up),
            q23(g_dn),
            liftfw::units::Kilograms::from_f64(m),
            (mean * 65536.0).round() as i64,
        )
        .unwrap()
        .to_f64();
        prop_assert!((got - want).abs() <= 2e-3 * want.abs() + 2e-3, "T_r {} vs {}", got, want);
    }
}

/// The twin of `ident::stick::periodic_breakaway`: P = T̄ + k_c·ω·(T − t_s)/2, t_s = π·√(I/k_c),
/// the period T in ticks of `tick_us`.
fn twin_periodic_breakaway(
    mean: f64,
    period: f64,
    kc: f64,
    w: f64,
    tick_us: f64,
    i_ukgm2: f64,
) -> f64 {
    let t_s = std::f64::consts::PI * (i_ukgm2 * 1e-6 / kc).sqrt();
    let stuck = (period * tick_us * 1e-6 - t_s).max(0.0);
    mean + kc * w * stuck / 2.0
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    /// A fast stick-slip's breakaway from its period within 0.5 % (+5 mN·m, + the slip time's
    /// resolution) of the twin over the envelope: mean thread torque 0…100 N·m, periods 4…17 ticks (Q8), k_c 1…10 000 N·m/rad
    /// (the setting's range), the reference 0.2…20 rad/s, ticks 100…10 000 µs, the screw's
    /// inertia 0…100 000 µkg·m² (the setting's range). And the load it gives, P/(ρ₁·G_up),
    /// within 0.1 % (+0.5 kg) of P/(ρ₁·G_up) in f64 (`ident::stick::load`).
    #[test]
    fn a_fast_stick_slip_breakaway_follows_the_twin(
        mean in 0.0f64..100.0,
        period in 4.0f64..17.0,
        kc in 1.0f64..10_000.0,
        w in 0.2f64..20.0,
        tick_us in 100u32..=10_000,
        i_ukgm2 in 0i32..=100_000,
        alpha in 20.0f64..70.0,
        mu0 in 0.05f64..0.8,
        p in 0.5f64..100.0,
    ) {
        let q16 = |x: f64| (x * 65536.0).round() as i64;
        let period_q8 = (period * 256.0).round() as i32;
        let want = twin_periodic_breakaway(mean, f64::from(period_q8) / 256.0, kc, w, f64::from(tick_us), f64::from(i_ukgm2));
        // k_c and ω as the core holds them (Q16).
        let (kc_q, w_q) = (q16(kc), q16(w));
        let got = liftfw::ident::stick::periodic_breakaway(q16(mean), period_q8, kc_q, w_q, tick_us, i_ukgm2);
        // Beyond i64's range of the fall the fixed point gives None: not in this envelope.
        let got = got.map(|v| v as f64 / 65536.0);
        prop_assert!(got.is_some(), "None for {} {} {} {} {} {}", mean, period, kc, w, tick_us, i_ukgm2);
        let got = got.unwrap();
        // The slip time t_s = π·√(I/k_c) is resolved to π/4096 ms (the root's Q12 ms, floored):
        // k_c·ω·t_s's half of that on P, which dominates where the stick is short against the
        // slip (a period of 11.25 ticks of 438 µs against t_s = 4.84 ms: P 2.851 vs 2.829).
        let t_s_lsb = std::f64::consts::PI / 4096.0 * 1e-3;
        prop_assert!(
            (got - want).abs() <= 5e-3 * want.abs() + 5e-3 + kc * w * t_s_lsb / 2.0,
            "P {} vs {}", got, want
        );

        let g_up = g_per_kg(alpha, 1.0, 0.3);
        let sc = screw();
        let rho1 = pair::rho_q32(&sc, Ratio::from_f64(mu0), 1).unwrap();
        let want_m = p / (rho(1.0, mu0) * g_up);
        let got_m = liftfw::ident::stick::load(q16(p), rho1, (g_up * f64::from(1u32 << 23)).round() as i64);
        if want_m < 10_000.0 {
            let got_m = got_m.unwrap().to_f64();
            prop_assert!((got_m - want_m).abs() <= 1e-3 * want_m + 0.5, "M {} vs {}", got_m, want_m);
        }
    }
}

/// The twin of `ident::stick::StuckLowering`'s τ(ρ) (docs/model.md "A stick-slipping
/// lowering"): r_m·ξ_down(ρ·μ(0))·(G_R − ρ·G_F), N·m per kg, signed.
fn twin_tau(rho_: f64, mu0: f64, g_up: f64, g_dn: f64) -> f64 {
    let (g_r, g_f) = ((g_up + g_dn) / 2.0, (g_up - g_dn) / 2.0);
    rho(-1.0, rho_ * mu0) * (g_r - rho_ * g_f)
}

/// Where |τ| peaks over ρ ∈ [0, 1] and its value, by a dense scan and a golden-section
/// refinement (no closed form: the fixed point's ρ_x drops the denominator's variation).
fn twin_peak(mu0: f64, g_up: f64, g_dn: f64) -> (f64, f64) {
    let f = |r: f64| -twin_tau(r, mu0, g_up, g_dn);
    let mut best = (0.0, f(0.0));
    for i in 0..=1000 {
        let r = f64::from(i) / 1000.0;
        if f(r) > best.1 {
            best = (r, f(r));
        }
    }
    let (mut a, mut b) = ((best.0 - 1e-3).max(0.0), (best.0 + 1e-3).min(1.0));
    for _ in 0..60 {
        let (c, d) = (b - (b - a) / 1.618, a + (b - a) / 1.618);
        if f(c) > f(d) {
            b = d;
        } else {
            a = c;
        }
    }
    let r = (a + b) / 2.0;
    (r, f(r))
}

/// The stuck lowering's T_r at one thread torque `t`: below the load's push alone, ρ where
/// M·τ(ρ) = T on [0, ρ_x], T_r = −M·r_m·ρμ₀·(G_R − ρG_F)/(1 + ρμ₀·tan λ); above it the
/// statics resist lifting, as a stuck lift's (`twin_lift_friction`).
/// (`rx`: where |τ| peaks.)
fn twin_lower_friction_at(m: f64, t: f64, mu0: f64, g_up: f64, g_dn: f64, rx: f64) -> f64 {
    if t > m * twin_tau(0.0, mu0, g_up, g_dn) {
        return twin_lift_friction(m, t, mu0, g_up, g_dn);
    }
    let r = twin_bisect(rx, |mid| m * twin_tau(mid, mu0, g_up, g_dn) > t);
    let (rm, tan) = twin_screw();
    let (g_r, g_f) = ((g_up + g_dn) / 2.0, (g_up - g_dn) / 2.0);
    -m * rm * r * mu0 * (g_r - r * g_f) / (1.0 + r * mu0 * tan)
}

/// The twin of `StuckLowering::friction`: the mean of the stuck T_r over a wind-up uniform in
/// the thread torque from the breakaway P = M·τ(1) to the trough 2·T̄ − P, within the stuck
/// thread's reach: up to the lifting branch's breakaway M·τ_up(1), down to τ's peak (a mean
/// beyond P; 400 midpoints: the integral).
fn twin_lower_friction(m: f64, mean: f64, mu0: f64, g_up: f64, g_dn: f64) -> f64 {
    let (rx, peak) = twin_peak(mu0, g_up, g_dn);
    let p = m * twin_tau(1.0, mu0, g_up, g_dn);
    let top = (2.0 * mean - p)
        .min(m * twin_tau_up(1.0, mu0, g_up, g_dn))
        .max(-m * peak);
    let n = 400;
    (0..n)
        .map(|j| {
            let t = p + (top - p) * (f64::from(j) + 0.5) / f64::from(n);
            twin_lower_friction_at(m, t, mu0, g_up, g_dn, rx)
        })
        .sum::<f64>()
        / f64::from(n)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    /// A stuck lowering's breakaway load within 0.2 % (+0.5 kg) of the twin, and its mean T_r
    /// over the wind-up within 0.4 % of the breakaway's T_r (+2 mN·m; eight steps of ρ a
    /// branch: 0.29 % at worst over 2000 cases, sixteen 0.17 %), over the envelope: α 12…44°
    /// (above, G_down < G_up/8 and lowering does not weigh, docs/model.md), loads 50…2000 kg,
    /// μ(0) 0.1…0.4 (self-locking), pins μ_b 0.05…0.4, mean mobilisation anywhere between the
    /// load's push alone and the breakaway.
    #[test]
    fn a_stuck_lowering_follows_the_twin(
        alpha in 12.0f64..44.0,
        m in 50.0f64..2000.0,
        mu0 in 0.1f64..0.4,
        mu_pin in 0.05f64..0.4,
        at in 0.0f64..1.0,
    ) {
        let (g_up, g_dn) = (g_per_kg(alpha, 1.0, mu_pin), g_per_kg(alpha, -1.0, mu_pin));
        prop_assume!(g_dn >= g_up / 8.0);
        let q23 = |x: f64| (x * f64::from(1u32 << 23)).round() as i64;
        let sc = screw();
        let s = liftfw::ident::stick::StuckLowering::new(&sc, Ratio::from_f64(mu0), q23(g_up), q23(g_dn));
        let (rx, _) = twin_peak(mu0, g_up, g_dn);
        let s = s.expect("self-locking at μ(0) ≥ 0.1");
        // The breakaway at full mobilisation: the load a twin peak gives.
        let p = -m * twin_tau(1.0, mu0, g_up, g_dn);
        let got = s.load((p * 65536.0).round() as i64).unwrap().to_f64();
        prop_assert!((got - m).abs() <= 2e-3 * m + 0.5, "M {} vs {}", got, m);
        // And back: the breakaway torque of that load (the creep's gate).
        let pb = s.breakaway_torque(liftfw::units::Kilograms::from_f64(m)) as f64 / 65536.0;
        prop_assert!((pb - p).abs() <= 2e-3 * p + 1e-3, "P {} vs {}", pb, p);
        // |τ|'s peak within 1 % of ρ (where it is flat).
        let px = s.peak_mobilisation() as f64 / 65536.0;
        prop_assert!((px - rx).abs() <= 0.01, "ρ_x {} vs {}", px, rx);
        // The mean T_r at a mean torque between the push alone (ρ = 0) and |τ|'s peak: the
        // trough 2·T̄ − P from beyond the breakaway (T̄ alone) to far up the lifting branch.
        let mean = m * twin_tau(at * rx, mu0, g_up, g_dn);
        let want = twin_lower_friction(m, mean, mu0, g_up, g_dn);
        let load = liftfw::units::Kilograms::from_f64(m);
        let got = s.friction(&sc, load, (mean * 65536.0).round() as i64).unwrap().to_f64();
        // The quadrature's error is the span's, not the reading's (which can cancel to
        // nothing where the trough runs far up the lifting branch): against T_r at the
        // breakaway.
        let scale = twin_lower_friction_at(m, -p, mu0, g_up, g_dn, rx).abs();
        prop_assert!(
            (got - want).abs() <= 4e-3 * scale + 2e-3,
            "T_r {} vs {} (scale {})", got, want, scale
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, ..ProptestConfig::default() })]

    /// A breakaway pair (`LoadIdent::breakaway_pair`: a lift's mean breakaway and a lowering's
    /// creep's, the nut standing, D = 0) solved by the pair search: within 0.2 % (scale) and
    /// 0.3 % + 0.5 kg (load) of the twin's bisection, and within 1 % of the truth the
    /// breakaways were made from (P_d = M·ρ_d(s·μ(0))·G_d), over α 16…40°, loads 100…2000 kg,
    /// a static μ(0) 0.15…0.35 (the dry law's 0.238) and scales 0.8…2.2.
    #[test]
    fn a_breakaway_pair_follows_the_twin(
        alpha in 16.0f64..40.0,
        m in 100.0f64..2000.0,
        mu0 in 0.15f64..0.35,
        s in 0.8f64..2.2,
    ) {
        let (_, tan) = twin_screw();
        prop_assume!(mu0 * s > 1.1 * tan && mu0 * s < 0.55);
        let gu = g_per_kg(alpha, 1.0, 0.3);
        let gd = g_per_kg(alpha, -1.0, 0.3);
        prop_assume!(gd >= gu / 7.5);
        let b = |dir: f64, g: f64| pair::Breakaway {
            torque: NewtonMetres::from_f64(rho(dir, mu0 * s) * m * g),
            g_per_kg: (g * f64::from(1u32 << 23)).round() as i32,
        };
        let mu = Ratio::from_f64(mu0);
        let (up, dn) = (b(1.0, gu).means(1, mu), b(-1.0, gd).means(-1, mu));
        prop_assert!(up.free == Newtons::ZERO && dn.n == 0 && dn.dir == -1);
        let q = |x: &MotionMeans| (x.torque.to_f64(), f64::from(x.g_per_kg) / f64::from(1u32 << 23), 0.0, x.mu.to_f64());
        let twin = twin_solve(q(&up), q(&dn));
        let got = pair::solve(&screw(), &up, &dn);
        match (twin, got) {
            (Some((ts, tm)), Some(sol)) => {
                near_twin(&sol, ts, tm)?;
                near_truth(&sol, s, m)?;
            }
            (t, g) => prop_assert!(false, "twin {:?}, core {:?}", t, g),
        }
    }
}

/// The stuck readings at the status take a mean thread torque from the current's samples and
/// a load from the identification: any of them, however wild (a dead sensor's full scale, i64's
/// ends, a load of one raw unit or i32's end), gives a reading or `None`, never a panic (the
/// test profile checks overflow), and a finite reading is no larger than the breakaway's
/// reach on either branch allows.
#[test]
fn a_stuck_reading_of_any_mean_and_load_gives_a_reading_or_none() {
    use liftfw::ident::stick::{lift_friction, StuckLowering};
    use liftfw::units::Kilograms;
    let sc = screw();
    let q23 = |x: f64| (x * f64::from(1u32 << 23)).round() as i64;
    let (g_up, g_dn) = (g_per_kg(20.0, 1.0, 0.3), g_per_kg(20.0, -1.0, 0.3));
    let mu0 = Ratio::from_f64(0.238);
    let s = StuckLowering::new(&sc, mu0, q23(g_up), q23(g_dn)).expect("self-locking");
    let means = [
        i64::MIN,
        i64::from(i32::MIN),
        -(1 << 27),
        -1,
        0,
        1,
        1 << 27,
        i64::from(i32::MAX),
        i64::MAX,
    ];
    let loads = [i32::MIN, -1, 0, 1, 4096, 2000 << 12, i32::MAX].map(Kilograms::from_bits);
    for &load in &loads {
        for &mean in &means {
            let m = load.to_f64();
            if let Some(tr) = s.friction(&sc, load, mean) {
                // The lifting branch's breakaway at μ(0) bounds either branch's T_r.
                let reach = m * twin_screw().0 * 0.238 * (g_up + g_dn) / 2.0 * 2.0 + 1e-3;
                assert!(
                    tr.to_f64().abs() <= reach,
                    "{mean} at {m} kg: {}",
                    tr.to_f64()
                );
            }
            if let Some(tr) = lift_friction(&sc, mu0, q23(g_up), q23(g_dn), load, mean) {
                let reach = m * twin_screw().0 * 0.238 * g_up * 1.1 + 1e-3;
                assert!(
                    tr.to_f64().abs() <= reach,
                    "lift {mean} at {m} kg: {}",
                    tr.to_f64()
                );
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 4000, ..ProptestConfig::default() })]

    /// The status's stuck readings on any pose, law and car the core can hold (`g_per_kg`'s
    /// i32, μ(0)'s raw Q28, a load's raw Q12, the samples' mean thread torque anywhere in
    /// i32's Q16 N·m) give a reading or `None` and never panic (overflow checked): a corrupt
    /// configuration or a dead sensor must not crash the control task, which builds the
    /// status with the lock held.
    /// Half the cases are drawn where a stuck lowering exists (G_up ≥ G_down ≥ 0, μ(0) > 0),
    /// to its ends (in one run, 1 960 of the 2 036 draws that made one gave a reading).
    #[test]
    fn stuck_readings_never_panic(
        valid in proptest::bool::ANY,
        g_up in proptest::num::i32::ANY,
        g_dn in proptest::num::i32::ANY,
        mu0 in proptest::num::i32::ANY,
        load in proptest::num::i32::ANY,
        mean in proptest::num::i32::ANY,
    ) {
        use liftfw::ident::stick::{lift_friction, StuckLowering};
        use liftfw::units::Kilograms;
        let sc = screw();
        // Valid: G_up ≤ 2^30 (128 N/kg), G_down in [0, G_up], μ(0) ≤ 4, a car of any weight
        // and a mean within ±2048 N·m (beyond, Q16·2^36 leaves i64: `None`).
        let (g_up, g_dn, mu0, load, mean) = if valid {
            let up = g_up.unsigned_abs() >> 1;
            (
                up as i32,
                (g_dn.unsigned_abs() % (up + 1)) as i32,
                (mu0.unsigned_abs() >> 1).max(1) as i32,
                load.saturating_abs(),
                mean >> 4,
            )
        } else {
            (g_up, g_dn, mu0, load, mean)
        };
        let (mu0, load) = (Ratio::from_bits(mu0), Kilograms::from_bits(load));
        let (up, dn, mean) = (i64::from(g_up), i64::from(g_dn), i64::from(mean));
        if let Some(s) = StuckLowering::new(&sc, mu0, up, dn) {
            let _ = s.friction(&sc, load, mean);
            let _ = s.load(mean.abs());
            let _ = s.breakaway_torque(load);
        }
        let _ = lift_friction(&sc, mu0, up, dn, load, mean);
    }
}
