//! The speed loop: a PI on the encoder speed of the gear output, with the motor's steady-state
//! voltage as feed-forward (back-EMF at the reference speed plus R·i for the model's torque),
//! and a position term that pulls the reference onto the screw-position estimate.
//!
//! Gains follow from the motor constants (docs/control.md): the proportional gain is 1/8 of
//! k_e·n (so it adds little to the encoder's quantisation noise), the integral gives a 5 Hz
//! crossover with the plant's DC gain 1/(k_e·n), well below the 40 Hz speed filter whose three
//! poles add ≈ 12 ms of lag; the position gain is 4 /s.
//!
//! Current limit without a current loop: the voltage may leave the back-EMF of the measured
//! speed by at most R·I_limit, so the steady current never exceeds the limit (the armature's
//! L/R ≈ 1 ms is shorter than the tick).

use crate::units::{
    qmul, sat32, Amperes, Factor, NewtonMetres, Radians, RadiansPerSecond, Ratio, Volts, Q,
};

/// Quantised gains.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpeedGains {
    /// Back-EMF per screw speed, k_e·n, V/(rad/s).
    pub ke_n: Factor,
    /// R/k_t, V per N·m at the motor shaft.
    pub r_over_kt: Factor,
    /// Proportional gain, V/(rad/s).
    pub kp: Factor,
    /// Integral gain × tick, V/(rad/s) per tick.
    pub ki_t: Ratio,
    /// Position gain, 1/s (screw rad/s per screw rad).
    pub kpos: Factor,
}

impl SpeedGains {
    /// Gains for motor constants k_t (= k_e), loop resistance R, gear ratio n and tick `tick_us`.
    pub fn design(kt: Ratio, resistance: Ratio, ratio: Factor, tick_us: u32) -> SpeedGains {
        let ke_n: Factor = qmul(kt, ratio);
        let r_over_kt = Factor::from_raw(sat32(
            (i64::from(resistance.bits()) << 16) / i64::from(kt.bits().max(1)),
        ));
        // kp = k_e·n/8; ki = 2π·5 Hz·k_e·n; ki·T in V/(rad/s) per tick.
        let kp = Factor::from_raw(ke_n.bits() / 8);
        const TWO_PI_5_Q16: i64 = 2_058_874; // 2π·5·2^16
        let ki_t = Ratio::from_raw(sat32(
            i64::from(ke_n.bits()) * TWO_PI_5_Q16 * i64::from(tick_us) / 1_000_000 >> 4,
        ));
        SpeedGains {
            ke_n,
            r_over_kt,
            kp,
            ki_t,
            kpos: Factor::from_int(4),
        }
    }
}

/// What the loop needs each tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpeedInputs {
    /// Reference screw speed.
    pub reference: RadiansPerSecond,
    /// Reference screw position − estimated screw position.
    pub position_error: Radians,
    /// Measured (filtered) screw speed.
    pub measured: RadiansPerSecond,
    /// The model's torque at the motor shaft (feed-forward).
    pub model_motor_torque: NewtonMetres,
    /// Supply voltage.
    pub supply: Volts,
    /// R·I_limit: how far the voltage may leave the back-EMF of the measured speed.
    pub current_headroom: Volts,
    /// Measured motor current and its limit: beyond it the headroom shrinks by 4·R per
    /// ampere of excess (the filtered speed lags a sudden jam by ≈ 12 ms).
    pub current: Amperes,
    /// The current limit.
    pub current_limit: Amperes,
    /// Loop resistance R.
    pub resistance: Ratio,
}

/// The integrator state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SpeedLoop {
    integral: Volts,
}

impl SpeedLoop {
    /// Forget the integrator.
    pub fn reset(&mut self) {
        self.integral = Volts::ZERO;
    }

    /// One tick: the duty cycle in Q15 (±`i16::MAX`).
    pub fn step(&mut self, g: &SpeedGains, x: &SpeedInputs) -> i16 {
        let pos_term: RadiansPerSecond = qmul(x.position_error, g.kpos);
        let command = x.reference.sat_add(pos_term);
        let error = command.sat_sub(x.measured);
        let ff: Volts = qmul::<_, _, Volts>(x.reference, g.ke_n)
            .sat_add(qmul(x.model_motor_torque, g.r_over_kt));
        let p: Volts = qmul(error, g.kp);
        let unsat = ff.sat_add(p).sat_add(self.integral);
        let vmax = x.supply.sat_abs();
        // Current limit from the motor model: |V − k_e·n·ω| ≤ R·I_limit.
        let emf: Volts = qmul(x.measured, g.ke_n);
        let excess = x
            .current
            .sat_abs()
            .sat_sub(x.current_limit)
            .max(Amperes::ZERO);
        let cut: Volts = qmul(
            excess.sat_add(excess).sat_add(excess).sat_add(excess),
            x.resistance,
        );
        let room = x.current_headroom.sat_sub(cut).max(Volts::ZERO);
        let (room_hi, room_lo) = if x.current.bits() >= 0 {
            (room, x.current_headroom)
        } else {
            (x.current_headroom, room)
        };
        let hi = emf.sat_add(room_hi).min(vmax);
        let lo = emf.sat_sub(room_lo).max(vmax.sat_neg());
        let out = unsat.max(lo).min(hi);
        // Conditional integration: stop integrating into a saturated output.
        let di: Volts = qmul(error, g.ki_t);
        let winding_up = (out != unsat) && ((di.bits() > 0) == (unsat.bits() > 0));
        if !winding_up {
            self.integral = self.integral.sat_add(di).max(vmax.sat_neg()).min(vmax);
        }
        duty_q15(out, x.supply)
    }
}

/// `v / supply` as a Q15 duty, saturated to ±1; zero if the supply reads below 1 V.
///
/// One 32-bit division (`UDIV`: one instruction, 2–12 cycles on the M4; it was a Newton
/// reciprocal, ≈ 30 instructions more on every driving tick): |v|·2^11 over the
/// supply rounded to Q12, the quotient rounded. Error ≤ ½ LSB + 2^15·2^−13/supply\[V\]
/// (the supply's rounding: ≤ 0.8 LSB at 9 V), proptest below.
#[inline(always)]
pub fn duty_q15(v: Volts, supply: Volts) -> i16 {
    if supply < const { Volts::lit("1") } {
        return 0;
    }
    // Supply in Q12 V, rounded: 1…31 V → 4096…126 976 (never zero).
    let s = ((supply.bits().min(31 << 16) + 8) >> 4) as u32;
    // |v| ≤ supply (beyond it the duty saturates anyway), so |v|·2^11 + s/2 < 2^32.
    let mag = v.bits().unsigned_abs().min(s << 4);
    let d = (((mag << 11) + s / 2) / s).min(i16::MAX as u32) as i16;
    if v.bits() < 0 {
        -d
    } else {
        d
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn duty_is_voltage_over_supply() {
        for &(v, s) in &[
            (6.0, 12.0),
            (-3.0, 12.6),
            (12.6, 12.6),
            (20.0, 12.0),
            (0.5, 9.0),
        ] {
            let d = duty_q15(Volts::from_f64(v), Volts::from_f64(s));
            let want = (v / s).clamp(-1.0, 1.0) * 32767.0;
            assert!((f64::from(d) - want).abs() <= 3.0, "{v}/{s}: {d} vs {want}");
        }
        assert_eq!(duty_q15(Volts::from_f64(5.0), Volts::ZERO), 0);
    }

    proptest::proptest! {
        /// The division's duty against the float64 quotient, over every supply the bridge
        /// can see (1…31 V; above 31 V the supply is taken as 31 V) and any voltage.
        #[test]
        fn duty_matches_its_float_twin(
            v in -(1i32 << 23)..(1i32 << 23),
            supply in (1i32 << 16)..(31 << 16),
        ) {
            let d = duty_q15(Volts::from_raw(v), Volts::from_raw(supply));
            let s = f64::from(supply) / 65536.0;
            let want = (f64::from(v) / f64::from(supply) * 32768.0).clamp(-32767.0, 32767.0);
            let bound = 0.5 + 32768.0 / 8192.0 / s + 1e-9;
            proptest::prop_assert!(
                (f64::from(d) - want).abs() <= bound,
                "{} V / {} V: {} vs {}", f64::from(v) / 65536.0, s, d, want
            );
        }
    }

    #[test]
    fn gains_follow_the_motor_constants() {
        let g = SpeedGains::design(
            Ratio::lit("0.04"),
            Ratio::lit("0.091"),
            Factor::from_int(60),
            1000,
        );
        assert!((g.ke_n.to_f64() - 2.4).abs() < 1e-4);
        assert!((g.r_over_kt.to_f64() - 2.275).abs() < 1e-3);
        assert!((g.kp.to_f64() - 0.3).abs() < 1e-4);
        assert!((g.ki_t.to_f64() - 2.4 * 31.4159 * 1e-3).abs() < 1e-4);
    }

    #[test]
    fn integrator_does_not_wind_up_at_full_duty() {
        let g = SpeedGains::design(
            Ratio::lit("0.04"),
            Ratio::lit("0.091"),
            Factor::from_int(60),
            1000,
        );
        let mut l = SpeedLoop::default();
        let x = SpeedInputs {
            reference: RadiansPerSecond::from_int(10),
            position_error: Radians::ZERO,
            measured: RadiansPerSecond::ZERO,
            model_motor_torque: NewtonMetres::ZERO,
            supply: Volts::from_int(12),
            current_headroom: Volts::from_int(20),
            current: Amperes::ZERO,
            current_limit: Amperes::from_int(40),
            resistance: Ratio::lit("0.091"),
        };
        for _ in 0..10_000 {
            assert_eq!(l.step(&g, &x), i16::MAX);
        }
        // The integrator stopped growing once the output saturated.
        assert!(l.integral <= Volts::from_int(12));
    }
}
