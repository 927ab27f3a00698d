//! Shared set-ups for the host-sim tests: short horizons so the suite stays fast in debug.
#![allow(dead_code, clippy::expect_used)]

use host_sim::physics::Lubricant;
use host_sim::plant::{SpeedProfile, StructureDamping};
use host_sim::sim::{Driver, Sim, SimConfig, Summary};
use host_sim::trace::{Record, Trace};

/// Paper-mode configuration: lubricant, μ_b, start angle (deg), horizon (s), step (s).
pub fn paper_cfg(lube: Lubricant, mu_pin: f64, deg: f64, duration: f64, dt: f64) -> SimConfig {
    let mut cfg = SimConfig::paper(lube.law(), mu_pin, deg);
    cfg.duration = duration;
    cfg.dt = dt;
    cfg.record_rate = 20_000.0;
    cfg.window = (duration - 1e-3, duration);
    cfg
}

/// Runs `cfg` in paper mode at cruise speed `cruise` (rad/s, negative lowers).
pub fn paper(cfg: SimConfig, cruise: f64) -> (Summary, Trace) {
    let mut sim = Sim::new(cfg, Driver::Paper(SpeedProfile::paper(cruise))).expect("valid config");
    let s = sim.run();
    (s, sim.trace)
}

/// Paper mode with a constant structure damping `c_x` (kg/s). Under the paper's 10⁶ the thread
/// slides steadily when lifting; lowering needs a rising friction law (PTFE) and small c_x,
/// because ξ < 0 there turns c_x into negative damping (DESIGN.md).
pub fn steady_cx(
    lube: Lubricant,
    mu_pin: f64,
    deg: f64,
    duration: f64,
    cruise: f64,
    c_x: f64,
) -> (Summary, Trace) {
    let mut cfg = paper_cfg(lube, mu_pin, deg, duration, 4e-6);
    cfg.plant.damping = StructureDamping::Constant(c_x);
    paper(cfg, cruise)
}

/// Lifting with the paper's c_x = 10⁶ kg/s: steady sliding.
pub fn steady(
    lube: Lubricant,
    mu_pin: f64,
    deg: f64,
    duration: f64,
    cruise: f64,
) -> (Summary, Trace) {
    steady_cx(lube, mu_pin, deg, duration, cruise, 1e6)
}

/// Records with t in [a, b].
pub fn between(trace: &Trace, a: f64, b: f64) -> impl Iterator<Item = &Record> {
    trace.records.iter().filter(move |r| r.t >= a && r.t <= b)
}

/// Mean of `f` over the records with t in [a, b].
pub fn mean(trace: &Trace, a: f64, b: f64, f: impl Fn(&Record) -> f64) -> f64 {
    let (n, s) = between(trace, a, b).fold((0usize, 0.0), |(n, s), r| (n + 1, s + f(r)));
    s / n as f64
}
