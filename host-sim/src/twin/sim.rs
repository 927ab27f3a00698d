//! A run of the twin: the plant, one driver, a fixed-step RK23 loop with stick/slip events,
//! the ground-truth trace and a summary.
//!
//! Drivers:
//! - [`Driver::Paper`]: θ_i(t) prescribed by seed 000's Fig. 2 profile (no motor);
//! - [`Driver::Core`]: the liftfw core's `Controller::step` at its own control rate, seeing only
//!   [`Inputs`] (encoder counter, ADC codes, switches) and driving the simulated bridge;
//! - [`Driver::OpenLoop`]: a fixed duty with a soft-start ramp, to exercise the motor path;
//! - [`Driver::Custom`]: any closure from time and inputs to a bridge command.
//!
//! Hybrid integration: the base step `dt` is fixed; inside a step the phase (stick, slip up,
//! slip down) and the bridge state are fixed, so the right-hand side is smooth. When the step
//! ends across a phase event (θ̇ reaching 0 while slipping; the breakaway margin turning
//! positive while stuck) the event time is bracketed by regula falsi on the step length, the
//! step is cut there, the phase switched and the rest of the step taken in the new phase.

use crate::twin::physics::FrictionLaw;
use crate::twin::plant::kernel::Kernel;
use crate::twin::plant::screw_nut::Loads;
use crate::twin::plant::{
    drive::coast_clamp, BridgeState, DriveParams, Phase, ScrewNut, SensorParams, Sensors,
    SpeedProfile,
};
use crate::twin::solver::{
    bracket_root, rk23_embedded, rk23_step, rk23_step_from, OdeState, StepControl,
};
use crate::twin::trace::{Energy, PhaseChange, Record, Trace};
use liftfw::control::{Bridge, Controller, Inputs};
use liftfw::units::Instant;
use std::cell::Cell;
use std::fmt;

macro_rules! state {
    ($($(#[$m:meta])* $f:ident),* $(,)?) => {
        /// The continuous state: mechanics, drive and the running energy/torque integrals
        /// (integrated with the same RK23 as the dynamics, so the balance is as exact as the
        /// solution).
        #[derive(Clone, Copy, Debug, Default, PartialEq)]
        pub struct State { $($(#[$m])* pub $f: f64,)* }
        impl OdeState for State {
            #[inline(always)]
            fn add_scaled(&mut self, a: f64, o: &Self) { $(self.$f += a * o.$f;)* }
            #[inline(always)]
            fn scale(&mut self, a: f64) { $(self.$f *= a;)* }
        }
    };
}

state! {
    /// Screw angle θ, rad (0 at α = α₀).
    theta,
    /// Screw rate θ̇, rad/s.
    theta_dot,
    /// Motor shaft angle, rad (closed loop).
    motor_angle,
    /// Motor speed, rad/s (closed loop).
    motor_speed,
    /// Armature current, A (closed loop).
    current,
    /// ∫ T_c·θ̇_i dt.
    e_input,
    /// ∫ T_c·θ̇ dt.
    e_screw_input,
    /// ∫ μ|N||v_s| dt.
    e_thread,
    /// ∫ (T₀|θ̇| + cθ̇²) dt.
    e_support,
    /// ∫ F₀|ẋ| dt.
    e_pins,
    /// ∫ c_x ẋ² dt.
    e_structure,
    /// ∫ T_r dt.
    q_friction_torque,
    /// ∫ V_oc·i_b dt.
    e_source,
    /// ∫ ohmic + diode losses dt.
    e_electrical,
    /// ∫ motor friction + gear losses dt.
    e_drive,
}

/// Open-loop duty driver: ramps the duty linearly from 0 to `duty` over `ramp` seconds and
/// holds it; coasts once a limit switch in the direction of travel closes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OpenLoopDuty {
    /// Signed duty in [−1, 1] (positive lifts).
    pub duty: f64,
    /// Soft-start ramp, s.
    pub ramp: f64,
}

impl OpenLoopDuty {
    /// The bridge command at time `t` given the board's inputs.
    pub fn command(&self, t: f64, inputs: &Inputs) -> Bridge {
        use liftfw::control::Switches;
        let blocked = if self.duty > 0.0 {
            inputs.switches.is_active(Switches::LIMIT_UPPER)
        } else {
            inputs.switches.is_active(Switches::LIMIT_LOWER)
        };
        if blocked || self.duty == 0.0 {
            return Bridge::Coast;
        }
        let d = self.duty.clamp(-1.0, 1.0) * (t / self.ramp.max(1e-9)).min(1.0);
        Bridge::Drive((d * f64::from(i16::MAX)).round() as i16)
    }
}

/// A custom bridge commander: `(t, inputs) -> bridge`.
pub type Commander = Box<dyn FnMut(f64, &Inputs) -> Bridge + Send>;

/// A custom board: `(t, inputs) -> outputs` (bridge and brake output).
pub type Board = Box<dyn FnMut(f64, &Inputs) -> liftfw::control::Outputs + Send>;

/// What moves the coupling's input side.
pub enum Driver {
    /// Fig. 2 profile: θ_i prescribed, no motor.
    Paper(SpeedProfile),
    /// The liftfw core.
    Core(Box<Controller>),
    /// Fixed duty with soft start.
    OpenLoop(OpenLoopDuty),
    /// Any closure `(t, inputs) -> bridge` (a brake in the plant stays released).
    Custom(Commander),
    /// Any closure `(t, inputs) -> outputs`: the bridge and the brake output.
    Board(Board),
}

impl Driver {
    fn is_paper(&self) -> bool {
        matches!(self, Driver::Paper(_))
    }
}

impl fmt::Debug for Driver {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Driver::Paper(p) => write!(f, "Paper({p:?})"),
            Driver::Core(_) => write!(f, "Core"),
            Driver::OpenLoop(o) => write!(f, "OpenLoop({o:?})"),
            Driver::Custom(_) => write!(f, "Custom"),
            Driver::Board(_) => write!(f, "Board"),
        }
    }
}

/// How the run loop chooses its steps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Stepping {
    /// The fixed base step [`SimConfig::dt`], as seed 000's `ode3`; the convergence study
    /// (docs/plant.md) chooses it.
    Fixed,
    /// Bogacki–Shampine with its embedded error estimate: every step's estimated local error
    /// within `tol` of the scales of [`Sim::error_norm`], steps at most `h_max` s. Events are
    /// located as at a fixed step; [`SimConfig::dt`] is the first trial step, the step inside
    /// [`SimConfig::dense_window`] and the scale of the event-time tolerance. Paper mode only
    /// (the closed loop keeps its fixed step, a whole fraction of the control period).
    Adaptive {
        /// Error tolerance, relative to the scales of [`Sim::error_norm`].
        tol: f64,
        /// Largest step, s.
        h_max: f64,
    },
}

/// The largest adaptive step by default, s: the Table 1 damping and the coupling put the
/// screw's eigenvalues near 7·10³ s⁻¹, so RK23's stability, not the error, bounds sliding steps
/// to ≈ 0.3 ms; while stuck the error bound lets steps grow to this cap.
pub const ADAPTIVE_H_MAX: f64 = 1e-3;

/// The adaptive tolerance recommended for paper mode: the loosest of the sweep
/// 10⁻², 3·10⁻³, 10⁻³, … at which the mean T_r over 0.999–1 s and over 0.06–1 s of every one
/// of the 18 matrix cases is within 1 % of the fixed step 1 µs, and stays so one level tighter
/// (docs/plant.md; at 10⁻³ dry lifting from 65° is 2.1 % off).
pub const DEFAULT_TOL: f64 = 3e-4;

/// Everything a run needs besides its driver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimConfig {
    /// The lift.
    pub plant: ScrewNut,
    /// Arm angle at the start, rad.
    pub start_alpha: f64,
    /// Base integration step, s.
    pub dt: f64,
    /// Fixed or adaptive steps.
    pub stepping: Stepping,
    /// Simulated time, s.
    pub duration: f64,
    /// Trace sampling rate, Hz (0: no trace).
    pub record_rate: f64,
    /// A time window (s) in which every base step is recorded as well (zoomed plots), if any.
    pub dense_window: Option<(f64, f64)>,
    /// Control-tick rate of the core (closed loop), Hz.
    pub control_rate: f64,
    /// Motor, gearbox, bridge, battery.
    pub drive: DriveParams,
    /// Encoder, ADCs, limit switches.
    pub sensors: SensorParams,
    /// Seed of the sensor noise.
    pub seed: u64,
    /// Window over which the summary averages T_r and measures the twist oscillation, s.
    pub window: (f64, f64),
    /// A spring-applied holding brake on the screw, driven by the board's brake output
    /// ([`Driver::Core`], [`Driver::Board`]); none by default.
    pub brake: Option<crate::twin::plant::BrakeParams>,
    /// Faults injected into a closed-loop run ([`crate::twin::inject`]); none by default.
    pub faults: crate::twin::inject::Plan,
}

/// Default base step, s (docs/plant.md, convergence study).
pub const DEFAULT_DT: f64 = 2e-6;

impl SimConfig {
    /// Seed 000's setting: 1000 kg, the given lubricant, μ_b, start angle (degrees); 5 s at the
    /// default step, 10 kHz trace, 1 kHz control, window 0.999–1 s.
    pub fn paper(law: FrictionLaw, mu_pin: f64, start_deg: f64) -> Self {
        let mut plant = ScrewNut::paper(law, 1000.0);
        plant.geometry.mu_pin = mu_pin;
        let g = plant.geometry;
        Self {
            plant,
            start_alpha: start_deg.to_radians(),
            dt: DEFAULT_DT,
            stepping: Stepping::Fixed,
            duration: 5.0,
            record_rate: 10_000.0,
            dense_window: None,
            control_rate: 1000.0,
            drive: DriveParams::default(),
            sensors: SensorParams::with_limits(
                g.height(16f64.to_radians()),
                g.height(74f64.to_radians()),
            ),
            seed: 0,
            window: (0.999, 1.0),
            brake: None,
            faults: crate::twin::inject::Plan::default(),
        }
    }
}

/// Why a configuration was refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ConfigError {
    /// The control period is not a whole number of base steps.
    ControlPeriodNotMultipleOfDt,
    /// A step, duration or rate is not positive and finite.
    NonPositive,
    /// Adaptive steps were asked for outside paper mode.
    AdaptiveNeedsPaperMode,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConfigError::ControlPeriodNotMultipleOfDt => {
                write!(f, "the control period must be a whole number of steps dt")
            }
            ConfigError::NonPositive => write!(
                f,
                "dt, duration, control rate, tolerance and largest step must be positive"
            ),
            ConfigError::AdaptiveNeedsPaperMode => {
                write!(f, "adaptive steps are for paper mode only")
            }
        }
    }
}

impl std::error::Error for ConfigError {}

/// Statistics over one time window.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WindowStats {
    /// Window start, s.
    pub start: f64,
    /// Window end, s.
    pub end: f64,
    /// Mean thread friction torque T_r, N·m (time average from the exact integral).
    pub mean_friction_torque: f64,
    /// Peak-to-peak of θ − θ_i, rad.
    pub twist_peak_to_peak: f64,
    /// Fraction of the window spent stuck.
    pub stick_fraction: f64,
    /// Number of stick phases that began in the window.
    pub sticks: usize,
}

#[derive(Clone, Copy, Debug)]
struct Window {
    a: f64,
    b: f64,
    q_a: Option<f64>,
    q_b: Option<f64>,
    twist_min: f64,
    twist_max: f64,
    stick_time: f64,
    sticks: usize,
}

impl Window {
    fn new(a: f64, b: f64) -> Self {
        Self {
            a,
            b,
            q_a: None,
            q_b: None,
            twist_min: f64::INFINITY,
            twist_max: f64::NEG_INFINITY,
            stick_time: 0.0,
            sticks: 0,
        }
    }

    fn overlap(&self, t0: f64, t1: f64) -> f64 {
        (t1.min(self.b) - t0.max(self.a)).max(0.0)
    }

    fn stats(&self) -> Option<WindowStats> {
        let len = self.b - self.a;
        Some(WindowStats {
            start: self.a,
            end: self.b,
            mean_friction_torque: (self.q_b? - self.q_a?) / len,
            twist_peak_to_peak: self.twist_max - self.twist_min,
            stick_fraction: self.stick_time / len,
            sticks: self.sticks,
        })
    }
}

/// The outcome of a run.
#[derive(Clone, Debug)]
pub struct Summary {
    /// Simulated time, s.
    pub duration: f64,
    /// Head height at start and end, m.
    pub height: (f64, f64),
    /// Arm angle at start and end, degrees.
    pub alpha_deg: (f64, f64),
    /// The requested window (default 0.999–1 s).
    pub window: Option<WindowStats>,
    /// The constant-speed phase of the paper profile (or the whole run in closed loop).
    pub cruise: Option<WindowStats>,
    /// Fraction of the whole run spent stuck.
    pub stick_fraction: f64,
    /// Number of stick phases.
    pub sticks: usize,
    /// Energy terms at the end.
    pub energy: Energy,
    /// Largest |motor current|, A.
    pub peak_current: f64,
    /// Mean screw speed over the second half of the run, rad/s.
    pub late_screw_speed: f64,
    /// Steps taken (base steps at a fixed step, accepted steps when adaptive).
    pub steps: u64,
    /// Adaptive steps rejected by the error test.
    pub rejected: u64,
    /// Phase events located.
    pub events: u64,
    /// Right-hand-side evaluations by the integrator and the event location.
    pub evaluations: u64,
}

/// A run in progress.
#[derive(Debug)]
pub struct Sim {
    /// Configuration.
    pub cfg: SimConfig,
    driver: Driver,
    /// Continuous state.
    pub state: State,
    /// Stick/slip phase.
    pub phase: Phase,
    bridge: BridgeState,
    sensors: Sensors,
    theta_start: f64,
    /// Recorded ground truth.
    pub trace: Trace,
    /// The plant's hot-path form, built from `cfg.plant` by [`Sim::new`].
    kernel: Kernel,
    /// Loads at the angle the screw is stuck at (θ does not move while stuck): (θ, loads).
    stuck_loads: (f64, Loads),
    windows: [Window; 2],
    stick_time: f64,
    sticks: usize,
    peak_current: f64,
    steps: u64,
    rejected: u64,
    control: StepControl,
    /// Consecutive adaptive steps cut by an event at zero length (a guard against chatter).
    chatter: u32,
    events: u64,
    evaluations: Cell<u64>,
    late: (f64, f64),
    /// The holding brake's engagement, 0 (released) … 1 (engaged; it starts unpowered).
    brake_level: f64,
    /// Injected faults' state: the count a lost encoder froze at, the start of a control
    /// task's hang, the watchdog resets not yet taken by the caller, the overload applied.
    frozen_encoder: Option<u16>,
    stall_since: Option<f64>,
    watchdog_resets: u32,
    extra_load: f64,
    /// The configured battery voltage (a sag or surge replaces it while it lasts).
    battery: f64,
}

struct Eval {
    deriv: State,
    theta_i: f64,
    t_c: f64,
    mech: crate::twin::plant::screw_nut::Mechanics,
    loads: crate::twin::plant::screw_nut::Loads,
    drive: crate::twin::plant::drive::DriveRates,
}

impl Sim {
    /// A run of `cfg` driven by `driver`, starting at rest with the coupling relaxed.
    pub fn new(cfg: SimConfig, driver: Driver) -> Result<Self, ConfigError> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !(pos(cfg.dt) && pos(cfg.duration) && pos(cfg.control_rate)) {
            return Err(ConfigError::NonPositive);
        }
        if let Stepping::Adaptive { tol, h_max } = cfg.stepping {
            if !(pos(tol) && pos(h_max)) {
                return Err(ConfigError::NonPositive);
            }
            if !driver.is_paper() {
                return Err(ConfigError::AdaptiveNeedsPaperMode);
            }
        }
        if !driver.is_paper() {
            let per = 1.0 / (cfg.control_rate * cfg.dt);
            if (per - per.round()).abs() > 1e-6 || per.round() < 1.0 {
                return Err(ConfigError::ControlPeriodNotMultipleOfDt);
            }
        }
        let theta_start = cfg.plant.theta_at_alpha(cfg.start_alpha);
        let cruise = match &driver {
            Driver::Paper(p) => Window::new(p.ramp_end, p.brake_start.min(cfg.duration)),
            _ => Window::new(0.0, cfg.duration),
        };
        let kernel = Kernel::new(cfg.plant);
        Ok(Self {
            state: State {
                theta: theta_start,
                ..State::default()
            },
            kernel,
            stuck_loads: (theta_start, kernel.loads(theta_start)),
            phase: Phase::Stick,
            bridge: BridgeState::Coast,
            sensors: Sensors::new(cfg.sensors, cfg.seed),
            theta_start,
            trace: Trace::default(),
            windows: [Window::new(cfg.window.0, cfg.window.1), cruise],
            stick_time: 0.0,
            sticks: 0,
            peak_current: 0.0,
            steps: 0,
            rejected: 0,
            control: StepControl::default(),
            chatter: 0,
            events: 0,
            evaluations: Cell::new(0),
            late: (0.0, 0.0),
            brake_level: 1.0,
            frozen_encoder: None,
            stall_since: None,
            watchdog_resets: 0,
            extra_load: 0.0,
            battery: cfg.drive.battery_voltage,
            cfg,
            driver,
        })
    }

    /// θ_i and θ̇_i at time t for state y.
    #[inline]
    fn input(&self, t: f64, y: &State) -> (f64, f64) {
        match &self.driver {
            Driver::Paper(p) => (self.theta_start + p.angle(t), p.speed(t)),
            _ => {
                let n = self.cfg.drive.ratio;
                (self.theta_start + y.motor_angle / n, y.motor_speed / n)
            }
        }
    }

    /// Loads at θ; while stuck, from the cache filled when the screw stuck.
    #[inline]
    fn loads_at(&self, theta: f64, phase: Phase) -> Loads {
        if phase == Phase::Stick && self.stuck_loads.0 == theta {
            self.stuck_loads.1
        } else {
            self.kernel.loads(theta)
        }
    }

    /// The integrator's right-hand side in the current phase and bridge state (counted).
    #[inline]
    fn rhs(&self, t: f64, y: &State) -> State {
        self.evaluations.set(self.evaluations.get() + 1);
        self.eval(t, y, self.phase, self.bridge).deriv
    }

    #[inline]
    fn eval(&self, t: f64, y: &State, phase: Phase, bridge: BridgeState) -> Eval {
        let p = &self.kernel;
        let (theta_i, theta_i_dot) = self.input(t, y);
        let t_c = self.cfg.plant.screw.coupling * (theta_i - y.theta);
        let loads = self.loads_at(y.theta, phase);
        let mut d = State::default();
        let mech = match phase {
            Phase::Slip(dir) => {
                let m = p.slipping(&loads, y.theta_dot, t_c, dir);
                let pw = p.powers(&loads, y.theta_dot, &m);
                d.theta = y.theta_dot;
                d.theta_dot = m.theta_ddot;
                d.e_thread = pw.thread;
                d.e_support = pw.support;
                d.e_pins = pw.pins;
                d.e_structure = pw.structure;
                m
            }
            Phase::Stick => p.stuck(&loads, t_c),
        };
        d.e_input = t_c * theta_i_dot;
        d.e_screw_input = t_c * d.theta;
        d.q_friction_torque = mech.contact.friction_torque;
        let mut drive = Default::default();
        if !self.driver.is_paper() {
            let r = self.cfg.drive.rates(y.current, y.motor_speed, bridge, t_c);
            d.motor_angle = y.motor_speed;
            d.motor_speed = r.dw;
            d.current = r.di;
            d.e_source = r.source_power;
            d.e_electrical = r.ohmic_loss + r.diode_loss;
            d.e_drive = r.motor_friction_loss + r.gear_loss;
            drive = r;
        }
        Eval {
            deriv: d,
            theta_i,
            t_c,
            mech,
            loads,
            drive,
        }
    }

    /// Event function of `phase`: crosses from ≤ 0 to > 0 when the phase must end.
    #[inline]
    fn event_fn(&self, t: f64, y: &State, phase: Phase) -> f64 {
        match phase {
            Phase::Slip(dir) => -dir.sign() * y.theta_dot,
            Phase::Stick => {
                let (theta_i, _) = self.input(t, y);
                self.kernel.breakaway_margin(
                    &self.loads_at(y.theta, phase),
                    self.cfg.plant.screw.coupling * (theta_i - y.theta),
                )
            }
        }
    }

    #[inline]
    fn substep(&self, t: f64, y: &State, h: f64) -> State {
        let mut f = |t: f64, y: &State| self.rhs(t, y);
        let out = rk23_step(&mut f, t, y, h);
        self.constrain(y, out)
    }

    /// [`Self::substep`] with `k1 = f(t, y)` known.
    #[inline]
    fn substep_from(&self, t: f64, y: &State, k1: &State, h: f64) -> State {
        let mut f = |t: f64, y: &State| self.rhs(t, y);
        let out = rk23_step_from(&mut f, t, y, k1, h);
        self.constrain(y, out)
    }

    /// What the phase and bridge hold exactly: no motion while stuck, no current through a
    /// blocked coasting bridge.
    #[inline]
    fn constrain(&self, y: &State, mut out: State) -> State {
        out.current = coast_clamp(self.bridge, y.current, out.current);
        if self.phase == Phase::Stick {
            out.theta_dot = 0.0;
        }
        out
    }

    /// The phase to enter at (t, y), where the current phase's event fired.
    fn next_phase(&self, t: f64, y: &State) -> Phase {
        let (theta_i, _) = self.input(t, y);
        let t_c = self.cfg.plant.screw.coupling * (theta_i - y.theta);
        match self
            .kernel
            .breakaway(&self.loads_at(y.theta, self.phase), t_c)
        {
            Some(d) => Phase::Slip(d),
            None => Phase::Stick,
        }
    }

    /// Advances one base step from t to t_end.
    fn advance(&mut self, t: f64, t_end: f64) {
        let mut t0 = t;
        let mut transitions = 0;
        while t_end - t0 > 1e-15 {
            let h = t_end - t0;
            let y0 = self.state;
            let y1 = self.substep(t0, &y0, h);
            let fired = transitions < 8 && self.event_fn(t0 + h, &y1, self.phase) > 0.0;
            let (t1, y_new) = if fired {
                let (_, hi) = self.locate(t0, &y0, None, h, &y1);
                let yh = if hi < h {
                    self.substep(t0, &y0, hi)
                } else {
                    y1
                };
                (t0 + hi, yh)
            } else {
                (t_end, y1)
            };
            self.commit(t0, t1, &y0, y_new, fired);
            if fired {
                transitions += 1;
            }
            t0 = t1;
        }
    }

    /// Where in a step of length `h` from `(t0, y0)` that reached `y1` (where the phase's event
    /// fired) the event lies: its time bracketed by regula falsi on the step length to
    /// 10⁻⁶·dt, each trial a step of that length from `y0`, so the state there is an RK23
    /// solution. `k1` is `f(t0, y0)` if known. Returns the bracket `(lo, hi)` of step lengths
    /// (the phase still holds at `lo`, the event has fired at `hi`; `hi − lo` ≤ 10⁻⁶·dt).
    fn locate(&self, t0: f64, y0: &State, k1: Option<&State>, h: f64, y1: &State) -> (f64, f64) {
        let g1 = self.event_fn(t0 + h, y1, self.phase);
        let step = |s: f64| match k1 {
            Some(k1) => self.substep_from(t0, y0, k1, s),
            None => self.substep(t0, y0, s),
        };
        let g0 = self.event_fn(t0, y0, self.phase).min(0.0);
        let mut g = |s: f64| self.event_fn(t0 + s, &step(s), self.phase);
        bracket_root(&mut g, 0.0, h, g0, g1, 1e-6 * self.cfg.dt, 40)
    }

    /// Books the step from `(t0, y0)` to `(t1, y1)` and switches the phase if its event fired.
    fn commit(&mut self, t0: f64, t1: f64, y0: &State, y1: State, fired: bool) {
        if self.phase == Phase::Stick {
            self.stick_time += t1 - t0;
            for w in &mut self.windows {
                w.stick_time += w.overlap(t0, t1);
            }
        }
        self.integrate_windows(t0, t1, y0, &y1);
        self.state = y1;
        if !fired {
            return;
        }
        self.events += 1;
        let old = self.phase;
        if let Phase::Slip(_) = old {
            self.state.theta_dot = 0.0;
        }
        self.phase = self.next_phase(t1, &self.state);
        if self.phase == Phase::Stick {
            let th = self.state.theta;
            self.stuck_loads = (th, self.kernel.loads(th));
        }
        if self.phase != old {
            let (theta_i, _) = self.input(t1, &self.state);
            self.trace.phases.push(PhaseChange {
                t: t1,
                phase: self.phase,
                twist: self.state.theta - theta_i,
            });
        }
        if self.phase == Phase::Stick && old != Phase::Stick {
            self.sticks += 1;
            for w in &mut self.windows {
                if (w.a..w.b).contains(&t1) {
                    w.sticks += 1;
                }
            }
        }
        if let (Phase::Slip(a), Phase::Slip(b)) = (old, self.phase) {
            debug_assert!(a != b, "slip continued in the same direction after θ̇ = 0");
        }
    }

    /// The error norm of an adaptive step from `y0` to `y1` of length `h` with estimate `err`:
    /// ≤ 1 accepts. The largest of |error|/(`tol`·scale) over
    /// - θ: 1 rad (absolute: θ counts from α₀ and reaches 10³ rad, but what matters is the
    ///   twist θ − θ_i, of order 0.1 rad),
    /// - θ̇: |θ̇| + 1 rad/s,
    /// - ∫T_r: its increment over the step + h·1 N·m, so the mean T_r over any window is as
    ///   accurate as T_r itself,
    /// - each energy integral: the step's energy throughput (the sum of the increments of the
    ///   input and all loss terms) + h·1 W, so the balance, which is relative to the input,
    ///   is kept; a term whose power passes through zero does not force tiny steps.
    fn error_norm(err: &State, y0: &State, y1: &State, h: f64, tol: f64) -> f64 {
        let d = |f: fn(&State) -> f64| (f(y1) - f(y0)).abs();
        let flow = d(|y| y.e_input)
            + d(|y| y.e_screw_input)
            + d(|y| y.e_thread)
            + d(|y| y.e_support)
            + d(|y| y.e_pins)
            + d(|y| y.e_structure)
            + h;
        let w = y0.theta_dot.abs().max(y1.theta_dot.abs());
        let q = d(|y| y.q_friction_torque) + h;
        let worst_energy = [
            err.e_input,
            err.e_screw_input,
            err.e_thread,
            err.e_support,
            err.e_pins,
            err.e_structure,
        ]
        .into_iter()
        .fold(0.0f64, |m, e| m.max(e.abs()));
        [
            err.theta.abs(),
            err.theta_dot.abs() / (w + 1.0),
            err.q_friction_torque.abs() / q,
            worst_energy / flow,
        ]
        .into_iter()
        .fold(0.0, f64::max)
            / tol
    }

    /// One accepted adaptive step from `t0`, at most `h_try` long, cut at a phase event; `k1`
    /// carries `f(t0, y)` from the previous step when it is still valid (first same as last).
    /// Returns the time reached and the next step to try.
    ///
    /// When the phase's event fires inside a trial step, the step's error estimate says nothing
    /// (past the event this phase's right-hand side no longer applies: μ(|θ̇|) kinks at θ̇ = 0,
    /// the stuck share saturates at breakaway), so the event is located first and the error
    /// test is made on the step cut there.
    fn adaptive_step(
        &mut self,
        t0: f64,
        h_try: f64,
        tol: f64,
        k1: &mut Option<State>,
    ) -> (f64, f64) {
        let y0 = self.state;
        let first = match k1.take() {
            Some(k) => k,
            None => self.rhs(t0, &y0),
        };
        let h_min = 1e-6 * self.cfg.dt;
        let embedded = |sim: &Self, h: f64| {
            let mut f = |t: f64, y: &State| sim.rhs(t, y);
            let st = rk23_embedded(&mut f, t0, &y0, &first, h);
            let norm = Self::error_norm(&st.err, &y0, &st.y, h, tol);
            (st, norm)
        };
        let mut h = h_try;
        loop {
            let (st, norm) = embedded(self, h);
            let y1 = self.constrain(&y0, st.y);
            let fires = self.event_fn(t0 + h, &y1, self.phase) > 0.0 && self.chatter < 8;
            if fires {
                // The error is tested on the step to `lo`, where the phase still holds: at `hi`
                // the right-hand side may already jump (the stuck share lowering with large
                // pin friction, docs/plant.md), which the last stage would see.
                let (lo, hi) = self.locate(t0, &y0, Some(&first), h, &y1);
                let norm = if lo > 0.0 { embedded(self, lo).1 } else { 0.0 };
                let factor = self.control.factor(norm);
                if norm <= 1.0 || hi <= h_min {
                    let y = if hi < h {
                        self.substep_from(t0, &y0, &first, hi)
                    } else {
                        y1
                    };
                    self.chatter = if hi <= h_min { self.chatter + 1 } else { 0 };
                    self.commit(t0, t0 + hi, &y0, y, true);
                    // The next phase starts afresh from the converged fixed step.
                    return (t0 + hi, (hi * factor).max(self.cfg.dt));
                }
                self.rejected += 1;
                h = (hi * factor).max(h_min);
                continue;
            }
            let factor = self.control.factor(norm);
            if norm <= 1.0 || h <= h_min {
                // The last stage is the next step's first unless the step was constrained.
                if y1 == st.y {
                    *k1 = Some(st.k_end);
                }
                self.chatter = 0;
                self.commit(t0, t0 + h, &y0, y1, false);
                return (t0 + h, h * factor);
            }
            self.rejected += 1;
            h = (h * factor).max(h_min);
        }
    }

    fn integrate_windows(&mut self, t0: f64, t1: f64, y0: &State, y1: &State) {
        let lerp = |s: f64| {
            y0.q_friction_torque
                + (y1.q_friction_torque - y0.q_friction_torque) * (s - t0) / (t1 - t0)
        };
        for w in &mut self.windows {
            if w.q_a.is_none() && t1 > w.a && t0 <= w.a {
                w.q_a = Some(lerp(w.a));
            }
            if w.q_b.is_none() && t1 >= w.b && t0 < w.b {
                w.q_b = Some(lerp(w.b));
            }
        }
    }

    fn observe(&mut self, t: f64, h: f64) {
        let y = self.state;
        self.sensors.observe_encoder(t, y.motor_angle);
        let (theta_i, _) = self.input(t, &y);
        let twist = y.theta - theta_i;
        for w in &mut self.windows {
            if t >= w.a && t <= w.b {
                w.twist_min = w.twist_min.min(twist);
                w.twist_max = w.twist_max.max(twist);
            }
        }
        self.peak_current = self.peak_current.max(y.current.abs());
        if t >= 0.5 * self.cfg.duration {
            self.late.0 += y.theta_dot * h;
            self.late.1 += h;
        }
    }

    /// Energy terms of state y at time t.
    pub fn energy(&self, t: f64, y: &State) -> Energy {
        let p = &self.cfg.plant;
        let (theta_i, _) = self.input(t, y);
        let d = &self.cfg.drive;
        let open = !self.driver.is_paper();
        Energy {
            input: y.e_input,
            screw_input: y.e_screw_input,
            thread: y.e_thread,
            support: y.e_support,
            pins: y.e_pins,
            structure: y.e_structure,
            potential: p.potential_energy(y.theta) - p.potential_energy(self.theta_start),
            kinetic: p.kinetic_energy(y.theta_dot),
            spring: 0.5 * p.screw.coupling * (theta_i - y.theta).powi(2),
            source: y.e_source,
            electrical_loss: y.e_electrical,
            drive_loss: y.e_drive,
            drive_stored: if open {
                0.5 * d.inertia() * y.motor_speed.powi(2)
                    + 0.5 * d.armature_inductance * y.current.powi(2)
            } else {
                0.0
            },
        }
    }

    /// The ground-truth record at time t.
    pub fn record(&self, t: f64) -> Record {
        let y = self.state;
        let e = self.eval(t, &y, self.phase, self.bridge);
        let c = e.mech.contact;
        Record {
            t,
            theta_i: e.theta_i,
            theta: y.theta,
            theta_dot: y.theta_dot,
            twist: y.theta - e.theta_i,
            alpha_deg: e.loads.alpha.to_degrees(),
            height: e.loads.height,
            r: e.loads.r,
            f0: e.loads.f0,
            c_x: e.loads.c_x,
            mu: c.mu,
            mu_s: c.mu_s,
            normal: c.normal,
            friction_torque: c.friction_torque,
            coupling_torque: e.t_c,
            phase: self.phase,
            flank: e.mech.flank,
            current: y.current,
            armature_voltage: e.drive.armature_voltage,
            bus_voltage: e.drive.bus_voltage,
            duty: self.bridge.duty(),
            motor_speed: y.motor_speed,
            energy: self.energy(t, &y),
        }
    }

    /// One control tick: sample the sensors, run the driver, latch the bridge.
    fn tick(&mut self, t: f64) {
        let y = self.state;
        let bus = self
            .cfg
            .drive
            .rates(y.current, y.motor_speed, self.bridge, 0.0)
            .bus_voltage;
        let sensing = matches!(self.bridge, BridgeState::Drive(d) if d != 0.0);
        let h = self.cfg.plant.loads(y.theta).height;
        let mut inputs = self
            .sensors
            .sample(t, y.motor_angle, y.current, bus, sensing, h);
        let mut jam = 0.0;
        if !self.cfg.faults.is_empty() {
            jam = self.plant_faults(t);
            self.cfg
                .faults
                .inputs(t, &mut inputs, &mut self.frozen_encoder);
            if self.control_hangs(t) {
                return;
            }
        }
        let (cmd, release) = match &mut self.driver {
            Driver::Paper(_) => return,
            Driver::Core(c) => {
                let o = c.step(Instant((t * 1e6).round() as u64 as u32), &inputs);
                // As the firmware's tick: the work the outputs do not wait for.
                c.finish_tick();
                (o.bridge, o.brake_release)
            }
            Driver::OpenLoop(o) => (o.command(t, &inputs), true),
            Driver::Custom(f) => (f(t, &inputs), true),
            Driver::Board(f) => {
                let o = f(t, &inputs);
                (o.bridge, o.brake_release)
            }
        };
        self.bridge = BridgeState::from_command(cmd);
        if jam > 0.0 || self.cfg.brake.is_some() || !self.cfg.faults.is_empty() {
            if let Some(b) = self.cfg.brake {
                self.brake_level = b.step(self.brake_level, release, 1.0 / self.cfg.control_rate);
            }
            let brake = self
                .cfg
                .brake
                .map_or(0.0, |b| self.brake_level * b.holding_torque);
            self.kernel.plant.screw.support_torque =
                self.cfg.plant.screw.support_torque + brake + jam;
            // A stuck screw the brake no longer holds breaks away now.
            if self.phase == Phase::Stick {
                let next = self.next_phase(t, &self.state);
                if next != Phase::Stick {
                    self.phase = next;
                    self.events += 1;
                    let (theta_i, _) = self.input(t, &self.state);
                    self.trace.phases.push(PhaseChange {
                        t,
                        phase: next,
                        twist: self.state.theta - theta_i,
                    });
                }
            }
        }
    }

    /// The plant under the injected faults at `t` (battery, load); returns a jam's torque.
    fn plant_faults(&mut self, t: f64) -> f64 {
        let p = self.cfg.faults.plant(t, self.battery);
        self.cfg.drive.battery_voltage = p.battery;
        if p.extra_load != self.extra_load {
            self.extra_load = p.extra_load;
            let mut plant = self.kernel.plant;
            plant.load = self.cfg.plant.load + p.extra_load;
            self.kernel = Kernel::new(plant);
            let th = self.stuck_loads.0;
            self.stuck_loads = (th, self.kernel.loads(th));
        }
        p.jam_torque
    }

    /// A hung control task (`watchdog-stall`): the outputs stay as they are; past the board's
    /// IWDG period the board resets (the bridge floats: coast) and reboots with the
    /// `watchdog reset` fault latched ([`Driver::Core`]; other drivers take the reset with
    /// [`Sim::take_watchdog_reset`]). True while the tick is withheld.
    fn control_hangs(&mut self, t: f64) -> bool {
        if !self.cfg.faults.stalled(t) {
            self.stall_since = None;
            return false;
        }
        let since = *self.stall_since.get_or_insert(t);
        if t - since < crate::twin::inject::WATCHDOG_S {
            return true;
        }
        // Reset: the pins float, the firmware boots again, the hang is over.
        self.bridge = BridgeState::Coast;
        self.stall_since = None;
        if let Driver::Core(c) = &mut self.driver {
            let pos = c.position_counts();
            if let Ok(mut n) = liftfw::control::Controller::new(c.config(), pos) {
                n.report_watchdog_reset(Instant((t * 1e6).round() as u64 as u32));
                **c = n;
            }
        } else {
            self.watchdog_resets += 1;
        }
        // The rest of this stall is the reboot: the next ticks run the new controller.
        self.cfg.faults.end_stall(t);
        false
    }

    /// Watchdog resets an injected stall caused since the last call, for a driver that owns its
    /// controller ([`Driver::Custom`], [`Driver::Board`]): reboot it and call
    /// `report_watchdog_reset`.
    pub fn take_watchdog_reset(&mut self) -> bool {
        let r = self.watchdog_resets > 0;
        self.watchdog_resets = 0;
        r
    }

    /// Add a fault to a run under way (`host-sim serve`'s side channel).
    pub fn inject(&mut self, f: crate::twin::inject::Injection) -> Result<(), String> {
        self.cfg.faults.push(f)
    }

    /// Live stepping (`host-sim serve`): advances `n` base steps from where the previous call
    /// ended, ticking the driver on schedule and observing the sensors after every step as
    /// [`Sim::run`] does (the encoder's edge times: without them the board's speed loop sees
    /// whole counts only and rings, ±0.5 A at 3 rad/s); no trace, no summary, no end. Returns
    /// the simulated time reached. Not to be mixed with [`Sim::run`] on the same `Sim`.
    pub fn step_n(&mut self, n: u64) -> f64 {
        let dt = self.cfg.dt;
        let per_tick = (1.0 / (self.cfg.control_rate * dt)).round().max(1.0) as u64;
        for _ in 0..n {
            let k = self.steps;
            let t = k as f64 * dt;
            if !self.driver.is_paper() && k.is_multiple_of(per_tick) {
                self.tick(t);
            }
            let t_next = (k + 1) as f64 * dt;
            self.advance(t, t_next);
            self.steps += 1;
            self.observe(t_next, dt);
        }
        self.steps as f64 * dt
    }

    /// [`Self::step_n`], and the plant's friction torque T_r averaged over those `n` steps:
    /// the truth a control tick's estimate is scored against (at the tick's instant alone it
    /// aliases a thread that stick-slips in step with the tick: `host-sim estimate`'s lithium
    /// 250 kg lowering from 150 mm read 2.3 % heavy). Returns (t, mean T_r).
    pub fn step_n_mean_friction(&mut self, n: u64) -> (f64, f64) {
        let mut sum = 0.0;
        let mut t = self.steps as f64 * self.cfg.dt;
        for _ in 0..n {
            t = self.step_n(1);
            sum += self.record(t).friction_torque;
        }
        (t, sum / n.max(1) as f64)
    }

    /// Runs to the configured duration and summarises.
    pub fn run(&mut self) -> Summary {
        let start = self.record(0.0);
        if self.trace.phases.is_empty() {
            self.trace.phases.push(PhaseChange {
                t: 0.0,
                phase: self.phase,
                twist: start.twist,
            });
        }
        let t_end = match self.cfg.stepping {
            Stepping::Fixed => self.run_fixed(),
            Stepping::Adaptive { tol, h_max } => self.run_adaptive(tol, h_max),
        };
        self.finish(start, t_end)
    }

    /// The fixed-step loop; returns the end time.
    fn run_fixed(&mut self) -> f64 {
        let dt = self.cfg.dt;
        let n_steps = (self.cfg.duration / dt).round() as u64;
        let per_tick = (1.0 / (self.cfg.control_rate * dt)).round().max(1.0) as u64;
        let per_record = if self.cfg.record_rate > 0.0 {
            Some((1.0 / (self.cfg.record_rate * dt)).round().max(1.0) as u64)
        } else {
            None
        };
        for n in 0..n_steps {
            let t = n as f64 * dt;
            if !self.driver.is_paper() && n % per_tick == 0 {
                self.tick(t);
            }
            let dense = self
                .cfg
                .dense_window
                .is_some_and(|(a, b)| t >= a - 0.5 * dt && t <= b + 0.5 * dt);
            if dense || per_record.is_some_and(|k| n % k == 0) {
                let r = self.record(t);
                self.trace.records.push(r);
            }
            let t_next = (n + 1) as f64 * dt;
            self.advance(t, t_next);
            self.steps += 1;
            self.observe(t_next, dt);
        }
        n_steps as f64 * dt
    }

    /// The adaptive loop (paper mode): steps end exactly on the record times, the summary
    /// windows' edges and the profile's corners; inside the summary window steps are at most a
    /// 64th of it (its twist peak-to-peak is sampled at step ends) and inside the dense window
    /// at most dt (every step is recorded there). Returns the end time.
    fn run_adaptive(&mut self, tol: f64, h_max: f64) -> f64 {
        let dur = self.cfg.duration;
        let dt = self.cfg.dt;
        let mut stops = vec![dur];
        for w in &self.windows {
            stops.extend([w.a, w.b]);
        }
        if let Driver::Paper(p) = &self.driver {
            stops.extend([p.ramp_end, p.brake_start, p.stop]);
        }
        if let Some((a, b)) = self.cfg.dense_window {
            stops.extend([a, b]);
        }
        let rate = self.cfg.record_rate;
        if rate > 0.0 {
            let n = (dur * rate).floor() as u64;
            stops.extend((1..=n).map(|k| k as f64 / rate));
        }
        stops.retain(|&x| x > 0.0 && x <= dur);
        stops.sort_by(f64::total_cmp);
        stops.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
        let dense_window = self.cfg.dense_window;
        let dense = |t: f64| dense_window.is_some_and(|(a, b)| t >= a - 1e-12 && t < b - 1e-12);
        let (wa, wb) = (self.windows[0].a, self.windows[0].b);
        let window_cap = (wb - wa) / 64.0;
        if rate > 0.0 || dense(0.0) {
            let r = self.record(0.0);
            self.trace.records.push(r);
        }
        let mut next_record = 1u64;
        let mut t = 0.0;
        let mut h = dt;
        let mut k1 = None;
        for stop in stops {
            while stop - t > 1e-12 {
                let in_dense = dense(t);
                let mut cap = h_max;
                if in_dense {
                    cap = cap.min(dt);
                }
                if t >= wa - 1e-12 && t < wb - 1e-12 {
                    cap = cap.min(window_cap);
                }
                let left = stop - t;
                // Land on the stop rather than leave a sliver before it.
                let h_try = if h.min(cap) >= 0.99 * left {
                    left
                } else {
                    h.min(cap)
                };
                let (t1, h_next) = self.adaptive_step(t, h_try, tol, &mut k1);
                let t1 = if (stop - t1).abs() <= 1e-12 { stop } else { t1 };
                self.steps += 1;
                self.observe(t1, t1 - t);
                h = h_next;
                t = t1;
                if in_dense && stop - t > 1e-12 {
                    let r = self.record(t);
                    self.trace.records.push(r);
                }
            }
            let on_record = rate > 0.0 && (stop * rate - next_record as f64).abs() < 1e-6;
            if on_record {
                next_record += 1;
            }
            if (on_record || dense(stop - 0.5 * dt)) && stop < dur - 1e-12 {
                let r = self.record(stop);
                self.trace.records.push(r);
            }
        }
        dur
    }

    /// Closes the windows and summarises; `start` is the record at t = 0.
    fn finish(&mut self, start: Record, t_end: f64) -> Summary {
        let dt = self.cfg.dt;
        // The last window may end within rounding of the last step.
        for w in &mut self.windows {
            if w.q_b.is_none() && w.b <= t_end + 0.5 * dt {
                w.q_b = Some(self.state.q_friction_torque);
            }
        }
        let end = self.record(t_end);
        if self.cfg.record_rate > 0.0 {
            self.trace.records.push(end);
        }
        Summary {
            duration: t_end,
            height: (start.height, end.height),
            alpha_deg: (start.alpha_deg, end.alpha_deg),
            window: self.windows[0].stats(),
            cruise: self.windows[1].stats(),
            stick_fraction: self.stick_time / t_end,
            sticks: self.sticks,
            energy: end.energy,
            peak_current: self.peak_current,
            late_screw_speed: if self.late.1 > 0.0 {
                self.late.0 / self.late.1
            } else {
                0.0
            },
            steps: self.steps,
            rejected: self.rejected,
            events: self.events,
            evaluations: self.evaluations.get(),
        }
    }
}

/// Convenience: the paper-mode run of seed 000 with lubricant law, μ_b, start angle (deg) and
/// cruise speed (rad/s, negative lowers), over `duration` s at step `dt`, without a trace; the
/// summary window is the last millisecond (0.999–1 s for a 1 s run, as in the paper's figures).
pub fn paper_run(
    law: FrictionLaw,
    mu_pin: f64,
    start_deg: f64,
    cruise: f64,
    duration: f64,
    dt: f64,
) -> Summary {
    paper_run_with(
        law,
        mu_pin,
        start_deg,
        cruise,
        duration,
        dt,
        Stepping::Fixed,
    )
}

/// [`paper_run`] with the stepping given (`dt` is then the first trial step when adaptive).
pub fn paper_run_with(
    law: FrictionLaw,
    mu_pin: f64,
    start_deg: f64,
    cruise: f64,
    duration: f64,
    dt: f64,
    stepping: Stepping,
) -> Summary {
    let mut cfg = SimConfig::paper(law, mu_pin, start_deg);
    cfg.duration = duration;
    cfg.window = (duration - 1e-3, duration);
    cfg.dt = dt;
    cfg.stepping = stepping;
    cfg.record_rate = 0.0;
    let mut sim = match Sim::new(cfg, Driver::Paper(SpeedProfile::paper(cruise))) {
        Ok(s) => s,
        Err(e) => unreachable!("paper mode has no control period: {e}"),
    };
    sim.run()
}

/// One line per direction, for humans.
impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "height      {:7.1} mm → {:7.1} mm   (α {:.2}° → {:.2}°) in {:.3} s",
            self.height.0 * 1e3,
            self.height.1 * 1e3,
            self.alpha_deg.0,
            self.alpha_deg.1,
            self.duration
        )?;
        for (name, w) in [("window", self.window), ("cruise", self.cruise)] {
            if let Some(w) = w {
                writeln!(
                    f,
                    "{name:<11} {:.3}–{:.3} s: mean T_r {:8.3} N·m, twist θ−θi p-p {:8.3} mrad, stuck {:5.1} % ({} sticks)",
                    w.start,
                    w.end,
                    w.mean_friction_torque,
                    w.twist_peak_to_peak * 1e3,
                    100.0 * w.stick_fraction,
                    w.sticks
                )?;
            }
        }
        let e = &self.energy;
        writeln!(
            f,
            "energy      in {:.3} J = thread {:.3} + supports {:.3} + pins {:.3} + structure {:.3} + ΔPE {:.3} + ΔKE {:.2e} + Δspring {:.3}  (error {:.4} %)",
            e.input,
            e.thread,
            e.support,
            e.pins,
            e.structure,
            e.potential,
            e.kinetic,
            e.spring,
            100.0 * e.balance_error()
        )?;
        if e.source != 0.0 {
            writeln!(
                f,
                "drive       battery {:.3} J = electrical {:.3} + motor/gear {:.3} + stored {:.3} + coupling {:.3}  (error {:.4} %), peak current {:.1} A",
                e.source,
                e.electrical_loss,
                e.drive_loss,
                e.drive_stored,
                e.input,
                100.0 * e.drive_balance_error(),
                self.peak_current
            )?;
        }
        write!(
            f,
            "stick-slip  stuck {:.1} % of the run, {} sticks; screw speed over the 2nd half {:.3} rad/s; {} steps ({} rejected), {} events, {} evaluations",
            100.0 * self.stick_fraction,
            self.sticks,
            self.late_screw_speed,
            self.steps,
            self.rejected,
            self.events,
            self.evaluations
        )
    }
}
