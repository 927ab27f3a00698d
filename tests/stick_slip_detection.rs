//! The core's stick-slip detector in closed loop against host-sim's truth (the small set of
//! `host-sim stickslip --quick`; the scored set and its numbers are in BENCHMARKS.md).
#![allow(clippy::expect_used, clippy::unwrap_used)]

use host_sim::score::{self, match_run, quick_set, ScoreConfig};

#[test]
fn dry_stick_slip_is_detected_and_smooth_runs_do_not_alarm() {
    let sc = ScoreConfig::default();
    // #2 (greased, creeping at 0.2 rad/s, 0.9 N·m drops) is a known miss: the drop threshold
    // (1.5 N·m) sits above it to keep the speed loop's ripple out (docs/stick-slip.md).
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
