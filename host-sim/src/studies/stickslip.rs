//! `host-sim stickslip`: the core's stick-slip detector scored against the plant's truth.
//!
//! Every scenario is a closed-loop run of the liftfw core (the same `Controller::step` as the
//! board, seeing only encoder counts and ADC codes) on the float64 plant: one UP or DOWN
//! command at 20 ms, STOP 0.3 s before the end. The truth is [`crate::truth::label`] over the
//! phase log up to the STOP; the detections are the core's `Event::StickSlip` onsets.
//!
//! Matching, per run: each episode takes the first unused onset between its first breakaway
//! and 0.2 s after its last return to stick (a true positive; latency = onset − the breakaway
//! that confirmed the episode). Every other onset is a false positive, whether it repeats an
//! already detected episode (flag flicker), sits on micro stick-slip below the definition, or
//! on nothing at all. Precision = TP/(TP + FP), recall = TP/episodes, per episode over the
//! whole set; the false-alarm rate is the share of runs without any episode (smooth runs) that
//! raised at least one onset.

use crate::physics::{Geometry, Lubricant};
use crate::sim::{Driver, Sim, SimConfig};
use crate::truth::{self, Labels, TruthParams};
use liftfw::control::config::ControlConfig;
use liftfw::control::{Command, Controller, Event, Inputs, State};
use liftfw::detect::stickslip::Reaction;
use liftfw::model::friction::FrictionLaw;
use liftfw::units::{Instant, Metres, NewtonMetres, RadiansPerSecond};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::fmt;
use std::sync::{Arc, Mutex};

/// When the scenarios command the motion, s.
pub const COMMAND_AT: f64 = 0.02;
/// STOP this long before the end of a run, s.
pub const STOP_BEFORE_END: f64 = 0.3;
/// An onset up to this long after an episode's last stick still matches it, s.
pub const MATCH_GRACE: f64 = 0.2;

/// One scored scenario.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Scenario {
    /// Index in its set.
    pub id: usize,
    /// The plant's lubricant.
    pub lubricant: Lubricant,
    /// The friction law the core is configured with (differs from the plant in the
    /// "grease worn off" scenarios).
    pub core_law: Lubricant,
    /// Mass on the head, kg.
    pub load: f64,
    /// Arm angle at the start, degrees.
    pub start_deg: f64,
    /// Lift (true) or lower.
    pub lifting: bool,
    /// Configured cruise screw speed, rad/s.
    pub cruise: f64,
    /// Sensor noise scale (0: quantisation only; 1: the modelled ADC noise).
    pub noise: f64,
    /// Noise seed.
    pub seed: u64,
    /// Simulated time, s.
    pub duration: f64,
    /// The detector's reaction.
    pub reaction: Reaction,
}

impl Scenario {
    /// A short name.
    pub fn name(&self) -> String {
        format!(
            "{:>3} {:<7}{} {:>4} kg {:>2}° {} {:>3} rad/s noise {}",
            self.id,
            self.lubricant.name(),
            if self.core_law != self.lubricant {
                format!("(core {})", self.core_law.name())
            } else {
                String::new()
            },
            self.load,
            self.start_deg,
            if self.lifting { "up  " } else { "down" },
            self.cruise,
            self.noise
        )
    }
}

fn core_law(l: Lubricant) -> FrictionLaw {
    match l {
        Lubricant::Dry => FrictionLaw::DRY,
        Lubricant::Ptfe => FrictionLaw::PTFE,
        Lubricant::Lithium => FrictionLaw::LITHIUM,
    }
}

/// The scored set: `n` scenarios drawn from a seeded generator over every lubricant, start
/// angle, direction, speed (creeping 0.2–0.3 rad/s up to 5 rad/s), load (0–1500 kg) and noise
/// level (0, 1, 3), with every twelfth a dry thread the core believes greased.
pub fn scenario_set(n: usize, seed: u64) -> Vec<Scenario> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut pick = |xs: &[f64]| xs[(rng.random::<u64>() % xs.len() as u64) as usize];
    (0..n)
        .map(|id| {
            let lubricant = match id % 4 {
                0 | 2 => Lubricant::Dry,
                1 => Lubricant::Ptfe,
                _ => Lubricant::Lithium,
            };
            let lifting = pick(&[1.0, 1.0, 0.0]) > 0.5;
            let start_deg = if lifting {
                pick(&[17.0, 30.0, 45.0, 65.0])
            } else {
                pick(&[20.0, 30.0, 45.0, 65.0])
            };
            let load = pick(&[0.0, 150.0, 300.0, 600.0, 1000.0, 1500.0]);
            let cruise = if lubricant == Lubricant::Lithium && pick(&[0.0, 1.0]) > 0.5 {
                0.2
            } else {
                pick(&[0.3, 1.0, 2.0, 3.0, 5.0])
            };
            let noise = pick(&[0.0, 1.0, 1.0, 3.0]);
            let seed = (pick(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]) as u64) + 100 * id as u64;
            let core = if id % 12 == 6 {
                Lubricant::Lithium
            } else {
                lubricant
            };
            Scenario {
                id,
                lubricant,
                core_law: core,
                load,
                start_deg,
                lifting,
                cruise,
                noise,
                seed,
                duration: if cruise <= 0.3 { 4.0 } else { 2.5 },
                reaction: Reaction::Log,
            }
        })
        .collect()
}

/// A small set for the regression test: dry stick-slip lifting and lowering, a creeping
/// greased run that stick-slips, and smooth PTFE and unloaded runs.
pub fn quick_set() -> Vec<Scenario> {
    let base = Scenario {
        id: 0,
        lubricant: Lubricant::Dry,
        core_law: Lubricant::Dry,
        load: 1000.0,
        start_deg: 17.0,
        lifting: true,
        cruise: 3.0,
        noise: 1.0,
        seed: 11,
        duration: 0.9,
        reaction: Reaction::Log,
    };
    vec![
        base,
        Scenario {
            id: 1,
            load: 1500.0,
            start_deg: 30.0,
            lifting: false,
            cruise: 1.0,
            noise: 3.0,
            ..base
        },
        Scenario {
            id: 2,
            lubricant: Lubricant::Lithium,
            core_law: Lubricant::Lithium,
            cruise: 0.2,
            duration: 1.6,
            ..base
        },
        Scenario {
            id: 3,
            lubricant: Lubricant::Ptfe,
            core_law: Lubricant::Ptfe,
            noise: 3.0,
            ..base
        },
        Scenario {
            id: 4,
            load: 0.0,
            cruise: 5.0,
            ..base
        },
    ]
}

/// How the set is simulated and labelled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScoreConfig {
    /// Integration step, s.
    pub dt: f64,
    /// The episode definition.
    pub truth: TruthParams,
    /// The detector's escape speed for the `speed` reaction, rad/s.
    pub escape_speed: f64,
    /// The detector's slip threshold (`stickslip.drop`), N·m; `None`: the default.
    pub drop_threshold: Option<f64>,
}

impl Default for ScoreConfig {
    fn default() -> Self {
        Self {
            dt: 4e-6,
            truth: TruthParams::default(),
            escape_speed: 1.5,
            drop_threshold: None,
        }
    }
}

/// One run's truth and detections.
#[derive(Clone, Debug)]
pub struct RunResult {
    /// The scenario.
    pub scenario: Scenario,
    /// The truth up to the STOP.
    pub labels: Labels,
    /// Detector onsets: (time s, amplitude N·m).
    pub onsets: Vec<(f64, f64)>,
    /// Detected slips (every slip the detector saw), count.
    pub slips: usize,
    /// Time the flag was up, s.
    pub flagged: f64,
    /// When STOP was sent, s.
    pub stop_at: f64,
    /// When the commanded motion ended (STOP, or earlier: a fault or a limit switch), s: the
    /// end of the scored window. While the bridge does not drive, the current sense reads 0 A
    /// and the board sees nothing of the screw.
    pub motion_end: f64,
    /// Mean screw speed over the run's second half (truth), rad/s.
    pub late_speed: f64,
    /// Simulation wall time, s.
    pub wall: f64,
}

/// Run one scenario.
pub fn run(s: &Scenario, sc: &ScoreConfig) -> RunResult {
    let wall = std::time::Instant::now();
    let mut control = ControlConfig::DEFAULT;
    control.estimator.law = core_law(s.core_law);
    control.motion.cruise_speed = RadiansPerSecond::from_f64(s.cruise);
    // Stops near the mechanism's ends, as tests/support does (the lower switch's reference
    // just above α₀, 0.55 mm under the lower stop).
    control.limits.switch_lower = Metres::from_f64(0.13355);
    control.limits.lower = Metres::from_f64(0.1341);
    control.limits.upper = Metres::from_f64(0.414);
    control.stick_slip.reaction = s.reaction;
    control.stick_slip.escape_speed = RadiansPerSecond::from_f64(sc.escape_speed);
    if let Some(d) = sc.drop_threshold {
        control.stick_slip.drop_threshold = NewtonMetres::from_f64(d);
    }
    let mut cfg = SimConfig::paper(s.lubricant.law(), 0.3, s.start_deg);
    cfg.plant.load = s.load;
    cfg.duration = s.duration;
    cfg.dt = sc.dt;
    cfg.record_rate = 0.0;
    cfg.seed = s.seed;
    cfg.sensors.current_noise *= s.noise;
    cfg.sensors.supply_noise *= s.noise;
    let g = Geometry::paper();
    let start = Controller::new(&control, 0)
        .ok()
        .and_then(|c| {
            c.estimator()
                .geometry()
                .counts_for_height(Metres::from_f64(g.height(s.start_deg.to_radians())))
        })
        .unwrap_or(0);
    let controller = match Controller::new(&control, start) {
        Ok(c) => c,
        Err(e) => panic!("scenario {}: invalid control configuration: {e}", s.id),
    };
    let stop_at = s.duration - STOP_BEFORE_END;
    #[derive(Default)]
    struct Log {
        onsets: Vec<(f64, f64)>,
        slips: usize,
        flagged_ticks: usize,
        moved: bool,
        motion_end: Option<f64>,
    }
    let shared = Arc::new(Mutex::new((controller, Log::default(), 0u8)));
    let inner = Arc::clone(&shared);
    let cmd = if s.lifting {
        Command::Up
    } else {
        Command::Down
    };
    let driver = Driver::Custom(Box::new(move |t: f64, inputs: &Inputs| {
        let mut g = inner.lock().unwrap_or_else(|p| p.into_inner());
        let (c, log, sent) = &mut *g;
        if *sent == 0 && t >= COMMAND_AT {
            *sent = 1;
            let _ = c.command(cmd);
        }
        if *sent == 1 && t >= stop_at {
            *sent = 2;
            let _ = c.command(Command::Stop);
        }
        let out = c.step(Instant((t * 1e6).round() as u64 as u32), inputs);
        if let Some(Event::StickSlip { amplitude, .. }) = out.event {
            log.onsets.push((t, amplitude.to_f64()));
        }
        let st = c.status();
        log.flagged_ticks += usize::from(st.stick_slip);
        log.slips += usize::from(c.stick_slip_output().slip);
        let moving = matches!(c.state(), State::Lifting | State::Lowering);
        log.moved |= moving;
        if log.moved && !moving && log.motion_end.is_none() {
            log.motion_end = Some(t);
        }
        out.bridge
    }));
    let mut sim = match Sim::new(cfg, driver) {
        Ok(sim) => sim,
        Err(e) => panic!("scenario {}: {e}", s.id),
    };
    let summary = sim.run();
    let k = sim.cfg.plant.screw.coupling;
    let motion_end = {
        let g = shared.lock().unwrap_or_else(|p| p.into_inner());
        g.1.motion_end.unwrap_or(stop_at).min(stop_at)
    };
    let labels = truth::label(&sim.trace.phases, k, (0.0, motion_end), &sc.truth);
    drop(sim);
    let g = shared.lock().unwrap_or_else(|p| p.into_inner());
    RunResult {
        scenario: *s,
        labels,
        onsets: g.1.onsets.clone(),
        slips: g.1.slips,
        flagged: g.1.flagged_ticks as f64 / 1000.0,
        stop_at,
        motion_end,
        late_speed: summary.late_screw_speed,
        wall: wall.elapsed().as_secs_f64(),
    }
}

/// How one run's detections matched its truth.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Matched {
    /// Episodes detected, with latency from confirmation, s.
    pub latencies: Vec<f64>,
    /// Episodes missed: their confirmation times, s.
    pub missed: Vec<f64>,
    /// Onsets that repeated a detected episode.
    pub duplicates: usize,
    /// Onsets on micro stick-slip.
    pub on_micro: usize,
    /// Onsets on nothing.
    pub spurious: usize,
    /// Amplitude estimate / true median drop, per detected episode.
    pub amplitude_ratios: Vec<f64>,
}

/// Match a run's onsets to its episodes (see the module docs).
pub fn match_run(r: &RunResult) -> Matched {
    let mut used = vec![false; r.onsets.len()];
    let mut m = Matched::default();
    for e in &r.labels.episodes {
        let hit = r
            .onsets
            .iter()
            .enumerate()
            .find(|(i, (t, _))| !used[*i] && *t >= e.start && *t <= e.end + MATCH_GRACE);
        match hit {
            Some((i, (t, a))) => {
                used[i] = true;
                m.latencies.push(t - e.confirmed);
                if e.drop > 0.0 {
                    m.amplitude_ratios.push(a / e.drop);
                }
            }
            None => m.missed.push(e.confirmed),
        }
    }
    for (i, (t, _)) in r.onsets.iter().enumerate() {
        if used[i] {
            continue;
        }
        let within = |s: f64, e: f64| *t >= s && *t <= e + MATCH_GRACE;
        if r.labels.episodes.iter().any(|e| within(e.start, e.end)) {
            m.duplicates += 1;
        } else if r.labels.micro.iter().any(|e| within(e.start, e.end)) {
            m.on_micro += 1;
        } else {
            m.spurious += 1;
        }
    }
    m
}

/// The set's score.
#[derive(Clone, Debug, Default)]
pub struct Score {
    /// Runs.
    pub runs: usize,
    /// Labelled episodes.
    pub episodes: usize,
    /// Detected episodes.
    pub true_positives: usize,
    /// Onsets that match no new episode (duplicates + on micro + spurious).
    pub false_positives: usize,
    /// Of which repeats of a detected episode.
    pub duplicates: usize,
    /// Of which on micro stick-slip.
    pub on_micro: usize,
    /// Runs without episodes.
    pub smooth_runs: usize,
    /// Smooth runs that raised at least one onset.
    pub smooth_alarms: usize,
    /// Runs without episodes and without micro stick-slip (smooth sliding throughout).
    pub clean_runs: usize,
    /// Clean runs that raised an onset.
    pub clean_alarms: usize,
    /// Runs with micro stick-slip only.
    pub micro_runs: usize,
    /// Latencies of the detected episodes, s, sorted.
    pub latencies: Vec<f64>,
    /// Amplitude estimate / truth, sorted.
    pub amplitude_ratios: Vec<f64>,
    /// Missed episodes: (scenario id, confirmed at s).
    pub missed: Vec<(usize, f64)>,
}

fn quantile(v: &[f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let i = ((v.len() - 1) as f64 * q).round() as usize;
    v[i.min(v.len() - 1)]
}

impl Score {
    /// TP/(TP + FP).
    pub fn precision(&self) -> f64 {
        let d = self.true_positives + self.false_positives;
        if d == 0 {
            1.0
        } else {
            self.true_positives as f64 / d as f64
        }
    }

    /// TP/episodes.
    pub fn recall(&self) -> f64 {
        if self.episodes == 0 {
            1.0
        } else {
            self.true_positives as f64 / self.episodes as f64
        }
    }

    /// Median latency, s.
    pub fn median_latency(&self) -> f64 {
        quantile(&self.latencies, 0.5)
    }

    /// Latency quantile, s.
    pub fn latency_quantile(&self, q: f64) -> f64 {
        quantile(&self.latencies, q)
    }

    /// Median amplitude ratio.
    pub fn median_amplitude_ratio(&self) -> f64 {
        quantile(&self.amplitude_ratios, 0.5)
    }
}

/// Score a set of runs.
pub fn score(results: &[RunResult]) -> Score {
    let mut s = Score {
        runs: results.len(),
        ..Score::default()
    };
    for r in results {
        let m = match_run(r);
        s.episodes += r.labels.episodes.len();
        s.true_positives += m.latencies.len();
        s.false_positives += m.duplicates + m.on_micro + m.spurious;
        s.duplicates += m.duplicates;
        s.on_micro += m.on_micro;
        s.latencies.extend(&m.latencies);
        s.amplitude_ratios.extend(&m.amplitude_ratios);
        s.missed
            .extend(m.missed.iter().map(|&t| (r.scenario.id, t)));
        if r.labels.episodes.is_empty() {
            s.smooth_runs += 1;
            s.smooth_alarms += usize::from(!r.onsets.is_empty());
            if r.labels.micro.is_empty() {
                s.clean_runs += 1;
                s.clean_alarms += usize::from(!r.onsets.is_empty());
            } else {
                s.micro_runs += 1;
            }
        }
    }
    s.latencies.sort_by(f64::total_cmp);
    s.amplitude_ratios.sort_by(f64::total_cmp);
    s
}

impl fmt::Display for Score {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "episodes    {} in {} runs: detected {}, missed {}",
            self.episodes,
            self.runs,
            self.true_positives,
            self.episodes - self.true_positives
        )?;
        writeln!(
            f,
            "precision   {:.1} %  ({} TP, {} FP: {} repeats of a detected episode, {} on micro stick-slip, {} on nothing)",
            100.0 * self.precision(),
            self.true_positives,
            self.false_positives,
            self.duplicates,
            self.on_micro,
            self.false_positives - self.duplicates - self.on_micro
        )?;
        writeln!(f, "recall      {:.1} %", 100.0 * self.recall())?;
        writeln!(
            f,
            "latency     median {:.1} ms, p90 {:.1} ms, max {:.1} ms, min {:.1} ms (from the confirming breakaway)",
            1e3 * self.median_latency(),
            1e3 * self.latency_quantile(0.9),
            1e3 * self.latency_quantile(1.0),
            1e3 * self.latency_quantile(0.0)
        )?;
        writeln!(
            f,
            "smooth runs {} without episodes: {} raised an alarm ({:.1} %); of them {} slide smoothly throughout ({} alarms), {} have micro stick-slip only",
            self.smooth_runs,
            self.smooth_alarms,
            100.0 * self.smooth_alarms as f64 / self.smooth_runs.max(1) as f64,
            self.clean_runs,
            self.clean_alarms,
            self.micro_runs
        )?;
        write!(
            f,
            "amplitude   estimate/truth median {:.2} (p10 {:.2}, p90 {:.2})",
            self.median_amplitude_ratio(),
            quantile(&self.amplitude_ratios, 0.1),
            quantile(&self.amplitude_ratios, 0.9)
        )
    }
}

/// One line per run.
pub fn run_line(r: &RunResult) -> String {
    let m = match_run(r);
    let ep = &r.labels.episodes;
    let drop = ep.first().map_or(0.0, |e| e.drop);
    format!(
        "{}  episodes {:>2} (drop {:6.2} N·m, {:>4} cycles) micro {:>2} | onsets {:>2} slips {:>4} | lat {:>6} | miss {} dup {} micro {} spur {} | {:.1} s wall",
        r.scenario.name(),
        ep.len(),
        drop,
        ep.iter().map(|e| e.cycles).sum::<usize>(),
        r.labels.micro.len(),
        r.onsets.len(),
        r.slips,
        m.latencies
            .first()
            .map_or("-".to_string(), |l| format!("{:.0}ms", l * 1e3)),
        m.missed.len(),
        m.duplicates,
        m.on_micro,
        m.spurious,
        r.wall
    ) + &if r.motion_end < r.stop_at - 1e-3 {
        format!(" | motion ended at {:.3} s, before STOP", r.motion_end)
    } else {
        String::new()
    }
}

/// The mitigation comparison of one scenario: the same run with reaction `log` and `speed`.
#[derive(Clone, Debug)]
pub struct Mitigation {
    /// The scenario (reaction `log`).
    pub scenario: Scenario,
    /// Run with `log`.
    pub log: RunResult,
    /// Run with `speed`.
    pub speed: RunResult,
}

impl Mitigation {
    /// Stick-slip time after the first onset of the `speed` run (or after `t`) until STOP, s:
    /// the span of significant cycles after it.
    pub fn stick_slip_after(r: &RunResult, t: f64) -> (f64, usize) {
        let cs: Vec<_> = r
            .labels
            .episodes
            .iter()
            .flat_map(|e| {
                r.labels
                    .cycles
                    .iter()
                    .filter(move |c| c.breakaway >= e.start && c.stuck <= e.end)
            })
            .filter(|c| c.breakaway >= t)
            .collect();
        let span = cs.last().map_or(0.0, |c| c.stuck - cs[0].breakaway.max(t));
        (span, cs.len())
    }
}

/// The scenarios of the mitigation demonstration.
pub fn mitigation_set() -> Vec<Scenario> {
    let base = Scenario {
        id: 0,
        lubricant: Lubricant::Lithium,
        core_law: Lubricant::Lithium,
        load: 1000.0,
        start_deg: 17.0,
        lifting: true,
        cruise: 0.2,
        noise: 1.0,
        seed: 5,
        duration: 4.0,
        reaction: Reaction::Log,
    };
    vec![
        base,
        Scenario {
            id: 1,
            load: 1500.0,
            start_deg: 30.0,
            ..base
        },
        Scenario {
            id: 2,
            lubricant: Lubricant::Dry,
            core_law: Lubricant::Dry,
            load: 1500.0,
            start_deg: 30.0,
            lifting: false,
            cruise: 3.0,
            duration: 2.5,
            ..base
        },
        Scenario {
            id: 3,
            lubricant: Lubricant::Dry,
            core_law: Lubricant::Dry,
            load: 300.0,
            cruise: 3.0,
            duration: 2.5,
            ..base
        },
    ]
}
