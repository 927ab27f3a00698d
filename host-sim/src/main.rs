//! `host-sim`: run the lift's digital twin from the command line.

use clap::{Parser, Subcommand, ValueEnum};
use host_sim::physics::Lubricant;
use host_sim::plant::SpeedProfile;
use host_sim::sim::{Driver, OpenLoopDuty, Sim, SimConfig};
use std::process::ExitCode;
use std::time::Instant as WallClock;

#[derive(Parser, Debug)]
#[command(
    name = "host-sim",
    version,
    about = "Digital twin of a 12 V screw-jack car scissor lift (seed 000 model)"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Simulate one lift run and print a summary (the default).
    Run(RunArgs),
    /// Step-size convergence study of the mean friction torque over 0.999–1 s.
    Convergence(ConvergenceArgs),
}

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Lube {
    Dry,
    Ptfe,
    Lithium,
}

impl From<Lube> for Lubricant {
    fn from(l: Lube) -> Self {
        match l {
            Lube::Dry => Lubricant::Dry,
            Lube::Ptfe => Lubricant::Ptfe,
            Lube::Lithium => Lubricant::Lithium,
        }
    }
}

#[derive(Clone, Copy, Debug, ValueEnum, PartialEq)]
enum Direction {
    Up,
    Down,
}

#[derive(Clone, Copy, Debug, ValueEnum, PartialEq)]
enum Mode {
    /// θ_i prescribed by the paper's Fig. 2 speed profile.
    Paper,
    /// The liftfw core in the loop (motor, bridge, sensors simulated).
    Closed,
    /// Fixed bridge duty with a soft start (tests the motor path).
    Duty,
}

#[derive(clap::Args, Debug)]
struct RunArgs {
    /// Thread lubrication.
    #[arg(long, value_enum, default_value_t = Lube::Dry)]
    lubricant: Lube,
    /// Arm angle at the start, degrees.
    #[arg(long, default_value_t = 15.0)]
    start_deg: f64,
    /// Direction of travel.
    #[arg(long, value_enum, default_value_t = Direction::Up)]
    direction: Direction,
    /// Lifted mass, kg.
    #[arg(long, default_value_t = 1000.0)]
    load_kg: f64,
    /// Pin friction coefficient μ_b.
    #[arg(long, default_value_t = 0.3)]
    pin_friction: f64,
    /// Simulated time, s.
    #[arg(long, default_value_t = 5.0)]
    duration: f64,
    /// Constant structure damping c_x, kg/s (default: Table 1's c_x(α); the paper's text
    /// value 1e6 makes the thread slide steadily).
    #[arg(long)]
    cx: Option<f64>,
    /// Driving mode.
    #[arg(long, value_enum, default_value_t = Mode::Paper)]
    mode: Mode,
    /// Paper mode: cruise screw speed, rad/s.
    #[arg(long, default_value_t = 15.0)]
    cruise: f64,
    /// Duty mode: bridge duty magnitude, 0–1.
    #[arg(long, default_value_t = 1.0)]
    duty: f64,
    /// Seed of the sensor noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Base integration step, s.
    #[arg(long, default_value_t = host_sim::sim::DEFAULT_DT)]
    dt: f64,
    /// Control rate of the core, Hz.
    #[arg(long, default_value_t = 1000.0)]
    control_hz: f64,
    /// Trace sampling rate, Hz.
    #[arg(long, default_value_t = 10_000.0)]
    record_hz: f64,
    /// Write the ground-truth trace as CSV.
    #[arg(long)]
    csv: Option<std::path::PathBuf>,
}

#[derive(clap::Args, Debug)]
struct ConvergenceArgs {
    /// Thread lubrication.
    #[arg(long, value_enum, default_value_t = Lube::Dry)]
    lubricant: Lube,
    /// Arm angle at the start, degrees.
    #[arg(long, default_value_t = 15.0)]
    start_deg: f64,
    /// Direction of travel.
    #[arg(long, value_enum, default_value_t = Direction::Up)]
    direction: Direction,
    /// Pin friction coefficient μ_b.
    #[arg(long, default_value_t = 0.3)]
    pin_friction: f64,
    /// Largest step tried, s; each next one is half.
    #[arg(long, default_value_t = 8e-6)]
    dt_max: f64,
    /// Number of step sizes.
    #[arg(long, default_value_t = 5)]
    levels: u32,
    /// Study the paper's six dry cases and the two lubricants at 15° lifting instead of one case.
    #[arg(long)]
    all: bool,
}

impl ConvergenceArgs {
    fn default_args() -> Self {
        match Cli::parse_from(["host-sim", "convergence"]).command {
            Some(Command::Convergence(a)) => a,
            _ => unreachable!("the convergence subcommand parses to itself"),
        }
    }
}

fn run(a: &RunArgs) -> Result<(), Box<dyn std::error::Error>> {
    let mut cfg = SimConfig::paper(
        Lubricant::from(a.lubricant).law(),
        a.pin_friction,
        a.start_deg,
    );
    cfg.plant.load = a.load_kg;
    if let Some(cx) = a.cx {
        cfg.plant.damping = host_sim::plant::StructureDamping::Constant(cx);
    }
    cfg.duration = a.duration;
    cfg.dt = a.dt;
    cfg.seed = a.seed;
    cfg.control_rate = a.control_hz;
    cfg.record_rate = if a.csv.is_some() { a.record_hz } else { 0.0 };
    let sign = if a.direction == Direction::Up {
        1.0
    } else {
        -1.0
    };
    let driver = match a.mode {
        Mode::Paper => Driver::Paper(SpeedProfile::paper(sign * a.cruise.abs())),
        Mode::Closed => Driver::Core(Box::new(
            liftfw::control::Controller::new(&liftfw::control::config::ControlConfig::DEFAULT, 0)
                .map_err(|e| format!("{e:?}"))?,
        )),
        Mode::Duty => Driver::OpenLoop(OpenLoopDuty {
            duty: sign * a.duty.abs(),
            ramp: 0.2,
        }),
    };
    println!(
        "host-sim run: {:?} mode, {} thread, {:?} from α = {}°, load {} kg, μ_b = {}, {} s at dt = {:.1e} s",
        a.mode,
        Lubricant::from(a.lubricant).name(),
        a.direction,
        a.start_deg,
        a.load_kg,
        a.pin_friction,
        a.duration,
        a.dt
    );
    let wall = WallClock::now();
    let mut sim = Sim::new(cfg, driver)?;
    let summary = sim.run();
    let secs = wall.elapsed().as_secs_f64();
    println!("{summary}");
    println!(
        "wall time   {:.2} s ({:.2} s per simulated second)",
        secs,
        secs / summary.duration
    );
    if let Some(path) = &a.csv {
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

fn convergence(a: &ConvergenceArgs) {
    let sign = if a.direction == Direction::Up {
        1.0
    } else {
        -1.0
    };
    let cases: Vec<(Lubricant, f64, f64, f64)> = if a.all {
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
        vec![(a.lubricant.into(), a.pin_friction, a.start_deg, sign)]
    };
    // Two cases at a time: the studies are independent.
    for chunk in cases.chunks(2) {
        let out: Vec<String> = std::thread::scope(|s| {
            let handles: Vec<_> = chunk
                .iter()
                .map(|&(lube, mu, deg, sg)| {
                    s.spawn(move || {
                        let st = host_sim::study::convergence(
                            lube.law(),
                            mu,
                            deg,
                            sg * 15.0,
                            a.dt_max,
                            a.levels,
                        );
                        let dir = if sg > 0.0 { "lifting" } else { "lowering" };
                        format!(
                            "{} thread, μ_b = {mu}, {dir} from {deg}°:\n{st}",
                            lube.name()
                        )
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().unwrap_or_else(|_| "study panicked".into()))
                .collect()
        });
        for o in out {
            println!("{o}");
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // A bare `host-sim` is `host-sim run` with the defaults.
    let cmd = cli
        .command
        .or_else(|| Cli::parse_from(["host-sim", "run"]).command);
    match cmd.unwrap_or(Command::Convergence(ConvergenceArgs::default_args())) {
        Command::Run(a) => {
            if let Err(e) = run(&a) {
                eprintln!("error: {e}");
                return ExitCode::FAILURE;
            }
        }
        Command::Convergence(a) => convergence(&a),
    }
    ExitCode::SUCCESS
}
