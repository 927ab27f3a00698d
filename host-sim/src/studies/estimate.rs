//! `host-sim estimate`: the core's load and friction identification (`liftfw::ident`) scored
//! against the plant's truth over a seeded matrix, in parallel.
//!
//! **Matrix.** Loads 0, 100, 250, 500, 700, 1000, 1300 kg × dry/PTFE/lithium × lifting/lowering
//! × start heights 150, 200, 260 mm (α ≈ 17.5°, 25.9°, 36.9°), each a fresh board (prior: the
//! rated 1000 kg, the configured law) moving the head by the travel of 1.5 s at cruise, with the
//! plant's sensor noise. **Drier set**: the plant's thread 1.5× and 2× drier than the configured
//! law, loads 250, 700, 1000, 1300 kg, from 200 mm: lift, lower, lift (the first pair is what
//! the friction identification needs).
//!
//! **Scores** (each move): over the whole cruise (the profile's reference at cruise speed,
//! stick and slip ticks alike) the mean of the core's T_r against the plant's (each tick's the
//! mean over its integration steps), within 3 % or
//! 0.05 N·m; the identified load 0.5 s after the cruise began, and its worst error from then to
//! the end of the cruise, within 3 % or the load whose torque is 0.05 N·m at that pose
//! (|∂T/∂M| of the plant's model: the same floor); and whether the stated intervals (load,
//! T_r) cover the truth (a goal on the drier set's first two moves, before the pair: "before
//! that, the uncertainty covers the truth"; a column on the others). **Tuning split**: the identification's constants were tuned on the
//! 200 mm start height with seed 1; the report's verdict is on the 150 and 260 mm heights
//! (seeds 2 and 4) and the drier set (seed 7), which were not looked at while tuning.
//! `--seed-sets N` repeats the report and drier sets with N − 1 further sets of seeds (each
//! 100 higher: [`matrix_with`]): the sensor noise is held out too, and a count that moves
//! between one set and several was partly the first set's luck.

use crate::physics::{FrictionLaw, Geometry, Lubricant};
use crate::sim::{Driver, Sim, SimConfig};
use liftfw::control::config::ControlConfig;
use liftfw::control::{Command, Controller, Event, State};
use liftfw::model::friction::FrictionLaw as CoreLaw;
use liftfw::units::{Amperes, Instant, Metres};
use plotters::prelude::*;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// Loads of the matrix, kg.
pub const LOADS: [f64; 7] = [0.0, 100.0, 250.0, 500.0, 700.0, 1000.0, 1300.0];
/// Start heights, mm.
pub const HEIGHTS: [f64; 3] = [150.0, 200.0, 260.0];
/// The height the identification was tuned on.
pub const TUNE_HEIGHT: f64 = 200.0;
/// Loads of the drier set, kg.
pub const DRY_LOADS: [f64; 4] = [250.0, 700.0, 1000.0, 1300.0];
/// How much drier the drier set's thread is.
pub const DRY_SCALES: [f64; 2] = [1.5, 2.0];
/// Cruise time of each move, s.
pub const CRUISE_S: f64 = 1.5;
/// Relative goal (T_r and load), and the torque floor where the torque is tiny, N·m.
pub const GOAL_REL: f64 = 0.03;
/// See [`GOAL_REL`].
pub const GOAL_FLOOR: f64 = 0.05;

/// One run: a fresh board and a plant, one or three moves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Case {
    /// Thread lubricant (the core's configured law and the plant's).
    pub lub: Lubricant,
    /// Mass on the head, kg.
    pub load: f64,
    /// The first move lifts.
    pub up: bool,
    /// Start height, mm.
    pub start_mm: f64,
    /// The plant's thread friction as a multiple of the configured law.
    pub dry: f64,
    /// Sensor-noise seed.
    pub seed: u64,
}

impl Case {
    /// Tuning case (not part of the verdict).
    pub fn tuning(&self) -> bool {
        self.dry == 1.0 && self.start_mm == TUNE_HEIGHT
    }
}

/// One move's scores.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MoveScore {
    /// Lifting.
    pub up: bool,
    /// Cruise ticks.
    pub cruise_ticks: usize,
    /// Mean plant T_r over the cruise, N·m.
    pub tr_plant: f64,
    /// Mean core T_r over the cruise, N·m.
    pub tr_core: f64,
    /// Mean of the core's stated T_r range ends over the cruise, N·m.
    pub tr_lo: f64,
    /// See `tr_lo`.
    pub tr_hi: f64,
    /// Identified load 0.5 s into the cruise, kg.
    pub load_half: f64,
    /// Its stated interval, kg.
    pub load_lo: f64,
    /// See `load_lo`.
    pub load_hi: f64,
    /// Worst |identified − true| from 0.5 s into the cruise to its end, kg.
    pub load_worst: f64,
    /// The load whose torque is [`GOAL_FLOOR`] at this pose and direction, kg.
    pub load_floor: f64,
}

impl MoveScore {
    /// |T_r error| allowed.
    pub fn tr_allowed(&self) -> f64 {
        (GOAL_REL * self.tr_plant.abs()).max(GOAL_FLOOR)
    }
    /// T_r within the goal.
    pub fn tr_ok(&self) -> bool {
        (self.tr_core - self.tr_plant).abs() <= self.tr_allowed()
    }
    /// Load within the goal (0.5 s on, to the end of the cruise).
    pub fn load_ok(&self, truth: f64) -> bool {
        self.load_worst <= (GOAL_REL * truth).max(self.load_floor)
    }
    /// The stated intervals cover the truth.
    pub fn covers(&self, truth: f64) -> bool {
        let m = (GOAL_REL * truth).max(self.load_floor);
        self.load_lo - m <= truth
            && truth <= self.load_hi + m
            && self.tr_lo - GOAL_FLOOR <= self.tr_plant
            && self.tr_plant <= self.tr_hi + GOAL_FLOOR
    }
}

/// A run's outcome.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Outcome {
    /// Its moves.
    pub moves: Vec<MoveScore>,
    /// A lubrication warning was raised.
    pub warned: bool,
    /// The friction scale the core ended with.
    pub scale: f64,
    /// A fault, if one ended a move.
    pub fault: Option<String>,
}

/// The seeded matrix: the main set, then the drier set.
pub fn matrix() -> Vec<Case> {
    matrix_with(1)
}

/// Seed offset between seed sets ([`matrix_with`]).
pub const SEED_SET_STEP: u64 = 100;

/// The matrix over `sets` seed sets: the first is [`matrix`]'s (the tuning set at 200 mm with
/// seed 1; the report set at 150 and 260 mm with seeds 2 and 4; the drier set with seed 7);
/// each further set repeats the report and drier sets (not the tuning set) with every seed
/// [`SEED_SET_STEP`] higher: held-out sensor noise, to see whether a count stops moving.
pub fn matrix_with(sets: u64) -> Vec<Case> {
    let mut v = Vec::new();
    for k in 0..sets.max(1) {
        let step = k * SEED_SET_STEP;
        for (hi, &start_mm) in HEIGHTS.iter().enumerate() {
            if start_mm == TUNE_HEIGHT && k > 0 {
                continue;
            }
            for lub in Lubricant::ALL {
                for &load in &LOADS {
                    for up in [true, false] {
                        v.push(Case {
                            lub,
                            load,
                            up,
                            start_mm,
                            dry: 1.0,
                            seed: step
                                + if start_mm == TUNE_HEIGHT {
                                    1
                                } else {
                                    2 + hi as u64
                                },
                        });
                    }
                }
            }
        }
        for &dry in &DRY_SCALES {
            for lub in Lubricant::ALL {
                for &load in &DRY_LOADS {
                    v.push(Case {
                        lub,
                        load,
                        up: true,
                        start_mm: 200.0,
                        dry,
                        seed: step + 7,
                    });
                }
            }
        }
    }
    v
}

fn core_law(l: Lubricant) -> CoreLaw {
    match l {
        Lubricant::Dry => CoreLaw::DRY,
        Lubricant::Ptfe => CoreLaw::PTFE,
        Lubricant::Lithium => CoreLaw::LITHIUM,
    }
}

fn scaled(law: FrictionLaw, s: f64) -> FrictionLaw {
    FrictionLaw {
        base: law.base * s,
        amp: law.amp * s,
        slope: law.slope * s,
        ..law
    }
}

/// |∂T/∂M| of the plant's model at arm angle `alpha` (rad), direction `dir`, law coefficient
/// `mu`: r_m·|ξ|·|G_d| (the load a [`GOAL_FLOOR`] of torque is worth).
fn load_gain(alpha: f64, dir: f64, mu: f64) -> f64 {
    let s = crate::physics::Screw::paper();
    let (r, tan) = (s.r_m, s.lambda.tan());
    let mus = dir * mu;
    let xi = (tan + mus) / (1.0 - mus * tan);
    let g = 9.80665 * (alpha.cos() + 0.6 * dir) / alpha.sin();
    (r * xi * g).abs()
}

/// One tick as recorded.
#[derive(Clone, Copy, Debug, Default)]
struct Tick {
    cruise: bool,
    tr_plant: f64,
    tr_core: f64,
    tr_lo: f64,
    tr_hi: f64,
    load: f64,
    load_lo: f64,
    load_hi: f64,
    alpha: f64,
    mu: f64,
}

/// The plant's sensor model needs the no-load current of its motor at cruise: the setting the
/// board is commissioned with (`ballscrew.no_load_current`, docs/model.md).
pub fn no_load_current(cruise: f64) -> f64 {
    let d = crate::plant::DriveParams::default();
    let w = cruise * d.ratio;
    (d.motor_coulomb + d.motor_viscous * w) / d.torque_constant
}

/// How long the board rests after power-up before the first move, ms: the rest's settling
/// and one batch of the current sense's zero (`control::sense::ZERO_SAMPLES` ticks), with
/// room.
const BOOT_REST_MS: u64 = 600;

/// Run one case.
pub fn run_case(c: &Case) -> Result<Outcome, String> {
    run_case_observed(c, None)
}

/// The plant at one integration step of a case's move, for [`run_case_observed`]'s observer.
#[derive(Clone, Copy, Debug)]
pub struct Step<'a> {
    /// The move's index (0: the first; the drier set's lift, lower, lift).
    pub index: usize,
    /// Seconds since the move was commanded.
    pub t: f64,
    /// The core was at its cruise on the tick before this one.
    pub cruise: bool,
    /// The plant's state.
    pub record: &'a crate::trace::Record,
}

/// [`run_case`], calling `observe` with the plant at every integration step of the moves (the
/// plant's own detail under the core's 1 kHz: what the sensors average over).
pub fn run_case_observed(
    c: &Case,
    mut observe: Option<&mut dyn FnMut(Step<'_>)>,
) -> Result<Outcome, String> {
    let g = Geometry::paper();
    let s = (c.start_mm * 1e-3 - g.h0) / g.length;
    let start_deg = s.asin().to_degrees();
    let mut control = ControlConfig::DEFAULT;
    control.estimator.law = core_law(c.lub);
    let cruise = control.motion.cruise_speed.to_f64();
    control.lube.no_load_current = Amperes::from_f64(no_load_current(cruise));
    let probe = Controller::new(&control, 0).map_err(|e| e.to_string())?;
    let geo = *probe.estimator().geometry();
    let start = geo
        .counts_for_height(Metres::from_f64(c.start_mm * 1e-3))
        .ok_or("start outside the mechanism")?;
    let controller = Controller::new(&control, start).map_err(|e| e.to_string())?;
    // The travel of CRUISE_S at cruise (+ the ramps), in counts.
    let rad_per_count = 2.0 * std::f64::consts::PI / (48.0 * 60.0);
    let span = ((CRUISE_S + 0.06) * cruise / rad_per_count).round() as i32;
    let target = |from: i32, up: bool| -> Metres {
        let to = if up { from + span } else { from - span };
        geo.pose(to).height
    };
    let dirs: Vec<bool> = if c.dry == 1.0 {
        vec![c.up]
    } else {
        vec![true, false, true]
    };

    let mut cfg = SimConfig::paper(scaled(c.lub.law(), c.dry), 0.3, start_deg);
    cfg.plant.load = c.load;
    cfg.dt = 4e-6;
    cfg.duration = 1e9;
    cfg.record_rate = 0.0;
    cfg.seed = c.seed;
    // The core, shared with the sim's driver closure; its events are collected.
    let shared = Arc::new(Mutex::new((controller, false)));
    let inner = Arc::clone(&shared);
    let driver = Driver::Custom(Box::new(move |t: f64, inputs| {
        let mut g = lock(&inner);
        let (c, warned) = &mut *g;
        let out = c.step(Instant((t * 1e6).round() as u64 as u32), inputs);
        c.finish_tick();
        if matches!(out.event, Some(Event::ThreadDry(_))) {
            *warned = true;
        }
        out.bridge
    }));
    let mut sim = Sim::new(cfg, driver).map_err(|e| e.to_string())?;
    let per_tick = (1e-3 / cfg.dt).round() as u64;
    let mut out = Outcome::default();
    // The board at rest after power-up before the first command: it reads its supply and
    // measures the current sense's zero (`control::sense`, a batch of ZERO_SAMPLES codes once
    // the rest has settled).
    let mut t = sim.step_n(per_tick * BOOT_REST_MS);
    for (index, &up) in dirs.iter().enumerate() {
        // Command the move from where the core believes the screw is.
        {
            let mut g = lock(&shared);
            let from = g.0.position_counts();
            g.0.command(Command::GoTo(target(from, up)))
                .map_err(|r| r.message().to_string())?;
        }
        let mut ticks: Vec<Tick> = Vec::new();
        let mut rested = None;
        let t_start = t;
        loop {
            // The plant's T_r: the mean over the tick's integration steps.
            let (now, tr_tick) = match observe.as_deref_mut() {
                None => sim.step_n_mean_friction(per_tick),
                Some(f) => {
                    let cruise = ticks.last().is_some_and(|k| k.cruise);
                    let (mut now, mut sum) = (t, 0.0);
                    for _ in 0..per_tick {
                        now = sim.step_n(1);
                        let record = sim.record(now);
                        sum += record.friction_torque;
                        f(Step {
                            index,
                            t: now - t_start,
                            cruise,
                            record: &record,
                        });
                    }
                    (now, sum / per_tick as f64)
                }
            };
            t = now;
            let r = sim.record(t);
            let g = lock(&shared);
            let core = &g.0;
            let st = core.status();
            let moving = matches!(core.state(), State::Lifting | State::Lowering);
            let reference = core.reference().to_f64().abs();
            ticks.push(Tick {
                cruise: moving && (reference - cruise).abs() < 1e-3,
                tr_plant: tr_tick,
                tr_core: st.friction_torque.to_f64(),
                tr_lo: st.friction_torque_range.0.to_f64(),
                tr_hi: st.friction_torque_range.1.to_f64(),
                load: st.load.load.to_f64(),
                load_lo: st.load.load_lo.to_f64(),
                load_hi: st.load.load_hi.to_f64(),
                alpha: r.alpha_deg.to_radians(),
                mu: r.mu,
            });
            if let Some(f) = core.fault() {
                out.fault = Some(format!("{} at {:.3} s", f.kind.name(), t));
                break;
            }
            if !moving && t > t_start + 0.01 {
                let at = *rested.get_or_insert(t);
                if t > at + 0.3 {
                    break;
                }
            }
            if t > t_start + 30.0 {
                return Err("move did not end".into());
            }
        }
        out.moves.push(score(&ticks, up, c.load));
        if out.fault.is_some() {
            break;
        }
    }
    let g = lock(&shared);
    out.scale = g.0.status().load.scale.to_f64();
    out.warned = g.1;
    Ok(out)
}

fn score(ticks: &[Tick], up: bool, truth: f64) -> MoveScore {
    let cruise: Vec<usize> = (0..ticks.len()).filter(|&i| ticks[i].cruise).collect();
    let mut m = MoveScore {
        up,
        cruise_ticks: cruise.len(),
        ..MoveScore::default()
    };
    if cruise.is_empty() {
        return m;
    }
    let n = cruise.len() as f64;
    let mean = |f: &dyn Fn(&Tick) -> f64| cruise.iter().map(|&i| f(&ticks[i])).sum::<f64>() / n;
    m.tr_plant = mean(&|t| t.tr_plant);
    m.tr_core = mean(&|t| t.tr_core);
    m.tr_lo = mean(&|t| t.tr_lo);
    m.tr_hi = mean(&|t| t.tr_hi);
    let c0 = cruise[0];
    let half = (c0 + 500).min(*cruise.last().unwrap_or(&c0));
    let h = &ticks[half];
    m.load_half = h.load;
    m.load_lo = h.load_lo;
    m.load_hi = h.load_hi;
    m.load_worst = cruise
        .iter()
        .filter(|&&i| i >= half)
        .map(|&i| (ticks[i].load - truth).abs())
        .fold(0.0, f64::max);
    let dir = if up { 1.0 } else { -1.0 };
    m.load_floor = GOAL_FLOOR / load_gain(h.alpha, dir, h.mu).max(1e-9);
    m
}

/// The default overload limit, kg: (1 + `protect.overload_margin`) × the rated load.
fn overload_limit_kg() -> f64 {
    let c = ControlConfig::DEFAULT;
    c.rated_load.to_f64() * (1.0 + c.protection.overload_margin.to_f64())
}

/// Command-line arguments.
#[derive(Clone, Debug)]
pub struct EstimateArgs {
    /// Worker threads (0: all cores).
    pub jobs: usize,
    /// Where to write the PNG (`None`: no plot).
    pub plot: Option<PathBuf>,
    /// Seed sets ([`matrix_with`]; 1: the matrix alone).
    pub seed_sets: u64,
}

/// Run the matrix, print the table, draw the PNG. Returns the verdict (every report case met
/// every goal).
pub fn main(a: &EstimateArgs) -> Result<bool, String> {
    let cases = matrix_with(a.seed_sets);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.jobs)
        .build()
        .map_err(|e| e.to_string())?;
    let wall = std::time::Instant::now();
    let results: Vec<(Case, Result<Outcome, String>)> =
        pool.install(|| cases.par_iter().map(|c| (*c, run_case(c))).collect());
    let secs = wall.elapsed().as_secs_f64();
    let ok = report(&results);
    println!(
        "\n{} runs in {:.1} s wall on {} threads (other load on the machine inflates it)",
        results.len(),
        secs,
        pool.current_num_threads()
    );
    if let Some(p) = &a.plot {
        match plot(p, &results) {
            Ok(()) => println!("plot: {}", p.display()),
            Err(e) => println!("plot skipped: {e}"),
        }
    }
    Ok(ok)
}

/// Print the tables; true when every report case met every goal.
pub fn report(results: &[(Case, Result<Outcome, String>)]) -> bool {
    let mut all_ok = true;
    // (set, met, runs, covered) of the main tables; the drier set's met and runs.
    let mut totals: Vec<(&str, usize, usize, usize)> = Vec::new();
    let (mut dry_met, mut dry_runs) = (0usize, 0usize);
    // Runs with all three moves, and those whose three moves' intervals held the truth.
    let (mut dry_moved, mut dry_covered) = (0usize, 0usize);
    println!("host-sim estimate: the core's T_r and identified load against the plant's truth");
    println!("goals: cruise-mean T_r within 3 % (or 0.05 N·m); load within 3 % (or the 0.05 N·m load) from 0.5 s of cruise");
    println!("covered: the stated load and T_r intervals hold the truth (0.5 s into the cruise and the cruise's means, within the goal's allowance)\n");
    for (title, tuning) in [
        (
            "report set (150 and 260 mm; seeds 2, 4 and each further seed set's)",
            false,
        ),
        ("tuning set (200 mm, seed 1)", true),
    ] {
        println!("### {title}\n");
        let mut total = (if tuning { "tuning set" } else { "report set" }, 0, 0, 0);
        println!("| lubricant | load kg | dir | T_r plant N·m (range) | T_r err worst | load err worst kg (floor) | goals | covered |");
        println!("|---|---|---|---|---|---|---|---|");
        for lub in Lubricant::ALL {
            for &load in &LOADS {
                for up in [true, false] {
                    let rows: Vec<&(Case, Result<Outcome, String>)> = results
                        .iter()
                        .filter(|(c, _)| {
                            c.dry == 1.0
                                && c.lub == lub
                                && c.load == load
                                && c.up == up
                                && c.tuning() == tuning
                        })
                        .collect();
                    let mut tr_lo = f64::MAX;
                    let mut tr_hi = f64::MIN;
                    let mut tr_err: f64 = 0.0;
                    let mut tr_err_rel = String::new();
                    let mut ld_err: f64 = 0.0;
                    let mut floor: f64 = 0.0;
                    let mut met = 0;
                    let mut covered = 0;
                    let mut fails = Vec::new();
                    for (c, r) in &rows {
                        match r {
                            Ok(o) if o.fault.is_none() && !o.moves.is_empty() => {
                                let m = &o.moves[0];
                                tr_lo = tr_lo.min(m.tr_plant);
                                tr_hi = tr_hi.max(m.tr_plant);
                                let e = m.tr_core - m.tr_plant;
                                // The worst relative to its allowance.
                                if e.abs() / m.tr_allowed() >= tr_err {
                                    tr_err = e.abs() / m.tr_allowed();
                                    tr_err_rel = format!(
                                        "{:+.3} N·m ({:+.2} %)",
                                        e,
                                        100.0 * e / m.tr_plant.abs().max(1e-9)
                                    );
                                }
                                if m.load_worst > ld_err {
                                    ld_err = m.load_worst;
                                    floor = m.load_floor;
                                }
                                covered += usize::from(m.covers(c.load));
                                if m.tr_ok() && m.load_ok(c.load) {
                                    met += 1;
                                } else {
                                    fails.push(format!("{} mm s{}", c.start_mm, c.seed));
                                }
                            }
                            Ok(o) => fails.push(format!(
                                "{} mm s{}: {}",
                                c.start_mm,
                                c.seed,
                                o.fault.clone().unwrap_or_else(|| "no move".into())
                            )),
                            Err(e) => fails.push(format!("{} mm s{}: {e}", c.start_mm, c.seed)),
                        }
                    }
                    if !tuning && !fails.is_empty() {
                        all_ok = false;
                    }
                    total.1 += met;
                    total.2 += rows.len();
                    total.3 += covered;
                    let range = if tr_lo <= tr_hi {
                        format!("{tr_lo:.3}…{tr_hi:.3}")
                    } else {
                        "—".to_string()
                    };
                    println!(
                        "| {} | {} | {} | {} | {} | {:.1} ({:.1}) | {}/{}{} | {}/{} |",
                        lub.name(),
                        load,
                        if up { "up" } else { "down" },
                        range,
                        tr_err_rel,
                        ld_err,
                        floor.max(GOAL_REL * load),
                        met,
                        rows.len(),
                        if fails.is_empty() {
                            String::new()
                        } else {
                            format!(" ✗ {}", fails.join(", "))
                        },
                        covered,
                        rows.len()
                    );
                }
            }
        }
        println!();
        totals.push(total);
    }
    println!(
        "### drier set (thread 1.5× / 2× drier than configured; lift, lower, lift from 200 mm)\n"
    );
    println!("| lubricant | dry | load kg | seed | move 1: load (interval) / T_r err (moves 1…3 covered) | pair: scale, warning | move 3: T_r err, load err | goals |");
    println!("|---|---|---|---|---|---|---|---|");
    for (c, r) in results.iter().filter(|(c, _)| c.dry != 1.0) {
        // Each row's text and whether it met its goals.
        let (line, met) = match r {
            Ok(o) if o.moves.len() == 3 && o.fault.is_none() => {
                let (m1, m3) = (&o.moves[0], &o.moves[2]);
                // Before the pair (the lift and the lowering) the intervals must hold the truth;
                // after it (the third move), they should (counted apart).
                let covers = [m1, &o.moves[1], m3].map(|m| m.covers(c.load));
                dry_moved += 1;
                dry_covered += usize::from(covers == [true; 3]);
                let ok = covers[..2] == [true; 2] && o.warned && m3.tr_ok() && m3.load_ok(c.load);
                let line = format!(
                    "{:.0} ({:.0}…{:.0}) / {:+.2} % ({}) | {:.3}, {} | {:+.2} %, {:+.1} kg | {} |",
                    m1.load_half,
                    m1.load_lo,
                    m1.load_hi,
                    100.0 * (m1.tr_core - m1.tr_plant) / m1.tr_plant.abs().max(1e-9),
                    match covers {
                        [true, true, true] => "yes".to_string(),
                        _ => format!(
                            "no: move {}",
                            (1..=3)
                                .filter(|&k| !covers[k - 1])
                                .map(|k| k.to_string())
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    },
                    o.scale,
                    if o.warned { "warned" } else { "no warning" },
                    100.0 * (m3.tr_core - m3.tr_plant) / m3.tr_plant.abs().max(1e-9),
                    m3.load_worst,
                    if ok { "met" } else { "✗" }
                );
                (line, ok)
            }
            // A car above the overload limit must be refused (overload, or a drive that cannot
            // move it at all stalls): that is the goal there, not the estimate.
            Ok(o)
                if c.load > overload_limit_kg()
                    && o.fault
                        .as_deref()
                        .is_some_and(|f| f.starts_with("overload") || f.starts_with("stall")) =>
            {
                let line = format!(
                    "refused: {} ({:.0} kg > the {:.0} kg limit) | | | met |",
                    o.fault.as_deref().unwrap_or_default(),
                    c.load,
                    overload_limit_kg()
                );
                (line, true)
            }
            Ok(o) => {
                let line = format!(
                    "✗ {} | | | ✗ |",
                    o.fault
                        .clone()
                        .unwrap_or_else(|| format!("{} moves", o.moves.len()))
                );
                (line, false)
            }
            Err(e) => (format!("✗ {e} | | | ✗ |"), false),
        };
        all_ok &= met;
        dry_runs += 1;
        dry_met += usize::from(met);
        println!(
            "| {} | {} | {} | {} | {line}",
            c.lub.name(),
            c.dry,
            c.load,
            c.seed
        );
    }
    println!();
    for (set, met, runs, covered) in totals {
        println!("{set}: {met} of {runs} met, {covered} of {runs} covered");
    }
    println!(
        "drier set: {dry_met} of {dry_runs} met; covered in all three moves: {dry_covered} of the {dry_moved} runs that made them"
    );
    println!(
        "\nverdict (report and drier sets): {}",
        if all_ok {
            "every goal met"
        } else {
            "goals missed (✗ above)"
        }
    );
    all_ok
}

fn plot(path: &Path, results: &[(Case, Result<Outcome, String>)]) -> Result<(), String> {
    crate::plotting::init_font()?;
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    let pts: Vec<(Case, MoveScore)> = results
        .iter()
        .filter_map(|(c, r)| {
            let o = r.as_ref().ok()?;
            let m = if c.dry == 1.0 {
                o.moves.first()?
            } else {
                o.moves.get(2)?
            };
            Some((*c, *m))
        })
        .collect();
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        let root = BitMapBackend::new(path, (1200, 800)).into_drawing_area();
        root.fill(&WHITE)?;
        let (top, bottom) = root.split_vertically(400);
        let colour = |l: Lubricant| match l {
            Lubricant::Dry => RED,
            Lubricant::Ptfe => BLUE,
            Lubricant::Lithium => GREEN,
        };
        for (area, title, f) in [
            (
                &top,
                "cruise-mean T_r: core estimate − plant, % (goal ±3 %, or 0.05 N·m where tiny)",
                &(|m: &MoveScore, _c: &Case| 100.0 * (m.tr_core - m.tr_plant) / m.tr_plant.abs().max(1e-9))
                    as &dyn Fn(&MoveScore, &Case) -> f64,
            ),
            (
                &bottom,
                "identified load, worst error from 0.5 s of cruise, % of the true load (floor: 0.05 N·m)",
                &(|m: &MoveScore, c: &Case| 100.0 * m.load_worst / c.load.max(1.0)) as &dyn Fn(&MoveScore, &Case) -> f64,
            ),
        ] {
            let mut ch = ChartBuilder::on(area)
                .caption(title, (crate::plotting::FONT, 17))
                .margin(10)
                .x_label_area_size(30)
                .y_label_area_size(50)
                .build_cartesian_2d(-50.0..1400.0, -8.0..8.0)?;
            ch.configure_mesh()
                .x_desc("load, kg (circles: lifting, triangles: lowering, squares: drier set, 3rd move)")
                .label_style((crate::plotting::FONT, 12))
                .draw()?;
            for y in [-3.0, 3.0] {
                ch.draw_series(LineSeries::new([(-50.0, y), (1400.0, y)], BLACK.mix(0.4)))?;
            }
            for (c, m) in &pts {
                let x = c.load + (c.start_mm - 200.0) * 0.2;
                let y = f(m, c).clamp(-7.9, 7.9);
                let col = colour(c.lub);
                if c.dry != 1.0 {
                    ch.draw_series([Rectangle::new([(x - 8.0, y - 0.15), (x + 8.0, y + 0.15)], col.filled())])?;
                } else if c.up {
                    ch.draw_series([Circle::new((x, y), 4, col.filled())])?;
                } else {
                    ch.draw_series([TriangleMarker::new((x, y), 5, col.filled())])?;
                }
            }
        }
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| format!("{}: {e}", path.display()))
}

/// The amplitude of the sinusoid of frequency `f` (Hz) in `x`, sampled every `dt` s: one bin
/// of the discrete Fourier transform (Goertzel's recurrence), the mean removed first.
pub fn tone(x: &[f64], dt: f64, f: f64) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    let w = 2.0 * std::f64::consts::PI * f * dt;
    let c = 2.0 * w.cos();
    let (mut s1, mut s2) = (0.0f64, 0.0f64);
    for &v in x {
        let s0 = (v - mean) + c * s1 - s2;
        s2 = s1;
        s1 = s0;
    }
    // |X(f)|² = s1² + s2² − c·s1·s2; the amplitude is 2|X|/N.
    let power = (s1 * s1 + s2 * s2 - c * s1 * s2).max(0.0);
    2.0 * power.sqrt() / x.len() as f64
}

/// The strongest frequency of `x` (sampled every `dt` s) in `lo..=hi` Hz, on a grid of `step`
/// Hz, and its amplitude ([`tone`]).
pub fn dominant(x: &[f64], dt: f64, lo: f64, hi: f64, step: f64) -> (f64, f64) {
    let n = ((hi - lo) / step).floor().max(0.0) as usize;
    (0..=n)
        .map(|k| {
            let f = lo + k as f64 * step;
            (f, tone(x, dt, f))
        })
        .fold((lo, 0.0), |best, x| if x.1 > best.1 { x } else { best })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_matrix_has_every_case_once() {
        let m = matrix();
        assert_eq!(m.len(), 7 * 3 * 2 * 3 + 2 * 3 * 4);
        assert_eq!(m.iter().filter(|c| c.tuning()).count(), 7 * 3 * 2);
    }

    #[test]
    fn further_seed_sets_repeat_the_report_and_drier_sets_with_new_seeds() {
        let m = matrix_with(3);
        assert_eq!(
            m.len(),
            7 * 3 * 2 * 3 + 2 * 3 * 4 + 2 * (7 * 3 * 2 * 2 + 2 * 3 * 4)
        );
        // The tuning set once, with its seed; no further set reuses a seed of the first.
        assert_eq!(m.iter().filter(|c| c.tuning()).count(), 7 * 3 * 2);
        let first: std::collections::BTreeSet<u64> = matrix().iter().map(|c| c.seed).collect();
        let later = &m[matrix().len()..];
        assert!(later
            .iter()
            .all(|c| !first.contains(&c.seed) && !c.tuning()));
        assert_eq!(&m[..matrix().len()], &matrix()[..]);
    }
}
