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

/// Current-sense codes averaged at rest for the zero ([`Adc::rest_sample`]): a power of two,
/// so that their sum is their mean in 1/256 codes.
pub const ZERO_SAMPLES: u16 = 256;
/// How far (codes) the zero measured at rest may lie from the configured
/// `sense.current_zero` (0.5 A at the default scaling): an amplifier's offset drift stays
/// inside; a current that flows at rest or a dead sensor does not, and is not taken.
pub const ZERO_RANGE_CODES: i32 = 16;
/// The zero in force is the running mean of the batches taken, the last [`ZERO_BATCHES`] at
/// most (then each new batch moves it by 1/ZERO_BATCHES: ≈ 4 s of rest, far quicker than an
/// amplifier's thermal drift). One batch's mean scatters by 1.5/√256 ≈ 0.09 codes at host-sim's
/// noise (≈ 7 mA, 0.012 N·m at the screw: ≈ 20 kg of a PTFE lowering's load); 16 take that to
/// a quarter.
pub const ZERO_BATCHES: u8 = 16;
/// A batch farther than this from the zero in force (1/256 codes: one code, ten times a
/// batch's scatter at host-sim's noise) is no scatter: the offset moved (a step, not a drift),
/// and the running mean starts over from the batch, which becomes the zero at once.
pub const ZERO_STEP_Q8: i32 = 256;

/// ADC scalings, quantised once, and the current-sense zero measured at rest.
///
/// **Zero at rest.** With the bridge off no current flows through the sense path, so the
/// codes read then are the zero. Their mean over [`ZERO_SAMPLES`] has a fraction of a code
/// that the configured zero (an integer code) cannot hold: an ADC that truncates reads half a
/// code low on average (host-sim's does: 16 mA, ≈ 0.033 N·m at the screw, worth ≈ 90 kg on a
/// PTFE lowering's load), and the current-sense amplifier's offset drifts with temperature.
/// The measured zero replaces the configured one while within [`ZERO_RANGE_CODES`] of it, as
/// the running mean of the batches ([`ZERO_BATCHES`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Adc {
    /// The zero in force, 1/256 codes.
    zero_q8: i32,
    /// The configured zero, 1/256 codes.
    configured_q8: i32,
    /// Σ of the rest codes of the batch under way, and their count.
    rest_sum: u32,
    rest_n: u16,
    /// Batches in the zero in force (0: the configured zero), at most [`ZERO_BATCHES`].
    batches: u8,
    /// A per code in Q16·2^8 (Q24), so that one `SMULL` and a shift give Q16 amperes: ≤ 2^24
    /// for a validated scaling (≤ 1 A per code), an i32 (it was an i64: a 64 × 64-bit product
    /// on every tick).
    amps_q24: i32,
    /// V per code in Q24 (≤ 0.1 V per code validated).
    volts_q24: i32,
}

/// What a batch of rest codes concluded ([`Adc::rest_sample`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ZeroUpdate {
    /// The batch was taken: the zero in force is now this (1/256 codes), the running mean of
    /// the batches.
    Taken(i32),
    /// The batch's mean (1/256 codes) lies beyond [`ZERO_RANGE_CODES`] of the configured
    /// zero: the zero in force stays.
    OutOfRange(i32),
}

impl Adc {
    /// From validated scalings.
    pub fn new(s: &SensingConfig) -> Adc {
        // µ-units per code → Q24 per code: x·2^24/10^6.
        // (Saturated beyond 128 units per code, far outside the validated ranges.)
        let q24 =
            |micro: u32| i32::try_from((i64::from(micro) << 24) / 1_000_000).unwrap_or(i32::MAX);
        let zero = i32::from(s.current_zero_code) << 8;
        Adc {
            zero_q8: zero,
            configured_q8: zero,
            rest_sum: 0,
            rest_n: 0,
            batches: 0,
            amps_q24: q24(s.current_ua_per_code),
            volts_q24: q24(s.supply_uv_per_code),
        }
    }

    /// Motor current for a current-sense code (codes above 4095 are read as 4095).
    #[inline]
    pub fn current(&self, code: u16) -> Amperes {
        let c = i64::from((i32::from(code.min(4095)) << 8) - self.zero_q8);
        Amperes::from_raw(crate::units::sat32((c * i64::from(self.amps_q24)) >> 16))
    }

    /// The current-sense zero in force, 1/256 codes.
    pub fn zero_q8(&self) -> i32 {
        self.zero_q8
    }

    /// A current-sense code read while no current flows (at rest, the bridge off since the
    /// last tick at least): every [`ZERO_SAMPLES`] codes, their mean joins the zero's running
    /// mean ([`ZERO_BATCHES`]) if it is within [`ZERO_RANGE_CODES`] of the configured one.
    #[inline]
    pub fn rest_sample(&mut self, code: u16) -> Option<ZeroUpdate> {
        // ≤ 4095 · 256 < 2^20: the sum cannot overflow.
        self.rest_sum += u32::from(code.min(4095));
        self.rest_n += 1;
        if self.rest_n < ZERO_SAMPLES {
            return None;
        }
        let mean = i32::try_from(self.rest_sum).unwrap_or(i32::MAX);
        self.rest_sum = 0;
        self.rest_n = 0;
        if (mean - self.configured_q8).abs() <= ZERO_RANGE_CODES << 8 {
            // (|mean − zero| ≤ 2^21: no overflow; a native 32-bit division.)
            if (mean - self.zero_q8).abs() > ZERO_STEP_Q8 {
                self.batches = 0;
            }
            self.batches = self.batches.saturating_add(1).min(ZERO_BATCHES);
            self.zero_q8 += (mean - self.zero_q8) / i32::from(self.batches);
            Some(ZeroUpdate::Taken(self.zero_q8))
        } else {
            Some(ZeroUpdate::OutOfRange(mean))
        }
    }

    /// A batch under way is dropped (the bridge drove: the codes are no longer the zero's).
    #[inline]
    pub fn rest_interrupted(&mut self) {
        self.rest_sum = 0;
        self.rest_n = 0;
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

    /// The codes an ADC that truncates reads for a true level `level` (codes, fractional) with
    /// Gaussian noise `sigma` (codes rms): host-sim's sensor model, from a seeded generator.
    fn truncated_codes(level: f64, sigma: f64, seed: u64, n: usize) -> impl Iterator<Item = u16> {
        let mut x = seed | 1;
        let mut uniform = move || {
            // xorshift64*: enough for a noise model in a test.
            x ^= x >> 12;
            x ^= x << 25;
            x ^= x >> 27;
            (x.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n).map(move |_| {
            // Box–Muller.
            let (u, v) = (uniform().max(1e-300), uniform());
            let g = (-2.0 * u.ln()).sqrt() * (2.0 * core::f64::consts::PI * v).cos();
            (level + sigma * g).floor().clamp(0.0, 4095.0) as u16
        })
    }

    #[test]
    fn the_zero_measured_at_rest_takes_the_truncation_half_code_out() {
        let mut adc = Adc::new(&SensingConfig::DEFAULT);
        // The amplifier sits at code 2048.0 exactly; a truncating ADC reads 2047.5 on average.
        let mut last = None;
        for code in truncated_codes(2048.0, 1.5, 7, usize::from(ZERO_SAMPLES) * 4) {
            last = adc.rest_sample(code).or(last);
        }
        let Some(ZeroUpdate::Taken(z)) = last else {
            panic!("{last:?}")
        };
        let zero = f64::from(z) / 256.0;
        assert!((zero - 2047.5).abs() < 0.2, "{zero}");
        // A current at the true zero now reads (within the mean's noise) 0 A: before, the
        // configured integer zero read it half a code (16 mA) low.
        let i = adc.current(2048).to_f64() - adc.current(2047).to_f64();
        assert!((i - 0.032227).abs() < 1e-4, "{i}");
        let mid = (adc.current(2047).to_f64() + adc.current(2048).to_f64()) / 2.0;
        assert!(mid.abs() < 0.2 * 0.032227, "{mid}");
    }

    #[test]
    fn the_zero_is_the_running_mean_of_the_batches_and_follows_a_drift() {
        // One batch's mean scatters by ≈ 1.5/16 codes; 16 batches' running mean by a quarter
        // of that. Over 64 seeds: the zero after one batch, and after 16 (the configured zero
        // is 2048; the truncating ADC reads the true 2048.3 as 2047.8 on average).
        let (mut one, mut sixteen) = (0.0f64, 0.0f64);
        for seed in 0..64u64 {
            let mut adc = Adc::new(&SensingConfig::DEFAULT);
            let codes: std::vec::Vec<u16> =
                truncated_codes(2048.3, 1.5, 1000 + seed, usize::from(ZERO_SAMPLES) * 16).collect();
            for (i, &code) in codes.iter().enumerate() {
                let Some(ZeroUpdate::Taken(z)) = adc.rest_sample(code) else {
                    continue;
                };
                assert_eq!(z, adc.zero_q8());
                let err = (f64::from(z) / 256.0 - 2047.8).powi(2);
                if i + 1 == usize::from(ZERO_SAMPLES) {
                    one += err;
                }
                if i + 1 == codes.len() {
                    sixteen += err;
                }
            }
        }
        let (one, sixteen) = ((one / 64.0).sqrt(), (sixteen / 64.0).sqrt());
        assert!(one > 0.06 && one < 0.13, "one batch: {one} codes rms");
        assert!(
            sixteen < 0.4 * one,
            "16 batches: {sixteen} codes rms against {one}"
        );
        // 16 batches at `before` (codes), then the zeros 64 batches at `after` take.
        let zeros_after = |before: f64, after: f64, seed: u64| {
            let mut adc = Adc::new(&SensingConfig::DEFAULT);
            for code in truncated_codes(before, 1.5, seed, usize::from(ZERO_SAMPLES) * 16) {
                adc.rest_sample(code);
            }
            let mut zeros = std::vec::Vec::new();
            for code in truncated_codes(after, 1.5, seed + 1, usize::from(ZERO_SAMPLES) * 64) {
                if let Some(ZeroUpdate::Taken(z)) = adc.rest_sample(code) {
                    zeros.push(f64::from(z) / 256.0);
                }
            }
            let last = zeros.last().copied().unwrap_or(0.0);
            (zeros.first().copied().unwrap_or(0.0), last)
        };
        // The amplifier's offset steps by 2 codes (a reference that moved): no scatter, the
        // first batch after it is the zero.
        let (first, last) = zeros_after(2048.5, 2050.5, 11);
        assert!((first - 2050.0).abs() < 0.3, "{first}");
        assert!((last - 2050.0).abs() < 0.1, "{last}");
        // A drift by half a code (within a code of the zero in force): followed 1/16 a batch.
        let (first, last) = zeros_after(2048.5, 2049.0, 13);
        assert!((first - 2048.03).abs() < 0.05, "{first}");
        assert!((last - 2048.5).abs() < 0.1, "{last}");
    }

    #[test]
    fn a_rest_reading_far_from_the_configured_zero_is_not_taken() {
        let mut adc = Adc::new(&SensingConfig::DEFAULT);
        let before = adc.zero_q8();
        // A dead sensor (stuck at 0), then a current flowing at rest (≈ 1 A = 31 codes).
        for level in [0.0, 2048.0 + 31.0] {
            let mut last = None;
            for code in truncated_codes(level, 1.0, 3, usize::from(ZERO_SAMPLES)) {
                last = adc.rest_sample(code).or(last);
            }
            assert!(
                matches!(last, Some(ZeroUpdate::OutOfRange(_))),
                "{level}: {last:?}"
            );
            assert_eq!(adc.zero_q8(), before);
            assert_eq!(adc.current(2048), Amperes::ZERO);
        }
        // An interrupted batch starts over: 255 codes, a drive, 255 more conclude nothing.
        for code in truncated_codes(2050.0, 1.0, 5, usize::from(ZERO_SAMPLES) - 1) {
            assert_eq!(adc.rest_sample(code), None);
        }
        adc.rest_interrupted();
        for code in truncated_codes(2050.0, 1.0, 6, usize::from(ZERO_SAMPLES) - 1) {
            assert_eq!(adc.rest_sample(code), None);
        }
    }

    proptest::proptest! {
        /// Over the validated scalings and every zero the rest may measure: the current is the
        /// float model (code − zero)·A/code, within the Q16 result's rounding.
        #[test]
        fn current_with_a_measured_zero_is_the_float_model(
            ua in 1u32..=1_000_000,
            zero in 0u16..=4095,
            frac in -(ZERO_RANGE_CODES << 8)..=(ZERO_RANGE_CODES << 8),
            code in 0u16..=4095,
        ) {
            let s = SensingConfig {
                current_zero_code: zero,
                current_ua_per_code: ua,
                supply_uv_per_code: 4_468,
            };
            let mut adc = Adc::new(&s);
            let z = (i32::from(zero) << 8) + frac;
            // Feed a batch whose sum is exactly z (a constant code and one adjustment).
            let base = (z / 256).clamp(0, 4095);
            let mut rest = z - base * 256;
            let mut last = None;
            for _ in 0..ZERO_SAMPLES {
                let step = rest.clamp(-base, 4095 - base);
                let c = u16::try_from(base + step).unwrap_or(0);
                rest -= step;
                last = adc.rest_sample(c).or(last);
            }
            let taken = rest == 0 && matches!(last, Some(ZeroUpdate::Taken(m)) if m == z);
            proptest::prop_assume!(taken);
            let want = (f64::from(code) - f64::from(z) / 256.0) * f64::from(ua) * 1e-6;
            let got = adc.current(code).to_f64();
            // The scale is quantised to Q24 per code (≤ 2^-24 A per code · 4096 codes) and
            // the result to Q16.
            let tol = 4096.0 / 16_777_216.0 + 1.0 / 65_536.0;
            proptest::prop_assert!((got - want).abs() <= tol, "{got} vs {want}");
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
