//! `host-sim serve`: the simulated board, its console on loopback TCP. The arguments are the
//! app's own settings ([`ServeArgs`]: tests and liftctl's end-to-end tests start it with them),
//! and `--firmware [ELF]`: the flashed firmware's console instead (fwsim, [`super::firmware`]).

use crate::apps::serve::ServeArgs;
use crate::twin::physics::{Geometry, Lubricant};
use std::error::Error;
use std::path::PathBuf;

/// `host-sim serve`'s arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The simulated board's settings.
    #[command(flatten)]
    pub serve: ServeArgs,
    /// Serve the flashed firmware's console: the ELF on the emulated STM32G431 (the `fwsim`
    /// program, docs/fwsim.md) against the same plant; without a path, scripts/fw-build's
    /// default image (built when missing). `--flash` then keeps its store's flash pages.
    #[arg(long, value_name = "ELF", num_args = 0..=1, default_missing_value = "")]
    pub firmware: Option<PathBuf>,
}

/// Runs `host-sim serve` until it is stopped.
pub fn run(a: &Args) -> Result<(), Box<dyn Error>> {
    let Some(elf) = &a.firmware else {
        return crate::apps::serve::main(&a.serve);
    };
    let s = &a.serve;
    let g = Geometry::paper();
    let from_mm = (g.h0 + g.length * s.start_deg.to_radians().sin()) * 1e3;
    let lube = match Lubricant::from(s.lubricant) {
        Lubricant::Dry => "dry",
        Lubricant::Ptfe => "ptfe",
        Lubricant::Lithium => "lithium",
    };
    let mut args = vec![
        "--listen".to_string(),
        s.listen.to_string(),
        "--speed".into(),
        s.speed.to_string(),
        "--from-mm".into(),
        from_mm.to_string(),
        "--load-kg".into(),
        s.load_kg.to_string(),
        "--lubricant".into(),
        lube.into(),
    ];
    if let Some(f) = &s.flash {
        args.push("--flash".into());
        args.push(f.display().to_string());
    }
    let elf = (!elf.as_os_str().is_empty()).then(|| elf.clone());
    super::firmware::run("serve", elf, &args)
}
