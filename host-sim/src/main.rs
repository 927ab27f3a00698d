//! `host-sim`: run the lift's digital twin from the command line.

use clap::{Args, Parser, Subcommand, ValueEnum};
use host_sim::cli::Lube;
use host_sim::paper::{self, CaseResult, MatrixConfig, Steady};
use host_sim::physics::Lubricant;
use host_sim::plant::{SpeedProfile, StructureDamping};
use host_sim::sim::{Driver, OpenLoopDuty, Sim, SimConfig, Stepping};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant as WallClock;

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
    Lift(LiftArgs),
    /// Simulate one lift run and print a summary (the default).
    Run(RunArgs),
    /// Run seed 000's 18-case matrix in parallel: CSV, PNG plots, summary.md and
    /// docs/paper-reproduction.md.
    Paper(PaperArgs),
    /// Step-size convergence study of the mean friction torque over 0.999–1 s.
    Convergence(ConvergenceArgs),
    /// Score the core's stick-slip detector against the plant's truth over a seeded scenario
    /// set (precision, recall, latency, false alarms), and show the `speed` reaction.
    Stickslip(StickslipArgs),
    /// The simulated board in closed loop, its console on a loopback TCP port (for liftctl).
    Serve(host_sim::serve::ServeArgs),
    /// Seed 001's ball-screw load distribution study (Figs 14–21): CSV, PNG plots and
    /// docs/ballscrew-reproduction.md; `--bench` times the solver.
    Ballscrew(BallscrewArgs),
}

#[derive(Args, Debug)]
struct LiftArgs {
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
    fault: Vec<host_sim::inject::Injection>,
}

fn parse_fault(s: &str) -> Result<host_sim::inject::Injection, String> {
    s.parse()
}

#[derive(Args, Debug)]
struct StickslipArgs {
    /// Number of scenarios in the scored set.
    #[arg(long, default_value_t = 64)]
    scenarios: usize,
    /// Seed of the scenario generator.
    #[arg(long, default_value_t = 7)]
    seed: u64,
    /// Run the regression test's small set instead.
    #[arg(long)]
    quick: bool,
    /// Print one line per run.
    #[arg(long)]
    verbose: bool,
    /// Also run the mitigation demonstration (reaction `log` against `speed`).
    #[arg(long)]
    mitigation: bool,
    /// Integration step, s.
    #[arg(long, default_value_t = 4e-6)]
    dt: f64,
    /// Override the detector's slip threshold `stickslip.drop`, N·m (for tuning).
    #[arg(long)]
    drop: Option<f64>,
    /// Parallel jobs [default: one per core].
    #[arg(long)]
    jobs: Option<usize>,
}

#[derive(Args, Debug)]
struct BallscrewArgs {
    /// Output directory for CSVs and PNGs.
    #[arg(long, default_value = "target/ballscrew")]
    out: PathBuf,
    /// Where to write the report [default: the repository's docs/ballscrew-reproduction.md,
    /// which `host-sim paper` includes in docs/paper-reproduction.md].
    #[arg(long, value_name = "PATH")]
    doc: Option<PathBuf>,
    /// Do not write the report.
    #[arg(long)]
    no_doc: bool,
    /// Skip the PNG plots.
    #[arg(long)]
    no_plots: bool,
    /// Seed of the random error pattern of the bands.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Also time the solver (one 78-ball case; a 100-point sweep) and print the report.
    #[arg(long)]
    bench: bool,
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
                h_max: h_max.unwrap_or(host_sim::sim::ADAPTIVE_H_MAX),
            },
            None => Stepping::Fixed,
        }
    }
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
    /// Faults to inject in closed mode (`host_sim::inject`), e.g. ["jam@2:800"].
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
            cruise: host_sim::plant::profile::PAPER_CRUISE,
            duty: 1.0,
            seed: 0,
            noise: 1.0,
            dt: host_sim::sim::DEFAULT_DT,
            tol: None,
            h_max: None,
            control_hz: 1000.0,
            record_hz: 10_000.0,
            csv: None,
            faults: Vec::new(),
        }
    }
}

#[derive(Args, Debug, Default)]
#[command(
    after_help = "TOML scenario file (every key optional; flags override it):\n\n  \
lubricant = \"ptfe\"      # dry | ptfe | lithium\n  start_deg = 45.0\n  direction = \"down\"      # up | down\n  \
pin_friction = 0.3\n  load_kg = 800.0\n  duration = 2.0\n  cx = 1e6                # constant structure damping, kg/s\n  \
mode = \"paper\"          # paper | duty | closed\n  cruise = 15.0\n  duty = 0.8\n  seed = 7\n  noise = 1.0\n  \
dt = 2e-6\n  tol = 3e-4              # adaptive steps (paper mode)\n  h_max = 1e-3\n  control_hz = 1000.0\n  record_hz = 10000.0\n  csv = \"trace.csv\"\n  \
faults = [\"supply-sag@1:9.5+0.5\", \"jam@2\"]   # closed mode: KIND@TIME[:SIZE][+DURATION]"
)]
struct RunArgs {
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

impl RunArgs {
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

#[derive(Args, Debug)]
struct PaperArgs {
    /// Output directory for CSVs, PNGs and summary.md.
    #[arg(long, default_value = "target/paper")]
    out: PathBuf,
    /// Where to write the generated reproduction report [default: the repository's
    /// docs/paper-reproduction.md]. A docs/ballscrew-reproduction.md beside it is included.
    #[arg(long, value_name = "PATH")]
    doc: Option<PathBuf>,
    /// Do not write the reproduction report.
    #[arg(long)]
    no_doc: bool,
    /// Skip the PNG plots.
    #[arg(long)]
    no_plots: bool,
    /// Skip the steady-sliding companion runs (constant c_x = 1e6, lifting, 1 s).
    #[arg(long)]
    no_steady: bool,
    /// Parallel jobs [default: one per core].
    #[arg(long)]
    jobs: Option<usize>,
    /// Duration, speed, damping (main matrix) and step of every run.
    #[command(flatten)]
    sim: SimArgs,
    /// Sampling rate of the per-run CSVs, Hz (the 0.999–1 s window is written at every step).
    #[arg(long, default_value_t = 1000.0)]
    csv_hz: f64,
}

#[derive(Args, Debug)]
struct ConvergenceArgs {
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

fn run(a: &RunArgs) -> Result<(), Box<dyn std::error::Error>> {
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
        .map(|f| f.parse::<host_sim::inject::Injection>())
        .collect::<Result<Vec<_>, _>>()?;
    if !faults.is_empty() && sc.mode != Mode::Closed {
        return Err("faults are injected into closed-loop runs: add --mode closed".into());
    }
    cfg.faults = host_sim::inject::Plan::new(&faults)?;
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

/// The repository's docs/paper-reproduction.md (host-sim sits one level below the root).
fn default_doc() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("docs")
        .join("paper-reproduction.md")
}

/// One job of the paper command: a case of the main matrix (with files) or a companion run.
struct Job {
    case: paper::Case,
    steady: bool,
}

fn paper_cmd(a: &PaperArgs) -> Result<(), Box<dyn std::error::Error>> {
    let wall = WallClock::now();
    let d = MatrixConfig::default();
    let m = MatrixConfig {
        cruise: a.sim.cruise.unwrap_or(d.cruise),
        duration: a.sim.duration.unwrap_or(d.duration),
        dt: a.sim.dt.unwrap_or(d.dt),
        stepping: SimArgs::stepping(a.sim.tol, a.sim.h_max),
        damping: a
            .sim
            .cx
            .map_or(StructureDamping::Table1, StructureDamping::Constant),
        ..d
    };
    let steady_cx = 1e6;
    let ms = MatrixConfig {
        duration: m.duration.min(1.0),
        damping: StructureDamping::Constant(steady_cx),
        record_rate: 2000.0,
        ..m
    };
    std::fs::create_dir_all(&a.out)?;
    let plots = !a.no_plots;
    if plots {
        match host_sim::plots::init_font() {
            Ok(p) => println!("font        {}", p.display()),
            Err(e) => return Err(e.into()),
        }
    }
    let mut jobs: Vec<Job> = paper::matrix()
        .into_iter()
        .map(|case| Job {
            case,
            steady: false,
        })
        .collect();
    if !a.no_steady {
        // Lifting only: lowering under c_x = 1e6 turns the damping negative (docs/plant.md).
        jobs.extend(
            paper::matrix()
                .into_iter()
                .filter(|c| c.lifting)
                .map(|case| Job { case, steady: true }),
        );
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.jobs.unwrap_or(0))
        .build()?;
    let pb = ProgressBar::new(jobs.len() as u64);
    pb.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} runs  {msg}",
        )?
        .progress_chars("=> "),
    );
    let csv_every = (m.record_rate / a.csv_hz.max(1e-9)).round().max(1.0) as usize;
    let out: Vec<Result<(CaseResult, bool, f64), String>> = pool.install(|| {
        jobs.par_iter()
            .map(|job| {
                let t0 = WallClock::now();
                let cfg = if job.steady { &ms } else { &m };
                let (r, trace) = paper::run_case(job.case, cfg);
                if !job.steady {
                    let stem = job.case.slug();
                    let csv = paper::csv_trace(&trace, csv_every, m.zoom);
                    let path = a.out.join(format!("{stem}.csv"));
                    let f = std::fs::File::create(&path)
                        .map_err(|e| format!("{}: {e}", path.display()))?;
                    csv.write_csv(std::io::BufWriter::new(f))
                        .map_err(|e| format!("{}: {e}", path.display()))?;
                    drop(trace);
                    if plots {
                        host_sim::plots::case_plot(&a.out.join(format!("{stem}.png")), &r)?;
                    }
                }
                let secs = t0.elapsed().as_secs_f64();
                pb.set_message(format!(
                    "{}{}",
                    job.case.slug(),
                    if job.steady { " (steady)" } else { "" }
                ));
                pb.inc(1);
                Ok((r, job.steady, secs))
            })
            .collect()
    });
    pb.finish_and_clear();
    let mut main = Vec::new();
    let mut steady = Vec::new();
    let mut run_secs = Vec::new();
    for o in out {
        let (r, is_steady, secs) = o?;
        if is_steady {
            steady.push(r);
        } else {
            run_secs.push((r.case.slug(), secs));
            main.push(r);
        }
    }
    if plots {
        for l in Lubricant::ALL {
            let rs: Vec<&CaseResult> = main.iter().filter(|r| r.case.lubricant == l).collect();
            let fig = rs.first().map_or(13, |r| r.case.figure());
            let path = a.out.join(format!("fig{fig}_{}.png", l.name()));
            host_sim::plots::figure(
                &path,
                &format!(
                    "{} thread: friction torque T and θ − θi (layout of seed 000 Fig. {fig})",
                    l.name()
                ),
                &rs,
            )?;
        }
    }
    let steady = (!a.no_steady).then_some(Steady {
        c_x: steady_cx,
        results: steady,
    });
    let total = wall.elapsed().as_secs_f64();
    let mut summary = paper::summary_markdown(&main, &m);
    summary.push_str(&format!(
        "\nWall time: {total:.2} s for {} runs on {} threads (per run: {}).\n",
        jobs.len(),
        pool.current_num_threads(),
        run_secs
            .iter()
            .map(|(s, t)| format!("{s} {t:.2} s"))
            .collect::<Vec<_>>()
            .join(", ")
    ));
    std::fs::write(a.out.join("summary.md"), &summary)?;
    println!("{}", paper::matrix_table(&main));
    if !a.no_doc {
        let doc = a.doc.clone().unwrap_or_else(default_doc);
        let ball = doc.with_file_name("ballscrew-reproduction.md");
        let ball = std::fs::read_to_string(&ball).ok();
        let text = paper::reproduction_markdown(&main, steady.as_ref(), &m, ball.as_deref());
        std::fs::write(&doc, text)?;
        println!("report      {}", doc.display());
    }
    println!(
        "output      {} (CSV{}, summary.md)",
        a.out.display(),
        if plots { ", PNG" } else { "" }
    );
    println!(
        "wall time   {total:.2} s for {} runs ({} of the matrix + {} steady companions) on {} threads",
        jobs.len(),
        main.len(),
        jobs.len() - main.len(),
        pool.current_num_threads()
    );
    Ok(())
}

fn convergence(a: &ConvergenceArgs) {
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
                Some(tol) => host_sim::study::tolerance_convergence(
                    lube.law(),
                    mu,
                    deg,
                    sg * 15.0,
                    tol,
                    a.levels,
                ),
                None => {
                    host_sim::study::convergence(lube.law(), mu, deg, sg * 15.0, a.dt_max, a.levels)
                }
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

fn stickslip(a: &StickslipArgs) -> Result<(), Box<dyn std::error::Error>> {
    use host_sim::score::{self, Mitigation, ScoreConfig};
    let wall = WallClock::now();
    let sc = ScoreConfig {
        dt: a.dt,
        drop_threshold: a.drop,
        ..ScoreConfig::default()
    };
    let set = if a.quick {
        score::quick_set()
    } else {
        score::scenario_set(a.scenarios, a.seed)
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.jobs.unwrap_or(0))
        .build()?;
    let t = &sc.truth;
    println!(
        "host-sim stickslip: {} scenarios (seed {}), dt = {:.0e} s; episode = ≥ {} cycles of drop ≥ {} N·m and period ≥ {} ms, breakaways ≤ {} s apart, ≥ {} ms long",
        set.len(),
        a.seed,
        sc.dt,
        t.min_cycles,
        t.min_drop,
        t.min_period * 1e3,
        t.max_gap,
        t.min_duration * 1e3
    );
    let results: Vec<score::RunResult> =
        pool.install(|| set.par_iter().map(|s| score::run(s, &sc)).collect());
    if a.verbose {
        for r in &results {
            println!("{}", score::run_line(r));
        }
    }
    let s = score::score(&results);
    println!("{s}");
    if !s.missed.is_empty() {
        println!(
            "missed      {}",
            s.missed
                .iter()
                .map(|(id, t)| format!("#{id} at {t:.3} s"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let goals = [
        ("precision ≥ 95 %", s.precision() >= 0.95),
        ("recall ≥ 95 %", s.recall() >= 0.95),
        ("median latency ≤ 50 ms", s.median_latency() <= 0.050),
        ("no false alarm on smooth runs", s.smooth_alarms == 0),
    ];
    println!(
        "goals       {}",
        goals
            .iter()
            .map(|(g, ok)| format!("{g}: {}", if *ok { "met" } else { "MISSED" }))
            .collect::<Vec<_>>()
            .join("; ")
    );
    if a.mitigation {
        let set = score::mitigation_set();
        let jobs: Vec<(score::Scenario, bool)> =
            set.iter().flat_map(|s| [(*s, false), (*s, true)]).collect();
        let runs: Vec<score::RunResult> = pool.install(|| {
            jobs.par_iter()
                .map(|(s, speed)| {
                    let s = score::Scenario {
                        reaction: if *speed {
                            liftfw::detect::stickslip::Reaction::ChangeSpeed
                        } else {
                            liftfw::detect::stickslip::Reaction::Log
                        },
                        ..*s
                    };
                    score::run(&s, &sc)
                })
                .collect()
        });
        println!(
            "mitigation  reaction `speed` (escape {} rad/s) against `log`: stick-slip after the first onset until STOP",
            sc.escape_speed
        );
        for pair in runs.chunks(2) {
            let m = Mitigation {
                scenario: pair[0].scenario,
                log: pair[0].clone(),
                speed: pair[1].clone(),
            };
            let t_on = m.speed.onsets.first().map_or(f64::NAN, |o| o.0);
            let (a_log, n_log) = Mitigation::stick_slip_after(&m.log, t_on);
            let (a_spd, n_spd) = Mitigation::stick_slip_after(&m.speed, t_on);
            println!(
                "  {}: onset {:.3} s; log {:.3} s of stick-slip ({} cycles) → speed {:.3} s ({} cycles); screw speed late {:.2} → {:.2} rad/s",
                m.scenario.name(),
                t_on,
                a_log,
                n_log,
                a_spd,
                n_spd,
                m.log.late_speed,
                m.speed.late_speed
            );
        }
    }
    println!("wall time   {:.1} s", wall.elapsed().as_secs_f64());
    Ok(())
}

/// Min and median of `reps` timings of `f`, seconds.
fn time_it(reps: usize, mut f: impl FnMut()) -> (f64, f64) {
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let w = WallClock::now();
            f();
            w.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    (t[0], t[t.len() / 2])
}

fn ballscrew_cmd(a: &BallscrewArgs) -> Result<(), Box<dyn std::error::Error>> {
    use host_sim::ballscrew::{self as bs, study};
    let wall = WallClock::now();
    let cfg = study::StudyConfig {
        seed: a.seed,
        distribution_seeds: [a.seed, a.seed + 1, a.seed + 2],
        ..study::StudyConfig::default()
    };
    let st = study::run(cfg)?;
    let solved = wall.elapsed().as_secs_f64();
    std::fs::create_dir_all(&a.out)?;
    // One CSV per sweep: the load curve; one for the per-ball loads at the figures' loads.
    for sw in st.bands.iter().chain(&st.distributions) {
        let name = sw
            .label
            .replace('±', "pm")
            .replace([' ', '(', ')'], "_")
            .replace("µ", "u");
        let ks = sw.stiffness();
        let mut csv = String::from(
            "fa_n,loaded,axial_displacement_um,stiffness_n_per_m,q_min_n,q_max_n,q78_over_q1\n",
        );
        for (i, c) in sw.cases.iter().enumerate() {
            let (lo, hi) = c.load_range();
            let k = ks.get(i).map_or(String::new(), |k| format!("{:.6e}", k.1));
            csv.push_str(&format!(
                "{},{},{:.6},{k},{lo:.4},{hi:.4},{:.6}\n",
                c.fa,
                c.loaded,
                c.axial_displacement * 1e6,
                c.end_ratio()
            ));
        }
        std::fs::write(a.out.join(format!("sweep_{name}.csv")), csv)?;
    }
    let mut balls = String::from("set,fa_n,ball,error_um,delta_um,q_n,alpha_deg\n");
    for sw in &st.bands {
        for fa in [500.0, 1000.0, 5000.0] {
            if let Some(c) = sw.at(fa) {
                for j in 0..c.q.len() {
                    balls.push_str(&format!(
                        "{},{fa},{},{:.4},{:.6},{:.4},{:.4}\n",
                        sw.label,
                        j + 1,
                        sw.errors[j] * 1e6,
                        c.delta[j] * 1e6,
                        c.q[j],
                        c.alpha[j].to_degrees()
                    ));
                }
            }
        }
    }
    std::fs::write(a.out.join("balls.csv"), balls)?;
    if !a.no_plots {
        bs::plots::write_all(&a.out, &st)?;
    }
    if !a.no_doc {
        let doc = a
            .doc
            .clone()
            .unwrap_or_else(|| default_doc().with_file_name("ballscrew-reproduction.md"));
        std::fs::write(&doc, study::markdown(&st))?;
        println!("report      {}", doc.display());
    }
    println!(
        "output      {} (CSV{})",
        a.out.display(),
        if a.no_plots { "" } else { ", PNG" }
    );
    println!(
        "study       {} sweeps × {} loads + Figs 14/15, solved in {solved:.3} s",
        st.bands.len() + st.distributions.len(),
        st.config.points
    );
    for sw in &st.bands {
        let c = sw.at(5000.0);
        println!(
            "  {:>6}: loaded at 100/500/1000 N = {}/{}/{}, K_s(1000 N) = {:.3e} N/m, Q78/Q1(5000 N) = {:.3}",
            sw.label,
            sw.at(100.0).map_or(0, |c| c.loaded),
            sw.at(500.0).map_or(0, |c| c.loaded),
            sw.at(1000.0).map_or(0, |c| c.loaded),
            sw.stiffness_at(1000.0).unwrap_or(f64::NAN),
            c.map_or(f64::NAN, |c| c.end_ratio())
        );
    }
    if a.bench {
        let screw = bs::BallScrew::paper();
        let errors = bs::random_errors(a.seed, 2e-6, screw.balls);
        let loads = study::StudyConfig::default().loads();
        let (tmin, tmed) = time_it(20, || {
            let _ = bs::Solver::new(screw, errors.clone());
        });
        println!(
            "bench       K(α) table + solver setup: min {:.3} ms, median {:.3} ms (20 runs)",
            tmin * 1e3,
            tmed * 1e3
        );
        let solver = bs::Solver::new(screw, errors.clone())?;
        for fa in [500.0, 5000.0] {
            let (tmin, tmed) = time_it(200, || {
                let _ = solver.solve(fa, None);
            });
            let c = solver.solve(fa, None)?;
            println!(
                "bench       one case, 78 balls, ±2 µm, F_a = {fa:.0} N, cold start: min {:.1} µs, median {:.1} µs (200 runs; {} Newton iterations, {} passes)",
                tmin * 1e6, tmed * 1e6, c.iterations, c.passes
            );
        }
        let (tmin, tmed) = time_it(20, || {
            let _ = study::sweep(&solver, &loads);
        });
        println!("bench       100-point sweep (100…10 000 N), ±2 µm, warm-started: min {:.2} ms, median {:.2} ms (20 runs)", tmin * 1e3, tmed * 1e3);
        let (tmin, tmed) = time_it(20, || {
            for &fa in &loads {
                let _ = solver.solve(fa, None);
            }
        });
        println!("bench       100-point sweep, every load from a cold start: min {:.2} ms, median {:.2} ms (20 runs)", tmin * 1e3, tmed * 1e3);
        let (tmin, tmed) = time_it(5, || {
            let _ = bs::Solver::new(screw, errors.clone()).and_then(|s| study::sweep(&s, &loads));
        });
        println!("bench       100-point sweep including the solver setup: min {:.2} ms, median {:.2} ms (5 runs)", tmin * 1e3, tmed * 1e3);
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // A bare `host-sim` is `host-sim run` with the defaults.
    let cmd = cli.command.unwrap_or(Command::Run(RunArgs::default()));
    let res = match cmd {
        Command::Lift(a) => host_sim::lift::main(&host_sim::lift::LiftArgs {
            lubricant: a.lubricant.into(),
            load_kg: a.load_kg,
            from_mm: a.from_mm,
            to_mm: a.to_mm,
            seed: a.seed,
            plot: (!a.no_plot).then_some(a.plot),
            faults: a.fault.clone(),
        })
        .map(|_| ())
        .map_err(Into::into),
        Command::Run(a) => run(&a),
        Command::Paper(a) => paper_cmd(&a),
        Command::Convergence(a) => {
            convergence(&a);
            Ok(())
        }
        Command::Stickslip(a) => stickslip(&a),
        Command::Serve(a) => host_sim::serve::main(&a),
        Command::Ballscrew(a) => ballscrew_cmd(&a),
    };
    match res {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
