//! The speed filter: a fading-memory α-β-γ tracker on the encoder count (three coincident
//! discrete poles at `e^(−2π·f_b·T)`), with no lag for constant acceleration.

use super::{EstimateFlags, Estimator};
use crate::math::exp_neg_q16;
use crate::units::{Instant, RadiansPerSecond, RadiansPerSecond2, Q};

/// The filter gains α, β, 2γ in Q28 for bandwidth `bandwidth_hz` at a `tick_us` tick.
pub(super) fn gains(bandwidth_hz: u32, tick_us: u32) -> [i32; 3] {
    // Fading-memory α-β-γ gains, θ = e^(−2π f_b T), in Q28.
    const TWO_PI_Q16: u64 = 411_775;
    let wt_q16 = (TWO_PI_Q16 * u64::from(bandwidth_hz) * u64::from(tick_us) / 1_000_000) as u32;
    // In i64: 0 ≤ θ ≤ 2^28, so every product stays below 2^59 (the i128 form it replaces
    // gives the same bits; 128-bit multiplies are long inline code on the board).
    let theta = i64::from(exp_neg_q16(wt_q16)) >> 4; // Q28
    let one = 1i64 << 28;
    let om = one - theta; // 1 − θ
    let alpha = one - ((theta * theta >> 28) * theta >> 28);
    let beta = 3 * (om * om >> 28) * (one + theta) >> 29;
    let gamma2 = (om * om >> 28) * om >> 28;
    [alpha as i32, beta as i32, gamma2 as i32]
}

impl Estimator {
    /// Restart the speed filter at a position, at rest (after a fault or a re-home).
    pub fn reset(&mut self, position_counts: i32) {
        self.last_counts = position_counts;
        self.q = 0;
        self.v = 0;
        self.a = 0;
        self.last = None;
    }

    /// Shift the filter's count reference by `by` counts and keep its speed and acceleration:
    /// a re-home (the encoder rebased to the switch) while the screw still turns.
    /// [`Estimator::reset`] there would read a spinning screw as at rest for the filter's
    /// settling time, and a motion started in that time would drive against the back-EMF.
    pub fn rebase(&mut self, by: i32) {
        self.last_counts = self.last_counts.saturating_add(by);
    }

    /// The α-β-γ tracking filter: (speed, acceleration, flags) for this tick.
    #[inline(always)]
    pub(super) fn filter(
        &mut self,
        now: Instant,
        counts: i32,
        fraction: u16,
    ) -> (RadiansPerSecond, RadiansPerSecond2, u8) {
        let mut flags = 0u8;
        match self.last {
            None => self.reset(counts),
            Some(prev) => {
                if now.micros_since(prev) > self.late_us {
                    flags |= EstimateFlags::LATE_TICK;
                }
            }
        }
        self.last = Some(now);
        // α-β-γ: predict one tick, correct with the measured position. The filter's position
        // is kept relative to the last count (q = p − count·2^16), so the whole state is i32:
        // residual r = count·2^16 + fraction − (p + v + a/2), then p ← p + α·r, i.e.
        // q ← α·r − r + fraction.
        // The count's move is clamped to ±32 767 counts per tick (beyond any drive: `SSAT`)
        // and every sum saturates in i32 (`QADD`/`QSUB`), so the residual is i32 without
        // 64-bit arithmetic and each correction is one 32×32→64 product; the gains (≤ 1 in
        // Q28) keep it in i32.
        let moved = counts
            .saturating_sub(self.last_counts)
            .clamp(-32_768, 32_767);
        self.last_counts = counts;
        let predicted = self.q.saturating_add(self.v).saturating_add(self.a >> 1);
        let r = (moved << 16)
            .saturating_add(i32::from(fraction))
            .saturating_sub(predicted);
        let correction = |g: i32| ((i64::from(r) * i64::from(g)) >> 28) as i32;
        self.q = correction(self.gains[0])
            .saturating_sub(r)
            .saturating_add(i32::from(fraction));
        self.v = self
            .v
            .saturating_add(self.a)
            .saturating_add(correction(self.gains[1]));
        self.a = self.a.saturating_add(correction(self.gains[2]));
        let speed = RadiansPerSecond::from_raw(self.speed_scale.apply32(self.v));
        let accel = RadiansPerSecond2::from_raw(self.accel_scale.apply32(self.a));
        (speed, accel, flags)
    }
}
