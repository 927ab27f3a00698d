//! From the board's raw samples to typed quantities: ADC codes → amperes and volts, the 16-bit
//! encoder counter → an unbounded position, and debounced switches.

use super::config::SensingConfig;
use crate::units::{Amperes, Volts, Q};

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

/// ADC scalings, quantised once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Adc {
    zero: i32,
    /// A per code in Q16·2^8 (Q24), so that one `SMULL` and a shift give Q16 amperes: ≤ 2^24
    /// for a validated scaling (≤ 1 A per code), an i32 (it was an i64: a 64 × 64-bit product
    /// on every tick).
    amps_q24: i32,
    /// V per code in Q24 (≤ 0.1 V per code validated).
    volts_q24: i32,
}

impl Adc {
    /// From validated scalings.
    pub fn new(s: &SensingConfig) -> Adc {
        // µ-units per code → Q24 per code: x·2^24/10^6.
        // (Saturated beyond 128 units per code, far outside the validated ranges.)
        let q24 =
            |micro: u32| i32::try_from((i64::from(micro) << 24) / 1_000_000).unwrap_or(i32::MAX);
        Adc {
            zero: i32::from(s.current_zero_code),
            amps_q24: q24(s.current_ua_per_code),
            volts_q24: q24(s.supply_uv_per_code),
        }
    }

    /// Motor current for a current-sense code (codes above 4095 are read as 4095).
    #[inline]
    pub fn current(&self, code: u16) -> Amperes {
        let c = i64::from(i32::from(code.min(4095)) - self.zero);
        Amperes::from_raw(crate::units::sat32((c * i64::from(self.amps_q24)) >> 8))
    }

    /// Supply voltage for a divider code.
    #[inline]
    pub fn supply(&self, code: u16) -> Volts {
        let c = i64::from(code.min(4095));
        Volts::from_raw(crate::units::sat32((c * i64::from(self.volts_q24)) >> 8))
    }
}

/// The free-running 16-bit encoder counter extended to a 32-bit position.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EncoderTracker {
    last: Option<u16>,
    position: i32,
}

impl EncoderTracker {
    /// A tracker whose first sample is taken to be at `position`.
    pub fn new(position: i32) -> Self {
        Self {
            last: None,
            position,
        }
    }

    /// Feed one counter sample; returns the counts moved since the previous one. The signed
    /// 16-bit difference is exact while the motor turns less than 32 767 counts per tick.
    #[inline]
    pub fn update(&mut self, counter: u16) -> i32 {
        let delta = match self.last {
            None => 0,
            Some(prev) => i32::from(counter.wrapping_sub(prev) as i16),
        };
        self.last = Some(counter);
        self.position = self.position.saturating_add(delta);
        delta
    }

    /// Position in counts.
    #[inline]
    pub fn position(&self) -> i32 {
        self.position
    }

    /// Declare the current position to be `position` counts (homing); the next sample's
    /// delta is measured from the last counter value as before.
    pub fn rebase(&mut self, position: i32) {
        self.position = position;
    }
}

/// Switch debouncing: a level counts once it has been stable for `ticks` consecutive ticks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Debouncer {
    stable: Switches,
    candidate: Switches,
    count: u16,
    ticks: u16,
}

impl Debouncer {
    /// A debouncer that needs `ticks` (≥ 1) equal samples; starts with every input released.
    pub fn new(ticks: u16) -> Self {
        Self {
            ticks: ticks.max(1),
            ..Self::default()
        }
    }

    /// Feed one raw sample; returns the debounced levels.
    #[inline]
    pub fn update(&mut self, raw: Switches) -> Switches {
        if raw == self.candidate {
            self.count = self.count.saturating_add(1);
        } else {
            self.candidate = raw;
            self.count = 1;
        }
        if self.count >= self.ticks {
            self.stable = self.candidate;
        }
        self.stable
    }

    /// The debounced levels.
    pub fn levels(&self) -> Switches {
        self.stable
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_board_scalings_match_the_hardware() {
        let adc = Adc::new(&SensingConfig::DEFAULT);
        assert_eq!(adc.current(2048), Amperes::ZERO);
        // 1000 codes above zero: 32.227 A.
        assert!((adc.current(3048).to_f64() - 32.227).abs() < 1e-3);
        assert!((adc.current(1048).to_f64() + 32.227).abs() < 1e-3);
        // 12.6 V on the bus: 12.6 / 4.468e-3 = 2820 codes.
        assert!((adc.supply(2820).to_f64() - 12.6).abs() < 5e-3);
        // Out-of-range codes clamp instead of wrapping.
        assert_eq!(adc.current(u16::MAX), adc.current(4095));
    }

    #[test]
    fn validated_extreme_scalings_convert_as_with_a_64_bit_scale() {
        // The i32 scale holds the largest validated scalings (1 A and 0.1 V per code): every
        // code converts exactly as with the i64 scale it replaced.
        for (ua, uv, zero) in [(1_000_000, 100_000, 0), (1, 1, 4095), (32_227, 4_468, 2048)] {
            let s = SensingConfig {
                current_zero_code: zero,
                current_ua_per_code: ua,
                supply_uv_per_code: uv,
            };
            let adc = Adc::new(&s);
            let q24 = |micro: u32| (i64::from(micro) << 24) / 1_000_000;
            for code in (0..=4095u16).chain([4096, u16::MAX]) {
                let c = i64::from(code.min(4095));
                let amps = crate::units::sat32(((c - i64::from(zero)) * q24(ua)) >> 8);
                let volts = crate::units::sat32((c * q24(uv)) >> 8);
                assert_eq!(adc.current(code).bits(), amps, "{ua} uA, code {code}");
                assert_eq!(adc.supply(code).bits(), volts, "{uv} uV, code {code}");
            }
        }
    }

    #[test]
    fn encoder_tracker_unwraps_the_16_bit_counter() {
        let mut e = EncoderTracker::new(100);
        assert_eq!(e.update(65_530), 0);
        assert_eq!(e.update(4), 10);
        assert_eq!(e.position(), 110);
        assert_eq!(e.update(65_534), -6);
        assert_eq!(e.position(), 104);
    }

    #[test]
    fn a_bounce_shorter_than_the_window_is_ignored() {
        let mut d = Debouncer::new(3);
        let on = Switches(Switches::LIMIT_UPPER);
        assert_eq!(d.update(on), Switches(0));
        assert_eq!(d.update(Switches(0)), Switches(0));
        assert_eq!(d.update(on), Switches(0));
        assert_eq!(d.update(on), Switches(0));
        assert_eq!(d.update(on), on);
    }
}
