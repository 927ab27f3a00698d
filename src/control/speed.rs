//! The speed loop: a PI on the encoder speed of the gear output, with the motor's voltage as
//! feed-forward (back-EMF at the reference speed plus R·i for the model's torque and the
//! drive's acceleration torque, `control::motion`), and a position term that pulls the
//! reference onto the screw-position estimate.
//!
//! Gains follow from the motor constants (docs/control.md): the proportional gain is 1/8 of
//! k_e·n (so it adds little to the encoder's quantisation noise), the integral gives a 5 Hz
//! crossover with the plant's DC gain 1/(k_e·n), well below the 40 Hz speed filter whose three
//! poles add ≈ 12 ms of lag; the position gain is 4 /s.
//!
//! Current limit without a separate current loop: the voltage may leave the back-EMF of the
//! measured speed by at most R·I_limit, and may move from the last tick's voltage at most
//! half the way to the limit the measured current leaves (the armature's L/R ≈ 1 ms is
//! shorter than the tick), so the current settles at the limit however the speed reads.

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
    /// The model's torque at the motor shaft, and the drive's acceleration torque for the
    /// reference's step (feed-forward).
    pub model_motor_torque: NewtonMetres,
    /// Supply voltage.
    pub supply: Volts,
    /// R·I_limit: how far the voltage may leave the back-EMF of the measured speed.
    pub current_headroom: Volts,
    /// Measured motor current: the voltage moves at most half the way to the limit from the
    /// last tick's (the filtered speed lags a sudden jam by ≈ 12 ms).
    pub current: Amperes,
    /// Loop resistance R.
    pub resistance: Ratio,
}

/// The loop's state: the integrator and what the current limit's second bound starts from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SpeedLoop {
    integral: Volts,
    /// The last output voltage (the current limit's second bound starts from it).
    last: Volts,
    /// The last back-EMF of the measured speed (its change per tick).
    last_emf: Volts,
}

impl SpeedLoop {
    /// Forget the state.
    pub fn reset(&mut self) {
        *self = Self::default();
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
        // Current limit, two bounds. The steady one: the voltage leaves the back-EMF of the
        // measured speed by at most R·I_limit. The measured speed lags a braking rotor (the
        // filter's ≈ 12 ms: a screw that stands while the coupling winds up brakes it) and
        // jumps when an encoder edge ends a stall, so that back-EMF reads high and the current
        // overshoots the limit by as much. The second bound follows the current itself: from
        // the last voltage, at most half the way to the limit (R·(I_limit ∓ i)/2), so the
        // excess halves every tick whatever the speed reads, plus the back-EMF's change since
        // the last tick where it takes current towards the limit (a braking rotor's falling
        // back-EMF: 0.12 V a tick at 3 rad/s² at the motor left 3.5 A over the limit without
        // it; a rising one, or an encoder edge's jump, is not followed: the current's own
        // correction follows it).
        // A cut of 4·R per ampere of excess (e' = L − 4·e) rang ±5 A about the limit and
        // tripped over-current on a screw that would not break away (host-sim, 1300 kg on a
        // 2× drier dry thread).
        let emf: Volts = qmul(x.measured, g.ke_n);
        let d_emf = emf.sat_sub(self.last_emf);
        self.last_emf = emf;
        // R·(I_limit ∓ i): the headroom R·I_limit ∓ R·i.
        let ri: Volts = qmul(x.current, x.resistance);
        let to_hi = x.current_headroom.sat_sub(ri);
        let to_lo = x.current_headroom.sat_add(ri);
        let hi = emf.sat_add(x.current_headroom).min(vmax).min(
            self.last
                .sat_add(Volts::from_raw(to_hi.bits() >> 1))
                .sat_add(d_emf.min(Volts::ZERO)),
        );
        let lo = emf.sat_sub(x.current_headroom).max(vmax.sat_neg()).max(
            self.last
                .sat_sub(Volts::from_raw(to_lo.bits() >> 1))
                .sat_add(d_emf.max(Volts::ZERO)),
        );
        let out = unsat.max(lo).min(hi);
        self.last = out;
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
        /// The current limit's bounds against their float64 twin, over the envelope (supply
        /// 8…16 V, ±60 A, the screw at ±8 rad/s, R 0.05…0.5 Ω, a limit of 1…60 A, any last
        /// voltage and back-EMF, any reference and integrator): the applied voltage
        /// (duty·supply) never leaves [lo, hi] by more than the duty's and Q16's rounding
        /// (where the bounds cross, hi wins; the duty saturates at the supply).
        #[test]
        fn the_current_bounds_match_their_float_twin(
            supply in 8.0f64..16.0,
            current in -60.0f64..60.0,
            measured in -8.0f64..8.0,
            last_speed in -8.0f64..8.0,
            last in -16.0f64..16.0,
            r in 0.05f64..0.5,
            limit in 1.0f64..60.0,
            reference in -8.0f64..8.0,
            integral in -16.0f64..16.0,
        ) {
            let g = SpeedGains::design(
                Ratio::lit("0.04"),
                Ratio::from_f64(r),
                Factor::from_int(60),
                1000,
            );
            let last = last.clamp(-supply, supply);
            let mut l = SpeedLoop {
                integral: Volts::from_f64(integral.clamp(-supply, supply)),
                last: Volts::from_f64(last),
                last_emf: qmul(RadiansPerSecond::from_f64(last_speed), g.ke_n),
            };
            let headroom = Volts::from_f64(r * limit);
            let x = SpeedInputs {
                reference: RadiansPerSecond::from_f64(reference),
                position_error: Radians::ZERO,
                measured: RadiansPerSecond::from_f64(measured),
                model_motor_torque: NewtonMetres::ZERO,
                supply: Volts::from_f64(supply),
                current_headroom: headroom,
                current: Amperes::from_f64(current),
                resistance: Ratio::from_f64(r),
            };
            let v = f64::from(l.step(&g, &x)) / 32768.0 * supply;
            // The float64 twin.
            let ke_n = 0.04 * 60.0;
            let (h, emf) = (headroom.to_f64(), ke_n * measured);
            let d_emf = emf - ke_n * last_speed;
            let hi = (emf + h)
                .min(supply)
                .min(last + (h - r * current) / 2.0 + d_emf.min(0.0));
            let lo = (emf - h)
                .max(-supply)
                .max(last - (h + r * current) / 2.0 + d_emf.max(0.0));
            let eps = 2e-3 + 2.0 * supply / 32768.0;
            // (The duty saturates at ±1: a bound beyond the supply applies the supply.)
            let hi = hi.max(-supply);
            let lo = lo.min(hi);
            proptest::prop_assert!(v <= hi + eps, "{v} V above hi {hi} V");
            proptest::prop_assert!(v >= lo - eps, "{v} V below lo {lo} V");
        }

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
            resistance: Ratio::lit("0.091"),
        };
        // (The current bound raises the voltage from rest by R·(I_limit − i)/2 a tick, the
        // headroom's half with no current flowing: full duty from the 2nd tick on.)
        for k in 0..10_000 {
            let d = l.step(&g, &x);
            assert!(k < 1 || d == i16::MAX, "tick {k}: {d}");
        }
        // The integrator stopped growing once the output saturated.
        assert!(l.integral <= Volts::from_int(12));
    }

    /// A rotor braked by a screw that will not break away: the filtered speed reads high by
    /// a lag that grows to 30 rad/s at the motor (0.5 rad/s at the screw, 1.2 V of back-EMF:
    /// 13 A at R = 0.091 Ω) and stays. The armature (L/R within the tick) draws
    /// (V − k_e·n·ω)/R. The current settles at the limit and never reaches a 45 A trip;
    /// the back-EMF bound alone (with a cut of 4·R per ampere of excess) crossed 45 A on the
    /// 19th tick.
    #[test]
    fn the_current_limit_holds_against_a_lagging_speed() {
        let r = 0.091;
        let g = SpeedGains::design(
            Ratio::lit("0.04"),
            Ratio::from_f64(r),
            Factor::from_int(60),
            1000,
        );
        let mut l = SpeedLoop::default();
        let (mut omega, mut current) = (3.5f64, 30.0f64);
        let mut worst = 0.0f64;
        for k in 0..400 {
            // The screw stands; the rotor slows (its gear-output speed from 3.5 rad/s down).
            omega = (omega - 0.004).max(0.0);
            let lag = (f64::from(k) / 50.0).min(1.0) * 0.5;
            let x = SpeedInputs {
                reference: RadiansPerSecond::from_int(3),
                position_error: Radians::from_int(2),
                measured: RadiansPerSecond::from_f64(omega + lag),
                model_motor_torque: NewtonMetres::ZERO,
                supply: Volts::from_f64(12.6),
                current_headroom: Volts::from_f64(r * 40.0),
                current: Amperes::from_f64(current),
                resistance: Ratio::from_f64(r),
            };
            let v = f64::from(l.step(&g, &x)) / 32767.0 * 12.6;
            current = (v - 2.4 * omega) / r;
            if k > 100 {
                worst = worst.max(current);
            }
            assert!(current < 45.0, "tick {k}: {current:.1} A");
        }
        assert!(worst < 41.0, "settled at {worst:.2} A");
    }
}
