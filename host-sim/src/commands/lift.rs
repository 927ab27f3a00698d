//! `host-sim lift`: the board's core lifts a car to a set height (the app: [`crate::apps::lift`]).

use crate::apps::lift::{self, LiftArgs};
use crate::cli::Lube;
use crate::twin::physics::Lubricant;
use std::error::Error;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Thread lubricant (plant and the core's friction law).
    #[arg(long, value_enum, default_value = "ptfe")]
    lubricant: Lube,
    /// Mass on the head, kg.
    #[arg(long, default_value_t = 1000.0)]
    load_kg: f64,
    /// Start height, mm (the mechanism spans 133.5–416.4 mm).
    #[arg(long, default_value_t = 150.0)]
    from_mm: f64,
    /// Target height, mm (between the limit stops, 145–410 mm by default).
    #[arg(long, default_value_t = 180.0)]
    to_mm: f64,
    /// Sensor-noise seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// PNG of height and T_r, plant vs core.
    #[arg(long, default_value = "target/lift.png")]
    plot: PathBuf,
    /// Skip the plot.
    #[arg(long)]
    no_plot: bool,
    /// Inject a fault: KIND@TIME[:SIZE][+DURATION] (s, size per kind), e.g. encoder-loss@2,
    /// current-offset@1.5:4, supply-sag@3:9.5+0.5, jam@4, overload@2:500,
    /// lower-switch-dead@0, watchdog-stall@3:0.2; repeat the flag for more.
    #[arg(long, value_name = "FAULT", value_parser = parse_fault)]
    fault: Vec<crate::twin::inject::Injection>,
    /// Lift with the flashed firmware instead of the core: the ELF on the emulated STM32G431
    /// (the `fwsim` program, docs/fwsim.md); without a path, scripts/fw-build's default image
    /// (built when missing). Prints the firmware's status beside the plant and the halt.
    #[arg(long, value_name = "ELF", num_args = 0..=1, default_missing_value = "")]
    firmware: Option<PathBuf>,
}

fn parse_fault(s: &str) -> Result<crate::twin::inject::Injection, String> {
    s.parse()
}

/// Runs `host-sim lift`.
pub fn run(a: Args) -> Result<(), Box<dyn Error>> {
    if let Some(elf) = a.firmware {
        if !a.fault.is_empty() {
            return Err(
                "--fault injects into the core-in-the-loop run; fwsim does not take it yet".into(),
            );
        }
        let lube = match Lubricant::from(a.lubricant) {
            Lubricant::Dry => "dry",
            Lubricant::Ptfe => "ptfe",
            Lubricant::Lithium => "lithium",
        };
        let args = [
            "--lubricant".to_string(),
            lube.into(),
            "--load-kg".into(),
            a.load_kg.to_string(),
            "--from-mm".into(),
            a.from_mm.to_string(),
            "--to-mm".into(),
            a.to_mm.to_string(),
            "--seed".into(),
            a.seed.to_string(),
        ];
        let elf = (!elf.as_os_str().is_empty()).then_some(elf);
        return super::firmware::run("lift", elf, &args);
    }
    lift::main(&LiftArgs {
        lubricant: a.lubricant.into(),
        load_kg: a.load_kg,
        from_mm: a.from_mm,
        to_mm: a.to_mm,
        seed: a.seed,
        plot: (!a.no_plot).then_some(a.plot),
        faults: a.fault,
    })
    .map(|_| ())
    .map_err(Into::into)
}
