//! Seed 000's scenario matrix (Figs 13–15): lifting from α = 15°, 45°, 65° and lowering from
//! 45°, 65° with μ_b = 0.3, lifting from 15° with μ_b = 0; for dry, PTFE and lithium grease.
//!
//! [`run_case`] simulates one case in paper mode and reduces its trace to what the figures and
//! the reproduction report need ([`CaseResult`]); [`summary_markdown`] and [`reproduction_markdown`]
//! write the tables and the claim-by-claim comparison. The CLI (`host-sim paper`) runs the cases
//! in parallel, writes the CSVs and draws the plots ([`plots`]).

use crate::twin::physics::geometry::DAMPING_TABLE;
use crate::twin::physics::Lubricant;
use crate::twin::plant::{SpeedProfile, StructureDamping};
use crate::twin::sim::{Driver, Sim, SimConfig, Stepping, Summary, DEFAULT_DT};
use crate::twin::trace::{Record, Trace};
use std::fmt::Write as _;

pub mod plots;
mod report;

pub use report::{fill, reproduction_markdown};

/// One scenario of the matrix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Case {
    /// Thread lubrication.
    pub lubricant: Lubricant,
    /// Arm angle at the start, degrees.
    pub start_deg: f64,
    /// Lifting (true) or lowering.
    pub lifting: bool,
    /// Pin friction coefficient μ_b.
    pub mu_pin: f64,
}

impl Case {
    /// File-name stem, e.g. `dry_15_up_mub0.3`.
    pub fn slug(&self) -> String {
        format!(
            "{}_{:.0}_{}_mub{}",
            self.lubricant.name(),
            self.start_deg,
            if self.lifting { "up" } else { "down" },
            self.mu_pin
        )
    }

    /// Human label, e.g. `lifting from 15°, μ_b 0.3`.
    pub fn label(&self) -> String {
        format!(
            "{} from {:.0}°, μ_b {}",
            if self.lifting { "lifting" } else { "lowering" },
            self.start_deg,
            self.mu_pin
        )
    }

    /// The panel letter of the torque plot in the paper's figure (a, d, g, j, m, p).
    pub fn panel(&self) -> &'static str {
        match (self.start_deg as u32, self.lifting, self.mu_pin > 0.0) {
            (15, true, true) => "a",
            (15, true, false) => "d",
            (45, true, _) => "g",
            (45, false, _) => "j",
            (65, true, _) => "m",
            _ => "p",
        }
    }

    /// The paper's figure number for this lubricant (13 dry, 14 PTFE, 15 lithium).
    pub fn figure(&self) -> u32 {
        match self.lubricant {
            Lubricant::Dry => 13,
            Lubricant::Ptfe => 14,
            Lubricant::Lithium => 15,
        }
    }
}

/// The six geometries of one figure, in the paper's panel order (a, d, g, j, m, p).
pub const GEOMETRIES: [(f64, bool, f64); 6] = [
    (15.0, true, 0.3),
    (15.0, true, 0.0),
    (45.0, true, 0.3),
    (45.0, false, 0.3),
    (65.0, true, 0.3),
    (65.0, false, 0.3),
];

/// The 18 cases: dry, PTFE, lithium × [`GEOMETRIES`].
pub fn matrix() -> Vec<Case> {
    Lubricant::ALL
        .iter()
        .flat_map(|&lubricant| {
            GEOMETRIES
                .iter()
                .map(move |&(start_deg, lifting, mu_pin)| Case {
                    lubricant,
                    start_deg,
                    lifting,
                    mu_pin,
                })
        })
        .collect()
}

/// Settings shared by every case of a matrix run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MatrixConfig {
    /// Cruise screw speed |ω_c|, rad/s.
    pub cruise: f64,
    /// Lifted mass, kg.
    pub load: f64,
    /// Simulated time, s (the paper: 5).
    pub duration: f64,
    /// Base step, s.
    pub dt: f64,
    /// Fixed or adaptive steps.
    pub stepping: Stepping,
    /// Structure damping.
    pub damping: StructureDamping,
    /// Trace rate for the plots' full-run envelope, Hz.
    pub record_rate: f64,
    /// The zoom window (every step recorded), s.
    pub zoom: (f64, f64),
}

impl Default for MatrixConfig {
    /// The paper's setting with our choices where it is silent (docs/plant.md).
    fn default() -> Self {
        Self {
            cruise: crate::twin::plant::profile::PAPER_CRUISE,
            load: 1000.0,
            duration: 5.0,
            dt: DEFAULT_DT,
            stepping: Stepping::Fixed,
            damping: StructureDamping::Table1,
            record_rate: 20_000.0,
            zoom: (0.999, 1.0),
        }
    }
}

/// Whether T_r falls or rises over the constant-speed phase.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trend {
    /// Mean |T_r| over the first second of the constant-speed phase, N·m.
    pub early: f64,
    /// Mean |T_r| over its last second, N·m.
    pub late: f64,
}

impl Trend {
    /// Relative change late vs early.
    pub fn change(&self) -> f64 {
        self.late / self.early - 1.0
    }
}

/// Stick-slip over the constant-speed phase.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StickSlip {
    /// Stick episodes (stick phases that began in the constant-speed phase).
    pub episodes: usize,
    /// Fraction of the constant-speed phase spent stuck.
    pub stuck: f64,
    /// Median over 50-ms blocks of the peak-to-peak θ − θ_i, rad: the oscillation amplitude,
    /// free of the slow drift of the mean twist as the load changes.
    pub amplitude: f64,
    /// Largest 50-ms block peak-to-peak θ − θ_i, rad.
    pub amplitude_max: f64,
}

/// A down-sampled series for a plot: (t, min, max) per bin.
pub type Envelope = Vec<(f64, f64, f64)>;

/// What the plots need of a run.
#[derive(Clone, Debug, Default)]
pub struct PlotData {
    /// T_r over the whole run, min/max per bin.
    pub torque: Envelope,
    /// θ − θ_i over the whole run, min/max per bin.
    pub twist: Envelope,
    /// (t, T_r) at every step in the zoom window.
    pub torque_zoom: Vec<(f64, f64)>,
    /// (t, θ − θ_i) at every step in the zoom window.
    pub twist_zoom: Vec<(f64, f64)>,
}

/// One case's outcome.
#[derive(Clone, Debug)]
pub struct CaseResult {
    /// The case.
    pub case: Case,
    /// The run's summary (window = zoom window, cruise = constant-speed phase).
    pub summary: Summary,
    /// T_r early vs late in the constant-speed phase.
    pub trend: Trend,
    /// Stick-slip statistics.
    pub stick_slip: StickSlip,
    /// Plot series.
    pub plot: PlotData,
}

impl CaseResult {
    /// Mean T_r over the zoom window (0.999–1 s), N·m.
    pub fn window_torque(&self) -> f64 {
        self.summary
            .window
            .map_or(f64::NAN, |w| w.mean_friction_torque)
    }

    /// Mean T_r over the constant-speed phase, N·m.
    pub fn cruise_torque(&self) -> f64 {
        self.summary
            .cruise
            .map_or(f64::NAN, |w| w.mean_friction_torque)
    }
}

/// The simulation configuration of `case`.
pub fn sim_config(case: &Case, m: &MatrixConfig) -> SimConfig {
    let mut cfg = SimConfig::paper(case.lubricant.law(), case.mu_pin, case.start_deg);
    cfg.plant.load = m.load;
    cfg.plant.damping = m.damping;
    cfg.duration = m.duration;
    cfg.dt = m.dt;
    cfg.stepping = m.stepping;
    cfg.window = m.zoom;
    cfg.record_rate = m.record_rate;
    cfg.dense_window = Some(m.zoom);
    cfg
}

/// Runs `case` and reduces its trace; returns the trace too (for the CSV).
pub fn run_case(case: Case, m: &MatrixConfig) -> (CaseResult, Trace) {
    let cfg = sim_config(&case, m);
    let speed = if case.lifting { m.cruise } else { -m.cruise };
    let profile = SpeedProfile::paper(speed);
    let mut sim = match Sim::new(cfg, Driver::Paper(profile)) {
        Ok(s) => s,
        Err(e) => unreachable!("paper mode has no control period: {e}"),
    };
    let summary = sim.run();
    let trace = std::mem::take(&mut sim.trace);
    let cruise = (profile.ramp_end, profile.brake_start.min(m.duration));
    let result = CaseResult {
        case,
        trend: trend(&trace, cruise),
        stick_slip: stick_slip(&trace, cruise, &summary),
        plot: plot_data(&trace, m),
        summary,
    };
    (result, trace)
}

fn mean_abs(trace: &Trace, a: f64, b: f64) -> f64 {
    let (n, s) = trace
        .records
        .iter()
        .filter(|r| r.t >= a && r.t <= b)
        .fold((0usize, 0.0), |(n, s), r| (n + 1, s + r.friction_torque));
    (s / n.max(1) as f64).abs()
}

fn trend(trace: &Trace, (a, b): (f64, f64)) -> Trend {
    let len = (b - a).min(1.0);
    Trend {
        early: mean_abs(trace, a, a + len),
        late: mean_abs(trace, b - len, b),
    }
}

/// The blocks over which the stick-slip amplitude is measured, s.
const AMPLITUDE_BLOCK: f64 = 0.05;

fn stick_slip(trace: &Trace, (a, b): (f64, f64), s: &Summary) -> StickSlip {
    let mut pp = Vec::new();
    let mut t0 = a;
    while t0 + AMPLITUDE_BLOCK <= b + 1e-9 {
        let (lo, hi) = trace
            .records
            .iter()
            .filter(|r| r.t >= t0 && r.t < t0 + AMPLITUDE_BLOCK)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
                (lo.min(r.twist), hi.max(r.twist))
            });
        if hi >= lo {
            pp.push(hi - lo);
        }
        t0 += AMPLITUDE_BLOCK;
    }
    pp.sort_by(f64::total_cmp);
    let (episodes, stuck) = s.cruise.map_or((0, 0.0), |c| (c.sticks, c.stick_fraction));
    StickSlip {
        episodes,
        stuck,
        amplitude: pp.get(pp.len() / 2).copied().unwrap_or(0.0),
        amplitude_max: pp.last().copied().unwrap_or(0.0),
    }
}

fn envelope(
    records: &[Record],
    duration: f64,
    bins: usize,
    f: impl Fn(&Record) -> f64,
) -> Envelope {
    let mut out = vec![(0.0, f64::INFINITY, f64::NEG_INFINITY); bins];
    for (i, e) in out.iter_mut().enumerate() {
        e.0 = (i as f64 + 0.5) * duration / bins as f64;
    }
    for r in records {
        let i = ((r.t / duration * bins as f64) as usize).min(bins - 1);
        let v = f(r);
        out[i].1 = out[i].1.min(v);
        out[i].2 = out[i].2.max(v);
    }
    out.retain(|e| e.2 >= e.1);
    out
}

fn plot_data(trace: &Trace, m: &MatrixConfig) -> PlotData {
    let bins = 1200;
    let zoom = |f: fn(&Record) -> f64| {
        trace
            .records
            .iter()
            .filter(|r| r.t >= m.zoom.0 - 1e-12 && r.t <= m.zoom.1 + 1e-12)
            .map(|r| (r.t, f(r)))
            .collect()
    };
    PlotData {
        torque: envelope(&trace.records, m.duration, bins, |r| r.friction_torque),
        twist: envelope(&trace.records, m.duration, bins, |r| r.twist),
        torque_zoom: zoom(|r| r.friction_torque),
        twist_zoom: zoom(|r| r.twist),
    }
}

/// The trace thinned for a CSV: every `every`-th record plus every record in the zoom window.
pub fn csv_trace(trace: &Trace, every: usize, zoom: (f64, f64)) -> Trace {
    Trace {
        records: trace
            .records
            .iter()
            .enumerate()
            .filter(|(i, r)| i % every.max(1) == 0 || (r.t >= zoom.0 && r.t <= zoom.1))
            .map(|(_, r)| *r)
            .collect(),
        phases: trace.phases.clone(),
    }
}

fn find(rs: &[CaseResult], l: Lubricant, deg: f64, up: bool, mu: f64) -> Option<&CaseResult> {
    rs.iter().find(|r| {
        r.case.lubricant == l
            && r.case.start_deg == deg
            && r.case.lifting == up
            && r.case.mu_pin == mu
    })
}

/// The matrix as a Markdown table (one row per case).
pub fn matrix_table(results: &[CaseResult]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| fig. | lubricant | case | mean T_r 0.999–1 s (N·m) | mean T_r constant speed (N·m) | \\|T_r\\| first → last second | trend | stick episodes | stuck | stick-slip amplitude θ−θ_i (median / max p-p per 50 ms, mrad) |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|");
    for r in results {
        let c = &r.case;
        let t = &r.trend;
        let ss = &r.stick_slip;
        let _ = writeln!(
            s,
            "| {}{} | {} | {} | {:.3} | {:.3} | {:.2} → {:.2} | {:+.1} % | {} | {:.1} % | {:.2} / {:.2} |",
            c.figure(),
            c.panel(),
            c.lubricant.name(),
            c.label(),
            r.window_torque(),
            r.cruise_torque(),
            t.early,
            t.late,
            100.0 * t.change(),
            ss.episodes,
            100.0 * ss.stuck,
            1e3 * ss.amplitude,
            1e3 * ss.amplitude_max
        );
    }
    s
}

/// `summary.md`: the parameters and the matrix table (wall times included by the caller).
pub fn summary_markdown(results: &[CaseResult], m: &MatrixConfig) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# host-sim paper: seed 000's scenario matrix\n");
    let _ = writeln!(s, "{}\n", parameters(m));
    s.push_str(&matrix_table(results));
    s
}

fn parameters(m: &MatrixConfig) -> String {
    let damping = match m.damping {
        StructureDamping::Table1 => {
            let t = DAMPING_TABLE;
            let (values, angles): (Vec<String>, Vec<String>) = t
                .iter()
                .map(|&(deg, c)| (grouped(c), format!("{deg:.0}°")))
                .unzip();
            format!(
                "c_x(α) from Table 1 ({} kg/s at {})",
                values.join(" / "),
                angles.join(" / ")
            )
        }
        StructureDamping::Constant(c) => format!("constant c_x = {c:.0} kg/s"),
    };
    let p = SpeedProfile::paper(m.cruise);
    let s = |x: f64| (x * 1e9).round() / 1e9;
    format!(
        "Paper mode (Fig. 2 profile, {} s ramp, hold, {} s brake), |ω_c| = {} rad/s at the screw, \
M = {} kg, {damping}, {} over {} s. Constant-speed phase: {}–{} s; \
trend: mean |T_r| over its first vs its last second.",
        s(p.ramp_end),
        s(p.stop - p.brake_start),
        m.cruise,
        m.load,
        stepping(m),
        m.duration,
        s(p.ramp_end),
        s(p.brake_start.min(m.duration)),
    )
}

/// An integer with its thousands apart, as the docs write them: 58 544.
fn grouped(x: f64) -> String {
    let digits = format!("{:.0}", x.abs());
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i) % 3 == 0 {
            out.push(' ');
        }
        out.push(c);
    }
    if x < 0.0 {
        out.insert(0, '-');
    }
    out
}

/// The integrator's setting in words.
fn stepping(m: &MatrixConfig) -> String {
    match m.stepping {
        Stepping::Fixed => format!("fixed-step RK23 at dt = {:.0e} s", m.dt),
        Stepping::Adaptive { tol, h_max } => {
            format!("adaptive RK23 at tol = {tol:.0e} (steps ≤ {h_max:.0e} s)")
        }
    }
}

/// A companion result in steady sliding (constant c_x = 10⁶ kg/s, 1 s horizon) for the claims
/// that compare kinetic friction levels.
#[derive(Clone, Debug)]
pub struct Steady {
    /// The c_x used, kg/s.
    pub c_x: f64,
    /// The companion runs (summary windows: 0.999–1 s and 0.06–1 s).
    pub results: Vec<CaseResult>,
}
