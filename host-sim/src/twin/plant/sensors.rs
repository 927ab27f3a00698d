//! What the board sees: a quadrature encoder on the motor shaft, two 12-bit ADC channels
//! (motor current, supply voltage) and two limit switches.
//!
//! ADC scalings (docs/plant.md; the core mirrors them):
//! - **Current**: the BTS7960's two IS pins (I_IS = I_load/k_ILIS, k_ILIS ≈ 8500) each drive
//!   1 kΩ to ground (0.1176 V/A), and a difference amplifier of gain 0.2125 with a 1.65 V
//!   reference gives `V = 1.65 V + 25 mV/A · i`. 12 bits over 3.3 V: code 2048 at 0 A,
//!   **32.23 mA per code**, ±66 A full scale. The IS pins only mirror a *conducting high side*:
//!   sampled mid-PWM-period while driving they read the motor current; while braking (low
//!   sides on) or coasting (diodes) they read 0 A, like the real part.
//! - **Supply**: 10 kΩ / 2.2 kΩ divider, `V = V_bus · 2.2/12.2`: **4.467 mV of bus per code**,
//!   18.3 V full scale.
//!
//! Noise is Gaussian (in volts at the ADC pin) before quantisation; codes saturate at 0 and 4095.
//!
//! **Encoder edge times** (docs/board.md): the board's TIM3 runs free at 1 MHz and captures its
//! counter on every count of the encoder timer (TIM4's encoder clock on TRGO); at the sample the
//! board reads TIM3's counter too, and passes the difference, 16-bit wrapping, as
//! `encoder_edge_age`. Here [`Sensors::observe_encoder`] watches the motor angle after every
//! integration step, locates the last edge crossed in the step by linear interpolation and
//! latches ⌊t_edge · 1 MHz⌋ mod 2^16, the capture register's value.

use liftfw::control::{Inputs, Switches};
use rand::{RngExt, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// ADC reference voltage, V.
pub const ADC_REF: f64 = 3.3;
/// ADC full-scale code + 1.
pub const ADC_CODES: f64 = 4096.0;
/// Current-sense gain at the ADC pin, V/A.
pub const CURRENT_GAIN: f64 = 0.025;
/// Current-sense offset at the ADC pin, V.
pub const CURRENT_OFFSET: f64 = 1.65;
/// Supply divider ratio V_pin/V_bus.
pub const SUPPLY_DIVIDER: f64 = 2.2 / 12.2;

/// Sensor configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorParams {
    /// Encoder counts per motor revolution (quadrature: 4 × lines).
    pub counts_per_rev: f64,
    /// Current-sense noise at the ADC pin, V rms.
    pub current_noise: f64,
    /// Supply-divider noise at the ADC pin, V rms.
    pub supply_noise: f64,
    /// Lower limit switch closes at or below this head height, m.
    pub lower_limit: f64,
    /// Upper limit switch closes at or above this head height, m.
    pub upper_limit: f64,
}

impl SensorParams {
    /// 12-line Hall encoder (48 counts/rev), ≈ 1.5 LSB rms current noise and ≈ 0.7 LSB supply
    /// noise, limit switches at `lower` and `upper` heights (m).
    pub fn with_limits(lower: f64, upper: f64) -> Self {
        Self {
            counts_per_rev: 48.0,
            current_noise: 1.2e-3,
            supply_noise: 0.55e-3,
            lower_limit: lower,
            upper_limit: upper,
        }
    }
}

/// Motor current for an ADC code, A (what the core must compute).
pub fn current_of_code(code: u16) -> f64 {
    (f64::from(code) * ADC_REF / ADC_CODES - CURRENT_OFFSET) / CURRENT_GAIN
}

/// Bus voltage for an ADC code, V.
pub fn supply_of_code(code: u16) -> f64 {
    f64::from(code) * ADC_REF / ADC_CODES / SUPPLY_DIVIDER
}

fn quantise(volts: f64) -> u16 {
    (volts / ADC_REF * ADC_CODES)
        .floor()
        .clamp(0.0, ADC_CODES - 1.0) as u16
}

/// The edge-capture timer's rate, Hz (TIM3 at 1 MHz).
pub const CAPTURE_HZ: f64 = 1e6;

/// The sensors, with their seeded noise source.
#[derive(Clone, Debug)]
pub struct Sensors {
    /// Configuration.
    pub params: SensorParams,
    rng: Xoshiro256PlusPlus,
    /// Last observed time (s), continuous count and count.
    seen: Option<(f64, f64, i64)>,
    /// The capture register: the 1 MHz timer at the latest count change.
    capture: u16,
}

impl Sensors {
    /// Sensors with noise seeded by `seed`.
    pub fn new(params: SensorParams, seed: u64) -> Self {
        Self {
            params,
            rng: Xoshiro256PlusPlus::seed_from_u64(seed),
            seen: None,
            capture: 0,
        }
    }

    /// The free-running 1 MHz capture timer's counter at time `t`, s.
    fn capture_timer(t: f64) -> u16 {
        ((t * CAPTURE_HZ + 1e-6).floor() as i64).rem_euclid(1 << 16) as u16
    }

    /// Watch the motor angle `theta_m` (rad) at time `t` (s), after every integration step:
    /// a count change latches the capture timer at the last edge crossed since the previous
    /// call (its time by linear interpolation over the step).
    pub fn observe_encoder(&mut self, t: f64, theta_m: f64) {
        let cont = theta_m / std::f64::consts::TAU * self.params.counts_per_rev;
        let count = cont.floor() as i64;
        if let Some((t0, c0, n0)) = self.seen {
            if count != n0 {
                // Counting up the count becomes n at the edge n; down, at the edge n + 1.
                let edge = if count > n0 { count } else { count + 1 } as f64;
                let s = if cont != c0 {
                    ((edge - c0) / (cont - c0)).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                self.capture = Self::capture_timer(t0 + s * (t - t0));
            }
        }
        self.seen = Some((t, cont, count));
    }

    /// One standard normal sample (Box–Muller).
    fn gauss(&mut self) -> f64 {
        let u1: f64 = 1.0 - self.rng.random::<f64>();
        let u2: f64 = self.rng.random::<f64>();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// The 16-bit wrapping counter for motor angle `theta_m` (rad): the count of edges passed.
    pub fn encoder_count(&self, theta_m: f64) -> u16 {
        let counts = (theta_m / std::f64::consts::TAU * self.params.counts_per_rev).floor();
        (counts as i64).rem_euclid(1 << 16) as u16
    }

    /// Sample everything the board reads at the start of a control tick at time `t`, s.
    pub fn sample(
        &mut self,
        t: f64,
        theta_m: f64,
        current: f64,
        bus: f64,
        sensing: bool,
        height: f64,
    ) -> Inputs {
        let i_seen = if sensing { current } else { 0.0 };
        let vi = CURRENT_OFFSET + CURRENT_GAIN * i_seen + self.params.current_noise * self.gauss();
        let vs = SUPPLY_DIVIDER * bus + self.params.supply_noise * self.gauss();
        let mut sw = 0u8;
        if height <= self.params.lower_limit {
            sw |= Switches::LIMIT_LOWER;
        }
        if height >= self.params.upper_limit {
            sw |= Switches::LIMIT_UPPER;
        }
        Inputs {
            encoder_count: self.encoder_count(theta_m),
            encoder_edge_age: Self::capture_timer(t).wrapping_sub(self.capture),
            current_raw: quantise(vi),
            supply_raw: quantise(vs),
            switches: Switches(sw),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encoder_wraps_at_sixteen_bits() {
        let s = Sensors::new(SensorParams::with_limits(0.0, 1.0), 1);
        let rev = std::f64::consts::TAU;
        assert_eq!(s.encoder_count(0.0), 0);
        assert_eq!(s.encoder_count(-1e-9), u16::MAX);
        let turns = 65536.0 / 48.0;
        assert_eq!(s.encoder_count(turns * rev + 0.5 * rev / 48.0), 0);
    }

    #[test]
    fn edge_age_is_the_capture_timer_since_the_last_count_change() {
        let mut s = Sensors::new(SensorParams::with_limits(0.0, 1.0), 1);
        let per_count = std::f64::consts::TAU / 48.0;
        // 0.25 counts per 4 µs step from count 2.5: the edge at 3 is crossed at 8 µs.
        for k in 0..=5 {
            let t = 0.1 + f64::from(k) * 4e-6;
            s.observe_encoder(t, (2.5 + 0.25 * f64::from(k)) * per_count);
        }
        let inp = s.sample(0.1 + 20e-6, 3.75 * per_count, 0.0, 12.0, true, 0.5);
        assert_eq!(inp.encoder_count, 3);
        assert_eq!(inp.encoder_edge_age, 12);
        // Counting down, the count 2 begins at the edge 3.
        s.observe_encoder(0.1 + 24e-6, 3.25 * per_count);
        s.observe_encoder(0.1 + 28e-6, 2.75 * per_count);
        let inp = s.sample(0.1 + 1028e-6, 2.75 * per_count, 0.0, 12.0, true, 0.5);
        assert_eq!(inp.encoder_count, 2);
        assert_eq!(inp.encoder_edge_age, 1002);
    }

    #[test]
    fn adc_scaling_round_trips_within_one_code() {
        let mut s = Sensors::new(
            SensorParams {
                current_noise: 0.0,
                supply_noise: 0.0,
                ..SensorParams::with_limits(0.0, 1.0)
            },
            1,
        );
        for (i, v) in [(0.0, 12.0), (37.0, 11.5), (-20.0, 13.8)] {
            let inp = s.sample(0.0, 0.0, i, v, true, 0.5);
            assert!(
                (current_of_code(inp.current_raw) - i).abs() <= 0.0323,
                "{i}"
            );
            assert!((supply_of_code(inp.supply_raw) - v).abs() <= 0.0045, "{v}");
        }
        assert_eq!(s.sample(0.0, 0.0, 30.0, 12.0, false, 0.5).current_raw, 2048);
    }
}
