//! `host-sim lift`: the product at a glance. The board's core (`liftfw::control::Controller`,
//! the same code the firmware runs) lifts a loaded car from one height to a set height in
//! closed loop with the plant; while it runs, a line every half second compares what the
//! core believes (height, speed, estimated thread friction torque T_r) with the plant's
//! truth, then the halt error and a plot of both.

use crate::plotting;
use crate::twin::inject::{Injection, Plan};
use crate::twin::physics::{Geometry, Lubricant};
use crate::twin::sim::{Driver, Sim, SimConfig};
use liftfw::console::service::write_fault;
use liftfw::control::config::ControlConfig;
use liftfw::control::{Command, Controller, Event, Refusal, State};
use liftfw::model::friction::FrictionLaw;
use liftfw::units::{Instant, Metres};
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, MutexGuard};

/// What to run.
#[derive(Clone, Debug)]
pub struct LiftArgs {
    /// Plant lubricant; the core is configured with the same law.
    pub lubricant: Lubricant,
    /// Mass on the head, kg.
    pub load_kg: f64,
    /// Start height, mm.
    pub from_mm: f64,
    /// Target height, mm.
    pub to_mm: f64,
    /// Sensor-noise seed.
    pub seed: u64,
    /// Where to write the PNG (`None`: no plot).
    pub plot: Option<PathBuf>,
    /// Faults to inject ([`crate::twin::inject`]).
    pub faults: Vec<Injection>,
}

/// One control tick as the core saw it, with the plant's truth at the same instant.
#[derive(Clone, Copy, Debug, Default)]
struct Sample {
    t: f64,
    true_height: f64,
    core_height: f64,
    true_speed: f64,
    core_speed: f64,
    true_tr: f64,
    core_tr: f64,
    current: f64,
    /// The core's identified load (or its prior), kg.
    core_load: f64,
    /// The profile's reference is at cruise speed.
    cruise: bool,
    /// The plant's thread sticks (its truth).
    stuck: bool,
    /// The board's stick-slip detector has an episode under way.
    flagged: bool,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

fn core_law(l: Lubricant) -> FrictionLaw {
    match l {
        Lubricant::Dry => FrictionLaw::DRY,
        Lubricant::Ptfe => FrictionLaw::PTFE,
        Lubricant::Lithium => FrictionLaw::LITHIUM,
    }
}

/// What a lift run measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LiftOutcome {
    /// True head height at the end, mm.
    pub final_mm: f64,
    /// Final height − target, mm.
    pub error_mm: f64,
    /// Largest excursion beyond the target, mm.
    pub overshoot_mm: f64,
    /// Mean plant T_r while the screw turned, N·m.
    pub tr_plant: f64,
    /// Mean core estimate of T_r over the same ticks, N·m.
    pub tr_core: f64,
}

/// Run it and print as it goes.
pub fn main(a: &LiftArgs) -> Result<LiftOutcome, String> {
    let g = Geometry::paper();
    let to_angle = |mm: f64| -> Result<f64, String> {
        let s = (mm * 1e-3 - g.h0) / g.length;
        if !(0.0..1.0).contains(&s) {
            return Err(format!("{mm} mm is outside the mechanism"));
        }
        Ok(s.asin().to_degrees())
    };
    let start_deg = to_angle(a.from_mm)?;
    let to_deg = to_angle(a.to_mm)?;
    let mut control = ControlConfig::DEFAULT;
    control.estimator.law = core_law(a.lubricant);
    // Commissioned for host-sim's motor: its no-load current at the cruise speed.
    control.lube.no_load_current = liftfw::units::Amperes::from_f64(
        crate::studies::estimate::no_load_current(control.motion.cruise_speed.to_f64()),
    );
    let probe = Controller::new(&control, 0).map_err(|e| e.to_string())?;
    let start = probe
        .estimator()
        .geometry()
        .counts_for_height(Metres::from_f64(a.from_mm * 1e-3))
        .ok_or("start height outside the mechanism")?;
    let controller = Controller::new(&control, start).map_err(|e| e.to_string())?;
    let target = Metres::from_f64(a.to_mm * 1e-3);

    let mut cfg = SimConfig::paper(a.lubricant.law(), 0.3, start_deg);
    cfg.plant.load = a.load_kg;
    cfg.dt = 4e-6;
    cfg.duration = 1e9;
    cfg.record_rate = 0.0;
    cfg.seed = a.seed;
    cfg.faults = Plan::new(&a.faults)?;
    let cap = time_cap(start_deg, to_deg, control.motion.cruise_speed.to_f64());

    // The core, shared with the sim's driver closure.
    let shared = Arc::new(Mutex::new((
        controller,
        None::<Event>,
        false,
        None::<Result<(), Refusal>>,
    )));
    let inner = Arc::clone(&shared);
    let driver = Driver::Custom(Box::new(move |t: f64, inputs| {
        let mut g = lock(&inner);
        let (c, last_event, sent, answer) = &mut *g;
        if !*sent && t >= 0.05 {
            *sent = true;
            *answer = Some(c.command(Command::GoTo(target)));
        }
        let out = c.step(Instant((t * 1e6).round() as u64 as u32), inputs);
        if out.event.is_some() {
            *last_event = out.event;
        }
        out.bridge
    }));
    let mut sim = Sim::new(cfg, driver).map_err(|e| e.to_string())?;

    println!(
        "host-sim lift: {} thread, {} kg, {:.1} mm → {:.1} mm; the liftfw core at 1 kHz against the plant\n",
        a.lubricant.name(),
        a.load_kg,
        a.from_mm,
        a.to_mm
    );
    println!(
        "{:>6}  {:>10} {:>10}  {:>9} {:>9}  {:>9} {:>9}  {:>7}  {:>8}  state",
        "t s", "height mm", "core mm", "ω rad/s", "core", "T_r N·m", "estimate", "I A", "load kg"
    );
    let dt: f64 = 4e-6;
    let per_tick = (1e-3 / dt).round() as u64;
    let mut samples: Vec<Sample> = Vec::new();
    let mut rested_at: Option<f64> = None;
    let wall = std::time::Instant::now();
    let mut t = 0.0;
    let mut ended = End::Cap;
    while t < cap {
        // The plant's T_r: the mean over the tick's integration steps (as `host-sim estimate`).
        let (now, true_tr) = sim.step_n_mean_friction(per_tick);
        t = now;
        let r = sim.record(t);
        let mut g = lock(&shared);
        if sim.take_watchdog_reset() {
            // An injected hang outlasted the IWDG: the board boots again, fault latched.
            let (c, ..) = &mut *g;
            let pos = c.position_counts();
            if let Ok(mut n) = Controller::new(c.config(), pos) {
                n.report_watchdog_reset(Instant((t * 1e6).round() as u64 as u32));
                *c = n;
            }
        }
        let (c, _, sent, answer) = &*g;
        if let Some(Err(why)) = answer {
            ended = End::Refused(*why);
            break;
        }
        let st = c.status();
        let s = Sample {
            t,
            true_height: r.height * 1e3,
            core_height: st.height.to_f64() * 1e3,
            true_speed: r.theta_dot,
            core_speed: st.screw_speed.to_f64(),
            true_tr,
            core_tr: st.friction_torque.to_f64(),
            current: r.current,
            core_load: st.load.load.to_f64(),
            cruise: matches!(c.state(), State::Lifting | State::Lowering)
                && (c.reference().to_f64().abs() - control.motion.cruise_speed.to_f64()).abs()
                    < 1e-3,
            stuck: matches!(r.phase, crate::twin::plant::Phase::Stick),
            flagged: st.stick_slip,
        };
        samples.push(s);
        let state = c.state();
        let moving = matches!(state, State::Lifting | State::Lowering);
        if samples.len().is_multiple_of(500)
            || (rested_at.is_none() && *sent && !moving && t > 0.06)
        {
            println!(
                "{:6.2}  {:10.3} {:10.3}  {:9.3} {:9.3}  {:9.3} {:9.3}  {:7.2}  {:8.1}  {}",
                s.t,
                s.true_height,
                s.core_height,
                s.true_speed,
                s.core_speed,
                s.true_tr,
                s.core_tr,
                s.current,
                s.core_load,
                state.name()
            );
        }
        if let Some(f) = c.fault() {
            let mut snapshot = String::new();
            let _ = write_fault(&mut snapshot, Some(f));
            ended = End::Fault(snapshot);
            break;
        }
        if *sent && !moving && t > 0.06 {
            let at = *rested_at.get_or_insert(t);
            // Let the coupling unwind and the brake settle before reading the final height.
            if t > at + 0.5 {
                ended = End::Arrived;
                break;
            }
        }
    }
    let last = samples.last().copied().unwrap_or_default();
    let state = lock(&shared).0.state();
    let why = match ended {
        End::Arrived => None,
        End::Refused(r) => Some(format!(
            "goto {:.1} mm refused: {} (nothing moved; the stops are limits.lower and \
             limits.upper, 145–410 mm by default)",
            a.to_mm,
            r.message()
        )),
        End::Fault(snapshot) => Some(format!(
            "stopped by a fault at {:.3} s, head at {:.3} mm (core {:.3} mm), {:.3} mm from the \
             target; the board's snapshot: {snapshot}",
            last.t,
            last.true_height,
            last.core_height,
            last.true_height - a.to_mm
        )),
        End::Cap => Some(format!(
            "cut off at {:.0} s (twice the stroke's time at cruise, plus 20 s) while {}: head at \
             {:.3} mm, {:.3} mm from the target",
            cap,
            state.name(),
            last.true_height,
            last.true_height - a.to_mm
        )),
    };
    if let Some(why) = why {
        println!("\n{why}");
        if let Some(path) = &a.plot {
            match plot(path, a, &samples) {
                Ok(()) => println!("plot: {}", path.display()),
                Err(e) => println!("plot skipped: {e}"),
            }
        }
        return Err(why);
    }
    let err = last.true_height - a.to_mm;
    let up = a.to_mm > a.from_mm;
    let extreme =
        samples
            .iter()
            .map(|s| s.true_height)
            .fold(if up { f64::MIN } else { f64::MAX }, |m, h| {
                if up {
                    m.max(h)
                } else {
                    m.min(h)
                }
            });
    let over = ((extreme - a.to_mm) * if up { 1.0 } else { -1.0 }).max(0.0);
    // Estimate vs truth over the whole cruise (the reference at cruise speed: stick and slip
    // ticks alike).
    let cruise: Vec<&Sample> = samples.iter().filter(|s| s.cruise).collect();
    let n = cruise.len().max(1) as f64;
    let mean_true = cruise.iter().map(|s| s.true_tr).sum::<f64>() / n;
    let mean_core = cruise.iter().map(|s| s.core_tr).sum::<f64>() / n;
    println!(
        "\nhalted at {:.3} mm: error {:+.3} mm, overshoot {:.3} mm (goal ±0.5 mm)",
        last.true_height, err, over
    );
    println!(
        "T_r over the whole cruise: plant {:.3} N·m mean, core estimate {:.3} N·m ({:+.3} N·m{}), {} ticks",
        mean_true,
        mean_core,
        mean_core - mean_true,
        relative(mean_core - mean_true, mean_true, 0.01),
        cruise.len()
    );
    {
        let g = lock(&shared);
        let l = g.0.status().load;
        let id = l.load.to_f64();
        println!(
            "load: identified {:.0} kg ({}, stated {:.0}…{:.0} kg, friction scale {:.3}{}), true {:.0} kg: {:+.1} kg{}",
            id,
            if l.identified { "from the current" } else { "prior" },
            l.load_lo.to_f64(),
            l.load_hi.to_f64(),
            l.scale.to_f64(),
            if l.scale_known { "" } else { " assumed" },
            a.load_kg,
            id - a.load_kg,
            relative(id - a.load_kg, a.load_kg, 1.0)
        );
    }
    {
        // Stick-slip, the plant's truth beside what the board saw (docs/stick-slip.md).
        let stuck = cruise.iter().filter(|s| s.stuck).count() as f64 / n;
        let flagged = cruise.iter().filter(|s| s.flagged).count() as f64 / n;
        let episodes = lock(&shared).0.status().stick_slip_episodes;
        println!(
            "stick-slip: the plant's thread stuck {:.0} % of the cruise; the board flagged {:.0} % of it ({} episode{})",
            100.0 * stuck,
            100.0 * flagged,
            episodes,
            if episodes == 1 { "" } else { "s" }
        );
    }
    println!(
        "{:.2} s simulated in {:.2} s wall",
        last.t,
        wall.elapsed().as_secs_f64()
    );
    if let Some(path) = &a.plot {
        // The numbers above are the result; a missing font only costs the picture.
        match plot(path, a, &samples) {
            Ok(()) => println!("plot: {}", path.display()),
            Err(e) => println!("plot skipped: {e}"),
        }
    }
    Ok(LiftOutcome {
        final_mm: last.true_height,
        error_mm: err,
        overshoot_mm: over,
        tr_plant: mean_true,
        tr_core: mean_core,
    })
}

/// How long `host-sim lift` lets a move from `from_deg` to `to_deg` run at a screw cruise of
/// `cruise` rad/s: 20 s plus twice the time at cruise (the head moves at the nut's speed
/// ω·lead/2π times cot α, slowest high up; a full stroke at 3 rad/s takes minutes, far beyond
/// the fixed 120 s cap this replaced).
pub fn time_cap(from_deg: f64, to_deg: f64, cruise: f64) -> f64 {
    let g = Geometry::paper();
    let nut_speed = cruise.max(1e-3) * 2e-3 / std::f64::consts::TAU;
    let (lo, hi) = (from_deg.min(to_deg), from_deg.max(to_deg));
    let steps = 400;
    let stroke_s: f64 = (0..steps)
        .map(|i| {
            let a0 = (lo + (hi - lo) * f64::from(i) / f64::from(steps)).to_radians();
            let a1 = (lo + (hi - lo) * f64::from(i + 1) / f64::from(steps)).to_radians();
            let dh = g.length * (a1.sin() - a0.sin());
            dh / (nut_speed / (0.5 * (a0 + a1)).tan())
        })
        .sum();
    20.0 + 2.0 * stroke_s
}

/// How a run ended.
enum End {
    /// At rest after the move.
    Arrived,
    /// The goto was refused.
    Refused(Refusal),
    /// A protection tripped (the `fault` line).
    Fault(String),
    /// Still going at the time cap.
    Cap,
}

fn plot(path: &Path, a: &LiftArgs, s: &[Sample]) -> Result<(), String> {
    plotting::init_font()?;
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    let draw = || -> Result<(), Box<dyn std::error::Error>> {
        let root = BitMapBackend::new(path, (1200, 760)).into_drawing_area();
        root.fill(&WHITE)?;
        let (top, bottom) = root.split_vertically(380);
        let t_end = s.last().map_or(1.0, |x| x.t);
        let (h_lo, h_hi) = plotting::range(s.iter().flat_map(|x| [x.true_height, x.core_height]));
        let mut c = ChartBuilder::on(&top)
            .caption(
                format!(
                    "{} thread, {} kg: head height, plant vs liftfw core (target {} mm)",
                    a.lubricant.name(),
                    a.load_kg,
                    a.to_mm
                ),
                (plotting::FONT, 18),
            )
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..t_end, h_lo - 0.5..h_hi + 0.5)?;
        c.configure_mesh()
            .x_desc("t, s")
            .y_desc("height, mm")
            .label_style((plotting::FONT, 13))
            .draw()?;
        c.draw_series(LineSeries::new(
            s.iter().map(|x| (x.t, x.true_height)),
            &BLUE,
        ))?
        .label("plant (truth)")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 18, y)], BLUE));
        c.draw_series(LineSeries::new(
            s.iter().map(|x| (x.t, x.core_height)),
            &RED,
        ))?
        .label("core (encoder, model)")
        .legend(|(x, y)| PathElement::new([(x, y), (x + 18, y)], RED));
        c.draw_series(LineSeries::new(
            [(0.0, a.to_mm), (t_end, a.to_mm)],
            BLACK.mix(0.4),
        ))?;
        c.configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font((plotting::FONT, 13))
            .position(SeriesLabelPosition::LowerRight)
            .draw()?;

        let (t_lo, t_hi) = plotting::range(s.iter().flat_map(|x| [x.true_tr, x.core_tr]));
        let mut c = ChartBuilder::on(&bottom)
            .caption(
                "thread friction torque T_r: plant vs the core's real-time estimate",
                (plotting::FONT, 18),
            )
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..t_end, t_lo - 0.2..t_hi + 0.2)?;
        c.configure_mesh()
            .x_desc("t, s")
            .y_desc("T_r, N·m")
            .label_style((plotting::FONT, 13))
            .draw()?;
        c.draw_series(LineSeries::new(s.iter().map(|x| (x.t, x.true_tr)), &BLUE))?
            .label("plant T_r")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 18, y)], BLUE));
        c.draw_series(LineSeries::new(s.iter().map(|x| (x.t, x.core_tr)), &RED))?
            .label("core estimate")
            .legend(|(x, y)| PathElement::new([(x, y), (x + 18, y)], RED));
        c.configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font((plotting::FONT, 13))
            .position(SeriesLabelPosition::UpperRight)
            .draw()?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| format!("{}: {e}", path.display()))
}

/// ", ±x.x %" of `truth`, or nothing where |truth| is below `least` and a percentage means
/// nothing (an empty lift printed "+127 kg (+12744799804687.5 %)").
fn relative(err: f64, truth: f64, least: f64) -> String {
    if truth.abs() < least {
        String::new()
    } else {
        format!(", {:+.1} %", 100.0 * err / truth.abs())
    }
}
