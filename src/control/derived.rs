//! What the controller derives from its configuration, once: the limit stops in counts, the
//! scales between counts, radians and ticks, the speed loop's gains, the protections' limits,
//! the supervisor's durations in ticks. Immutable while the configuration is in force;
//! [`super::Controller::reconfigure`] builds a new one.

use super::config::ControlConfig;
use super::protect::Limits;
use super::sense::Adc;
use super::speed::SpeedGains;
use crate::keys::ConfigError;
#[cfg(feature = "ball-screw")]
use crate::model::ballscrew::BallScrew;
use crate::model::geometry::Geometry;
use crate::model::Scale;
use crate::units::{
    ms_to_ticks, qmul, sat32, Amperes, Factor, NewtonMetres, RadiansPerSecond, Ratio, Volts, Q,
};

/// Ticks after the reference arrives during which the loop may settle before the bridge coasts.
const SETTLE_MS: u32 = 300;
/// Position error accepted as arrived, screw counts.
pub(super) const ARRIVED_COUNTS: i32 = 40;
/// Debounce of the switches, ticks at 1 kHz (scaled with the tick).
const DEBOUNCE_MS: u32 = 3;
/// Buttons must be seen released this long before they can start a motion.
const ARM_MS: u32 = 50;
/// Largest dynamic-braking current allowed, A (the BTS7960's low sides are rated 40 A).
const BRAKE_AMPS: i32 = 30;
/// After a motion ends above the brake speed, the bridge may brake regeneratively for at most
/// this long (`Controller::rest_bridge`); the rotor of the default motor needs a few ms.
const REGEN_MS: u32 = 50;
/// Overload monitoring starts this long after a motion starts (breakaway, winding the coupling).
const OVERLOAD_HOLDOFF_MS: u32 = 250;

/// The supervisor's durations in control ticks.
#[derive(Clone, Copy, Debug)]
pub(super) struct TickCounts {
    /// Overload monitoring holdoff after a start (+ one ramp).
    pub(super) overload_holdoff: u32,
    /// Settling after the reference arrived / after a stop.
    pub(super) settle: u32,
    /// Buttons seen released before they arm.
    pub(super) arm: u32,
    /// The switches' debounce.
    pub(super) debounce: u16,
    /// The speed ramp.
    pub(super) ramp: u32,
    /// The longest regenerative stop.
    pub(super) regen: u16,
}

impl TickCounts {
    fn new(tick_us: u32, ramp_ms: u32) -> TickCounts {
        let t = |ms: u32| ms_to_ticks(ms, tick_us);
        TickCounts {
            overload_holdoff: t(OVERLOAD_HOLDOFF_MS).saturating_add(t(ramp_ms)),
            settle: t(SETTLE_MS),
            arm: t(ARM_MS),
            debounce: t(DEBOUNCE_MS).max(1) as u16,
            ramp: t(ramp_ms),
            regen: t(REGEN_MS).min(u32::from(u16::MAX)) as u16,
        }
    }
}

/// The configuration in force and every number the tick derives from it.
#[derive(Clone, Debug)]
pub(super) struct Derived {
    pub(super) cfg: ControlConfig,
    /// ADC codes → amperes and volts.
    pub(super) adc: Adc,
    /// Limit stops in encoder counts.
    pub(super) lower_counts: i32,
    pub(super) upper_counts: i32,
    /// Where the lower limit switch closes, counts (the homing reference).
    pub(super) switch_counts: i32,
    /// counts → screw rad (Q16).
    pub(super) rad_per_count: Scale,
    /// Q16 counts/tick → screw rad/s (Q16).
    pub(super) speed_scale: Scale,
    /// Screw torque (Q16 N·m) → coupling twist in counts.
    pub(super) twist_scale: Scale,
    /// Durations in ticks, computed once (no division on the tick path).
    pub(super) ticks: TickCounts,
    pub(super) gains: SpeedGains,
    pub(super) limits: Limits,
    /// 1/(k_e·n), screw rad/s per volt.
    pub(super) inv_ke_n: Ratio,
    /// R·I_limit.
    pub(super) current_headroom: Volts,
    /// The drive's acceleration torque at the motor shaft per Q16 rad/s of screw speed the
    /// reference gains in a tick, Q16 (J·n/T): the speed loop's feed-forward.
    pub(super) accel_ff: i32,
    /// The drive's inertia at the screw, J·n²·η, Q16 kg·m² (`drive_inertia_q16`): the
    /// acceleration torque the current carries beside the thread's.
    pub(super) drive_inertia: i32,
    /// The same, at most [`DETECTOR_INERTIA_MAX`]: the stick-slip detector's lifting torque
    /// takes J·n²·η·θ̈ off in i32 (`Controller::detect_stick_slip`).
    pub(super) detector_inertia: i32,
    /// 15/16 of the current limit: above it a stick's breakaway may be clipped (`clip`).
    pub(super) clip_current: Amperes,
    /// The coupling's torque per encoder count of wind-up, k_c·rad per count (Q16 N·m).
    pub(super) torque_per_count: NewtonMetres,
    /// Highest screw speed at which shorting the motor keeps the current within [`BRAKE_AMPS`].
    pub(super) brake_speed: RadiansPerSecond,
    /// The cruise speeds the stick-slip reaction switches between, Q32 counts/tick: the
    /// configured one and `stickslip.escape_speed`.
    pub(super) cruise_q32: i64,
    pub(super) escape_q32: i64,
    /// A weighing lowering's creep speed ([`super::creep::CREEP_SPEED`], at most the cruise),
    /// Q32 counts per tick.
    pub(super) creep_q32: i64,
    /// A 4-tick mean's lag behind the coupling's wind-up at the creep speed, 1.5 ticks of
    /// k_c·ω (`creep`).
    pub(super) creep_lag: NewtonMetres,
    /// How far the reference may lead the screw before the planner waits for it, counts.
    pub(super) lag_counts: i32,
    /// The ball screw (`cfg.ball_screw`, compiled).
    #[cfg(feature = "ball-screw")]
    pub(super) ball_screw: BallScrew,
}

impl Derived {
    /// Validate what the estimator does not (the limit stops against `geometry`, the
    /// protections, the ball screw) and derive the tick's numbers.
    pub(super) fn new(cfg: &ControlConfig, geometry: &Geometry) -> Result<Derived, ConfigError> {
        #[cfg(feature = "ball-screw")]
        let ball_screw = cfg.ball_screw.compile()?;
        let (lower_counts, upper_counts, switch_counts) = cfg.validate_limit_counts(geometry)?;
        let tick_us = cfg.estimator.tick_us;
        let tick_hz = i128::from(1_000_000 / tick_us);
        let rad_per_count = geometry.screw_rad_per_count(); // counts → Q16 rad
        let speed_scale = rad_per_count.times(tick_hz, 1 << 16);
        // counts per screw rad (Q16) = 2^32 / rad_per_count(Q16 value).
        // Unsigned products and quotients through the one out-of-line `mul_div_u64`: every
        // operand is positive, and for a validated drive (4…65 536 counts/rev, gear 1…1000)
        // counts/rad (Q16) < 2^40, so the speeds below stay far inside `u64`.
        let (mant, shift) = rad_per_count.parts();
        let mul_div = crate::math::mul_div_u64;
        let counts_per_rad_q16 = mul_div(
            1 << 32,
            1 << shift.min(63),
            mant.max(1).unsigned_abs().into(),
        ) as i64;
        // Twist counts = T/k · counts/rad: from Q16 N·m.
        let k = i128::from(cfg.estimator.mechanics.coupling_stiffness.bits()); // Q16
        let twist_scale = Scale::from_ratio(i128::from(counts_per_rad_q16), k << 16);
        // Its inverse, Q16 N·m per count: k (Q16) · 2^16 / counts per rad (Q16).
        let torque_per_count = NewtonMetres::from_raw(sat32(mul_div(
            k.unsigned_abs() as u64,
            1 << 16,
            counts_per_rad_q16.unsigned_abs().max(1),
        ) as i64));
        // Cruise: rad/s → Q32 counts/tick = ω·counts/rad·T·2^32.
        // (Both speeds are validated positive: 0.2…20 rad/s.)
        let counts_per_rad_tick = counts_per_rad_q16.unsigned_abs() * u64::from(tick_us);
        let per_tick_q32 = |speed: RadiansPerSecond| {
            mul_div(
                speed.bits().unsigned_abs().into(),
                counts_per_rad_tick,
                1_000_000,
            ) as i64
        };
        let gear_ratio = cfg.estimator.drive.gear_ratio;
        let counts_per_motor_rad_q16 = mul_div(
            counts_per_rad_q16.unsigned_abs(),
            1 << 16,
            gear_ratio.to_bits().max(1).unsigned_abs().into(),
        );
        // Nut metres per count in Q40: the travel of 2^16 counts in Q24.
        let nut_q40 =
            i64::from(geometry.travel(1 << 16).bits()) - i64::from(geometry.travel(0).bits());
        let limits = Limits::new(
            &cfg.protection,
            tick_us,
            counts_per_motor_rad_q16 as i64,
            nut_q40,
            cfg.motion.cruise_speed,
        );
        let motor = &cfg.estimator.motor;
        let gains = SpeedGains::design(
            motor.torque_constant,
            motor.resistance,
            Factor::from_raw(gear_ratio.to_bits()),
            tick_us,
        );
        // A weighing lowering's creep speed, at most the cruise (`creep`).
        let creep = super::creep::CREEP_SPEED.min(cfg.motion.cruise_speed);
        let inv_ke_n = Ratio::from_raw(sat32((1i64 << 44) / i64::from(gains.ke_n.bits().max(1))));
        let drive_inertia = drive_inertia_q16(
            motor.inertia_ukgm2,
            cfg.estimator.drive.gear_ratio.to_bits(),
            motor.gear_efficiency.bits(),
        );
        Ok(Derived {
            cfg: *cfg,
            adc: Adc::new(&cfg.sensing),
            lower_counts,
            upper_counts,
            switch_counts,
            rad_per_count,
            speed_scale,
            twist_scale,
            ticks: TickCounts::new(tick_us, cfg.motion.ramp_ms),
            gains,
            limits,
            inv_ke_n,
            current_headroom: qmul(cfg.protection.current_limit, motor.resistance),
            drive_inertia,
            detector_inertia: drive_inertia.clamp(0, DETECTOR_INERTIA_MAX),
            accel_ff: accel_ff_q16(
                motor.inertia_ukgm2,
                cfg.estimator.drive.gear_ratio.to_bits(),
                cfg.estimator.tick_us,
            ),
            clip_current: cfg
                .protection
                .current_limit
                .sat_sub(Amperes::from_raw(cfg.protection.current_limit.bits() >> 4)),
            torque_per_count,
            brake_speed: qmul(
                qmul::<_, _, Volts>(Amperes::from_int(BRAKE_AMPS), motor.resistance),
                inv_ke_n,
            ),
            cruise_q32: per_tick_q32(cfg.motion.cruise_speed),
            escape_q32: per_tick_q32(cfg.stick_slip.escape_speed),
            creep_q32: per_tick_q32(creep),
            // k_c (Q16 N·m/rad)·ω (Q16 rad/s)·1.5 ticks (µs) → Q16 N·m; < 2^63 (k_c ≤ 10⁴,
            // ω ≤ 20, tick ≤ 10⁵ µs).
            creep_lag: NewtonMetres::from_raw(sat32(
                (i64::from(cfg.estimator.mechanics.coupling_stiffness.bits())
                    * i64::from(creep.bits())
                    * i64::from(tick_us)
                    * 3
                    / 2_000_000)
                    >> 16,
            )),
            // The planner waits while the screw lags its reference by more than 0.25 rad of
            // the screw (≈ 0.08 mm of nut on the S12x2; at least the arrival window), see
            // `drive`.
            lag_counts: sat32(counts_per_rad_q16 >> 18).max(ARRIVED_COUNTS),
            #[cfg(feature = "ball-screw")]
            ball_screw,
        })
    }
}

/// The drive's acceleration torque for the load identification's samples
/// (`ident::LoadIdent::set_drive_inertia`): its inertia `j_ukgm2` (µkg·m² at the motor shaft)
/// at the screw through the gear ratio `n_q16` and the efficiency `eta_q28` (motoring: the
/// current carries J·α·n·η of it), per Q16 rad/s gained over a sample's `DECIMATE` ticks of
/// `tick_us`, Q8: J·n²·η·2^8 / (DECIMATE·tick) with the µ of µkg·m² and of µs cancelling.
/// Saturated (a drive whose inertia the configuration allows but no lift has). Cold.
pub(super) fn sample_inertia_q8(j_ukgm2: i32, n_q16: i32, eta_q28: i32, tick_us: u32) -> i32 {
    let per = i128::from(crate::ident::DECIMATE) * i128::from(tick_us.max(1));
    j_n2_eta(j_ukgm2, n_q16, eta_q28, 8, per)
}

/// J·n²·η·2^`shift` / `per` (J in µkg·m², n Q16, η Q28; `per` in the µ units that cancel J's
/// µ), saturated at i32::MAX: the two factors at the screw below.
fn j_n2_eta(j_ukgm2: i32, n_q16: i32, eta_q28: i32, shift: u32, per: i128) -> i32 {
    let n = i128::from(n_q16);
    let num = (i128::from(j_ukgm2) * n * n * i128::from(eta_q28)) << shift;
    i32::try_from(num / (per << 60)).unwrap_or(i32::MAX)
}

/// The speed loop's acceleration feed-forward: the torque at the motor shaft that turns the
/// drive's inertia `j_ukgm2` (µkg·m² at the motor shaft) up by the gear ratio `n_q16` times a
/// Q16 rad/s step of the screw's reference in one tick of `tick_us`, Q16: J·n/T, the µ of
/// µkg·m² and of µs cancelling (no efficiency: the rotor is upstream of the gearbox).
/// Saturated. Cold.
pub(super) fn accel_ff_q16(j_ukgm2: i32, n_q16: i32, tick_us: u32) -> i32 {
    let num = i64::from(j_ukgm2) * i64::from(n_q16);
    sat32(num / i64::from(tick_us.max(1)))
}

/// The largest drive inertia at the screw the stick-slip detector takes the acceleration
/// torque of, Q16 kg·m² (0.5 kg·m², 2.7× host-sim's drive): with |θ̈| ≤
/// `estimator::ACCEL_MAX` (2^24 in Q8) the product, shifted to Q16 N·m, stays in i32 on every
/// tick without a saturating step. A larger drive's correction is that of 0.5 kg·m²: its short
/// stick-slip cycles' breakaways read partly low again (docs/model.md "Stick-slip").
pub(super) const DETECTOR_INERTIA_MAX: i32 = (1 << 15) - 1;
const _: () = assert!(
    (crate::estimator::ACCEL_MAX.to_bits() as i64) * (DETECTOR_INERTIA_MAX as i64) >> 8
        <= i32::MAX as i64
);

/// The drive's inertia `j_ukgm2` (µkg·m² at the motor shaft) at the screw through the gear
/// ratio `n_q16` and the efficiency `eta_q28` (the current carries J·α·n·η of it, as
/// [`sample_inertia_q8`]), Q16 kg·m²: J·n²·η. Saturated. Cold.
pub(super) fn drive_inertia_q16(j_ukgm2: i32, n_q16: i32, eta_q28: i32) -> i32 {
    j_n2_eta(j_ukgm2, n_q16, eta_q28, 16, 1_000_000)
}

#[cfg(test)]
mod tests {
    use super::{accel_ff_q16, drive_inertia_q16, sample_inertia_q8};
    use crate::ident::DECIMATE;

    /// The default drive (60 µkg·m², n = 60, η = 0.85, 1 kHz): 0.184 kg·m² at the screw,
    /// 45.9 N·m per rad/s gained over a sample's 4 ms.
    #[test]
    fn the_default_drive_s_acceleration_torque() {
        let q8 = sample_inertia_q8(60, 60 << 16, (0.85 * f64::from(1 << 28)) as i32, 1000);
        assert!(
            (f64::from(q8) / 256.0 - 45.9).abs() < 0.01,
            "{}",
            f64::from(q8) / 256.0
        );
    }

    proptest::proptest! {
        /// The drive's inertia factors against their float64 twins over the settings' whole
        /// range (inertia 0…100 000 µkg·m², ratio 1…1000, efficiency 0.1…1, tick
        /// 100…10 000 µs): the samples' (Q8), the feed-forward's and the inertia at the screw
        /// (Q16), each within one LSB, or saturated exactly where its twin passes i32.
        #[test]
        fn drive_inertia_factors_follow_their_twins(
            j in 0i32..=100_000,
            n in 1.0f64..1000.0,
            eta in 0.1f64..=1.0,
            tick in 100u32..=10_000,
        ) {
            let n_q16 = (n * 65_536.0) as i32;
            let eta_q28 = (eta * f64::from(1 << 28)) as i32;
            let (n, eta) = (f64::from(n_q16) / 65_536.0, f64::from(eta_q28) / f64::from(1 << 28));
            let (j_si, t) = (f64::from(j) * 1e-6, f64::from(tick) * 1e-6);
            for (got, twin) in [
                (
                    sample_inertia_q8(j, n_q16, eta_q28, tick),
                    j_si * n * n * eta / (f64::from(DECIMATE) * t) * 256.0,
                ),
                (accel_ff_q16(j, n_q16, tick), j_si * n / t * 65_536.0),
                (drive_inertia_q16(j, n_q16, eta_q28), j_si * n * n * eta * 65_536.0),
            ] {
                if twin >= f64::from(i32::MAX) {
                    proptest::prop_assert_eq!(got, i32::MAX);
                } else {
                    proptest::prop_assert!((f64::from(got) - twin).abs() <= 1.0, "{} vs {}", got, twin);
                }
            }
        }
    }
}
