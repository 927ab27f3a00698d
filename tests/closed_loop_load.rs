//! The load identification and the overload protection built on it, in closed loop with
//! host-sim's plant (`liftfw::ident`, docs/control.md "Protections"): the identified load
//! converges within 0.5 s of cruise; no overload trip at or below the rated load on any
//! lubricant, even on a thread twice as dry as configured (whose lift/lowering pair warns about
//! lubrication); a load above the limit is refused within 0.5 s of starting, lifting and
//! lowering, with the identified load in the fault.
#![allow(clippy::expect_used, clippy::unwrap_used)]

mod support;
use host_sim::physics::Lubricant;
use host_sim::plant::screw_nut::Phase;
use liftfw::control::config::ControlConfig;
use liftfw::control::{Command, Event, FaultKind};
use liftfw::units::{Metres, Ratio};
use support::{run, Run, Scenario, Tick};

/// GoTo `mm` of head travel from the start (`dmm` signed), at 20 ms, then (optionally) back;
/// `known_scale`: the board has identified its thread before (the scale restored from the
/// store, as after a power cycle).
fn moves(mut s: Scenario, steps: Vec<f64>, known_scale: bool) -> Run {
    s.wide_stops();
    let g = host_sim::physics::Geometry::paper();
    let mut h = g.height(s.start_deg.to_radians());
    let mut next = 0usize;
    let mut rest_since: Option<f64> = None;
    let mut restored = false;
    run(
        &s,
        Box::new(move |k: &mut Tick<'_>| {
            if known_scale && !restored {
                restored = true;
                k.controller.restore_friction_scale(Ratio::ONE);
            }
            if k.controller.fault().is_some() || k.t < 0.02 {
                return;
            }
            let moving = matches!(
                k.controller.state(),
                liftfw::control::State::Lifting | liftfw::control::State::Lowering
            );
            if moving {
                rest_since = None;
                return;
            }
            let since = *rest_since.get_or_insert(k.t);
            if next < steps.len() && (next == 0 || k.t - since > 0.3) {
                h += steps[next] * 1e-3;
                next += 1;
                k.controller
                    .command(Command::GoTo(Metres::from_f64(h)))
                    .unwrap();
            }
        }),
    )
}

/// A scenario with wide stops, commissioned as `host-sim estimate` is: `lube.no_load_current`
/// the plant motor's no-load current at cruise (the drive's no-load torque the identification
/// takes off).
fn commissioned(lub: Lubricant, load: f64, deg: f64, duration: f64) -> Scenario {
    let mut s = Scenario::new(lub, load, deg, duration);
    s.wide_stops();
    let cruise = s.control.motion.cruise_speed.to_f64();
    s.control.lube.no_load_current =
        liftfw::units::Amperes::from_f64(host_sim::studies::estimate::no_load_current(cruise));
    s
}

/// The run raised the lubrication warning (`Event::ThreadDry`).
fn warned(r: &Run) -> bool {
    r.events
        .iter()
        .any(|(_, e)| matches!(e, Event::ThreadDry(_)))
}

/// From `deg`: GoTo `mm` above the start at 20 ms, then back to the start 0.3 s after the lift
/// came to rest; `observe` sees every tick of a motion.
fn lift_then_lower(
    s: &Scenario,
    deg: f64,
    mm: f64,
    mut observe: impl FnMut(&mut Tick<'_>) + Send + 'static,
) -> Run {
    goto_from(s, deg, vec![mm, 0.0], 0.02, move |k, _| observe(k))
}

/// From `deg`: GoTo each of `mm` (above the start) in turn, the first at `first` s (20 ms; after
/// the boot's rest, 0.7 s: the current's zero measured, as `host-sim estimate`'s boards), each
/// next 0.3 s after the last came to rest; `observe` sees every tick of a motion with the
/// motion's number (1, 2, …).
fn goto_from(
    s: &Scenario,
    deg: f64,
    mm: Vec<f64>,
    first: f64,
    mut observe: impl FnMut(&mut Tick<'_>, usize) + Send + 'static,
) -> Run {
    let g = host_sim::physics::Geometry::paper();
    let h0 = g.height(deg.to_radians());
    let mut next = 0;
    let mut rest_since: Option<f64> = None;
    run(
        s,
        Box::new(move |k: &mut Tick<'_>| {
            if k.controller.fault().is_some() || k.t < first {
                return;
            }
            let state = k.controller.state();
            if state == liftfw::control::State::Lifting || state == liftfw::control::State::Lowering
            {
                rest_since = None;
                observe(k, next);
                return;
            }
            let since = *rest_since.get_or_insert(k.t);
            if next < mm.len() && (next == 0 || k.t - since > 0.3) {
                let h = h0 + mm[next] * 1e-3;
                next += 1;
                k.controller
                    .command(Command::GoTo(Metres::from_f64(h)))
                    .unwrap();
            }
        }),
    )
}

/// The plant's T_r at time `t` (the trace's record at or after it; records at 1 kHz).
fn plant_friction_at(r: &Run, t: f64) -> f64 {
    let i = r.trace.records.partition_point(|x| x.t < t);
    r.trace.records[i.min(r.trace.records.len() - 1)].friction_torque
}

/// The core's and the plant's mean T_r over a log's (t, load, T_r) ticks (`fresh_dry_lowering`'s).
fn tr_means(r: &Run, log: &[(f64, f64, f64)]) -> (f64, f64) {
    let n = log.len().max(1) as f64;
    let core = log.iter().map(|x| x.2).sum::<f64>() / n;
    let plant = log.iter().map(|x| plant_friction_at(r, x.0)).sum::<f64>() / n;
    (core, plant)
}

fn faults(r: &Run) -> Vec<(f64, FaultKind)> {
    r.events
        .iter()
        .filter_map(|(t, e)| match e {
            Event::Fault(f) => Some((*t, f.kind)),
            _ => None,
        })
        .collect()
}

/// A lowering of `mm` from the start angle `deg`, commanded at `at` s, with `each` called on
/// every tick at the cruise reference (−3 rad/s as quantised).
fn lowering(
    s: &Scenario,
    deg: f64,
    mm: f64,
    at: f64,
    mut each: impl FnMut(&mut Tick<'_>) + Send + 'static,
) -> Run {
    let g = host_sim::physics::Geometry::paper();
    let h = g.height(deg.to_radians()) - mm * 1e-3;
    run(
        s,
        Box::new(move |k: &mut Tick<'_>| {
            if (k.t - at).abs() < 5e-4 {
                k.controller
                    .command(Command::GoTo(Metres::from_f64(h)))
                    .unwrap();
            }
            if (k.controller.reference().to_f64() + 3.0).abs() < 1e-3 {
                each(k);
            }
        }),
    )
}

#[test]
fn the_identified_load_converges_within_half_a_second_of_cruise() {
    for (lub, load) in [
        (Lubricant::Ptfe, 600.0),
        // Dry lifting whose stick-slip the current does not resolve (250 kg from 150 mm,
        // 500 kg from 260 mm) is 13…41 kg off (docs/control.md "Known limits"); at 1000 kg
        // the breakaway peaks give the load (`ident::stick`).
        (Lubricant::Dry, 1000.0),
        (Lubricant::Lithium, 1300.0),
    ] {
        let mut s = Scenario::new(lub, load, 20.0, 2.2);
        s.seed = 3;
        // The head's travel of ≈ 1.6 s at cruise from 20°.
        let mut cruise_at: Option<f64> = None;
        // Shared with the hook (a `move` closure would take a copy of a plain f64).
        let worst = std::sync::Arc::new(std::sync::Mutex::new((0.0f64, 0u32)));
        let seen = std::sync::Arc::clone(&worst);
        let r = {
            s.wide_stops();
            let g = host_sim::physics::Geometry::paper();
            let h = g.height(20f64.to_radians()) + 3.5e-3;
            run(
                &s,
                Box::new(move |k: &mut Tick<'_>| {
                    if (k.t - 0.02).abs() < 5e-4 {
                        // The prior before any evidence: the rated load, 0…2× rated.
                        let p = k.controller.status().load;
                        assert!(!p.identified && p.load.to_f64() == 1000.0, "{p:?}");
                        assert!(
                            p.load_lo.to_f64() == 0.0 && p.load_hi.to_f64() == 2000.0,
                            "{p:?}"
                        );
                        k.controller
                            .command(Command::GoTo(Metres::from_f64(h)))
                            .unwrap();
                    }
                    let c = &k.controller;
                    // The cruise reference (3 rad/s as quantised: not `lit("3")` exactly).
                    let at_cruise = (c.reference().to_f64() - 3.0).abs() < 1e-3;
                    if at_cruise {
                        let t0 = *cruise_at.get_or_insert(k.t);
                        if k.t >= t0 + 0.5 {
                            let l = c.status().load;
                            assert!(l.identified, "{lub:?} {load}: not identified at {}", k.t);
                            let mut w = seen.lock().unwrap();
                            *w = (w.0.max((l.load.to_f64() - load).abs()), w.1 + 1);
                            assert!(
                                (l.load.to_f64() - load).abs() <= 0.03 * load,
                                "{lub:?} {load}: {:?} at {:.3} s",
                                l,
                                k.t
                            );
                            assert!(
                                l.load_lo.to_f64() <= load && load <= l.load_hi.to_f64(),
                                "{l:?}"
                            );
                        }
                    }
                }),
            )
        };
        assert!(faults(&r).is_empty(), "{lub:?}: {:?}", faults(&r));
        assert!(r.controller.status().load.identified);
        let (worst, checked) = *worst.lock().unwrap();
        assert!(
            checked > 100,
            "{lub:?}: {checked} ticks from 0.5 s of cruise checked"
        );
        println!("{lub:?} {load} kg: worst load error from 0.5 s of cruise {worst:.1} kg");
    }
}

#[test]
fn no_overload_trip_at_or_below_rated_on_any_lubricant_even_on_a_drier_thread() {
    for lub in Lubricant::ALL {
        for dry in [1.0, 2.0] {
            // (A dry thread twice as dry lifting 1000 kg below ≈ 25° needs more than the 45 A
            // the over-current protection allows: not this test's subject.)
            for (load, deg) in [(1000.0, 30.0), (1000.0, 40.0), (500.0, 18.0)] {
                let mut s = Scenario::new(lub, load, deg, 1.6);
                s.thread_friction_factor = dry;
                let r = moves(s, vec![2.5, -2.5], false);
                assert!(
                    faults(&r).is_empty(),
                    "{lub:?} ×{dry} {load} kg {deg}°: {:?}",
                    faults(&r)
                );
            }
        }
    }
}

#[test]
fn a_lift_and_lowering_on_a_drier_thread_identify_it_and_warn() {
    // (A dry thread's means leave their pair unsolved: its breakaways make it, the next test;
    // lithium's at 2× put the scale 12…20 % low: docs/control.md, known limits. PTFE is held
    // to it.)
    {
        let lub = Lubricant::Ptfe;
        let mut s = Scenario::new(lub, 1000.0, 30.0, 5.5);
        s.thread_friction_factor = 2.0;
        let r = moves(s, vec![2.5, -2.5, 2.5], false);
        assert!(faults(&r).is_empty(), "{lub:?}: {:?}", faults(&r));
        let l = r.controller.status().load;
        assert!(warned(&r), "{lub:?}: no lubrication warning, {l:?}");
        // Measured: PTFE 2.13 and 953 kg, from one pair at 30° (the lowering's torque is
        // small against the drive's own there).
        assert!((l.scale.to_f64() - 2.0).abs() < 0.15, "{lub:?}: {l:?}");
        assert!((l.load.to_f64() - 1000.0).abs() < 60.0, "{lub:?}: {l:?}");
        assert!(r.controller.status().load.scale_known);
        // The scale is offered to the store once.
        let mut c = r.controller;
        assert!(c.take_friction_store().is_some());
        assert!(c.take_friction_store().is_none());
    }
    // A nominal thread: no warning, no fault.
    for lub in [Lubricant::Ptfe, Lubricant::Lithium] {
        let s = Scenario::new(lub, 1000.0, 20.0, 4.0);
        let r = moves(s, vec![2.5, -2.5], false);
        assert!(
            faults(&r).is_empty(),
            "{lub:?}: {:?} {:?} {:?}",
            faults(&r),
            r.controller.fault(),
            r.controller.status().load
        );
        assert!(!warned(&r));
    }
}

/// A dry thread 1.5× drier than configured: a lift read by its breakaways, then a lowering whose
/// creep pairs its breakaways with the lift's (docs/model.md "A breakaway pair"): the pair finds
/// the thread drier, warns, offers the scale to the store once, and the next lift reads the car
/// at that scale. (Its accuracy is the two readings' agreement times ≈ 3: BENCHMARKS.md.)
#[test]
fn a_dry_thread_drier_than_configured_is_found_by_its_breakaways() {
    let mut s = commissioned(Lubricant::Dry, 1000.0, 20.0, 7.0);
    s.thread_friction_factor = 1.5;
    let r = moves(s, vec![3.0, -3.0, 3.0], false);
    assert!(faults(&r).is_empty(), "{:?}", faults(&r));
    let l = r.controller.status().load;
    eprintln!("dry 1.5× drier, 1000 kg: {l:?}");
    assert!(warned(&r) && l.scale_known && l.pairs == 1, "{l:?}");
    // Measured: scale 1.446, 1041 kg (+4.1 %; interval 967…1119) after the third move; read
    // with the configured law the lift had said 1.4× the car.
    assert!((l.scale.to_f64() - 1.5).abs() < 0.1, "{l:?}");
    assert!((l.load.to_f64() - 1000.0).abs() < 80.0, "{l:?}");
    let mut c = r.controller;
    assert!(c.take_friction_store().is_some());
    assert!(c.take_friction_store().is_none());
}

/// Overload at 1.5× rated: refused within 0.5 s of the start, lifting and lowering, on a board
/// that knows its thread; the fault names the identified load.
#[test]
fn an_overload_is_refused_within_half_a_second_lifting_and_lowering() {
    // A dry thread stick-slips: lifting, its mean friction is ≈ 2/3 of the law at cruise and
    // the load reads ≈ 30 % low; lowering, the trip came at 0.53 s (docs/control.md, known
    // limits): not held to this test.
    for lub in Lubricant::ALL {
        for (deg, up) in [(25.0, true), (30.0, false)] {
            if lub == Lubricant::Dry {
                continue;
            }
            // PTFE lowering barely self-locks (μ 0.085 against tan λ 0.061): the stored scale's
            // ±5 % is ±18 % of the lowering's load there, so its floor reaches the limit only
            // from ≈ 1.55× rated: 1.7× is tested.
            let load = if lub == Lubricant::Ptfe && !up {
                1700.0
            } else {
                1500.0
            };
            let s = Scenario::new(lub, load, deg, 1.0);
            let r = moves(s, vec![if up { 3.0 } else { -3.0 }], true);
            let f = faults(&r);
            assert_eq!(
                f.first().map(|x| x.1),
                Some(FaultKind::Overload),
                "{lub:?} {up}: {f:?}"
            );
            let t = f[0].0;
            assert!(t - 0.02 <= 0.5, "{lub:?} {up}: after {t:.3} s");
            let fault = r.controller.fault().unwrap();
            assert!(fault.load_identified, "{lub:?} {up}: the prior tripped");
            // Lowering, the trip comes on the first, noisier estimate (PTFE: 1531 kg for 1700).
            // The trip comes on the first estimates, before the coupling's catch-up after the ramp
            // has averaged out (measured: lithium lifting 1341 kg for 1500, PTFE lowering 1531
            // kg for 1700).
            let tol = 0.15;
            assert!(
                (fault.load.to_f64() - load).abs() < tol * load,
                "{lub:?} {up}: {:?}",
                fault.load
            );
        }
        // At the limit's other side (1.2× rated) it does not trip.
        let s = Scenario::new(lub, 1200.0, 25.0, 1.0);
        let r = moves(s, vec![3.0], true);
        assert!(faults(&r).is_empty(), "{lub:?} 1.2×: {:?}", faults(&r));
    }
}

/// A board that never identified its thread: the trip takes the driest thread it still
/// considers possible (2× the law), so it refuses what is over the limit even then.
#[test]
fn a_fresh_board_refuses_an_overload_beyond_the_driest_assumption() {
    let s = Scenario::new(Lubricant::Ptfe, 2500.0, 35.0, 1.0);
    let r = moves(s, vec![3.0], false);
    let f = faults(&r);
    assert_eq!(f.first().map(|x| x.1), Some(FaultKind::Overload), "{f:?}");
    assert!(f[0].0 - 0.02 <= 0.5, "after {:.3} s", f[0].0);
}

/// Before the first evidence (the settling after the start's ramp and the first windows) a
/// fresh board lowering a light car reports T_r from the measured thread torque, not the
/// prior's (the rated load: 10× the truth here, PTFE 100 kg from ≈ 200 mm, a power cycle with
/// a car on the lift): over those ticks its mean error is under half the prior's (what is left
/// is the rotor's overshoot after the ramp, docs/model.md).
#[test]
fn a_fresh_board_lowering_a_light_car_reports_t_r_from_the_current_before_evidence() {
    // Lowering, b_d's error is worth 1.5 kg per mA here.
    let s = commissioned(Lubricant::Ptfe, 100.0, 25.9, 2.2);
    let log = std::sync::Arc::new(std::sync::Mutex::new(Vec::<(f64, bool, f64, f64)>::new()));
    let inner = std::sync::Arc::clone(&log);
    let r = lowering(&s, 25.9, 4.0, 0.02, move |k| {
        let c = &k.controller;
        let st = c.status();
        inner.lock().unwrap().push((
            k.t,
            st.load.identified,
            st.friction_torque.to_f64(),
            c.estimate().friction_torque.to_f64(),
        ));
    });
    assert!(faults(&r).is_empty(), "{:?}", faults(&r));
    let log = log.lock().unwrap();
    let plant = |t: f64| plant_friction_at(&r, t);
    let pre: Vec<_> = log.iter().filter(|x| !x.1).collect();
    assert!(
        pre.len() >= 20,
        "{} ticks before the first evidence",
        pre.len()
    );
    let n = pre.len() as f64;
    let err: f64 = pre.iter().map(|x| x.2 - plant(x.0)).sum::<f64>() / n;
    let prior: f64 = pre.iter().map(|x| x.3 - plant(x.0)).sum::<f64>() / n;
    assert!(prior.abs() > 1.5, "the prior's error {prior}");
    assert!(err.abs() < prior.abs() / 2.0, "{err} (prior {prior})");
}

/// A lift 6 mm up from `deg` (the command at 20 ms) in `s`, and the status's (t, load, T_r) on
/// every tick at the 3 rad/s cruise.
fn lift_6mm(s: &Scenario, deg: f64) -> (Run, Vec<(f64, f64, f64)>) {
    let g = host_sim::physics::Geometry::paper();
    let h = g.height(deg.to_radians()) + 6.0e-3;
    let log = std::sync::Arc::new(std::sync::Mutex::new(Vec::<(f64, f64, f64)>::new()));
    let inner = std::sync::Arc::clone(&log);
    let r = run(
        s,
        Box::new(move |k: &mut Tick<'_>| {
            if (k.t - 0.02).abs() < 5e-4 {
                k.controller
                    .command(Command::GoTo(Metres::from_f64(h)))
                    .unwrap();
            }
            let c = &k.controller;
            if (c.reference().to_f64() - 3.0).abs() < 1e-3 {
                let st = c.status();
                inner.lock().unwrap().push((
                    k.t,
                    st.load.load.to_f64(),
                    st.friction_torque.to_f64(),
                ));
            }
        }),
    );
    let log = std::mem::take(&mut *log.lock().unwrap());
    (r, log)
}

/// A dry thread stick-slipping under a rated car (1000 kg from ≈ 200 mm): the mean torque reads
/// a lighter car (≈ 0.7 of it) and a lower friction; from the breakaways (`ident::stick`) the
/// status gives the load within 3 % once the stick-slip is established, and the mean T_r over
/// those ticks within 3 % of the plant's.
#[test]
fn a_stick_slipping_lift_reports_its_load_and_mean_t_r_from_the_breakaways() {
    let s = commissioned(Lubricant::Dry, 1000.0, 25.9, 2.0);
    let (r, log) = lift_6mm(&s, 25.9);
    assert!(faults(&r).is_empty(), "{:?}", faults(&r));
    let log: Vec<_> = log.into_iter().filter(|x| x.0 > 0.6).collect();
    assert!(log.len() > 500, "{} ticks", log.len());
    let plant = |t: f64| plant_friction_at(&r, t);
    for &(t, load, _) in log.iter() {
        assert!((load - 1000.0).abs() <= 30.0, "{load} kg at {t:.3} s");
    }
    let n = log.len() as f64;
    let core: f64 = log.iter().map(|x| x.2).sum::<f64>() / n;
    let truth: f64 = log.iter().map(|x| plant(x.0)).sum::<f64>() / n;
    assert!(
        (core - truth).abs() <= 0.03 * truth,
        "T_r {core} vs {truth}"
    );
    // And tick by tick: the sticks last tens of ticks, the current follows each wind-up, and
    // the status's T_r with it (the stuck thread's at the torque measured now, low-passed:
    // ≈ 8 ticks behind). A constant at the mean has no spread and no correlation.
    let p: Vec<f64> = log.iter().map(|x| plant(x.0)).collect();
    let c: Vec<f64> = log.iter().map(|x| x.2).collect();
    let sd = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len() as f64).sqrt()
    };
    let corr = |lag: usize| {
        let (a, b) = (&p[..p.len() - lag], &c[lag..]);
        let (ma, mb) = (
            a.iter().sum::<f64>() / a.len() as f64,
            b.iter().sum::<f64>() / b.len() as f64,
        );
        let cov = a
            .iter()
            .zip(b)
            .map(|(x, y)| (x - ma) * (y - mb))
            .sum::<f64>()
            / a.len() as f64;
        cov / (sd(a) * sd(b))
    };
    let (lag, best) =
        (0..20)
            .map(|l| (l, corr(l)))
            .fold((0, f64::MIN), |a, b| if b.1 > a.1 { b } else { a });
    eprintln!(
        "T_r per tick: spread {:.3} (plant {:.3}) N·m, correlation {best:.3} at {lag} ticks",
        sd(&c),
        sd(&p)
    );
    assert!(sd(&p) > 0.1 * truth, "no wind-up to follow: {}", sd(&p));
    assert!(
        sd(&c) > 0.5 * sd(&p),
        "the status's T_r does not follow the wind-up: {}",
        sd(&c)
    );
    assert!(best > 0.8, "correlation {best} at {lag} ticks");
}

/// A dry lift whose stick-slip cycles are short (600 kg from 30°, between `host-sim
/// estimate`'s heights: the thread breaks away every ≈ 25 ms). The speed loop still answers each
/// slip when the next breakaway comes, and the rotor, slowing, hides its deceleration torque in
/// the current; the detector's torque has the drive's acceleration torque taken out lifting
/// (`Controller::detect_stick_slip`), so its peaks are the coupling's: the load within 3 % from
/// 0.5 s of cruise (5 kg off). Before: the breakaways read the car 33 kg (5.5 %) light
/// (`host-sim estimate`: 700 kg from 260 mm 33 kg light; 500 kg from 200 mm refused, its
/// fall under half the span, and the mean torque's load 21 % light).
#[test]
fn a_fast_stick_slipping_lift_reads_its_breakaways_without_the_rotor_s_deceleration() {
    // The premise: breakaways (stick → slip) every 20…35 ms over the cruise.
    let (_, _, _, worst) = dry_lift(600.0, 30.0, 0.020..0.035);
    assert!(worst <= 18.0, "load {worst:.1} kg off");
}

/// A breakaway beyond the current limit (dry, 1300 kg from 150 mm, α ≈ 17.5°: the coupling
/// reaches ≈ 85 N·m, the 40 A limit gives 82.3): the current stands flat at the limit while the
/// rotor winds the coupling on, and the detector's peaks are clipped. The wind-up past the limit
/// (k_c times the encoder's travel, `control::clip`) is added back: the load within 3 % from
/// 0.5 s of cruise. Before: 48 kg light.
#[test]
fn a_breakaway_the_current_limit_clipped_is_read_with_the_wind_up_past_it() {
    let g = host_sim::physics::Geometry::paper();
    let deg = ((0.150 - g.h0) / g.length).asin().to_degrees();
    let mut s = commissioned(Lubricant::Dry, 1300.0, deg, 2.0);
    s.seed = 2;
    let (r, log) = lift_6mm(&s, deg);
    assert!(faults(&r).is_empty(), "{:?}", faults(&r));
    // The case is a clipped one: the current reached the limit.
    let limit = default_current_limit();
    assert!(
        r.peak_current() >= limit * 15.0 / 16.0,
        "{} A",
        r.peak_current()
    );
    let from = log.first().map_or(f64::INFINITY, |x| x.0) + 0.5;
    let log: Vec<_> = log.into_iter().filter(|x| x.0 >= from).collect();
    assert!(log.len() > 500, "{} ticks", log.len());
    for &(t, load, _) in log.iter() {
        assert!((load - 1300.0).abs() <= 39.0, "{load} kg at {t:.3} s");
    }
}

/// A fault during a stick-slipping lift names the load the status reported, the breakaways'
/// (the mean torque reads such a car ≈ 30 % light): dry 1000 kg from ≈ 200 mm, the supply sags
/// to 8 V at 1.2 s and the under-voltage monitor stops the lift. Before: the snapshot said the
/// mean torque's load (a dry 1300 kg lift from 145 mm tripped overload with load=935 kg).
#[test]
fn a_fault_during_a_stick_slipping_lift_names_the_breakaways_load() {
    let mut s = commissioned(Lubricant::Dry, 1000.0, 25.9, 2.0);
    s.faults = host_sim::inject::Plan::new(
        &host_sim::inject::parse_list("supply-sag@1.2:8+0.5").expect("a valid fault"),
    )
    .expect("a valid plan");
    let (r, _) = lift_6mm(&s, 25.9);
    let (t, f) = r.first_fault().expect("the sag stops the lift");
    assert_eq!(f.kind, FaultKind::UnderVoltage, "at {t:.3} s: {f:?}");
    assert_eq!(f.state, liftfw::control::State::Lifting, "{f:?}");
    assert!(f.load_identified, "{f:?}");
    let load = f.load.to_f64();
    assert!((load - 1000.0).abs() <= 30.0, "{load} kg at {t:.3} s");
}

#[test]
fn an_amplifier_offset_present_at_boot_is_measured_at_rest_and_leaves_the_load_unbiased() {
    // The current-sense amplifier reads 0.1 A (3.1 codes) more than flows from power-up on
    // (its offset drifted from the commissioned `sense.current_zero`): ≈ 0.2 N·m at the screw,
    // several hundred kg of a PTFE lowering's load. The board rests 0.7 s before the
    // command, measures the zero (`control::sense`), and the lowering's load is right.
    let load = 500.0;
    let mut s = commissioned(Lubricant::Ptfe, load, 30.0, 3.2);
    s.seed = 4;
    s.faults = host_sim::inject::Plan::new(
        &host_sim::inject::parse_list("current-offset@0:0.1").expect("a valid fault"),
    )
    .expect("a valid plan");
    let mut cruise_at: Option<f64> = None;
    let worst = std::sync::Arc::new(std::sync::Mutex::new((0.0f64, 0u32)));
    let seen = std::sync::Arc::clone(&worst);
    let r = lowering(&s, 30.0, 3.5, 0.7, move |k| {
        let t0 = *cruise_at.get_or_insert(k.t);
        if k.t >= t0 + 0.5 {
            let l = k.controller.status().load;
            assert!(l.identified, "{l:?}");
            let mut w = seen.lock().unwrap();
            *w = (w.0.max((l.load.to_f64() - load).abs()), w.1 + 1);
        }
    });
    assert!(faults(&r).is_empty(), "{:?}", faults(&r));
    let (worst, checked) = *worst.lock().unwrap();
    assert!(
        checked > 100,
        "{checked} ticks from 0.5 s of cruise checked"
    );
    println!("PTFE {load} kg lowering, +0.1 A offset: worst load error {worst:.1} kg");
    // The goal of `host-sim estimate`: 3 % of the load or the load whose torque is 0.05 N·m
    // (≈ 130 kg for a PTFE lowering at 30°); without the zero measured at rest it reads
    // 306 kg off (measured on main f1262f0).
    assert!(worst <= 0.1 * load, "{worst:.1} kg");
}

#[test]
fn an_empty_lift_lowering_reads_an_empty_head() {
    // A light lowering's torque is V-shaped in the load (docs/model.md "An empty head"): an
    // empty head carries on the thread's other flank, and the loaded flank's reading of the
    // same torque is tens of kg (PTFE at 30°: ≈ 30 kg). The status reports the near branch.
    for lub in [Lubricant::Ptfe, Lubricant::Lithium, Lubricant::Dry] {
        let mut s = commissioned(lub, 0.0, 30.0, 3.0);
        s.seed = 5;
        let last = std::sync::Arc::new(std::sync::Mutex::new(None));
        let seen = std::sync::Arc::clone(&last);
        let r = lowering(&s, 30.0, 3.5, 0.7, move |k| {
            let st = k.controller.status();
            *seen.lock().unwrap() = Some((k.t, st.load, st.friction_torque));
        });
        assert!(faults(&r).is_empty(), "{lub:?}: {:?}", faults(&r));
        let (t, l, tr) = last.lock().unwrap().expect("a cruise");
        let plant = plant_friction_at(&r, t);
        println!(
            "{lub:?} empty lowering: {:.1} kg at {t:.3} s, T_r {:.4} N·m (plant {plant:.4})",
            l.load.to_f64(),
            tr.to_f64()
        );
        assert!(l.load.to_f64() <= 10.0, "{lub:?}: {l:?}");
        // The goal's floor for a tiny torque: 0.05 N·m.
        assert!(
            (tr.to_f64() - plant).abs() <= 0.05,
            "{lub:?}: {tr:?} vs {plant}"
        );
    }
}

/// A dry thread stick-slips lowering: its mean torque is below the law's sliding torque (the
/// stick phases mobilise the static friction in part, the slips run where μ is lower), and
/// read with the law it gave the car too light. The lowering after the lift creeps to weigh
/// the car by its breakaways and holds that load (`LoadIdent::hold_start`); at rest the lift's
/// breakaways and the creep's make a pair, which finds the thread as configured and the car.
#[test]
fn a_stick_slipping_lowering_keeps_the_load_its_lift_identified() {
    use std::sync::{Arc, Mutex};
    let load = 700.0;
    let mut s = commissioned(Lubricant::Dry, load, 20.0, 5.0);
    s.seed = 5;
    // (t, lowering, load, stick-slip flag) at the cruise reference.
    let log = Arc::new(Mutex::new(Vec::<(f64, bool, f64, bool)>::new()));
    let sink = Arc::clone(&log);
    let r = lift_then_lower(&s, 20.0, 4.0, move |k: &mut Tick<'_>| {
        if (k.controller.reference().to_f64().abs() - 3.0).abs() < 1e-3 {
            let st = k.controller.status();
            let lowering = k.controller.state() == liftfw::control::State::Lowering;
            sink.lock()
                .unwrap()
                .push((k.t, lowering, st.load.load.to_f64(), st.stick_slip));
        }
    });
    assert!(faults(&r).is_empty(), "{:?}", faults(&r));
    let log = log.lock().unwrap().clone();
    let lift: Vec<_> = log.iter().filter(|x| !x.1).collect();
    let lower: Vec<_> = log.iter().filter(|x| x.1).collect();
    assert!(
        lift.len() > 800 && lower.len() > 800,
        "{} {}",
        lift.len(),
        lower.len()
    );
    let lifted = lift.last().unwrap().2;
    // Dry lifting at 250…700 kg reads 14…42 kg off (docs/control.md, known limits).
    assert!((lifted - load).abs() < 50.0, "lift {lifted} kg");
    assert!(lower.iter().any(|x| x.3), "the lowering did not stick-slip");
    let t0 = lower[0].0;
    let worst = lower
        .iter()
        .filter(|x| x.0 >= t0 + 0.5)
        .map(|x| (x.2 - lifted).abs())
        .fold(0.0, f64::max);
    // Measured: the lift 710 kg, the lowering flagged 0.23 s into its cruise and 710 kg from
    // then on (before: 487 kg, the lift's samples' mean, and the lowering's own reading).
    assert!(
        worst < 0.03 * load,
        "lowering {worst} kg off the lift's {lifted}"
    );
    // At rest after the lowering: the breakaway pair (measured: scale 0.986, 707.6 kg).
    let rest = r.controller.status().load;
    assert!(
        rest.identified
            && rest.scale_known
            && rest.pairs == 1
            && (rest.scale.to_f64() - 1.0).abs() < 0.05
            && (rest.load.to_f64() - load).abs() < 0.03 * load,
        "{rest:?}"
    );
}

/// A car the drive cannot break away: 1300 kg on a thread twice as dry as configured (lithium
/// and dry, ≈ 26°). The speed loop holds the current at its limit (the back-EMF bound alone
/// rang ±5 A about it and tripped over-current 0.2 s in), the rotor winds the coupling up and
/// slows to a creep, and a protection stops the lift: the torque monitor (the torque beyond
/// the model at the load the board knows) or the stall protection. The screw never moved, so
/// the board weighed nothing: the fault names the prior and says so (`load_identified`), or a
/// load read from the torque (heavier than the car).
#[test]
fn a_screw_that_will_not_break_away_stops_at_the_current_limit_without_over_current() {
    for lub in [Lubricant::Lithium, Lubricant::Dry] {
        let mut s = commissioned(lub, 1300.0, 25.9, 1.5);
        s.thread_friction_factor = 2.0;
        let r = moves(s, vec![3.0], false);
        let f = faults(&r);
        assert!(
            matches!(
                f.first().map(|x| x.1),
                Some(FaultKind::Stall | FaultKind::Overload)
            ),
            "{lub:?}: {f:?}"
        );
        // Measured: the torque monitor's overload 0.51 s after the command (lithium and dry);
        // a stall took the rotor's run-down and stall_ms (300 ms) of creeping, 0.52…0.59 s.
        let t = f[0].0 - 0.02;
        assert!(t <= 0.8, "{lub:?}: stopped after {t:.3} s");
        let worst = r.peak_current();
        let limit = default_current_limit();
        eprintln!(
            "{lub:?}: stall at {t:.3} s, worst current {worst:.2} A, load {:?}",
            r.controller.fault().unwrap().load
        );
        assert!(
            worst < limit + 2.0,
            "{lub:?}: {worst:.2} A against the {limit} A limit"
        );
        let fault = r.controller.fault().unwrap();
        assert!(
            if fault.load_identified {
                fault.load.to_f64() > 1300.0
            } else {
                fault.load == ControlConfig::DEFAULT.rated_load
            },
            "{lub:?}: {fault:?}"
        );
    }
}

/// The default current limit, amperes.
fn default_current_limit() -> f64 {
    liftfw::control::config::ProtectionConfig::DEFAULT
        .current_limit
        .to_f64()
}

/// A fresh board (the car unknown: the prior at boot) lowers a dry thread 5 mm from `deg`,
/// commanded at 0.6 s: whether it crept at 0.3 rad/s, and (t, load, T_r) of its status at every
/// tick at the −3 rad/s cruise.
fn fresh_dry_lowering(
    load: f64,
    deg: f64,
    seed: u64,
    secs: f64,
) -> (Run, bool, Vec<(f64, f64, f64)>) {
    use std::sync::{Arc, Mutex};
    let mut s = commissioned(Lubricant::Dry, load, deg, secs);
    s.seed = seed;
    let crept = Arc::new(Mutex::new(false));
    let seen = Arc::clone(&crept);
    let g = host_sim::physics::Geometry::paper();
    let h = g.height(deg.to_radians()) - 5e-3;
    let log = Arc::new(Mutex::new(Vec::<(f64, f64, f64)>::new()));
    let sink = Arc::clone(&log);
    let r = run(
        &s,
        Box::new(move |k: &mut Tick<'_>| {
            if (k.t - 0.6).abs() < 5e-4 {
                k.controller
                    .command(Command::GoTo(Metres::from_f64(h)))
                    .unwrap();
            }
            let w = k.controller.reference().to_f64();
            if (w + 0.3).abs() < 1e-3 {
                *seen.lock().unwrap() = true;
            }
            if (w + 3.0).abs() < 1e-3 {
                let st = k.controller.status();
                sink.lock().unwrap().push((
                    k.t,
                    st.load.load.to_f64(),
                    st.friction_torque.to_f64(),
                ));
            }
        }),
    );
    let crept = *crept.lock().unwrap();
    let log = log.lock().unwrap().clone();
    (r, crept, log)
}

/// The worst load error from 0.5 s of cruise in a `fresh_dry_lowering` log.
fn worst_from_half_a_second(log: &[(f64, f64, f64)], load: f64) -> f64 {
    let t0 = log[0].0;
    log.iter()
        .filter(|x| x.0 >= t0 + 0.5)
        .map(|x| (x.1 - load).abs())
        .fold(0.0, f64::max)
}

/// A fresh board lowering a dry thread creeps at 0.3 rad/s until two breakaways have weighed
/// the car, then cruises at that load (`control::creep`): the load from 0.5 s of cruise within
/// 3 %, and the cruise's mean T_r (the stuck thread's mean over the wind-up,
/// `ident::stick::StuckLowering::friction`) within 3 % of the plant's mean over stick and slip.
/// A pose and a car outside `host-sim estimate`'s matrix (900 kg from 22°, its own seed).
/// Before the creep the status said the prior's 1000 kg through the cruise.
#[test]
fn a_fresh_board_lowering_a_dry_thread_weighs_the_car_while_it_creeps() {
    let load = 900.0;
    let (r, crept, log) = fresh_dry_lowering(load, 22.0, 11, 2.6);
    assert!(faults(&r).is_empty(), "{:?}", faults(&r));
    assert!(crept, "the lowering did not creep");
    assert!(log.len() > 1000, "{} cruise ticks", log.len());
    let worst = worst_from_half_a_second(&log, load);
    let (core, plant) = tr_means(&r, &log);
    eprintln!("load worst {worst:.1} kg off; T_r mean {core:.3} against the plant's {plant:.3}");
    assert!(worst < 0.03 * load, "load {worst} kg off");
    assert!(
        (core - plant).abs() < 0.03 * plant.abs(),
        "T_r {core:.3} against {plant:.3}"
    );
}

/// Low on the stroke a dry thread does not self-lock while it slides fast: after the creep's
/// first breakaway the screw runs ahead and the coupling swings through zero, which the
/// detector counted as a second "breakaway" of −7 N·m after one of 12 (host-sim estimate, dry
/// 1300 kg from 150 mm: the creep read 992 kg). A later peak is taken only within a quarter of
/// the first. 1250 kg from 17° (its own seed): the load within 3 % from 0.5 s of cruise.
#[test]
fn a_creep_low_on_the_stroke_ignores_the_coupling_s_swing_after_a_slip() {
    let load = 1250.0;
    let (r, crept, log) = fresh_dry_lowering(load, 17.0, 13, 2.0);
    assert!(faults(&r).is_empty(), "{:?}", faults(&r));
    assert!(
        crept && log.len() > 500,
        "crept {crept}, {} cruise ticks",
        log.len()
    );
    let worst = worst_from_half_a_second(&log, load);
    // The first 120 ms of cruise, before the held lowering's first sample: the stuck thread's
    // T_r at the low-passed measured torque. The sliding model at the weighed load had stood
    // there, 55 % heavy this low (here −13.3 against −8.6 N·m; now −9.3: the wind-ups' mean
    // is read from a torque that swings through zero, docs/model.md).
    let (core, plant) = tr_means(&r, &log[..120]);
    eprintln!(
        "load worst {worst:.1} kg off; T_r over the first 120 ms {core:.3} against {plant:.3}"
    );
    assert!(worst < 0.03 * load, "load {worst} kg off");
    assert!(
        (core - plant).abs() < 0.2 * plant.abs(),
        "T_r over the first 120 ms {core:.3} against {plant:.3}"
    );
}

/// An overloaded dry lowering after power-up (the car unknown, the thread's scale restored from
/// the store, as after any pair) is refused by its weighing creep: 1.6× rated from 24° (its own
/// seed), the overload within 0.5 s of the command, before the head came down 0.1 mm, the
/// fault naming the creep's load within 5 %; and 1.15× rated (below the 1.25× limit) on the
/// same thread is not refused. (A board that never measured its thread takes the driest it
/// still assumes, 2× the law: a dry lowering's reading then trips only beyond ≈ 3× rated.)
#[test]
fn a_lowering_of_an_unknown_dry_car_is_refused_while_it_creeps() {
    for (load, trips) in [(1600.0, true), (1150.0, false)] {
        let mut s = commissioned(Lubricant::Dry, load, 24.0, 1.2);
        s.seed = 12;
        let g = host_sim::physics::Geometry::paper();
        let h0 = g.height(24f64.to_radians());
        let h = h0 - 5e-3;
        let r = run(
            &s,
            Box::new(move |k: &mut Tick<'_>| {
                if k.t < 5e-4 {
                    k.controller.restore_friction_scale(Ratio::ONE);
                }
                if (k.t - 0.6).abs() < 5e-4 {
                    k.controller
                        .command(Command::GoTo(Metres::from_f64(h)))
                        .unwrap();
                }
            }),
        );
        let f = faults(&r);
        if !trips {
            assert!(f.is_empty(), "{load} kg: {f:?}");
            continue;
        }
        assert_eq!(f.first().map(|x| x.1), Some(FaultKind::Overload), "{f:?}");
        let t = f[0].0 - 0.6;
        assert!(t <= 0.5, "refused {t:.3} s after the command");
        let i = r.trace.records.partition_point(|x| x.t < f[0].0);
        let height = g.height(r.trace.records[i].alpha_deg.to_radians());
        assert!(
            h0 - height < 1e-4,
            "came down {:.3} mm",
            (h0 - height) * 1e3
        );
        let fault = r.controller.fault().unwrap();
        assert!(fault.load_identified, "the prior tripped");
        eprintln!("refused after {t:.3} s at {:.1} kg", fault.load.to_f64());
        assert!(
            (fault.load.to_f64() - load).abs() < 0.05 * load,
            "{:?}",
            fault.load
        );
    }
}

/// A lowering right after a heavy lift: the coupling still holds the lift's twist, which the
/// board keeps at rest (the encoder less it is the screw). The lowering's reference began at
/// the encoder, a twist ahead of the screw, and the position term then drove the motor *up*:
/// at the weighing creep's 0.3 rad/s it wound the coupling on to 78 N·m (dry 700 kg, thread
/// twice as dry as configured: 81 counts up before the screw broke away downwards). Now the
/// motor turns down from the start.
#[test]
fn a_lowering_after_a_lift_never_drives_the_motor_up() {
    use std::sync::{Arc, Mutex};
    for (factor, load) in [(2.0, 700.0), (1.5, 1000.0)] {
        let mut s = commissioned(Lubricant::Dry, load, 20.0, 4.0);
        s.thread_friction_factor = factor;
        // (the encoder when the lowering began, its largest rise since, whether it crept)
        let up = Arc::new(Mutex::new((None::<i32>, 0i32, false)));
        let seen = Arc::clone(&up);
        let r = lift_then_lower(&s, 20.0, 3.0, move |k: &mut Tick<'_>| {
            if k.controller.state() == liftfw::control::State::Lowering {
                let mut g = seen.lock().unwrap();
                let p = k.controller.position_counts();
                let start = *g.0.get_or_insert(p);
                g.1 = g.1.max(p - start);
                g.2 |= k.controller.reference().to_f64().abs() < 0.31;
            }
        });
        assert!(
            faults(&r).is_empty(),
            "{factor}×, {load} kg: {:?}",
            faults(&r)
        );
        let (start, rise, crept) = *up.lock().unwrap();
        assert!(
            start.is_some() && crept,
            "{factor}×, {load} kg: no creeping lowering"
        );
        eprintln!("{factor}× drier, {load} kg: the encoder rose {rise} counts while lowering");
        assert!(
            rise <= 4,
            "{factor}×, {load} kg: the motor turned {rise} counts up"
        );
    }
}

/// A car whose lift stick-slipped is lifted again (dry 1000 kg from 20°, the thread 1.5× drier
/// than configured: lift, lower, lift; the lowering's creep pairs its breakaways with the
/// lift's and the law takes the scale): the second lift's status reads T_r on the stuck thread
/// from its start, at the kept load and the torque measured now (`control::loadid`,
/// `stick_slip_lift`), not the sliding model's until its own breakaways: its cruise-mean T_r
/// within 3 % of the plant's, and within 10 % over its first 0.2 s.
#[test]
fn a_stick_slipping_car_lifted_again_reads_t_r_on_the_stuck_thread_from_the_start() {
    let mut s = commissioned(Lubricant::Dry, 1000.0, 20.0, 7.0);
    s.thread_friction_factor = 1.5;
    let log = std::sync::Arc::new(std::sync::Mutex::new(Vec::<(usize, f64, f64)>::new()));
    let inner = std::sync::Arc::clone(&log);
    let r = goto_from(&s, 20.0, vec![3.0, 0.0, 3.0], 0.02, move |k, motion| {
        if (k.controller.reference().to_f64() - 3.0).abs() < 1e-3 {
            let tr = k.controller.status().friction_torque.to_f64();
            inner.lock().unwrap().push((motion, k.t, tr));
        }
    });
    assert!(faults(&r).is_empty(), "{:?}", faults(&r));
    assert!(r.controller.status().load.scale_known, "no pair");
    let log = std::mem::take(&mut *log.lock().unwrap());
    for lift in [1usize, 3] {
        // As (t, load, T_r) ticks for `tr_means` (the load is not read here).
        let l: Vec<_> = log
            .iter()
            .filter(|x| x.0 == lift)
            .map(|x| (x.1, 0.0, x.2))
            .collect();
        assert!(l.len() > 500, "lift {lift}: {} cruise ticks", l.len());
        let (core, plant) = tr_means(&r, &l);
        let t0 = l[0].0;
        let early: Vec<_> = l.iter().copied().filter(|x| x.0 < t0 + 0.2).collect();
        let (core_early, plant_early) = tr_means(&r, &early);
        eprintln!(
            "lift {lift}: T_r {core:.3} vs {plant:.3} N·m; first 0.2 s {core_early:.3} vs {plant_early:.3}"
        );
        if lift == 3 {
            assert!((core - plant).abs() <= 0.03 * plant, "{core} vs {plant}");
            assert!(
                (core_early - plant_early).abs() <= 0.1 * plant_early,
                "first 0.2 s: {core_early} vs {plant_early}"
            );
        }
    }
}

/// A dry lift whose stick-slip is too fast for the current to resolve its breakaways (450 kg
/// from 34°: every ≈ 7 ms, falls of ≈ 3.4 N·m; a pose and load outside `host-sim estimate`'s
/// matrix): the breakaway from the cycle's period (`ident::stick::periodic_breakaway`, the
/// detector's `Periodicity::period_q8`) gives the load within 3 % from 0.5 s of cruise (1.7 kg
/// off), and keeps it at rest after the lift. Before: the mean torque's load, its slips'
/// friction at tens of rad/s on the law's falling branch, 30 kg (6.7 %) light.
#[test]
fn a_fast_stick_slipping_lift_is_weighed_by_its_period() {
    let (r, log, _, worst) = dry_lift(450.0, 34.0, 0.005..0.016);
    let (core, plant) = tr_means(&r, &log);
    assert!(worst <= 13.5, "load {worst:.1} kg off");
    assert!(
        (core - plant).abs() <= 0.03 * plant,
        "T_r {core} vs {plant}"
    );
    // And kept at rest after the lift (the next motion's start).
    let kept = r.controller.status().load;
    assert!(
        kept.identified && (kept.load.to_f64() - 450.0).abs() <= 13.5,
        "{kept:?}"
    );
}

/// A dry lift of `load` kg 6 mm up from `deg`° (`lift_6mm`, commissioned), without a fault
/// and with the plant's breakaways over the cruise every `cycles` s (the premise): the run, its
/// cruise log (t, load, T_r), the cycle (s) and the load's worst error from 0.5 s of cruise
/// (kg).
fn dry_lift(
    load: f64,
    deg: f64,
    cycles: std::ops::Range<f64>,
) -> (Run, Vec<(f64, f64, f64)>, f64, f64) {
    let s = commissioned(Lubricant::Dry, load, deg, 2.0);
    let (r, log) = lift_6mm(&s, deg);
    assert!(faults(&r).is_empty(), "{load} kg, {deg}°: {:?}", faults(&r));
    let cycle = breakaway_cycle(&r, log[0].0);
    let worst = worst_from_half_a_second(&log, load);
    eprintln!(
        "{load} kg, {deg}°: cycle {:.1} ms, load worst from 0.5 s {worst:.1} kg",
        cycle * 1e3
    );
    assert!(cycles.contains(&cycle), "cycle {:.1} ms", cycle * 1e3);
    (r, log, cycle, worst)
}

/// The mean interval between the plant's breakaways (stick → slip) after `t0`, s.
fn breakaway_cycle(r: &Run, t0: f64) -> f64 {
    let starts: Vec<f64> = r
        .trace
        .phases
        .windows(2)
        .filter(|w| w[0].phase == Phase::Stick && w[1].phase != Phase::Stick && w[1].t > t0)
        .map(|w| w[1].t)
        .collect();
    if starts.len() < 3 {
        return 0.0;
    }
    (starts[starts.len() - 1] - starts[0]) / (starts.len() - 1) as f64
}

/// Dry lifts of 150…650 kg from 18…42° (48 runs, none of `host-sim estimate`'s: held out
/// from what the breakaway readings were built on), each its breakaway cycle, its load's worst
/// error from 0.5 s of cruise and its cruise-mean T_r against the plant's (BENCHMARKS.md;
/// `-- --nocapture` prints the table). Holds the count that met the load's 3 % when measured:
/// 40 of 48 (24 before the fast cycles were read by their period); T_r within 3 % in all 48.
#[test]
fn dry_lifts_over_poses_and_loads() {
    let (mut met, mut tr_met) = (0, 0);
    for deg in [18.0f64, 21.0, 24.0, 28.0, 31.0, 34.0, 38.0, 42.0] {
        for load in [150.0f64, 250.0, 350.0, 450.0, 550.0, 650.0] {
            let (r, log, cycle, worst) = dry_lift(load, deg, 0.0..1.0);
            let (core, plant) = tr_means(&r, &log);
            met += usize::from(worst <= 0.03 * load);
            tr_met += usize::from((core - plant).abs() <= 0.03 * plant.abs());
            println!(
                "{deg}° {load} kg: cycle {:.1} ms, load worst {worst:.1} kg ({:.1} %), T_r {:+.2} %",
                cycle * 1e3,
                100.0 * worst / load,
                100.0 * (core / plant - 1.0)
            );
        }
    }
    println!("load within 3 % from 0.5 s of cruise: {met} of 48, T_r within 3 %: {tr_met} of 48");
    assert!(met >= 40, "{met} of 48");
    assert_eq!(tr_met, 48);
}

/// (t, T_r, its stated range's ends) of the status at every tick at the −3 rad/s cruise of
/// motion `motion` (1, 2, …) of `goto_from(s, deg, mm)`.
fn range_log(s: &Scenario, deg: f64, mm: Vec<f64>, motion: usize) -> (Run, Vec<[f64; 4]>) {
    use std::sync::{Arc, Mutex};
    let log = Arc::new(Mutex::new(Vec::new()));
    let sink = Arc::clone(&log);
    let r = goto_from(s, deg, mm, 0.7, move |k, n| {
        if n == motion && (k.controller.reference().to_f64().abs() - 3.0).abs() < 1e-3 {
            let st = k.controller.status();
            let (lo, hi) = st.friction_torque_range;
            sink.lock()
                .unwrap()
                .push([k.t, st.friction_torque.to_f64(), lo.to_f64(), hi.to_f64()]);
        }
    });
    let log = log.lock().unwrap().clone();
    (r, log)
}

/// The cruise means of a `range_log`: the core's T_r, its range's ends, the plant's T_r.
fn range_means(r: &Run, log: &[[f64; 4]]) -> [f64; 4] {
    let n = log.len().max(1) as f64;
    let mean = |i: usize| log.iter().map(|x| x[i]).sum::<f64>() / n;
    let plant = log.iter().map(|x| plant_friction_at(r, x[0])).sum::<f64>() / n;
    [mean(1), mean(2), mean(3), plant]
}

/// A lowering the creep weighed by its breakaways on a thread 1.5× drier than configured,
/// before the lift/lowering pair has told the board so: its T_r is the stuck thread's at the
/// load the breakaways give at the configured law (heavy, as the thread is drier), and the
/// stated range must hold the plant's T_r over the cruise. It now spans the stuck thread's
/// reading at the scale band's ends (`Controller::friction_range`). A pose and car outside
/// `host-sim estimate`'s matrix (900 kg from 22°, its own seed; commanded after the boot's
/// rest). Measured: the plant's −6.77 N·m in −12.04…−5.74 (the core's −9.61); the sliding
/// model's factors had stated −10.86…−8.01.
#[test]
fn a_stuck_lowering_on_a_drier_thread_states_a_t_r_range_that_holds_the_plant_s() {
    let mut s = commissioned(Lubricant::Dry, 900.0, 22.0, 4.5);
    s.thread_friction_factor = 1.5;
    s.seed = 21;
    let (r, log) = range_log(&s, 22.0, vec![3.0, 0.0], 2);
    assert!(faults(&r).is_empty(), "{:?}", faults(&r));
    assert!(log.len() > 1000, "{} cruise ticks", log.len());
    let [core, lo, hi, plant] = range_means(&r, &log);
    eprintln!("T_r {core:.3} in {lo:.3}…{hi:.3}, the plant's {plant:.3}");
    assert!(
        lo <= plant && plant <= hi,
        "{plant:.3} outside {lo:.3}…{hi:.3}"
    );
}

/// A fresh board lowering a dry thread whose creep counted no breakaway (its falls under the
/// detector's threshold: light cars, high poses) slides on the configured law's model at the
/// load the mean torque gives, while the thread stands most of the time in cycles too short
/// for the current (host-sim, dry 700 kg from 260 mm: T_r −2.13 N·m, the plant's −2.93). The
/// stated range must still hold the plant's T_r: it also holds the stuck thread's reading at
/// the load interval's heaviest end. Four poses and cars outside `host-sim estimate`'s matrix.
/// Measured (the plant's in the range): 600 kg from 36° −2.36 in −3.36…−1.30 (the sliding
/// range had been −2.06…−1.30), 650 kg from 33° −3.05 in −4.14…−1.69, 450 kg from 38° −1.53 in
/// −2.41…−0.84, 300 kg from 28° −1.80 in −2.97…−1.04.
#[test]
fn a_dry_lowering_its_creep_did_not_weigh_states_a_t_r_range_that_holds_the_plant_s() {
    for (deg, load) in [(36.0, 600.0), (33.0, 650.0), (38.0, 450.0), (28.0, 300.0)] {
        let mut s = commissioned(Lubricant::Dry, load, deg, 3.0);
        s.seed = 23;
        let (r, log) = range_log(&s, deg, vec![-2.0], 1);
        assert!(faults(&r).is_empty(), "{:?}", faults(&r));
        assert!(log.len() > 500, "{} cruise ticks", log.len());
        let [core, lo, hi, plant] = range_means(&r, &log);
        eprintln!(
            "{load} kg from {deg}°: T_r {core:.3} in {lo:.3}…{hi:.3}, the plant's {plant:.3}"
        );
        assert!(
            lo <= plant && plant <= hi,
            "{load} kg from {deg}°: {plant:.3} outside {lo:.3}…{hi:.3}"
        );
    }
}

/// A mis-set coupling stiffness (`mech.coupling_stiffness`, the board's; host-sim's coupling
/// stays 160 N·m/rad), a commissioning error the board cannot check: a fast stick-slipping
/// lift is weighed by its period, P = T̄ + k_c·ω·(T − t_s)/2 (docs/model.md "Fast stick-slip
/// lifting"), so its load is off by the setting's error times the fall's share of P (≈ 11 %
/// here). The lift must still end where it was sent, with no fault (the overload trip reads
/// the mean torque's load, not this). 450 kg from 34° (7.1 ms cycles). Measured, the load at
/// the cruise's end (its worst from 0.5 s of cruise) at 0.5/0.8/1.25/2× the true stiffness:
/// −5.8 (27.9 kg) / −2.4 (11.8) / +2.6 (13.1) / +11.2 % (53.7 kg); the halt within 0.03 mm.
#[test]
fn a_mis_set_coupling_stiffness_biases_a_fast_stick_slipping_lift_but_faults_nothing() {
    let g = host_sim::physics::Geometry::paper();
    let target = g.height(34f64.to_radians()) + 6.0e-3;
    for factor in [0.5, 0.8, 1.25, 2.0] {
        let mut s = commissioned(Lubricant::Dry, 450.0, 34.0, 6.0);
        let kc = &mut s.control.estimator.mechanics.coupling_stiffness;
        *kc = liftfw::units::NewtonMetres::from_f64(kc.to_f64() * factor);
        let (r, log) = lift_6mm(&s, 34.0);
        assert!(faults(&r).is_empty(), "k_c ×{factor}: {:?}", faults(&r));
        let halt = r.final_height() - target;
        assert!(halt.abs() <= 0.5e-3, "k_c ×{factor}: halted {halt} m off");
        // The bias the fall's share allows, and the 3 % goal's own.
        let allowed = 450.0 * (0.03 + 0.12 * (factor - 1.0f64).abs());
        let worst = worst_from_half_a_second(&log, 450.0);
        eprintln!("k_c ×{factor}: load worst from 0.5 s {worst:.1} kg (allowed {allowed:.1})");
        assert!(worst <= allowed, "k_c ×{factor}: load {worst:.1} kg off");
    }
}

/// An empty dry head lowering from high on the stroke (260 mm, 36.9°): its thread torque is a
/// few hundredths of a N·m, far under what a stick-slip the detector can see needs, so an
/// episode the detector raises on the current's noise does not hold the load at the prior
/// (`LoadIdent::resists`). Before, on `host-sim estimate`'s seed 504 (`--seed-sets 6`) a
/// periodicity episode on white noise (a 5.1-tick "period", 0.4 s into the cruise) put the
/// load back to the 1000 kg prior for the rest of the cruise and T_r at −2.25 N·m against the
/// plant's −0.03. (A rare draw: none in 64 other seeds of the same run, nor in 240 of this
/// file's empty lowerings from 36.9°.)
#[test]
fn an_empty_dry_head_lowering_is_not_held_at_the_prior_by_a_noise_episode() {
    use host_sim::studies::estimate::{run_case, Case};
    let case = Case {
        lub: Lubricant::Dry,
        load: 0.0,
        up: false,
        start_mm: 260.0,
        dry: 1.0,
        seed: 504,
    };
    let o = run_case(&case).expect("the run");
    assert!(o.fault.is_none(), "{:?}", o.fault);
    let m = o.moves[0];
    println!(
        "empty dry lowering from 260 mm, seed 504: load worst {:.1} kg, T_r {:.4} (plant {:.4}) N·m",
        m.load_worst, m.tr_core, m.tr_plant
    );
    assert!(m.load_worst <= 10.0, "{m:?}");
    assert!(m.tr_ok() && m.load_ok(case.load), "{m:?}");
}

/// A light PTFE lowering high on the stroke read on the reversed flank (`lowering_load`: an
/// empty head's reading) states the loaded flank's load interval beside it, and its T_r range
/// holds T_r at that interval's heavy end (`Controller::friction_range`). Before, on
/// `host-sim estimate`'s seed 204 (`--seed-sets 3`), 100 kg from 260 mm read 0 kg in 0…254 kg
/// (holding the car) but T_r in −0.072…−0.004 N·m, the plant's −0.125 outside.
#[test]
fn a_light_lowering_read_on_the_reversed_flank_states_a_t_r_range_for_its_whole_interval() {
    use host_sim::studies::estimate::{run_case, Case};
    for seed in [104, 204] {
        let case = Case {
            lub: Lubricant::Ptfe,
            load: 100.0,
            up: false,
            start_mm: 260.0,
            dry: 1.0,
            seed,
        };
        let o = run_case(&case).expect("the run");
        assert!(o.fault.is_none(), "{:?}", o.fault);
        let m = o.moves[0];
        println!(
            "PTFE 100 kg lowering from 260 mm, seed {seed}: load {:.1} kg in {:.0}…{:.0}, T_r {:.3} in {:.3}…{:.3} (plant {:.3}) N·m",
            m.load_half, m.load_lo, m.load_hi, m.tr_core, m.tr_lo, m.tr_hi, m.tr_plant
        );
        assert!(m.covers(case.load), "{seed}: {m:?}");
    }
}

/// A light car on a thread drier than configured (dry 250 kg, 1.5× and 2×, from 200 mm: a lift,
/// a lowering, a lift): the lift stick-slips in cycles of ≈ 11 ticks, too fast for the
/// current's peaks, and is read by their period (`Controller::fast_breakaway`). That period
/// must outlast the lift's braking to its rest, where `end_load_motion` keeps its breakaways
/// for the pair: before, the detector forgot it when braking began, the lowering did not
/// creep, no pair formed, the lubrication warning never fired and the third move read the car
/// 103 and 206 kg heavy with T_r −7.5 and −10.8 %. Now (`host-sim estimate`'s seed 7) the pair
/// forms and warns (scales 1.344 and 1.943), and the third move's T_r is within 3 % (−1.2 %,
/// +0.1 %; its load, 25.8 and 6.8 kg off, still misses 1.5×'s 3 %).
#[test]
fn a_light_car_on_a_drier_thread_pairs_its_fast_stick_slipping_lift_and_warns() {
    use host_sim::studies::estimate::{run_case, Case};
    for dry in [1.5, 2.0] {
        let case = Case {
            lub: Lubricant::Dry,
            load: 250.0,
            up: true,
            start_mm: 200.0,
            dry,
            seed: 7,
        };
        let o = run_case(&case).expect("the run");
        assert!(o.fault.is_none(), "{:?}", o.fault);
        let m = o.moves[2];
        println!(
            "dry 250 kg, {dry}x drier: scale {:.3}, warned {}, third move T_r {:.3} (plant {:.3}), load worst {:.1} kg",
            o.scale, o.warned, m.tr_core, m.tr_plant, m.load_worst
        );
        assert!(o.warned, "{dry}x: no lubrication warning");
        assert!(
            (o.scale - dry).abs() < 0.15 * dry,
            "{dry}x: scale {}",
            o.scale
        );
        assert!(m.tr_ok(), "{dry}x: {m:?}");
    }
}
