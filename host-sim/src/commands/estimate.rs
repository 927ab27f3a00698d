//! `host-sim estimate`: the core's load and friction identification scored against the plant
//! (the study: [`crate::studies::estimate`]).

use crate::studies::estimate::{self, EstimateArgs};
use std::error::Error;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Worker threads (0: all cores).
    #[arg(long, default_value_t = 2)]
    jobs: usize,
    /// Where to write the plot.
    #[arg(long, default_value = "target/estimate.png")]
    plot: PathBuf,
    /// Do not draw the plot.
    #[arg(long)]
    no_plot: bool,
    /// Seed sets: 1 is the matrix; each further set repeats the report and drier sets with
    /// other sensor-noise seeds (held out: does a count stop moving?).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=50))]
    seed_sets: u64,
}

/// Runs `host-sim estimate`; fails when a goal of the report sets is missed.
pub fn run(a: &Args) -> Result<(), Box<dyn Error>> {
    let ok = estimate::main(&EstimateArgs {
        jobs: a.jobs,
        plot: (!a.no_plot).then(|| a.plot.clone()),
        seed_sets: a.seed_sets,
    })?;
    if ok {
        Ok(())
    } else {
        Err("goals missed (see the table)".into())
    }
}
