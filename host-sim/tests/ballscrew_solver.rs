//! The ball-screw load-distribution solver (seed 001): force balance, the loaded set, agreement
//! with an independent shooting solution, and the zero-error distribution.
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::needless_range_loop,
    missing_docs
)]

use host_sim::studies::load_distribution::{
    random_errors, AngleModel, BallScrew, LoadCase, SolveError, Solver,
};

const BANDS: [f64; 4] = [0.0, 1e-6, 2e-6, 3e-6];

fn solver(band: f64, seed: u64) -> Solver {
    let b = BallScrew::paper();
    Solver::new(b, random_errors(seed, band, b.balls)).unwrap()
}

/// Walk the screw from the first loaded ball with the segment law and check, ball by ball, that
/// loaded balls satisfy compatibility and non-loaded balls are not pressed (complementarity).
/// Independent of the solver's own bookkeeping: only its per-ball law (`Solver::ball`) is shared.
fn check_loaded_set(s: &Solver, c: &LoadCase) {
    let b = &s.screw;
    let k = b.segment_compliance() * b.ball_spacing();
    let p = c.first;
    let u_p = s.ball(p, c.delta[p]).u;
    let scale = u_p.abs().max(1e-9);
    for j in 0..p {
        let u = u_p + k * (p - j) as f64 * c.fa;
        assert!(
            u <= s.ball(j, 0.0).u + 1e-12 * scale,
            "ball {j} ahead of the first is pressed"
        );
        assert_eq!(c.delta[j], 0.0);
    }
    let mut u = u_p;
    let mut f = c.fa - s.ball(p, c.delta[p]).p;
    for j in p + 1..b.balls {
        u -= k * f;
        if c.delta[j] > 0.0 {
            let st = s.ball(j, c.delta[j]);
            assert!(
                (st.u - u).abs() <= 1e-9 * scale,
                "ball {j}: compatibility {} vs {u}",
                st.u
            );
            f -= st.p;
        } else {
            assert!(
                u <= s.ball(j, 0.0).u + 1e-9 * scale,
                "non-loaded ball {j} is pressed"
            );
        }
    }
    assert!(
        f.abs() <= 1e-9 * c.fa,
        "load left over after the last ball: {f}"
    );
}

#[test]
fn force_balance_holds_to_1e9_for_every_band_and_load() {
    for band in BANDS {
        for seed in [1, 7] {
            let s = solver(band, seed);
            let mut prev: Option<LoadCase> = None;
            for fa in [
                20.0, 100.0, 300.0, 1000.0, 2500.0, 5000.0, 10_000.0, 20_000.0,
            ] {
                for warm in [None, prev.as_ref()] {
                    let c = s.solve(fa, warm).unwrap();
                    let e = c.force_balance_error(&s.screw);
                    assert!(e < 1e-9, "band {band:e} seed {seed} F {fa}: {e:e}");
                    assert!(c.q.iter().all(|&q| q >= 0.0));
                }
                prev = Some(s.solve(fa, prev.as_ref()).unwrap());
            }
        }
    }
}

#[test]
fn converges_with_non_loaded_balls_and_the_loaded_set_is_consistent() {
    let mut saw_partial = 0;
    for band in [1e-6, 2e-6, 3e-6] {
        for fa in [10.0, 100.0, 500.0, 1000.0, 3000.0] {
            let s = solver(band, 3);
            let c = s.solve(fa, None).unwrap();
            assert!(c.loaded >= 1 && c.loaded <= 78);
            assert_eq!(c.loaded, c.q.iter().filter(|&&q| q > 0.0).count());
            if c.loaded < 78 {
                saw_partial += 1;
                assert!(
                    c.passes > 1,
                    "non-loaded balls found without an update pass"
                );
            }
            check_loaded_set(&s, &c);
        }
    }
    assert!(saw_partial >= 5, "the cases must include non-loaded balls");
}

#[test]
fn at_a_tiny_load_only_the_largest_ball_carries() {
    let s = solver(3e-6, 1);
    let c = s.solve(1e-3, None).unwrap();
    let big = (0..78)
        .max_by(|&a, &b| s.errors[a].total_cmp(&s.errors[b]))
        .unwrap();
    assert_eq!(c.loaded, 1);
    assert!(c.q[big] > 0.0);
}

/// Shooting: choose the approach at ball 1, walk the balls (each one's δ from its own law,
/// zero if its gap stays open), and bisect until the load is used up exactly at the last ball.
fn shoot(s: &Solver, fa: f64) -> Vec<f64> {
    let b = &s.screw;
    let k = b.segment_compliance() * b.ball_spacing();
    let delta_for = |j: usize, u: f64| -> f64 {
        if u <= s.ball(j, 0.0).u {
            return 0.0;
        }
        let (mut lo, mut hi) = (0.0, 1e-4);
        for _ in 0..200 {
            let m = 0.5 * (lo + hi);
            if s.ball(j, m).u < u {
                lo = m;
            } else {
                hi = m;
            }
        }
        0.5 * (lo + hi)
    };
    let walk = |u0: f64| -> (f64, Vec<f64>) {
        let (mut u, mut f, mut q) = (u0, fa, vec![0.0; b.balls]);
        for j in 0..b.balls {
            let d = delta_for(j, u);
            let st = s.ball(j, d);
            if d > 0.0 {
                q[j] = st.q;
                f -= st.p;
            }
            u -= k * f;
        }
        (f, q)
    };
    let (mut lo, mut hi) = (-1e-4, 1e-4);
    for _ in 0..200 {
        let m = 0.5 * (lo + hi);
        if walk(m).0 > 0.0 {
            lo = m;
        } else {
            hi = m;
        }
    }
    walk(0.5 * (lo + hi)).1
}

#[test]
fn agrees_with_an_independent_shooting_solution() {
    for (band, fa) in [(0.0, 5000.0), (2e-6, 500.0), (3e-6, 1000.0), (1e-6, 200.0)] {
        let s = solver(band, 2);
        let c = s.solve(fa, None).unwrap();
        let q = shoot(&s, fa);
        for j in 0..78 {
            assert!(
                (c.q[j] - q[j]).abs() <= 1e-6 * q[j].max(1.0),
                "band {band:e} F {fa} ball {j}: {} vs {}",
                c.q[j],
                q[j]
            );
        }
    }
}

#[test]
fn zero_error_gives_a_smooth_monotone_distribution() {
    let s = solver(0.0, 1);
    let mut prev_da = 0.0;
    for fa in [100.0, 500.0, 1000.0, 3000.0, 5000.0, 10_000.0] {
        let c = s.solve(fa, None).unwrap();
        assert_eq!(c.loaded, 78);
        assert_eq!(c.passes, 1, "no ball is ever dropped without errors");
        // Strictly decreasing away from the load's entry, and smooth: the decrements shrink
        // steadily (convex profile) rather than jumping.
        let d: Vec<f64> = c.q.windows(2).map(|w| w[0] - w[1]).collect();
        assert!(d.iter().all(|&x| x > 0.0), "F {fa}: not decreasing");
        assert!(
            d.windows(2).all(|w| w[1] <= w[0] * (1.0 + 1e-9)),
            "F {fa}: not convex"
        );
        // The contact angle grows with the load, more on the loaded end.
        assert!(c.alpha[0] > c.alpha[77] && c.alpha[77] > s.screw.alpha0);
        assert!(c.axial_displacement > prev_da);
        prev_da = c.axial_displacement;
    }
}

#[test]
fn negative_error_ball_carries_nothing_at_light_load_and_joins_later() {
    let b = BallScrew::paper();
    let mut e = vec![0.0; 78];
    e[32] = -2e-6;
    let s = Solver::new(b, e).unwrap();
    let light = s.solve(500.0, None).unwrap();
    assert_eq!(light.q[32], 0.0);
    assert_eq!(light.loaded, 77);
    let heavy = s.solve(5000.0, None).unwrap();
    assert!(heavy.q[32] > 0.0 && heavy.q[32] < heavy.q[31]);
    check_loaded_set(&s, &light);
}

#[test]
fn constant_angle_model_keeps_45_degrees() {
    let b = BallScrew {
        angle: AngleModel::Fixed,
        ..BallScrew::paper()
    };
    let s = Solver::new(b, random_errors(1, 2e-6, 78)).unwrap();
    let c = s.solve(5000.0, None).unwrap();
    assert!(c.alpha.iter().all(|&a| (a - b.alpha0).abs() < 1e-15));
    assert!(c.force_balance_error(&b) < 1e-9);
}

#[test]
fn rejects_bad_loads_and_error_vectors() {
    let s = solver(1e-6, 1);
    for fa in [0.0, -5.0, f64::NAN, f64::INFINITY] {
        assert_eq!(s.solve(fa, None), Err(SolveError::BadLoad));
    }
    assert!(matches!(
        Solver::new(BallScrew::paper(), vec![0.0; 77]),
        Err(SolveError::BadErrors)
    ));
    assert!(matches!(
        Solver::new(BallScrew::paper(), vec![f64::NAN; 78]),
        Err(SolveError::BadErrors)
    ));
}
