//! The paper command's matrix and report: the 18 cases of Figs 13–15, every claim in the
//! report, the ball-screw section included verbatim. Short horizons keep it fast.

// A failed expectation is a failed test: panicking is the point here.
#![allow(clippy::expect_used)]

use host_sim::physics::Lubricant;
use host_sim::studies::paper::{self, MatrixConfig};

fn short() -> MatrixConfig {
    MatrixConfig {
        duration: 0.12,
        dt: 4e-6,
        zoom: (0.119, 0.12),
        ..MatrixConfig::default()
    }
}

#[test]
fn matrix_has_the_papers_eighteen_cases_in_figure_order() {
    let m = paper::matrix();
    assert_eq!(m.len(), 18);
    let panels: String = m.iter().take(6).map(|c| c.panel()).collect();
    assert_eq!(panels, "adgjmp");
    for (i, l) in Lubricant::ALL.iter().enumerate() {
        assert!(m[6 * i..6 * i + 6].iter().all(|c| c.lubricant == *l));
    }
    let mut slugs: Vec<_> = m.iter().map(|c| c.slug()).collect();
    slugs.dedup();
    assert_eq!(slugs.len(), 18, "file names are unique");
}

#[test]
fn report_states_every_claim_and_includes_the_ball_screw_file_verbatim() {
    let cfg = short();
    let results: Vec<_> = paper::matrix()
        .into_iter()
        .filter(|c| c.lubricant != Lubricant::Lithium)
        .map(|c| paper::run_case(c, &cfg).0)
        .collect();
    for r in &results {
        assert!(r.window_torque().is_finite() && r.cruise_torque().is_finite());
        assert!(!r.plot.torque.is_empty() && !r.plot.torque_zoom.is_empty());
    }
    let ball = "### Ball screw\n\nSome *verbatim* text | with a table |\n";
    let doc = paper::reproduction_markdown(&results, None, &cfg, Some(ball))
        .expect("the template and the generator agree");
    for claim in 1..=7 {
        assert!(doc.contains(&format!("\n| {claim} | ")), "claim {claim}");
    }
    let (head, tail) = doc
        .split_once("## Ball-screw variant (seeds 001, 002)")
        .expect("ball-screw heading");
    assert!(head.contains("Arm length") && head.contains("Motor (screw) speed"));
    assert!(tail.contains(ball.trim_end()));
    let without = paper::reproduction_markdown(&results, None, &cfg, None)
        .expect("the template and the generator agree");
    assert!(without.contains("## Ball-screw variant (seeds 001, 002)"));
    assert!(without.contains("docs/ballscrew-reproduction.md"));
}

#[test]
fn csv_trace_keeps_the_zoom_window_at_every_step() {
    let cfg = short();
    let case = paper::matrix()[0];
    let (_, trace) = paper::run_case(case, &cfg);
    let thin = paper::csv_trace(&trace, 20, cfg.zoom);
    let in_zoom = thin
        .records
        .iter()
        .filter(|r| r.t >= cfg.zoom.0 && r.t <= cfg.zoom.1)
        .count();
    // 1 ms at 4 µs: 250 steps (+1 for the end point).
    assert!(in_zoom >= 250, "{in_zoom}");
    assert!(thin.records.len() < trace.records.len());
    assert!(thin.records.windows(2).all(|w| w[0].t < w[1].t));
}
