//! Breakaways the current limit clipped (docs/model.md "Stick-slip", a stick-slipping lift).
//!
//! A stick-slipping lift's load is read from its breakaways, the measured torque's peaks before
//! each slip (`detect::stickslip`, `ident::stick::lift`). Where a breakaway needs more than the
//! drive's current limit (dry 1300 kg from 150 mm: the plant's coupling reaches 83–85 N·m, the
//! 40 A limit gives 82.3) the current stands flat at the limit while the rotor still turns and
//! winds the coupling on: the peak the current shows is clipped and the load read light
//! (48 kg, 3.7 %). The screw stands during a stick, so the coupling's further wind-up is its
//! stiffness times the encoder's travel at the gear output: the breakaway is the torque the
//! current measured when it reached the limit plus k_c times the counts turned since, up to
//! where the slip began (the current shows it two ticks late, [`ClipTracker::step`]).
//! [`ClipTracker`] follows that and keeps the excess over the detector's peak, per slip, as a
//! sum beside the detector's.
//!
//! "At the limit" is the measured current above 15/16 of it (the speed loop holds it at
//! the limit within ≈ ±2 A, `control::speed`): from there the reading is the torque of a
//! current that still follows the coupling, and the wind-up from there is counted.

use crate::units::{NewtonMetres, Q};

/// A plateau ended this many ticks before the slip that ends it is detected at most (the
/// detector's 4-tick mean falls below its peak by the threshold within 2–3 ticks of the
/// current's fall): later slips are not this stick's.
pub const SLIP_WITHIN: u8 = 8;

/// The breakaway at the end of a plateau at the current limit: `onset` (Q16 N·m, resisting
/// the motion) measured when the current reached the limit, plus the coupling's wind-up over
/// `travel` counts of the encoder (in the direction of travel) at `per_count` (Q16 N·m per
/// count, k_c·rad per count at the gear output). Exact for any operands (sensor data): the
/// product of two `i32`s is within ±2^62 and the sum within `i64`.
#[inline]
pub fn clipped_peak(onset: i32, travel: i32, per_count: i32) -> i64 {
    i64::from(onset) + i64::from(travel) * i64::from(per_count)
}

/// The plateau under way or just ended, and the excess it added.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClipTracker {
    /// 0: no plateau; 1: at the limit now; 2 + k: ended k ticks ago, waiting for its slip.
    state: u8,
    /// Torque (resisting the motion, Q16) when the current reached the limit.
    onset: i32,
    /// Encoder position then, and where the slip began (see [`Self::step`]).
    from: i32,
    to: i32,
    /// The positions of the last two ticks at the limit.
    last: [i32; 2],
    /// The detector's breakaway sum and count then.
    sum: i64,
    count: u32,
    /// Σ of the excesses over the detector's peaks (Q16 N·m), since boot.
    extra: i64,
}

/// One tick's view of the drive and the detector.
#[derive(Clone, Copy, Debug)]
pub struct ClipTick {
    /// The current above 15/16 of the limit while driving.
    pub at_limit: bool,
    /// Measured screw torque resisting the motion (Q16 N·m).
    pub torque: i32,
    /// Encoder position in the direction of travel (the position times ±1).
    pub position: i32,
    /// The detector's breakaway sum and count after this tick (`StickSlipDetector::breakaways`).
    pub breakaways: (i64, u32),
    /// The detector found a slip this tick.
    pub slip: bool,
}

impl ClipTracker {
    /// Whether the tick must call [`Self::step`]: at the limit, or a plateau not yet settled.
    #[inline(always)]
    pub fn busy(&self) -> bool {
        self.state != 0
    }

    /// The current stands at the limit now (a plateau under way).
    #[inline(always)]
    pub fn at_limit(&self) -> bool {
        self.state == 1
    }

    /// Σ of the excesses the current limit clipped off the detector's peaks, since boot.
    pub fn extra(&self) -> i64 {
        self.extra
    }

    /// One tick (called while at the limit or [`Self::busy`]); `per_count` as in
    /// [`clipped_peak`].
    pub fn step(&mut self, x: &ClipTick, per_count: NewtonMetres) {
        if x.at_limit {
            if self.state != 1 {
                // A new plateau (one still waiting for its slip is this one, resumed only
                // if no slip came between: then it keeps its onset).
                if self.state == 0 || x.breakaways.1 != self.count {
                    self.onset = x.torque;
                    self.from = x.position;
                    self.last = [x.position; 2];
                    self.sum = x.breakaways.0;
                    self.count = x.breakaways.1;
                }
                self.state = 1;
            }
            if !x.slip {
                // The current shows a slip two ticks late (the coupling's torque falls within
                // the slip's millisecond, the current when the speed loop answers the rotor's
                // acceleration): the slip began 1.5 ticks before the last tick at the limit,
                // between the positions of the two ticks before it (host-sim, dry 1300 kg
                // from 150 mm: the coupling peaks between the samples 2 and 1 ticks before
                // the current's first sample under the limit's 15/16).
                self.to = ((i64::from(self.last[0]) + i64::from(self.last[1])) >> 1) as i32;
                self.last = [self.last[1], x.position];
                return;
            }
        } else if self.state != 0 {
            self.state = self.state.saturating_add(1);
        }
        if x.slip {
            // Exactly this plateau's slip: one breakaway since the onset.
            if x.breakaways.1 == self.count.wrapping_add(1) {
                // The detector's peak for this slip (its sum saturates: far from it, exact).
                let peak = x.breakaways.0.wrapping_sub(self.sum);
                let travel = self.to.saturating_sub(self.from);
                let excess = clipped_peak(self.onset, travel, per_count.bits()).wrapping_sub(peak);
                // Only a positive excess a torque can be (a wrap, or sensor garbage, is not).
                if excess > 0 && excess <= i64::from(i32::MAX) {
                    self.extra = self.extra.saturating_add(excess);
                }
            }
            self.state = 0;
        } else if self.state > SLIP_WITHIN.saturating_add(1) {
            self.state = 0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Float64 twin of [`clipped_peak`], N·m.
    fn clipped_peak_f64(onset: f64, travel: f64, k_c: f64, rad_per_count: f64) -> f64 {
        onset + k_c * travel * rad_per_count
    }

    fn q16(x: f64) -> i32 {
        (x * 65536.0).round() as i32
    }

    proptest::proptest! {
        /// Over the envelope (onset 0…120 N·m, −8…400 counts of wind-up, k_c 20…2000 N·m/rad,
        /// 500…100 000 counts per screw rad): the fixed point within the Q16 rounding of the
        /// per-count torque times the travel.
        #[test]
        fn the_clipped_peak_matches_its_float_twin(
            onset in 0.0f64..120.0,
            travel in -8i32..400,
            k_c in 20.0f64..2000.0,
            counts_per_rad in 500.0f64..100_000.0,
        ) {
            let per = q16(k_c / counts_per_rad);
            let got = clipped_peak(q16(onset), travel, per) as f64 / 65536.0;
            let want = clipped_peak_f64(onset, f64::from(travel), k_c, 1.0 / counts_per_rad);
            let tol = 1.0 / 65536.0 + f64::from(travel.unsigned_abs()) * 0.5 / 65536.0;
            proptest::prop_assert!((got - want).abs() <= tol, "{got} vs {want}");
        }
    }

    proptest::proptest! {
        /// Any sequence of ticks (sensor garbage, wrapped sums, counts out of order): no panic,
        /// the sum of excesses never falls, and a slip adds at most `i32::MAX`.
        #[test]
        fn any_ticks_never_panic_and_only_add_bounded_excesses(
            ticks in proptest::collection::vec(
                (proptest::bool::ANY, proptest::num::i32::ANY, proptest::num::i32::ANY,
                 proptest::num::i64::ANY, 0u32..4, proptest::bool::ANY),
                1..64,
            ),
            per in proptest::num::i32::ANY,
        ) {
            let mut c = ClipTracker::default();
            for (at_limit, torque, position, sum, count, slip) in ticks {
                let before = c.extra();
                c.step(
                    &ClipTick { at_limit, torque, position, breakaways: (sum, count), slip },
                    NewtonMetres::from_raw(per),
                );
                proptest::prop_assert!(c.extra() >= before);
                proptest::prop_assert!(c.extra() - before <= i64::from(i32::MAX));
            }
        }
    }

    /// A stick that reaches the limit at 80 N·m and winds 2 counts a tick at 0.35 N·m a count
    /// for 10 ticks at the limit; it slipped 1.5 ticks before the last of them (15 counts from
    /// the onset: 85.25 N·m), and the detector's clipped peak (82.3) is 2.95 N·m short.
    #[test]
    fn a_clipped_breakaway_adds_the_wind_up_past_the_limit() {
        let per = NewtonMetres::from_f64(0.35);
        let mut c = ClipTracker::default();
        let tick = |at_limit, torque: f64, position, sum: f64, n, slip| ClipTick {
            at_limit,
            torque: q16(torque),
            position,
            breakaways: ((sum * 65536.0) as i64, n),
            slip,
        };
        // Below the limit: nothing to do.
        assert!(!c.busy());
        for k in 0..10 {
            c.step(
                &tick(true, 80.0 + 0.2 * f64::from(k), 100 + 2 * k, 50.0, 3, false),
                per,
            );
        }
        assert!(c.busy());
        // The current falls; the detector reports the slip's peak a tick later.
        c.step(&tick(false, 60.0, 120, 50.0, 3, false), per);
        c.step(&tick(false, 40.0, 122, 50.0 + 82.3, 4, true), per);
        assert!(!c.busy());
        let extra = c.extra() as f64 / 65536.0;
        // 80 + 15 counts × 0.35 − 82.3.
        assert!(
            (extra - (80.0 + 15.0 * 0.35 - 82.3)).abs() < 1e-3,
            "{extra}"
        );
        // A later slip without a plateau adds nothing.
        c.step(&tick(false, 40.0, 150, 200.0, 5, true), per);
        assert!((c.extra() as f64 / 65536.0 - extra).abs() < 1e-9);
    }

    /// A plateau whose slip comes too late (or never: a stall) adds nothing, and a peak the
    /// detector read above the wind-up's is kept.
    #[test]
    fn a_plateau_without_its_slip_adds_nothing() {
        let per = NewtonMetres::from_f64(0.35);
        let mut c = ClipTracker::default();
        let t = |at_limit, position, sum: f64, n, slip| ClipTick {
            at_limit,
            torque: q16(80.0),
            position,
            breakaways: ((sum * 65536.0) as i64, n),
            slip,
        };
        c.step(&t(true, 0, 0.0, 0, false), per);
        c.step(&t(true, 5, 0.0, 0, false), per);
        for k in 0..=u32::from(SLIP_WITHIN) {
            c.step(&t(false, 6 + k as i32, 0.0, 0, false), per);
        }
        assert!(!c.busy());
        c.step(&t(false, 40, 90.0, 1, true), per);
        assert_eq!(c.extra(), 0);
        // The detector's peak above onset + wind-up: no excess.
        c.step(&t(true, 50, 90.0, 1, false), per);
        c.step(&t(false, 51, 90.0 + 85.0, 2, true), per);
        assert_eq!(c.extra(), 0);
    }
}
