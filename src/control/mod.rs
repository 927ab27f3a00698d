//! The control tick: `Controller::step(now, inputs) -> outputs`.
//!
//! This is the only function the firmware's control task and host-sim call every tick.
//! Inputs are what the board's peripherals deliver (raw counts and codes), outputs are what
//! its peripherals accept. Conversion to physical units happens here, in the core, so that
//! host-sim exercises exactly the arithmetic the board runs.

pub mod config;

use crate::units::Instant;

/// Raw inputs sampled by the board at the start of a control tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Inputs {
    /// Free-running 16-bit quadrature counter of the motor encoder (timer CNT register).
    pub encoder_count: u16,
    /// Motor current ADC code (12-bit, right aligned), sampled mid-PWM-period.
    pub current_raw: u16,
    /// Supply voltage ADC code (12-bit, right aligned) from the battery divider.
    pub supply_raw: u16,
    /// Digital inputs (limit switches, buttons), already debounced or not: see [`Switches`].
    pub switches: Switches,
}

/// Digital input levels as a bit set (1 = active), independent of the pins' polarity.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Switches(pub u8);

impl Switches {
    /// Upper limit switch.
    pub const LIMIT_UPPER: u8 = 1 << 0;
    /// Lower limit switch.
    pub const LIMIT_LOWER: u8 = 1 << 1;
    /// UP push button.
    pub const BUTTON_UP: u8 = 1 << 2;
    /// DOWN push button.
    pub const BUTTON_DOWN: u8 = 1 << 3;
    /// STOP push button (normally-closed wiring is resolved by the board).
    pub const BUTTON_STOP: u8 = 1 << 4;

    /// Whether every bit of `mask` is active.
    #[inline]
    pub fn is_active(self, mask: u8) -> bool {
        self.0 & mask == mask
    }
}

/// What the H-bridge should do for the next tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Bridge {
    /// Both half-bridges off: the motor free-wheels (the screw is self-locking when stopped).
    #[default]
    Coast,
    /// Both low sides on: the motor is short-circuited and brakes dynamically.
    Brake,
    /// Drive with a signed duty cycle in Q15 (`i16::MAX` ≈ +100 %, lifting; negative: lowering).
    Drive(i16),
}

/// Outputs applied by the board at the end of a control tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Outputs {
    /// H-bridge command.
    pub bridge: Bridge,
    /// True when this tick completed normally: only then may the board feed the watchdog.
    pub feed_watchdog: bool,
}

/// The control core's state between ticks.
#[derive(Clone, Debug, Default)]
pub struct Controller {
    last_tick: Option<Instant>,
    last_encoder: u16,
    /// Motor encoder position in counts, extended from the 16-bit counter (saturating).
    position_counts: i32,
}

impl Controller {
    /// A controller at rest; the first tick only latches the encoder counter.
    pub fn new() -> Self {
        Self::default()
    }

    /// One control tick. Never panics, whatever the inputs.
    pub fn step(&mut self, now: Instant, inputs: &Inputs) -> Outputs {
        match self.last_tick {
            None => self.last_encoder = inputs.encoder_count,
            Some(_) => {
                // The counter wraps; the signed 16-bit difference is exact as long as the
                // motor turns less than 32 767 counts per tick.
                let delta = inputs.encoder_count.wrapping_sub(self.last_encoder) as i16;
                self.last_encoder = inputs.encoder_count;
                self.position_counts = self.position_counts.saturating_add(i32::from(delta));
            }
        }
        self.last_tick = Some(now);
        Outputs {
            bridge: Bridge::Coast,
            feed_watchdog: true,
        }
    }

    /// Motor encoder position in counts since boot.
    pub fn position_counts(&self) -> i32 {
        self.position_counts
    }
}
