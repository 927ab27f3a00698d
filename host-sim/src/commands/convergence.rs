//! `host-sim convergence`: the step-size (or tolerance) convergence study of docs/plant.md.

use super::{CaseArgs, Direction};
use crate::cli::Lube;
use crate::studies::convergence::{convergence, tolerance_convergence};
use crate::studies::paper;
use crate::twin::physics::Lubricant;
use rayon::prelude::*;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    case: CaseArgs,
    /// Largest step tried, s; each next one is half.
    #[arg(long, default_value_t = 8e-6)]
    dt_max: f64,
    /// Number of step sizes.
    #[arg(long, default_value_t = 5)]
    levels: u32,
    /// Study the paper's six dry cases and the two lubricants at 15° lifting instead of one case.
    #[arg(long)]
    all: bool,
    /// Study all 18 cases of the paper's matrix.
    #[arg(long, conflicts_with = "all")]
    matrix: bool,
    /// Study the adaptive option instead: tolerances TOL, TOL/√10, … (1 s runs).
    #[arg(long, value_name = "TOL")]
    tol_max: Option<f64>,
}

/// Runs `host-sim convergence`.
pub fn run(a: &Args) {
    let c = &a.case;
    let sign = c.direction.unwrap_or(Direction::Up).sign();
    let cases: Vec<(Lubricant, f64, f64, f64)> = if a.matrix {
        paper::matrix()
            .into_iter()
            .map(|c| {
                (
                    c.lubricant,
                    c.mu_pin,
                    c.start_deg,
                    if c.lifting { 1.0 } else { -1.0 },
                )
            })
            .collect()
    } else if a.all {
        let mut v: Vec<_> = [
            (0.3, 15.0, 1.0),
            (0.0, 15.0, 1.0),
            (0.3, 45.0, 1.0),
            (0.3, 45.0, -1.0),
            (0.3, 65.0, 1.0),
            (0.3, 65.0, -1.0),
        ]
        .into_iter()
        .map(|(mu, deg, s)| (Lubricant::Dry, mu, deg, s))
        .collect();
        v.push((Lubricant::Ptfe, 0.3, 15.0, 1.0));
        v.push((Lubricant::Lithium, 0.3, 15.0, 1.0));
        v
    } else {
        vec![(
            c.lubricant.unwrap_or(Lube::Dry).into(),
            c.pin_friction.unwrap_or(0.3),
            c.start_deg.unwrap_or(15.0),
            sign,
        )]
    };
    let out: Vec<String> = cases
        .par_iter()
        .map(|&(lube, mu, deg, sg)| {
            let st = match a.tol_max {
                Some(tol) => tolerance_convergence(lube.law(), mu, deg, sg * 15.0, tol, a.levels),
                None => convergence(lube.law(), mu, deg, sg * 15.0, a.dt_max, a.levels),
            };
            let dir = if sg > 0.0 { "lifting" } else { "lowering" };
            format!(
                "{} thread, μ_b = {mu}, {dir} from {deg}°:\n{st}",
                lube.name()
            )
        })
        .collect();
    for o in out {
        println!("{o}");
    }
}
