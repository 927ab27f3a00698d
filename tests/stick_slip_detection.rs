//! The core's stick-slip detector in closed loop against host-sim's truth (the small set of
//! `host-sim stickslip --quick`; the scored set and its numbers are in BENCHMARKS.md).
#![allow(clippy::expect_used, clippy::unwrap_used)]

use host_sim::studies::stickslip::{self as score, match_run, quick_set, Scenario, ScoreConfig};
use host_sim::twin::physics::Lubricant;

/// (id, lubricant, load kg, start °, lifting, cruise rad/s, noise, noise seed).
type Legacy = (usize, Lubricant, f64, f64, bool, f64, f64, u64);

/// A scenario of the first generator (fixed values: the generator has been broadened since):
/// the core configured for the thread's lubricant, 4 s when creeping, else 2.5 s.
fn first_generator(
    (id, lubricant, load, start_deg, lifting, cruise, noise, seed): Legacy,
) -> Scenario {
    Scenario {
        id,
        lubricant,
        core_law: lubricant,
        load,
        start_deg,
        lifting,
        cruise,
        noise,
        seed,
        duration: if cruise <= 0.3 { 4.0 } else { 2.5 },
        ..quick_set()[0]
    }
}

#[test]
fn dry_stick_slip_is_detected_and_smooth_runs_do_not_alarm() {
    let sc = ScoreConfig::default();
    // #2 (greased, creeping at 0.2 rad/s, 0.9 N·m drops) is a known miss: the detector sees
    // two of its slips and the model (μ rising with speed) asks for three (docs/stick-slip.md).
    for s in quick_set().into_iter().filter(|s| s.id != 2) {
        let r = score::run(&s, &sc);
        let m = match_run(&r);
        println!("{}", score::run_line(&r));
        if r.labels.episodes.is_empty() {
            assert!(r.onsets.is_empty(), "false alarm: {}", s.name());
        } else {
            assert!(m.missed.is_empty(), "missed: {}", s.name());
            assert!(
                m.latencies.iter().all(|&l| l <= 0.1),
                "late: {} {:?}",
                s.name(),
                m.latencies
            );
            assert_eq!(m.duplicates + m.spurious + m.on_micro, 0, "{}", s.name());
        }
    }
}

#[test]
fn truth_labels_dry_lifting_at_rated_load_as_stick_slip_and_ptfe_as_smooth() {
    let sc = ScoreConfig::default();
    let set = quick_set();
    let dry = score::run(&set[0], &sc);
    assert_eq!(dry.labels.episodes.len(), 1);
    assert!(
        dry.labels.episodes[0].drop > 30.0,
        "{:?}",
        dry.labels.episodes
    );
    let ptfe = score::run(&set[3], &sc);
    assert!(ptfe.labels.episodes.is_empty() && ptfe.labels.micro.is_empty());
}

#[test]
fn creeping_smooth_run_has_no_slips_at_all() {
    // Seed 1's #7: greased, 150 kg, creeping up at 0.2 rad/s, quantisation noise only. With the
    // bare encoder count the speed loop's ripple made 145 "slips" and an alarm here; with the
    // edge-timed position (control::edges) the torque is flat.
    let s = first_generator((7, Lubricant::Lithium, 150.0, 45.0, true, 0.2, 0.0, 708));
    assert!(s.cruise < 0.25 && s.noise == 0.0, "{}", s.name());
    let r = score::run(&s, &ScoreConfig::default());
    println!("{}", score::run_line(&r));
    assert!(r.labels.episodes.is_empty(), "{:?}", r.labels.episodes);
    assert_eq!(r.slips, 0);
    assert!(r.onsets.is_empty());
}

#[test]
fn fast_lowering_stick_slip_is_found_by_its_periodicity() {
    // Seed 1's #58: dry, 1000 kg, lowering at 2 rad/s: the screw sticks and slips every 7.3 ms
    // with 2.2 N·m drops, a ripple of a few tenths of a N·m at the motor current, below the
    // drop threshold; the periodicity test finds it.
    let s = first_generator((58, Lubricant::Dry, 1000.0, 30.0, false, 2.0, 1.0, 5806));
    let r = score::run(&s, &ScoreConfig::default());
    let m = match_run(&r);
    println!("{}", score::run_line(&r));
    assert_eq!(r.labels.episodes.len(), 1);
    assert!(m.missed.is_empty(), "missed: {}", s.name());
    assert_eq!(m.duplicates + m.spurious + m.on_micro, 0);
}

#[test]
fn small_fast_stick_slip_is_found_and_faster_micro_stick_slip_is_not() {
    // Seed 7's #0: dry, 300 kg, lowering from 20° at 1 rad/s: 1.03 N·m drops every 7.0 ms
    // (significant), a ripple whose autocorrelation (≈ 0.02 N·m²) the first periodicity
    // threshold (0.04) missed. Seed 7's #10: dry, 600 kg, lifting from 65° at 3 rad/s: 1.53 N·m
    // drops every 3.7 ms, micro stick-slip by the definition (period < 5 ms) with a larger
    // ripple; the veto of periods under 5 ticks keeps it quiet at the lower threshold.
    let set = [
        first_generator((0, Lubricant::Dry, 300.0, 20.0, false, 1.0, 1.0, 2)),
        first_generator((10, Lubricant::Dry, 600.0, 65.0, true, 3.0, 1.0, 1005)),
    ];
    let sc = ScoreConfig::default();
    let fast = score::run(&set[0], &sc);
    let m = match_run(&fast);
    println!("{}", score::run_line(&fast));
    assert_eq!(fast.labels.episodes.len(), 1);
    assert!(
        fast.labels.episodes[0].drop < 1.5,
        "{:?}",
        fast.labels.episodes
    );
    assert!(m.missed.is_empty(), "missed: {}", set[0].name());
    assert_eq!(m.duplicates + m.spurious + m.on_micro, 0);
    let micro = score::run(&set[1], &sc);
    println!("{}", score::run_line(&micro));
    assert!(micro.labels.episodes.is_empty() && !micro.labels.micro.is_empty());
    assert!(micro.onsets.is_empty(), "false alarm: {}", set[1].name());
}

#[test]
fn a_creeping_start_and_micro_stick_slip_every_three_ticks_stay_quiet() {
    // Generator seed 4 #28 (shortened): dry, 744 kg, lowering from 40.9° at 0.22 rad/s,
    // noise 2.46. The coupling winds up for ≈ 30 ms, the screw breaks away from rest on the
    // start ramp and slides; the speed loop rings by 1–3 N·m for ≈ 50 ms. Counting slips on
    // the ramp made breakaway + two swings a chain (onset at 64 ms, no stick-slip at all).
    let creep = Scenario {
        id: 28,
        set: 4,
        lubricant: Lubricant::Dry,
        core_law: Lubricant::Dry,
        load: 744.0,
        start_deg: 40.9,
        lifting: false,
        cruise: 0.22,
        noise: 2.46,
        seed: 4 * 1_000_003 + 28,
        duration: 0.8,
        ..quick_set()[0]
    };
    // Generator seed 1 #16: dry, 545 kg, lifting from 54.7° at 5.8 rad/s: micro stick-slip
    // with 2 N·m drops every 2.9 ms. Its multiples (6, 9, 12, 15 ticks) correlate and lags 4
    // and 5 do not: the periodicity test fired at 0.9 s until lag 3 vetoed it.
    let micro = Scenario {
        id: 16,
        set: 1,
        load: 545.0,
        start_deg: 54.7,
        lifting: true,
        cruise: 5.8,
        noise: 1.07,
        seed: 1_000_003 + 16,
        duration: 2.5,
        ..creep
    };
    let sc = ScoreConfig::default();
    for s in [creep, micro] {
        let r = score::run(&s, &sc);
        println!("{}", score::run_line(&r));
        assert!(r.labels.episodes.is_empty(), "{:?}", r.labels.episodes);
        assert!(r.onsets.is_empty(), "false alarm: {}", s.name());
    }
}

#[test]
fn stick_slip_in_the_band_all_run_long_is_borderline_not_nothing() {
    // Generator seed 20 #50: dry, 436 kg, lowering at 1.36 rad/s: the whole run stick-slips
    // with 0.92 N·m drops every 4.8 ms (under the nominal 5 ms, over the loose 4 ms); a few
    // 5.0 ms cycles near the end make a short nominal episode, none strict. The periodicity
    // path fires at 0.60 s. The loose episode that holds the onset used to be dropped for
    // overlapping that nominal one, and the onset counted as a false alarm "on nothing".
    let s = score::scenario_set(64, 20)[50];
    assert_eq!(
        (s.lubricant, s.load, s.lifting),
        (Lubricant::Dry, 436.0, false)
    );
    let r = score::run(&s, &ScoreConfig::default());
    let m = match_run(&r);
    println!("{}", score::run_line(&r));
    assert!(r.labels.episodes.is_empty(), "{:?}", r.labels.episodes);
    assert!(
        r.labels
            .borderline
            .iter()
            .any(|b| b.start < 0.3 && b.end > 1.5),
        "{:?}",
        r.labels.borderline
    );
    assert!(
        m.false_onsets.is_empty(),
        "{:?} {:?}",
        m.false_onsets,
        r.onsets
    );
}

#[test]
fn stick_slip_is_watched_in_a_cruise_limited_motion() {
    // Generator seed 1 #18 (tuning): dry, 552 kg, lifting at 9.82 rad/s, beyond what the motor
    // reaches (≈ 5 rad/s): the controller limits the cruise. When the limit was re-set on every
    // lagging tick by the speed estimate's jitter (135 changes in 2 s), the reference never held
    // still for the detector's 25 ms, and this run's 249 cycles of 6.4 N·m went unseen.
    let s = score::scenario_set(64, 1)[18];
    assert_eq!(
        (s.lubricant, s.load, s.lifting),
        (Lubricant::Dry, 552.0, true)
    );
    let r = score::run(&s, &ScoreConfig::default());
    let m = match_run(&r);
    println!("{}", score::run_line(&r));
    let (limit, changes) = r.cruise_limit;
    assert!(limit.is_some_and(|w| w < s.cruise), "{limit:?}");
    assert!(changes <= 10, "the cruise limit changed {changes} times");
    assert_eq!(r.labels.episodes.len(), 1);
    assert!(m.missed.is_empty(), "missed: {}", s.name());
    assert_eq!(m.duplicates + m.spurious + m.on_micro, 0);
}
