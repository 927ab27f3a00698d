//! The emulated board in closed loop with host-sim's plant.
//!
//! host-sim's [`Sim`] integrates the lift at its fixed step and, every coupling period
//! ([`PERIOD_S`] = 40 µs, ten 4 µs steps), samples its sensor model and asks the board for its
//! outputs (`Driver::Board`). Here that answer is what the emulated pins drive at that instant;
//! the emulator then runs the firmware over the next period with the sensor values just sampled:
//! - bridge: R_EN/L_EN (PB12/PB13) both high → the signed duty RPWM − LPWM of TIM1 CH1/CH2 on
//!   PA8/PA9 (both 0 %: `Brake`, the low sides on); either low → `Coast`;
//! - brake output PB9 → the plant's holding brake;
//! - encoder: the plant's count (4 per line) steps TIM4 in encoder mode; each count's edge time
//!   (from the plant's capture model, ±1 µs) is captured by TIM3 through TIM4's TRGO;
//! - ADCs: the plant's supply code on PA4; its current code on the conducting half's IS pin
//!   (R_IS, PA0, unless LPWM drives: L_IS, PA1) and 0 V on the other, so the firmware's max()
//!   hands the core the plant's code (host-sim models one bidirectional current-sense code,
//!   2048 at 0 A: host-sim/src/plant/sensors.rs);
//! - switches: the plant's limit switches (normally closed to GND: active = open, the pull-up
//!   reads high), the STOP button closed, UP/DOWN from the scenario.
//!
//! So the firmware sees its inputs up to 40 µs late and the plant sees a new duty up to 40 µs
//! late (the PWM itself changes only at the next 50 µs period).

use crate::bus::{Analog, BoardOut};
use crate::machine::Machine;
use crate::TICK_HZ;
use host_sim::sim::{Driver, Sim, SimConfig};
use liftfw::control::{Bridge, Inputs, Outputs, Switches};
use std::sync::{Arc, Mutex};

/// The coupling period, s.
pub const PERIOD_S: f64 = 40e-6;
/// The plant's step, s (host-sim lift's).
pub const DT_S: f64 = 4e-6;

/// Buttons the scenario holds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Buttons {
    /// UP pressed.
    pub up: bool,
    /// DOWN pressed.
    pub down: bool,
    /// STOP pressed (the NC contact open).
    pub stop: bool,
}

/// What the plant handed over at the last coupling instant.
#[derive(Clone, Copy, Debug, Default)]
struct Exchange {
    inputs: Option<(f64, Inputs)>,
    outputs: Option<Outputs>,
}

/// The firmware on the emulated board, driving the plant.
pub struct Rig {
    /// The board.
    pub machine: Machine,
    /// The plant.
    pub sim: Sim,
    shared: Arc<Mutex<Exchange>>,
    /// The scenario's buttons.
    pub buttons: Buttons,
    /// A forced current-sense code on both IS pins (fault injection), from a global time.
    pub force_current: Option<u16>,
    /// Plant time, s.
    pub t: f64,
    steps: u64,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// The bridge command the pins amount to.
pub fn bridge_of(o: &BoardOut) -> Bridge {
    if !(o.enabled.0 && o.enabled.1) {
        return Bridge::Coast;
    }
    let d = o.duty.0 - o.duty.1;
    if o.duty.0 == o.duty.1 {
        // Both low sides (or both high sides) conduct: the armature is shorted.
        return Bridge::Brake;
    }
    Bridge::Drive(
        (d * f64::from(i16::MAX))
            .round()
            .clamp(-f64::from(i16::MAX), f64::from(i16::MAX)) as i16,
    )
}

impl Rig {
    /// The board with `machine`'s firmware against a plant configured by `cfg` (its `dt` and
    /// `control_rate` are set here).
    pub fn new(machine: Machine, mut cfg: SimConfig) -> Result<Self, String> {
        cfg.dt = DT_S;
        cfg.control_rate = 1.0 / PERIOD_S;
        let shared = Arc::new(Mutex::new(Exchange::default()));
        let inner = Arc::clone(&shared);
        let driver = Driver::Board(Box::new(move |t: f64, inputs: &Inputs| {
            let mut x = lock(&inner);
            x.inputs = Some((t, *inputs));
            x.outputs.unwrap_or(Outputs {
                bridge: Bridge::Coast,
                feed_watchdog: true,
                brake_release: false,
                event: None,
            })
        }));
        let sim = Sim::new(cfg, driver).map_err(|e| e.to_string())?;
        Ok(Self {
            machine,
            sim,
            shared,
            buttons: Buttons::default(),
            force_current: None,
            t: 0.0,
            steps: (PERIOD_S / DT_S).round() as u64,
        })
    }

    /// One coupling period: the plant over it with the board's outputs, then the firmware
    /// over it with the inputs sampled at its start.
    pub fn step(&mut self) -> Result<(), String> {
        self.t = self.sim.step_n(self.steps);
        let Some((t0, inputs)) = lock(&self.shared).inputs.take() else {
            return Err("the plant did not sample its sensors".into());
        };
        let out = self.machine.board_out();
        let lowering = out.duty.1 > 0.0 && out.duty.0 == 0.0;
        let code = self.force_current.unwrap_or(inputs.current_raw);
        let analog = Analog {
            r_is: if lowering { 0 } else { code },
            l_is: if lowering { code } else { 0 },
            supply: inputs.supply_raw,
        };
        if self.force_current.is_some() {
            self.machine.set_analog(Analog {
                r_is: code,
                l_is: code,
                supply: inputs.supply_raw,
            });
        } else {
            self.machine.set_analog(analog);
        }
        let sw = inputs.switches.0;
        let closed = |active: bool| !active;
        let mut low = 0u16;
        // Normally closed: the limit switches and STOP pull their pins low unless active.
        if closed(sw & Switches::LIMIT_UPPER != 0) {
            low |= 1 << 10;
        }
        if closed(sw & Switches::LIMIT_LOWER != 0) {
            low |= 1 << 11;
        }
        if !self.buttons.stop {
            low |= 1 << 5;
        }
        // Normally open: UP and DOWN pull low while pressed.
        if self.buttons.up {
            low |= 1 << 14;
        }
        if self.buttons.down {
            low |= 1 << 15;
        }
        self.machine.set_gpiob_inputs(low, 0);
        let edge =
            ((t0 - f64::from(inputs.encoder_edge_age) * 1e-6) * TICK_HZ as f64).max(0.0) as u64;
        self.machine.encoder(inputs.encoder_count, edge);
        self.machine
            .run_until((self.t * TICK_HZ as f64).round() as u64)?;
        let o = self.machine.board_out();
        lock(&self.shared).outputs = Some(Outputs {
            bridge: bridge_of(&o),
            feed_watchdog: true,
            brake_release: o.brake_release,
            event: None,
        });
        Ok(())
    }

    /// Runs `secs` of plant and firmware.
    pub fn run_for(&mut self, secs: f64) -> Result<(), String> {
        let end = self.t + secs;
        while self.t < end - 1e-12 {
            self.step()?;
        }
        Ok(())
    }

    /// Runs until the console printed `needle` (true) or `timeout_s` passed (false); the text
    /// seen is appended to `seen`.
    pub fn run_until_console(
        &mut self,
        needle: &str,
        timeout_s: f64,
        seen: &mut String,
    ) -> Result<bool, String> {
        let end = self.t + timeout_s;
        while self.t < end {
            self.run_for(1e-3)?;
            seen.push_str(&self.machine.take_console());
            if seen.contains(needle) {
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// Sends a console line and returns the reply line(s) up to the next CRLF-terminated
    /// line that does not start with `warning:` (notices), within `timeout_s`.
    pub fn command(&mut self, line: &str, timeout_s: f64) -> Result<String, String> {
        let _ = self.machine.take_console();
        self.machine.console_send(format!("{line}\r\n").as_bytes());
        let mut seen = String::new();
        let end = self.t + timeout_s;
        while self.t < end {
            self.run_for(1e-3)?;
            seen.push_str(&self.machine.take_console());
            if let Some(reply) = seen
                .split("\r\n")
                .collect::<Vec<_>>()
                .split_last()
                .and_then(|(_, done)| {
                    done.iter()
                        .find(|l| !l.is_empty() && !l.starts_with("warning:"))
                })
            {
                return Ok(reply.to_string());
            }
        }
        Err(format!(
            "no reply to `{line}` within {timeout_s} s (console: {seen:?})"
        ))
    }
}
