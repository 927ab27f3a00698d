//! Seed 000's prescribed drive (Fig. 2): the gear-output speed ramps 0 → ω_c in 0.06 s, holds
//! until 4.94 s and brakes to 0 at 5 s. θ_i is its exact integral.

/// A trapezoidal speed profile for the coupling's input angle θ_i.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpeedProfile {
    /// Cruise screw speed ω_c, rad/s (signed: negative lowers).
    pub cruise: f64,
    /// End of the acceleration ramp, s (Fig. 2: 0.06).
    pub ramp_end: f64,
    /// Start of the braking ramp, s (Fig. 2: 4.94).
    pub brake_start: f64,
    /// Stop, s (Fig. 2: 5).
    pub stop: f64,
}

/// Default cruise screw speed, rad/s: ≈ 143 rpm, nut ≈ 3.9 mm/s (docs/plant.md).
pub const PAPER_CRUISE: f64 = 15.0;

impl SpeedProfile {
    /// Fig. 2 with cruise speed `cruise` (rad/s, negative for lowering).
    pub fn paper(cruise: f64) -> Self {
        Self {
            cruise,
            ramp_end: 0.06,
            brake_start: 4.94,
            stop: 5.0,
        }
    }

    /// θ̇_i at time t, rad/s.
    #[inline]
    pub fn speed(&self, t: f64) -> f64 {
        let w = self.cruise;
        if t <= 0.0 || t >= self.stop {
            0.0
        } else if t < self.ramp_end {
            w * t / self.ramp_end
        } else if t <= self.brake_start {
            w
        } else {
            w * (self.stop - t) / (self.stop - self.brake_start)
        }
    }

    /// θ_i at time t, rad (exact integral of [`SpeedProfile::speed`]).
    #[inline]
    pub fn angle(&self, t: f64) -> f64 {
        let w = self.cruise;
        let (t1, t2, t3) = (self.ramp_end, self.brake_start, self.stop);
        let ramp = |tau: f64, len: f64| 0.5 * w * tau * tau / len;
        if t <= 0.0 {
            0.0
        } else if t < t1 {
            ramp(t, t1)
        } else if t <= t2 {
            ramp(t1, t1) + w * (t - t1)
        } else {
            let full = ramp(t1, t1) + w * (t2 - t1) + ramp(t3 - t2, t3 - t2);
            full - ramp(t3 - t.min(t3), t3 - t2)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angle_is_the_integral_of_speed() {
        let p = SpeedProfile::paper(15.0);
        let n = 200_000;
        let h = 5.2 / n as f64;
        let mut acc = 0.0;
        for i in 0..n {
            let t = i as f64 * h;
            acc += h * (p.speed(t) + 4.0 * p.speed(t + 0.5 * h) + p.speed(t + h)) / 6.0;
            if i % 10_000 == 9_999 {
                assert!(
                    (acc - p.angle(t + h)).abs() < 1e-6,
                    "{t}: {acc} {}",
                    p.angle(t + h)
                );
            }
        }
        // Total: ω_c·(stop − ramp) for symmetric ramps.
        assert!((p.angle(6.0) - 15.0 * 4.94).abs() < 1e-9);
    }
}
