//! Step-size convergence study: the mean thread friction torque over 0.999–1 s, computed at
//! halving steps, must change by less than 1 % from one step to the next. The same study over
//! the tolerance of the adaptive option ([`tolerance_convergence`]).

use crate::twin::physics::FrictionLaw;
use crate::twin::sim::{paper_run_with, Stepping, Summary, ADAPTIVE_H_MAX, DEFAULT_DT};
use std::fmt;

/// One level of the study.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Level {
    /// Base step, s (fixed step), or the error tolerance (adaptive).
    pub dt: f64,
    /// Whether `dt` is an adaptive tolerance rather than a step.
    pub adaptive: bool,
    /// Right-hand-side evaluations of the run.
    pub evaluations: u64,
    /// Mean T_r over 0.999–1 s, N·m.
    pub mean_friction_torque: f64,
    /// Peak-to-peak θ − θ_i over 0.999–1 s, rad.
    pub twist_peak_to_peak: f64,
    /// Stuck fraction over 0.999–1 s.
    pub stick_fraction: f64,
    /// Mean T_r over the constant-speed part of the first second (0.06–1 s), N·m.
    pub cruise_friction_torque: f64,
    /// Relative change of the mean T_r from the previous (twice larger) step.
    pub change: Option<f64>,
}

impl Study {
    /// The largest relative change between consecutive levels at or below step `dt`.
    pub fn worst_change_below(&self, dt: f64) -> f64 {
        self.levels
            .iter()
            .filter(|l| l.dt <= dt * (1.0 + 1e-9))
            .filter_map(|l| l.change)
            .fold(0.0, f64::max)
    }
}

/// The study's result.
#[derive(Clone, Debug, PartialEq)]
pub struct Study {
    /// Levels from the largest step down.
    pub levels: Vec<Level>,
}

/// Runs the paper profile to 1 s at `levels` steps `dt_max, dt_max/2, …`.
pub fn convergence(
    law: FrictionLaw,
    mu_pin: f64,
    start_deg: f64,
    cruise: f64,
    dt_max: f64,
    levels: u32,
) -> Study {
    convergence_to(law, mu_pin, start_deg, cruise, 1.0, dt_max, levels)
}

/// As [`convergence`] with the horizon `horizon` (s): the window is its last millisecond.
pub fn convergence_to(
    law: FrictionLaw,
    mu_pin: f64,
    start_deg: f64,
    cruise: f64,
    horizon: f64,
    dt_max: f64,
    levels: u32,
) -> Study {
    study((0..levels).map(|k| {
        let dt = dt_max / f64::from(1u32 << k);
        let s = paper_run_with(law, mu_pin, start_deg, cruise, horizon, dt, Stepping::Fixed);
        (dt, false, s)
    }))
}

/// The same study over the adaptive option's tolerance: `tol_max`, `tol_max/√10`, … (`levels`
/// of them), to 1 s; the change is between consecutive tolerances.
pub fn tolerance_convergence(
    law: FrictionLaw,
    mu_pin: f64,
    start_deg: f64,
    cruise: f64,
    tol_max: f64,
    levels: u32,
) -> Study {
    study((0..levels).map(|k| {
        let tol = tol_max / 10f64.sqrt().powi(k as i32);
        let stepping = Stepping::Adaptive {
            tol,
            h_max: ADAPTIVE_H_MAX,
        };
        let s = paper_run_with(law, mu_pin, start_deg, cruise, 1.0, DEFAULT_DT, stepping);
        (tol, true, s)
    }))
}

fn study(runs: impl Iterator<Item = (f64, bool, Summary)>) -> Study {
    let mut out: Vec<Level> = Vec::new();
    for (dt, adaptive, s) in runs {
        let (Some(w), Some(c)) = (s.window, s.cruise) else {
            continue;
        };
        let change = out.last().map(|p| {
            (w.mean_friction_torque - p.mean_friction_torque).abs()
                / p.mean_friction_torque.abs().max(1e-12)
        });
        out.push(Level {
            dt,
            adaptive,
            evaluations: s.evaluations,
            mean_friction_torque: w.mean_friction_torque,
            twist_peak_to_peak: w.twist_peak_to_peak,
            stick_fraction: w.stick_fraction,
            cruise_friction_torque: c.mean_friction_torque,
            change,
        });
    }
    Study { levels: out }
}

impl fmt::Display for Study {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (step, prev) = if self.levels.first().is_some_and(|l| l.adaptive) {
            ("tol", "the previous tol")
        } else {
            ("dt (s)", "2·dt")
        };
        writeln!(f, "| {step} | mean T_r 0.999–1 s (N·m) | change vs {prev} | θ−θi p-p (mrad) | stuck | mean T_r 0.06–1 s (N·m) | evaluations |")?;
        writeln!(f, "|---|---|---|---|---|---|---|")?;
        for l in &self.levels {
            let ch = l
                .change
                .map_or("—".to_string(), |c| format!("{:.3} %", 100.0 * c));
            writeln!(
                f,
                "| {:.2e} | {:.4} | {} | {:.4} | {:.1} % | {:.4} | {} |",
                l.dt,
                l.mean_friction_torque,
                ch,
                l.twist_peak_to_peak * 1e3,
                100.0 * l.stick_fraction,
                l.cruise_friction_torque,
                l.evaluations
            )?;
        }
        Ok(())
    }
}
