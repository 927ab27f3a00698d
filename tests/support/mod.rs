//! Closed-loop harness shared by the behaviour tests: the liftfw core's `Controller` driving
//! host-sim's float64 plant (motor, bridge, battery, encoder, ADCs, limit switches) at its own
//! 1 kHz tick, with hooks to send commands and to inject faults into what the board sees.
#![allow(dead_code, clippy::expect_used, clippy::unwrap_used)]

use host_sim::physics::Lubricant;
use host_sim::sim::{Driver, Sim, SimConfig, Summary};
use host_sim::trace::Trace;
use liftfw::control::config::ControlConfig;
use liftfw::control::{Bridge, Controller, Event, Inputs, Outputs};
use liftfw::model::friction::FrictionLaw;
use liftfw::units::{Instant, Kilograms, Metres};
use std::sync::{Arc, Mutex};

/// The core's preset for a plant lubricant.
pub fn core_law(l: Lubricant) -> FrictionLaw {
    match l {
        Lubricant::Dry => FrictionLaw::DRY,
        Lubricant::Ptfe => FrictionLaw::PTFE,
        Lubricant::Lithium => FrictionLaw::LITHIUM,
    }
}

/// One closed-loop scenario.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// Plant lubricant (the core is configured with the same preset).
    pub lubricant: Lubricant,
    /// Mass on the head, kg.
    pub load: f64,
    /// Arm angle at the start, degrees.
    pub start_deg: f64,
    /// Simulated time, s.
    pub duration: f64,
    /// Noise seed.
    pub seed: u64,
    /// The core's configuration.
    pub control: ControlConfig,
    /// Integration step, s.
    pub dt: f64,
    /// Battery open-circuit voltage, V.
    pub battery: f64,
    /// Boot with the position unknown ([`Controller::new_unhomed`]) instead of at the start.
    pub unhomed: bool,
    /// The plant has seed 001's 4008 ball screw instead of the S12x2 lead screw (see
    /// [`Scenario::ball_screw`]); the core's configuration is the caller's.
    pub ball_screw: bool,
    /// Ball screw: the plant's f(τ) multiplied by this (1: seed 002's law; more: degraded
    /// lubrication or wear).
    pub ball_friction_factor: f64,
    /// The motor's own friction (Coulomb and viscous) multiplied by this (1: host-sim's motor).
    pub motor_friction_factor: f64,
    /// A spring-applied holding brake in the plant, driven by the core's brake output.
    pub brake: Option<host_sim::plant::BrakeParams>,
    /// The plant's thread friction as a multiple of the lubricant's law (1: as configured;
    /// more: a drier thread than the core's law says).
    pub thread_friction_factor: f64,
    /// Faults injected by the simulation (`host_sim::inject`): sensors, supply, jam, overload.
    pub faults: host_sim::inject::Plan,
}

impl Scenario {
    /// Default lift and board, `load` kg, starting at `start_deg`, 1 kHz trace.
    pub fn new(lubricant: Lubricant, load: f64, start_deg: f64, duration: f64) -> Self {
        let mut control = ControlConfig::DEFAULT;
        control.estimator.law = core_law(lubricant);
        Self {
            lubricant,
            load,
            start_deg,
            duration,
            seed: 1,
            control,
            dt: 4e-6,
            battery: 12.6,
            unhomed: false,
            ball_screw: false,
            ball_friction_factor: 1.0,
            motor_friction_factor: 1.0,
            brake: None,
            thread_friction_factor: 1.0,
            faults: host_sim::inject::Plan::default(),
        }
    }

    /// Stops at the mechanism's ends (133.5 … 416.4 mm): lower stop 134.1 mm, upper 414 mm,
    /// the lower switch's reference just above α₀ (133.55 mm), 0.55 mm under the lower stop.
    pub fn wide_stops(&mut self) {
        self.control.limits.switch_lower = Metres::from_f64(0.13355);
        self.control.limits.lower = Metres::from_f64(0.1341);
        self.control.limits.upper = Metres::from_f64(0.414);
    }

    /// The ball-screw lift: plant with the 4008 ball screw (seed 002's law as a thread law at
    /// the rated load's axial force at 45°), core with `ControlConfig::ball_screw_4008()`.
    #[cfg(feature = "ball-screw")]
    pub fn ball_screw(load: f64, start_deg: f64, duration: f64) -> Self {
        let mut s = Self::new(Lubricant::Dry, load, start_deg, duration);
        s.control = ControlConfig::ball_screw_4008().expect("valid preset");
        s.ball_screw = true;
        s
    }
}

/// What a hook may do each tick, before the controller sees the inputs.
pub struct Tick<'a> {
    /// Simulated time, s.
    pub t: f64,
    /// The board's inputs (mutable: fault injection).
    pub inputs: &'a mut Inputs,
    /// The controller (commands).
    pub controller: &'a mut Controller,
    /// Skip the controller this tick (a hung control task): the bridge keeps its last command.
    pub skip: bool,
    /// Apply this bridge state instead of the controller's command (a failed bridge or driver);
    /// the controller still runs and does not know.
    pub force: Option<Bridge>,
}

/// A tick hook.
pub type Hook = Box<dyn FnMut(&mut Tick<'_>) + Send>;

/// What one tick did.
#[derive(Clone, Copy, Debug)]
pub struct TickLog {
    /// Time, s.
    pub t: f64,
    /// The bridge command applied.
    pub bridge: Bridge,
    /// Whether the watchdog was fed.
    pub fed: bool,
    /// The core's brake output (true: released).
    pub brake_release: bool,
}

/// The outcome of a closed-loop run.
pub struct Run {
    /// Ground truth.
    pub trace: Trace,
    /// Summary.
    pub summary: Summary,
    /// Events the core reported, with their time.
    pub events: Vec<(f64, Event)>,
    /// Every tick.
    pub ticks: Vec<TickLog>,
    /// The controller at the end.
    pub controller: Controller,
}

impl Run {
    /// True head height at the end, m.
    pub fn final_height(&self) -> f64 {
        self.summary.height.1
    }

    /// Highest (lifting) or lowest (lowering) true height reached, m.
    pub fn extreme_height(&self, lifting: bool) -> f64 {
        let it = self.trace.records.iter().map(|r| r.height);
        if lifting {
            it.fold(f64::NEG_INFINITY, f64::max)
        } else {
            it.fold(f64::INFINITY, f64::min)
        }
    }

    /// The largest true motor current of the run (the plant's, not the sensor's), A.
    pub fn peak_current(&self) -> f64 {
        self.trace
            .records
            .iter()
            .map(|r| r.current.abs())
            .fold(0.0, f64::max)
    }

    /// Time of the first fault event, s.
    pub fn first_fault(&self) -> Option<(f64, liftfw::control::Fault)> {
        self.events.iter().find_map(|(t, e)| match e {
            Event::Fault(f) => Some((*t, *f)),
            _ => None,
        })
    }
}

/// Encoder position (counts from fully down) the core must boot with for a start angle.
pub fn start_counts(c: &Controller, start_deg: f64) -> i32 {
    let g = host_sim::physics::Geometry::paper();
    let h = g.height(start_deg.to_radians());
    c.estimator()
        .geometry()
        .counts_for_height(Metres::from_f64(h))
        .expect("start inside the mechanism")
}

/// Run `s` with `hook` called every tick before the controller.
pub fn run(s: &Scenario, mut hook: Hook) -> Run {
    let mut cfg = SimConfig::paper(s.lubricant.law(), 0.3, s.start_deg);
    cfg.plant.load = s.load;
    cfg.duration = s.duration;
    cfg.dt = s.dt;
    cfg.record_rate = 1000.0;
    cfg.seed = s.seed;
    cfg.drive.battery_voltage = s.battery;
    cfg.drive.motor_coulomb *= s.motor_friction_factor;
    cfg.drive.motor_viscous *= s.motor_friction_factor;
    cfg.brake = s.brake;
    cfg.plant.law.base *= s.thread_friction_factor;
    cfg.plant.law.amp *= s.thread_friction_factor;
    cfg.plant.law.slope *= s.thread_friction_factor;
    cfg.faults = s.faults;
    if s.ball_screw {
        let mut bs = host_sim::physics::ballscrew::BallScrewFriction::seed_001_4008();
        bs.law.base *= s.ball_friction_factor;
        bs.law.amp *= s.ball_friction_factor;
        bs.law.slope *= s.ball_friction_factor;
        cfg.plant.screw = bs.plant_screw(cfg.plant.screw);
        cfg.plant.law = bs.equivalent_law(1000.0 * host_sim::physics::G);
    }
    let probe = Controller::new(&s.control, 0).expect("valid control config");
    let start = start_counts(&probe, s.start_deg);
    let controller = if s.unhomed {
        Controller::new_unhomed(&s.control)
    } else {
        Controller::new(&s.control, start)
    }
    .expect("valid control config");
    let shared = Arc::new(Mutex::new((
        controller,
        Vec::<(f64, Event)>::new(),
        Vec::<TickLog>::new(),
    )));
    let inner = Arc::clone(&shared);
    let mut last = Outputs {
        bridge: Bridge::Coast,
        feed_watchdog: false,
        brake_release: false,
        event: None,
    };
    let driver = Driver::Board(Box::new(move |t: f64, inputs: &Inputs| {
        let mut g = inner.lock().expect("not poisoned");
        let (c, events, ticks) = &mut *g;
        let mut inputs = *inputs;
        let mut tick = Tick {
            t,
            inputs: &mut inputs,
            controller: c,
            skip: false,
            force: None,
        };
        hook(&mut tick);
        if tick.skip {
            ticks.push(TickLog {
                t,
                bridge: last.bridge,
                fed: false,
                brake_release: last.brake_release,
            });
            return last;
        }
        let force = tick.force;
        let mut out = c.step(Instant((t * 1e6).round() as u64 as u32), &inputs);
        c.finish_tick();
        if let Some(b) = force {
            out.bridge = b;
        }
        if let Some(e) = out.event {
            events.push((t, e));
        }
        ticks.push(TickLog {
            t,
            bridge: out.bridge,
            fed: out.feed_watchdog,
            brake_release: out.brake_release,
        });
        out.event = None;
        last = out;
        out
    }));
    let mut sim = Sim::new(cfg, driver).expect("valid sim config");
    let summary = sim.run();
    let trace = std::mem::take(&mut sim.trace);
    drop(sim);
    let (controller, events, ticks) = Arc::try_unwrap(shared)
        .unwrap_or_else(|_| panic!("the sim still holds the driver"))
        .into_inner()
        .expect("not poisoned");
    Run {
        trace,
        summary,
        events,
        ticks,
        controller,
    }
}

/// A hook that sends `cmd` once at time `at`.
pub fn command_at(at: f64, cmd: liftfw::control::Command) -> Hook {
    let mut sent = false;
    Box::new(move |k: &mut Tick<'_>| {
        if !sent && k.t >= at {
            sent = true;
            k.controller.command(cmd).expect("command accepted");
        }
    })
}

/// Kilograms from f64.
pub fn kg(v: f64) -> Kilograms {
    Kilograms::from_f64(v)
}
