//! The `host-sim` command line: one file per subcommand, each with its arguments and its `run`.

use crate::cli::Lube;
use crate::twin::sim::Stepping;
use clap::{Args, Parser, Subcommand, ValueEnum};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

mod ballscrew;
mod convergence;
mod estimate;
mod firmware;
mod lift;
mod paper;
mod run;
mod serve;
mod stickslip;

#[derive(Parser, Debug)]
#[command(
    name = "host-sim",
    version,
    about = "Digital twin of a 12 V screw-jack car scissor lift (the screw-nut model of seed 000)",
    long_about = "Digital twin of a 12 V screw-jack car scissor lift: the screw-nut model of \
Woźniak et al. (seed 000) with stick/slip, in float64, driven by the paper's speed profile or by \
a motor.\n\nStart here:\n  host-sim lift                     the board's core lifts 1000 kg to 180 mm: core vs plant, plot\n  host-sim run                      one lift run (dry thread, lifting 1000 kg from 15°)\n  \
host-sim run --lubricant ptfe     the same with PTFE spray\n  host-sim run --config lift.toml   a \
scenario from a TOML file (flags override it)\n  host-sim paper                    the paper's 18 runs: \
CSV, plots, summary, docs/paper-reproduction.md\n  host-sim convergence --all        the step-size study \
of docs/plant.md\n  host-sim ballscrew                seed 001's ball-screw load distribution: CSV, plots, \
docs/ballscrew-reproduction.md\n\nWithout a subcommand, `host-sim` is `host-sim run`.",
    after_help = "Units: angles in degrees, speeds in rad/s at the screw, masses in kg, times in s."
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// The board's core lifts a car to a set height in closed loop: live core vs plant
    /// (height, speed, estimated friction torque), the halt error and a plot.
    Lift(lift::Args),
    /// Simulate one lift run and print a summary (the default).
    Run(run::Args),
    /// Run seed 000's 18-case matrix in parallel: CSV, PNG plots, summary.md and
    /// docs/paper-reproduction.md.
    Paper(paper::Args),
    /// Step-size convergence study of the mean friction torque over 0.999–1 s.
    Convergence(convergence::Args),
    /// Score the core's stick-slip detector against the plant's truth over a seeded scenario
    /// set (precision, recall, latency, false alarms), and show the `speed` reaction.
    Stickslip(stickslip::Args),
    /// The simulated board in closed loop, its console on a loopback TCP port (for liftctl).
    Serve(serve::Args),
    /// Score the core's load and friction identification against the plant: loads 0…1300 kg
    /// × three lubricants × up/down × three start heights, and a thread 1.5×/2× drier than
    /// configured; a table and a PNG.
    Estimate(estimate::Args),
    /// Seed 001's ball-screw load distribution study (Figs 14–21): CSV, PNG plots and
    /// docs/ballscrew-reproduction.md; `--bench` times the solver.
    Ballscrew(ballscrew::Args),
}

#[derive(Clone, Copy, Debug, ValueEnum, Deserialize, PartialEq)]
#[serde(rename_all = "lowercase")]
enum Direction {
    /// Lift the load.
    Up,
    /// Lower it.
    Down,
}

impl Direction {
    fn sign(self) -> f64 {
        match self {
            Direction::Up => 1.0,
            Direction::Down => -1.0,
        }
    }
}

/// The case flags shared by `run` and `convergence`.
#[derive(Args, Debug, Clone, Default)]
struct CaseArgs {
    /// Thread lubrication [default: dry].
    #[arg(long, value_enum)]
    lubricant: Option<Lube>,
    /// Arm angle at the start, degrees (15 = fully down) [default: 15].
    #[arg(long)]
    start_deg: Option<f64>,
    /// Direction of travel [default: up].
    #[arg(long, value_enum)]
    direction: Option<Direction>,
    /// Pin friction coefficient μ_b (0.3 steel pins, 0 ideal) [default: 0.3].
    #[arg(long)]
    pin_friction: Option<f64>,
}

/// The run flags shared by `run` and `paper`: simulated time, profile speed, structure damping
/// and the integrator's step.
#[derive(Args, Debug, Clone, Default)]
struct SimArgs {
    /// Simulated time, s [default: 5].
    #[arg(long)]
    duration: Option<f64>,
    /// Paper mode: cruise screw speed |ω_c|, rad/s [default: 15].
    #[arg(long)]
    cruise: Option<f64>,
    /// Constant structure damping c_x, kg/s [default: Table 1's c_x(α)]. The paper's text value
    /// 1e6 makes the thread slide steadily.
    #[arg(long)]
    cx: Option<f64>,
    /// Base integration step, s [default: 2e-6, the converged step]. With --tol: the first
    /// trial step and the step inside a zoom window.
    #[arg(long)]
    dt: Option<f64>,
    /// Paper mode: adaptive steps (embedded RK23 error estimate) with this error tolerance
    /// instead of the fixed step dt (docs/plant.md) [default: fixed step].
    #[arg(long)]
    tol: Option<f64>,
    /// With --tol: the largest step, s [default: 1e-3].
    #[arg(long, requires = "tol")]
    h_max: Option<f64>,
}

impl SimArgs {
    /// Fixed or adaptive steps, from --tol and --h-max.
    fn stepping(tol: Option<f64>, h_max: Option<f64>) -> Stepping {
        match tol {
            Some(tol) => Stepping::Adaptive {
                tol,
                h_max: h_max.unwrap_or(crate::twin::sim::ADAPTIVE_H_MAX),
            },
            None => Stepping::Fixed,
        }
    }
}

/// A report under the repository's docs/ (host-sim sits one level below the root).
fn repo_doc(file: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("docs")
        .join(file)
}

/// Parses the command line and runs the subcommand; errors are printed, with a failure status.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    // A bare `host-sim` is `host-sim run` with the defaults.
    let cmd = cli.command.unwrap_or(Command::Run(run::Args::default()));
    let res = match cmd {
        Command::Lift(a) => lift::run(a),
        Command::Run(a) => run::run(&a),
        Command::Paper(a) => paper::run(&a),
        Command::Convergence(a) => {
            convergence::run(&a);
            Ok(())
        }
        Command::Stickslip(a) => stickslip::run(&a),
        Command::Serve(a) => serve::run(&a),
        Command::Ballscrew(a) => ballscrew::run(&a),
        Command::Estimate(a) => estimate::run(&a),
    };
    match res {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Cli;
    use clap::CommandFactory;

    /// clap's own consistency checks over every subcommand: flag names, `requires`,
    /// `conflicts_with`, defaults that parse.
    #[test]
    fn the_command_line_is_consistent() {
        Cli::command().debug_assert();
    }
}
