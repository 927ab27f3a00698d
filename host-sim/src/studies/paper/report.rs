//! `docs/paper-reproduction.md`: the text is the template `reproduction.md` beside this file;
//! every number in it is computed here, from the runs, the twin's physics and the matrix's
//! configuration, and filled into the template's `{{name}}` markers.

use super::{find, matrix_table, parameters, CaseResult, MatrixConfig, Steady, AMPLITUDE_BLOCK};
use crate::twin::physics::{FrictionLaw, Geometry, Lubricant, Screw};
use crate::twin::plant::SpeedProfile;
use crate::twin::sim::Stepping;
use std::fmt::Write as _;

/// The report's text, with `{{name}}` markers for the computed values.
const TEMPLATE: &str = include_str!("reproduction.md");

/// The paper's claims 4 and 5: lifting from this angle, T up to this many times lower than
/// from 15°.
const ANGLE_CLAIMS: [(f64, f64); 2] = [(45.0, 5.0), (65.0, 10.0)];
/// Claim 1: PTFE's T is less than this share of dry's.
const PTFE_CLAIM: f64 = 0.5;
/// Claim 2: lithium grease about 20 % below dry; "about" read as 10–30 %.
const LITHIUM_CLAIM: std::ops::Range<f64> = 0.7..0.9;
/// Below this share of dry, lithium grease is at least lower than dry (claim 2 in part).
const LITHIUM_LOWER: f64 = 0.95;
/// Claims 4 and 5 agree "in order" when our largest ratio lies within these multiples of the
/// paper's.
const SAME_ORDER: (f64, f64) = (0.5, 1.1);
/// Claim 3: μ_b = 0 lowers T at least this many times.
const PIN_CLAIM: f64 = 3.0;
/// The printed lithium law is compared with this share of the dry law (claim 2's 20 %).
const LITHIUM_SHARE: f64 = 0.8;

/// Fills every `{{name}}` of `template` from `values`. A marker without a value, or a value
/// without a marker, is an error: the template and the generator must agree.
pub fn fill(template: &str, values: &[(&str, String)]) -> Result<String, String> {
    let mut out = String::with_capacity(template.len() * 2);
    let mut used = vec![false; values.len()];
    let mut rest = template;
    while let Some(at) = rest.find("{{") {
        out.push_str(&rest[..at]);
        let after = &rest[at + 2..];
        let end = after.find("}}").ok_or_else(|| {
            format!(
                "unclosed marker at `{}`",
                &rest[at..].lines().next().unwrap_or("")
            )
        })?;
        let name = &after[..end];
        let i = values
            .iter()
            .position(|(n, _)| *n == name)
            .ok_or_else(|| format!("no value for the marker {{{{{name}}}}}"))?;
        used[i] = true;
        out.push_str(&values[i].1);
        rest = &after[end + 2..];
    }
    out.push_str(rest);
    match values.iter().zip(&used).find(|(_, u)| !**u) {
        Some(((name, _), _)) => Err(format!("the template has no marker {{{{{name}}}}}")),
        None => Ok(out),
    }
}

/// `docs/paper-reproduction.md`: each claim of seed 000 beside our number. `ballscrew` is the
/// text of `docs/ballscrew-reproduction.md`, included verbatim when it exists.
pub fn reproduction_markdown(
    results: &[CaseResult],
    steady: Option<&Steady>,
    m: &MatrixConfig,
    ballscrew: Option<&str>,
) -> Result<String, String> {
    fill(TEMPLATE, &values(results, steady, m, ballscrew))
}

/// `a–b s`, the numbers as short as they print exactly.
fn span((a, b): (f64, f64)) -> String {
    format!("{}–{} s", short(a), short(b))
}

/// A time or length without the binary float's noise (5 − 4.94 prints as 0.06).
fn short(x: f64) -> String {
    format!("{}", (x * 1e9).round() / 1e9)
}

fn ratio_line(v: Option<(f64, f64)>) -> String {
    match v {
        Some((a, b)) => format!("{:.2}", a / b),
        None => "—".into(),
    }
}

/// Smallest screw rate (rad/s, up to 10⁴) where `f` turns true, by bisection; NaN if it never
/// does. `f` must switch once.
fn first_rate(f: impl Fn(f64) -> bool) -> f64 {
    let (mut lo, mut hi) = (0.0, 1e4);
    if !f(hi) {
        return f64::NAN;
    }
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if f(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

fn values(
    results: &[CaseResult],
    steady: Option<&Steady>,
    m: &MatrixConfig,
    ballscrew: Option<&str>,
) -> Vec<(&'static str, String)> {
    let g = Geometry::paper();
    let screw = Screw::paper();
    let profile = SpeedProfile::paper(m.cruise);
    let w = |l: Lubricant, deg: f64, up: bool, mu: f64| find(results, l, deg, up, mu);
    let mut v: Vec<(&'static str, String)> = Vec::new();
    let mut put = |name: &'static str, value: String| v.push((name, value));

    // --- The set-up -----------------------------------------------------------------------
    put("cases", results.len().to_string());
    put("parameters", parameters(m));
    put("length_m", format!("{:.2}", g.length));
    put("arm_m", format!("{:.1}", g.length / 2.0));
    put("h0_mm", format!("{:.0}", g.h0 * 1e3));
    put("h_low_mm", format!("{:.0}", g.height(g.alpha0) * 1e3));
    put("h_high_mm", format!("{:.0}", g.height(g.alpha_max) * 1e3));
    put("alpha0_deg", format!("{:.0}", g.alpha0.to_degrees()));
    put("alpha_max_deg", format!("{:.0}", g.alpha_max.to_degrees()));
    put("duration", short(m.duration));
    put("cruise", format!("{}", m.cruise));
    put(
        "cruise_rpm",
        format!("{:.0}", m.cruise * 60.0 / std::f64::consts::TAU),
    );
    put(
        "nut_mm_s",
        format!("{:.1}", m.cruise * screw.lead_per_rad() * 1e3),
    );
    // How far the arms turn over a run: the dry lifting runs' start and end angles.
    let turn = |deg: f64| {
        w(Lubricant::Dry, deg, true, 0.3).map_or("—".into(), |r| {
            format!("{:.0}", r.summary.alpha_deg.1 - r.summary.alpha_deg.0)
        })
    };
    put("turn_15", turn(15.0));
    put("turn_65", turn(65.0));
    put("load", format!("{}", m.load));
    let lith = FrictionLaw::lithium();
    let printed = FrictionLaw::lithium_as_printed();
    let dry = FrictionLaw::dry();
    let ptfe = FrictionLaw::ptfe();
    let mu = |law: &FrictionLaw, rate: f64| law.mu_at_rate(rate, screw.r_m, screw.lambda);
    put("lith_drop", format!("{:.3}", lith.amp));
    put("lith_s_max_mm_s", format!("{:.0}", lith.s_max * 1e3));
    put("lith_mu_flat", format!("{:.2}", lith.mu_of(lith.s_max)));
    put(
        "lith_printed_mu_cruise",
        format!("{:.1}", mu(&printed, m.cruise)),
    );
    put(
        "moment_arm_excess",
        format!("{:.2}", 100.0 * (1.0 / screw.lambda.cos() - 1.0)),
    );
    let (step, step_why) = match m.stepping {
        Stepping::Fixed => (
            format!("dt = {:.0e} s, fixed-step RK23", m.dt),
            format!(
                "Convergence study: docs/plant.md (the step at which halving it changes the {} \
                 mean by less than its criterion).",
                span(m.zoom)
            ),
        ),
        Stepping::Adaptive { tol, .. } => (
            format!("adaptive RK23, tol = {tol:.0e}"),
            "Tolerance study: docs/plant.md (both means within its criterion of the finest \
             fixed step in all cases)."
                .to_string(),
        ),
    };
    put("step", step);
    put("step_why", step_why);
    put("zoom", span(m.zoom));
    put("zoom_end", short(m.zoom.1));
    let cruise_span = (profile.ramp_end, profile.brake_start.min(m.duration));
    put("constant_speed", span(cruise_span));

    // --- Claims 1 and 2: lubricants vs dry ------------------------------------------------
    let lube_ratios = |l: Lubricant| -> Vec<(f64, f64)> {
        super::GEOMETRIES
            .iter()
            .filter_map(|&(deg, up, mu)| {
                let (d, x) = (w(Lubricant::Dry, deg, up, mu)?, w(l, deg, up, mu)?);
                Some((
                    x.window_torque() / d.window_torque(),
                    x.cruise_torque() / d.cruise_torque(),
                ))
            })
            .collect()
    };
    let steady_ratio = |l: Lubricant, window: bool| -> Option<(f64, f64)> {
        let st = steady?;
        let f = |l| find(&st.results, l, 15.0, true, 0.3);
        let (d, x) = (f(Lubricant::Dry)?, f(l)?);
        Some(if window {
            (x.window_torque(), d.window_torque())
        } else {
            (x.cruise_torque(), d.cruise_torque())
        })
    };
    let fmt_ratios = |v: &[(f64, f64)], cruise: bool| -> String {
        v.iter()
            .map(|&(wi, c)| format!("{:.2}", if cruise { c } else { wi }))
            .collect::<Vec<_>>()
            .join(" / ")
    };
    let steady_span = steady
        .and_then(|st| st.results.first())
        .map_or("—".into(), |r| {
            span((
                profile.ramp_end,
                profile.brake_start.min(r.summary.duration),
            ))
        });
    put("steady_span", steady_span.clone());
    let ptfe_r = lube_ratios(Lubricant::Ptfe);
    let lith_r = lube_ratios(Lubricant::Lithium);
    put("ptfe_cruise_ratios", fmt_ratios(&ptfe_r, true));
    put("ptfe_window_ratios", fmt_ratios(&ptfe_r, false));
    put(
        "ptfe_steady_window",
        ratio_line(steady_ratio(Lubricant::Ptfe, true)),
    );
    put(
        "ptfe_steady_cruise",
        ratio_line(steady_ratio(Lubricant::Ptfe, false)),
    );
    let ptfe_verdict = if ptfe_r.iter().all(|&(_, c)| c < PTFE_CLAIM) {
        "yes"
    } else if steady_ratio(Lubricant::Ptfe, false).is_some_and(|(a, b)| a / b < PTFE_CLAIM) {
        "in steady sliding only (see 1 below)"
    } else {
        "no (see 1 below)"
    };
    put("ptfe_verdict", ptfe_verdict.into());
    put("lith_cruise_ratios", fmt_ratios(&lith_r, true));
    put("lith_window_ratios", fmt_ratios(&lith_r, false));
    put(
        "lith_steady_window",
        ratio_line(steady_ratio(Lubricant::Lithium, true)),
    );
    put(
        "lith_steady_cruise",
        ratio_line(steady_ratio(Lubricant::Lithium, false)),
    );
    let lith_verdict = match steady_ratio(Lubricant::Lithium, false).map(|(a, b)| a / b) {
        Some(r) if LITHIUM_CLAIM.contains(&r) => "yes, in steady sliding (see 2)",
        Some(r) if r < LITHIUM_LOWER => "partly: lower, by less than 20 % (see 2)",
        _ => "no (see 2)",
    };
    put("lith_verdict", lith_verdict.into());

    // --- Claim 3: pin friction ------------------------------------------------------------
    let pin = |l: Lubricant| -> Option<(f64, f64)> {
        let (a, b) = (w(l, 15.0, true, 0.3)?, w(l, 15.0, true, 0.0)?);
        Some((
            a.cruise_torque() / b.cruise_torque(),
            a.window_torque() / b.window_torque(),
        ))
    };
    let ratio_text = |l: Lubricant, (c, wi): (f64, f64)| {
        format!("{} {:.1}× ({:.1}× at {})", l.name(), c, wi, span(m.zoom))
    };
    let pin_txt: Vec<String> = Lubricant::ALL
        .iter()
        .filter_map(|&l| pin(l).map(|x| ratio_text(l, x)))
        .collect();
    put("pin_ratios", pin_txt.join("; "));
    let pin_ok = Lubricant::ALL
        .iter()
        .all(|&l| pin(l).is_some_and(|(c, _)| c >= PIN_CLAIM));
    put(
        "pin_verdict",
        if pin_ok { "yes" } else { "partly (see 3)" }.into(),
    );

    // --- Claims 4 and 5: start angle ------------------------------------------------------
    for (deg, paper_x) in ANGLE_CLAIMS {
        let v: Vec<(Lubricant, f64, f64)> = Lubricant::ALL
            .iter()
            .filter_map(|&l| {
                let (a, b) = (w(l, 15.0, true, 0.3)?, w(l, deg, true, 0.3)?);
                Some((
                    l,
                    a.cruise_torque() / b.cruise_torque(),
                    a.window_torque() / b.window_torque(),
                ))
            })
            .collect();
        let txt: Vec<String> = v.iter().map(|&(l, c, wi)| ratio_text(l, (c, wi))).collect();
        let max = v.iter().map(|x| x.1).fold(0.0, f64::max);
        let verdict = if max <= paper_x * SAME_ORDER.1 && max >= SAME_ORDER.0 * paper_x {
            "yes (same order)"
        } else if max < SAME_ORDER.0 * paper_x {
            "smaller ratio (see 4–5)"
        } else {
            "larger ratio (see 4–5)"
        };
        let (ratios, verdict_name) = if deg == ANGLE_CLAIMS[0].0 {
            ("angle_45_ratios", "angle_45_verdict")
        } else {
            ("angle_65_ratios", "angle_65_verdict")
        };
        put(ratios, txt.join("; "));
        put(verdict_name, verdict.into());
    }

    // --- Claim 6: trend -------------------------------------------------------------------
    let (mut fall, mut nlift, mut rise, mut nlow) = (0, 0, 0, 0);
    for r in results {
        if r.case.lifting {
            nlift += 1;
            fall += usize::from(r.trend.change() < 0.0);
        } else {
            nlow += 1;
            rise += usize::from(r.trend.change() > 0.0);
        }
    }
    put("lift_falls", fall.to_string());
    put("lift_runs", nlift.to_string());
    put("lower_rises", rise.to_string());
    put("lower_runs", nlow.to_string());
    put(
        "trend_verdict",
        if fall == nlift && rise == nlow {
            "yes"
        } else {
            "mostly (see 6)"
        }
        .into(),
    );

    // --- Claim 7: stick-slip --------------------------------------------------------------
    let with_ss = results.iter().filter(|r| r.stick_slip.episodes > 0).count();
    let per_lube = |l: Lubricant, f: &dyn Fn(&CaseResult) -> String| -> String {
        results
            .iter()
            .filter(|r| r.case.lubricant == l)
            .map(f)
            .collect::<Vec<_>>()
            .join(" / ")
    };
    let amp_txt: Vec<String> = Lubricant::ALL
        .iter()
        .map(|&l| {
            format!(
                "{} {} episodes, median amplitude {} mrad",
                l.name(),
                per_lube(l, &|r| r.stick_slip.episodes.to_string()),
                per_lube(l, &|r| format!("{:.1}", 1e3 * r.stick_slip.amplitude))
            )
        })
        .collect();
    let amp = |l: Lubricant| -> f64 {
        results
            .iter()
            .filter(|r| r.case.lubricant == l)
            .map(|r| r.stick_slip.amplitude)
            .sum()
    };
    let smaller =
        amp(Lubricant::Ptfe) < amp(Lubricant::Dry) && amp(Lubricant::Lithium) < amp(Lubricant::Dry);
    put("stick_runs", with_ss.to_string());
    put("runs", results.len().to_string());
    put("stick_per_lubricant", amp_txt.join("; "));
    put(
        "stick_verdict",
        match (with_ss == results.len(), smaller) {
            (true, true) => "yes",
            (false, true) => "smaller when lubricated: yes; in every case: no (see 7)",
            _ => "no (see 7)",
        }
        .into(),
    );

    // --- Why: claims 1 and 2 --------------------------------------------------------------
    let dry15 = w(Lubricant::Dry, 15.0, true, 0.3);
    put(
        "dry_stick",
        dry15.map_or(String::new(), |r| {
            format!(
                " ({} stick episodes in the constant-speed phase, stuck {:.0} % of it)",
                r.stick_slip.episodes,
                100.0 * r.stick_slip.stuck
            )
        }),
    );
    // The mean slip: the time not stuck, over the episodes.
    put(
        "dry_slip_ms",
        dry15.map_or("—".into(), |r| {
            let ss = &r.stick_slip;
            let slipping = (1.0 - ss.stuck) * (cruise_span.1 - cruise_span.0);
            format!("{:.1}", 1e3 * slipping / ss.episodes.max(1) as f64)
        }),
    );
    put(
        "dry_mu_zero_rad_s",
        format!("{:.0}", first_rate(|rate| mu(&dry, rate) <= 0.0)),
    );
    put(
        "ptfe_dry_lift_15",
        format!("{:.2}", ptfe_r.first().map_or(f64::NAN, |x| x.1)),
    );
    put("ptfe_mu_cruise", format!("{:.2}", mu(&ptfe, m.cruise)));
    put("dry_mu_cruise", format!("{:.2}", mu(&dry, m.cruise)));
    put("dry_mu_cruise_3", format!("{:.3}", mu(&dry, m.cruise)));
    put(
        "lith_below_dry",
        format!(
            "{:.0}",
            100.0 * (1.0 - lith.mu_of(lith.s_max) / mu(&dry, m.cruise))
        ),
    );
    put(
        "lith_printed_08_rad_s",
        format!(
            "{:.0}",
            first_rate(|rate| mu(&printed, rate) >= LITHIUM_SHARE * mu(&dry, rate))
        ),
    );

    // --- Why: claims 3 to 6 (the loads of Eqs 1 and 6) ------------------------------------
    let kn = |x: f64| format!("{:.1}", x / 1e3);
    let at = |deg: f64| {
        let a = f64::to_radians(deg);
        (g.axial_load(m.load, a), g.pin_friction(m.load, a))
    };
    let ((r15, f15), (r45, f45), (r65, f65)) = (at(15.0), at(45.0), at(65.0));
    put("r_15_kn", kn(r15));
    put("r_45_kn", kn(r45));
    put("r_65_kn", kn(r65));
    put("f0_15_kn", kn(f15));
    put("f0_45_kn", kn(f45));
    put("f0_65_kn", kn(f65));
    put("pin_share", format!("{:.0}", 100.0 * f15 / (r15 + f15)));
    put(
        "pin_ptfe",
        format!("{:.1}", pin(Lubricant::Ptfe).map_or(f64::NAN, |x| x.0)),
    );
    put(
        "pin_lith",
        format!("{:.1}", pin(Lubricant::Lithium).map_or(f64::NAN, |x| x.0)),
    );
    // F₀ = 2R: μ_b = 2R / (F₀ per unit μ_b).
    put(
        "pin_for_threefold",
        format!("{:.2}", (PIN_CLAIM - 1.0) * r15 / (f15 / g.mu_pin)),
    );
    put("fold_45", format!("{:.1}", (r15 + f15) / (r45 + f45)));
    put("fold_65", format!("{:.1}", (r15 + f15) / (r65 + f65)));
    let changes = |up: bool, deg: f64| -> String {
        results
            .iter()
            .filter(|r| r.case.lifting == up && r.case.start_deg == deg)
            .map(|r| format!("{:+.0} %", 100.0 * r.trend.change()))
            .collect::<Vec<_>>()
            .join(", ")
    };
    put("trend_lift_15", changes(true, 15.0));
    put("trend_lift_45", changes(true, 45.0));
    put("trend_lift_65", changes(true, 65.0));
    put("trend_lower_45", changes(false, 45.0));
    put("trend_lower_65", changes(false, 65.0));

    // --- The matrix, the steady companion, the ball screw -------------------------------------
    put("block_ms", format!("{:.0}", AMPLITUDE_BLOCK * 1e3));
    put("matrix", matrix_table(results));
    let mut st_txt = String::new();
    if let Some(st) = steady {
        let _ = writeln!(
            st_txt,
            "\n### Steady-sliding companion (constant c_x = {:.0} kg/s, {} s)\n",
            st.c_x,
            st.results
                .first()
                .map_or("—".into(), |r| short(r.summary.duration))
        );
        let _ = writeln!(
            st_txt,
            "| lubricant | case | mean T_r {} (N·m) | mean T_r {} (N·m) | stick episodes |\n|---|---|---|---|---|",
            span(m.zoom),
            steady_span
        );
        for r in &st.results {
            let _ = writeln!(
                st_txt,
                "| {} | {} | {:.3} | {:.3} | {} |",
                r.case.lubricant.name(),
                r.case.label(),
                r.window_torque(),
                r.cruise_torque(),
                r.stick_slip.episodes
            );
        }
    }
    put("steady", st_txt);
    put(
        "ballscrew",
        match ballscrew {
            Some(text) => format!(
                "<!-- Included verbatim from docs/ballscrew-reproduction.md by the generator. -->\n\n{}",
                text.trim_end()
            ),
            None => "_Not yet reproduced. When `docs/ballscrew-reproduction.md` exists, `host-sim \
                     paper` includes it here verbatim._"
                .into(),
        },
    );
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fill_replaces_every_marker() {
        let out = fill(
            "a {{x}} b {{y}}{{x}}",
            &[("x", "1".into()), ("y", "22".into())],
        );
        assert_eq!(out, Ok("a 1 b 221".to_string()));
    }

    #[test]
    fn fill_refuses_a_marker_without_a_value_and_a_value_without_a_marker() {
        assert!(fill("{{x}} {{z}}", &[("x", String::new())]).is_err());
        assert!(fill("{{x}}", &[("x", String::new()), ("y", String::new())]).is_err());
        assert!(fill("{{x", &[("x", String::new())]).is_err());
    }

    #[test]
    fn the_template_has_only_markers_the_generator_fills() {
        // No runs: every claim's value is empty or "—", but every marker must still be known.
        let text = reproduction_markdown(&[], None, &MatrixConfig::default(), None);
        assert!(text.is_ok(), "{text:?}");
    }
}
