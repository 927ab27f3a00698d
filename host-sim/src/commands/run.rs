//! `host-sim run`: one run in paper, closed-loop or open-loop mode, its summary and energy
//! balance; the scenario from the defaults, a TOML file and the flags.

use super::{CaseArgs, Direction, SimArgs};
use crate::cli::Lube;
use crate::twin::physics::Lubricant;
use crate::twin::plant::{SpeedProfile, StructureDamping};
use crate::twin::sim::{Driver, OpenLoopDuty, Sim, SimConfig, Stepping};
use clap::ValueEnum;
use serde::Deserialize;
use std::error::Error;
use std::path::PathBuf;
use std::time::Instant as WallClock;

#[derive(Clone, Copy, Debug, ValueEnum, Deserialize, PartialEq)]
#[serde(rename_all = "lowercase")]
enum Mode {
    /// θ_i prescribed by the paper's Fig. 2 speed profile (no motor).
    Paper,
    /// The liftfw core in the loop (motor, bridge, sensors simulated).
    Closed,
    /// Fixed bridge duty with a soft start (exercises the motor path).
    Duty,
}

/// A scenario: the defaults, overridden by a TOML file, overridden by flags. Field names are
/// the flags' names with `_` for `-`.
#[derive(Debug, Clone, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct Scenario {
    lubricant: Lube,
    start_deg: f64,
    direction: Direction,
    pin_friction: f64,
    load_kg: f64,
    duration: f64,
    cx: Option<f64>,
    mode: Mode,
    cruise: f64,
    duty: f64,
    seed: u64,
    noise: f64,
    dt: f64,
    tol: Option<f64>,
    h_max: Option<f64>,
    control_hz: f64,
    record_hz: f64,
    csv: Option<PathBuf>,
    /// Faults to inject in closed mode ([`crate::twin::inject`]), e.g. ["jam@2:800"].
    faults: Vec<String>,
}

impl Default for Scenario {
    fn default() -> Self {
        Self {
            lubricant: Lube::Dry,
            start_deg: 15.0,
            direction: Direction::Up,
            pin_friction: 0.3,
            load_kg: 1000.0,
            duration: 5.0,
            cx: None,
            mode: Mode::Paper,
            cruise: crate::twin::plant::profile::PAPER_CRUISE,
            duty: 1.0,
            seed: 0,
            noise: 1.0,
            dt: crate::twin::sim::DEFAULT_DT,
            tol: None,
            h_max: None,
            control_hz: 1000.0,
            record_hz: 10_000.0,
            csv: None,
            faults: Vec::new(),
        }
    }
}

#[derive(clap::Args, Debug, Default)]
#[command(
    after_help = "TOML scenario file (every key optional; flags override it):\n\n  \
lubricant = \"ptfe\"      # dry | ptfe | lithium\n  start_deg = 45.0\n  direction = \"down\"      # up | down\n  \
pin_friction = 0.3\n  load_kg = 800.0\n  duration = 2.0\n  cx = 1e6                # constant structure damping, kg/s\n  \
mode = \"paper\"          # paper | duty | closed\n  cruise = 15.0\n  duty = 0.8\n  seed = 7\n  noise = 1.0\n  \
dt = 2e-6\n  tol = 3e-4              # adaptive steps (paper mode)\n  h_max = 1e-3\n  control_hz = 1000.0\n  record_hz = 10000.0\n  csv = \"trace.csv\"\n  \
faults = [\"supply-sag@1:9.5+0.5\", \"jam@2\"]   # closed mode: KIND@TIME[:SIZE][+DURATION]"
)]
pub struct Args {
    /// Read the scenario from a TOML file first (see below); flags given as well win.
    #[arg(long, value_name = "FILE.toml")]
    config: Option<PathBuf>,
    #[command(flatten)]
    case: CaseArgs,
    #[command(flatten)]
    sim: SimArgs,
    /// Lifted mass, kg [default: 1000].
    #[arg(long)]
    load_kg: Option<f64>,
    /// Driving mode [default: paper].
    #[arg(long, value_enum)]
    mode: Option<Mode>,
    /// Duty mode: bridge duty magnitude, 0–1 [default: 1].
    #[arg(long)]
    duty: Option<f64>,
    /// Seed of the sensor noise [default: 0].
    #[arg(long)]
    seed: Option<u64>,
    /// Sensor noise scale: 0 noiseless, 1 the modelled ADC noise [default: 1].
    #[arg(long)]
    noise: Option<f64>,
    /// Control rate of the core, Hz [default: 1000].
    #[arg(long)]
    control_hz: Option<f64>,
    /// Trace sampling rate for --csv, Hz [default: 10000].
    #[arg(long)]
    record_hz: Option<f64>,
    /// Write the ground-truth trace as CSV.
    #[arg(long, value_name = "PATH")]
    csv: Option<PathBuf>,
    /// Closed mode: inject a fault, KIND@TIME[:SIZE][+DURATION] (see `host-sim lift --help`);
    /// repeat for more; added to the file's `faults`.
    #[arg(long, value_name = "FAULT")]
    fault: Vec<String>,
}

impl Args {
    /// Defaults ← TOML file ← flags.
    fn scenario(&self) -> Result<Scenario, String> {
        let mut s = match &self.config {
            Some(path) => {
                let text = std::fs::read_to_string(path)
                    .map_err(|e| format!("{}: {e}", path.display()))?;
                toml::from_str::<Scenario>(&text).map_err(|e| format!("{}: {e}", path.display()))?
            }
            None => Scenario::default(),
        };
        macro_rules! take {
            ($($src:expr => $dst:ident),* $(,)?) => { $(if let Some(v) = $src.clone() { s.$dst = v; })* };
        }
        take!(
            self.case.lubricant => lubricant,
            self.case.start_deg => start_deg,
            self.case.direction => direction,
            self.case.pin_friction => pin_friction,
            self.load_kg => load_kg,
            self.sim.duration => duration,
            self.mode => mode,
            self.sim.cruise => cruise,
            self.duty => duty,
            self.seed => seed,
            self.noise => noise,
            self.sim.dt => dt,
            self.control_hz => control_hz,
            self.record_hz => record_hz,
        );
        for (flag, field) in [
            (self.sim.cx, &mut s.cx),
            (self.sim.tol, &mut s.tol),
            (self.sim.h_max, &mut s.h_max),
        ] {
            if flag.is_some() {
                *field = flag;
            }
        }
        if self.csv.is_some() {
            s.csv.clone_from(&self.csv);
        }
        s.faults.extend(self.fault.iter().cloned());
        Ok(s)
    }
}

/// Runs `host-sim run`.
pub fn run(a: &Args) -> Result<(), Box<dyn Error>> {
    let sc = a.scenario()?;
    let mut cfg = SimConfig::paper(
        Lubricant::from(sc.lubricant).law(),
        sc.pin_friction,
        sc.start_deg,
    );
    cfg.plant.load = sc.load_kg;
    if let Some(cx) = sc.cx {
        cfg.plant.damping = StructureDamping::Constant(cx);
    }
    cfg.duration = sc.duration;
    cfg.dt = sc.dt;
    cfg.stepping = SimArgs::stepping(sc.tol, sc.h_max);
    cfg.seed = sc.seed;
    cfg.sensors.current_noise *= sc.noise;
    cfg.sensors.supply_noise *= sc.noise;
    cfg.control_rate = sc.control_hz;
    cfg.record_rate = if sc.csv.is_some() { sc.record_hz } else { 0.0 };
    let faults = sc
        .faults
        .iter()
        .map(|f| f.parse::<crate::twin::inject::Injection>())
        .collect::<Result<Vec<_>, _>>()?;
    if !faults.is_empty() && sc.mode != Mode::Closed {
        return Err("faults are injected into closed-loop runs: add --mode closed".into());
    }
    cfg.faults = crate::twin::inject::Plan::new(&faults)?;
    let sign = sc.direction.sign();
    let driver = match sc.mode {
        Mode::Paper => Driver::Paper(SpeedProfile::paper(sign * sc.cruise.abs())),
        Mode::Closed => Driver::Core(Box::new(
            liftfw::control::Controller::new(&liftfw::control::config::ControlConfig::DEFAULT, 0)
                .map_err(|e| format!("{e:?}"))?,
        )),
        Mode::Duty => Driver::OpenLoop(OpenLoopDuty {
            duty: sign * sc.duty.abs(),
            ramp: 0.2,
        }),
    };
    println!(
        "host-sim run: {:?} mode, {} thread, {:?} from α = {}°, load {} kg, μ_b = {}, {} s {}",
        sc.mode,
        Lubricant::from(sc.lubricant).name(),
        sc.direction,
        sc.start_deg,
        sc.load_kg,
        sc.pin_friction,
        sc.duration,
        match cfg.stepping {
            Stepping::Fixed => format!("at dt = {:.1e} s", sc.dt),
            Stepping::Adaptive { tol, h_max } =>
                format!("with adaptive steps (tol {tol:.0e}, h_max {h_max:.0e} s)"),
        }
    );
    let wall = WallClock::now();
    let mut sim = Sim::new(cfg, driver)?;
    let summary = sim.run();
    let secs = wall.elapsed().as_secs_f64();
    println!("{summary}");
    println!(
        "wall time   {:.6} s ({:.6} s per simulated second)",
        secs,
        secs / summary.duration
    );
    if let Some(path) = &sc.csv {
        let f = std::io::BufWriter::new(std::fs::File::create(path)?);
        sim.trace.write_csv(f)?;
        println!(
            "trace       {} samples → {}",
            sim.trace.records.len(),
            path.display()
        );
    }
    Ok(())
}
