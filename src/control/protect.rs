//! Protections: each monitor looks at one tick's measurements and says whether its fault
//! trips. They keep only counters; the supervisor decides what a trip does (stop, latch,
//! snapshot).
//!
//! | fault | trips when | reaction time |
//! |---|---|---|
//! | over-current | one current sample above the limit | the same tick |
//! | stall | duty ≥ stall duty, current ≥ 90 % of the limit or the screw lagging its reference (the planner waiting), less than `CREEP_COUNTS` of encoder progress in the direction of travel since the pushing began, and the motor's voltage balance says the shaft is still, for `stall_ms` | `stall_ms` |
//! | encoder lost | no encoder count while the voltage balance says the shaft turns, for `stall_ms` | `stall_ms` |
//! | encoder implausible | a jump faster than the motor can turn | the same tick |
//! | under-voltage | supply below the run threshold while moving, for `supply_ms` | `supply_ms` |
//! | over-voltage | supply above the maximum, for `supply_ms` | `supply_ms` |
//! | overload | measured screw torque above the model's at rated load by the margin (a fraction of its size), for `overload_ms` | `overload_ms` |
//! | runaway | travel while stopped beyond `runaway_travel`, or lowering faster than 1.5× the reference + 25 % of cruise for 100 ms | immediate / 100 ms |

use super::config::ProtectionConfig;
use crate::units::{qmul, sat32, Amperes, NewtonMetres, RadiansPerSecond, Ratio, Volts, Q};

/// What went wrong.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FaultKind {
    /// Motor current above the limit.
    OverCurrent,
    /// High duty, no motion, no back-EMF: the mechanism is jammed.
    Stall,
    /// The motor turns (back-EMF) but the encoder does not count.
    EncoderLost,
    /// The encoder jumped faster than the motor can turn.
    EncoderImplausible,
    /// Supply below the run threshold while moving.
    UnderVoltage,
    /// Supply above the maximum.
    OverVoltage,
    /// Measured torque above the model's torque at rated load by the margin.
    Overload,
    /// Motion the motor did not command.
    Runaway,
    /// A limit switch closed where the soft limit should have stopped the lift first.
    LimitSwitch,
    /// Both limit switches closed at once (wiring fault).
    SwitchesImplausible,
    /// The watchdog reset the controller (reported at the next boot).
    WatchdogReset,
    /// A configuration had been stored but could not be used (corrupt, another version,
    /// refused, unreadable): the lift runs the factory defaults, whose stops are not the
    /// user's. Reported at boot; `fault clear` acknowledges it.
    FactoryDefaults,
    /// The stored configuration is a ball screw's (`drive.screw = ball` or the `ball` law) and
    /// this image is built without the `ball-screw` feature: the lift stays braked and the
    /// record untouched until the ball-screw firmware is flashed (`fault clear` refuses).
    NeedsBallScrew,
}

impl FaultKind {
    /// Short name for logs and the console.
    pub fn name(self) -> &'static str {
        match self {
            FaultKind::OverCurrent => "over-current",
            FaultKind::Stall => "stall",
            FaultKind::EncoderLost => "encoder lost",
            FaultKind::EncoderImplausible => "encoder implausible",
            FaultKind::UnderVoltage => "under-voltage",
            FaultKind::OverVoltage => "over-voltage",
            FaultKind::Overload => "overload",
            FaultKind::Runaway => "runaway",
            FaultKind::LimitSwitch => "limit switch before soft limit missed",
            FaultKind::SwitchesImplausible => "both limit switches closed",
            FaultKind::WatchdogReset => "watchdog reset",
            FaultKind::FactoryDefaults => "factory defaults in force",
            FaultKind::NeedsBallScrew => "stored configuration needs the ball-screw firmware",
        }
    }
}

impl core::fmt::Display for FaultKind {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// Thresholds in tick units, quantised once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Current limit.
    pub overcurrent: Amperes,
    /// Stall duty, Q15.
    pub stall_duty: i16,
    /// Ticks.
    pub stall_ticks: u32,
    /// Current that counts as pushing (90 % of the current limit).
    pub stall_current: Amperes,
    /// Largest plausible encoder step per tick, counts.
    pub max_counts_per_tick: i32,
    /// Motor speed from the voltage balance above which the shaft must be turning, screw rad/s.
    pub turning_speed: RadiansPerSecond,
    /// Supply thresholds.
    pub supply_run_min: Volts,
    /// Supply maximum.
    pub supply_max: Volts,
    /// Ticks.
    pub supply_ticks: u32,
    /// Overload margin, a fraction of the model's torque.
    pub overload_margin: Ratio,
    /// Ticks.
    pub overload_ticks: u32,
    /// Uncommanded travel, counts.
    pub runaway_counts: i32,
    /// Ticks of too-fast lowering.
    pub runaway_ticks: u32,
}

impl Limits {
    /// Quantise `p` for a tick of `tick_us` and a drive with `counts_per_motor_rad` (Q16) and a
    /// nut travel of `nut_metres_per_count_q40` (metres per count in Q40).
    pub fn new(
        p: &ProtectionConfig,
        tick_us: u32,
        counts_per_motor_rad_q16: i64,
        nut_metres_per_count_q40: i64,
        cruise: RadiansPerSecond,
    ) -> Limits {
        let ticks = |ms: u32| crate::units::ms_to_ticks(ms, tick_us).max(1);
        // counts/tick = ω·(counts/rad)·T.
        let max_counts = (i64::from(p.max_motor_speed.bits()) * counts_per_motor_rad_q16 >> 32)
            * i64::from(tick_us)
            / 1_000_000;
        let runaway_counts =
            (i64::from(p.runaway_travel.bits()) << 16) / nut_metres_per_count_q40.max(1);
        Limits {
            overcurrent: p.overcurrent,
            stall_duty: sat32(i64::from(p.stall_duty.bits()) >> 13).clamp(0, 32767) as i16,
            stall_ticks: ticks(p.stall_ms),
            stall_current: p.current_limit.scale(const { Ratio::lit("0.9") }),
            max_counts_per_tick: sat32(max_counts + 1).max(1),
            turning_speed: RadiansPerSecond::from_raw(cruise.bits() / 4),
            supply_run_min: p.supply_run_min,
            supply_max: p.supply_max,
            supply_ticks: ticks(p.supply_ms),
            overload_margin: p.overload_margin,
            overload_ticks: ticks(p.overload_ms),
            runaway_counts: sat32(runaway_counts).max(1),
            runaway_ticks: ticks(100),
        }
    }
}

/// One tick's view for the monitors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sample {
    /// Whether the supervisor is driving a motion.
    pub moving: bool,
    /// Whether the motion is lowering.
    pub lowering: bool,
    /// Duty applied during the last tick, Q15.
    pub duty: i16,
    /// Encoder counts moved this tick.
    pub delta: i32,
    /// Motor current.
    pub current: Amperes,
    /// Supply.
    pub supply: Volts,
    /// Screw speed from the voltage balance (V − R·i)/(k_e·n).
    pub emf_speed: RadiansPerSecond,
    /// Measured screw speed (encoder filter).
    pub speed: RadiansPerSecond,
    /// Reference screw speed.
    pub reference: RadiansPerSecond,
    /// Cruise speed.
    pub cruise: RadiansPerSecond,
    /// Travel since the lift stopped, counts (0 while moving).
    pub travel_while_stopped: i32,
    /// Measured and model (rated load) screw torque, projected on the direction of motion.
    pub measured_torque: NewtonMetres,
    /// Model screw torque at rated load, projected on the direction of motion.
    pub model_torque: NewtonMetres,
    /// Whether the overload check applies this tick (driving, past the start-up transient).
    pub overload_armed: bool,
    /// The screw lags its reference so far that the planner waits for it: the drive is
    /// pushing whatever its duty and current (at standstill the current limit can hold both
    /// just under the stall thresholds).
    pub lagging: bool,
}

/// Counters of the time-filtered monitors.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Monitors {
    still: u32,
    blind: u32,
    low_supply: u32,
    high_supply: u32,
    overload: u32,
    fast_lowering: u32,
    /// Counts forward since the stall monitor's pushing began.
    crept: i32,
}

impl Monitors {
    /// Reset every counter (on a new motion or a fault clear).
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// The first fault that trips this tick, if any, in order of urgency.
    pub fn check(&mut self, l: &Limits, s: &Sample) -> Option<FaultKind> {
        if s.current.sat_abs() > l.overcurrent {
            return Some(FaultKind::OverCurrent);
        }
        if s.delta.unsigned_abs() > l.max_counts_per_tick.unsigned_abs() {
            return Some(FaultKind::EncoderImplausible);
        }
        if count(&mut self.high_supply, s.supply > l.supply_max) >= l.supply_ticks {
            return Some(FaultKind::OverVoltage);
        }
        if count(
            &mut self.low_supply,
            s.moving && s.supply < l.supply_run_min,
        ) >= l.supply_ticks
        {
            return Some(FaultKind::UnderVoltage);
        }
        if !s.moving && s.travel_while_stopped.unsigned_abs() > l.runaway_counts.unsigned_abs() {
            return Some(FaultKind::Runaway);
        }
        // The limit is worked out only while lowering (short-circuit: ~15 instructions off
        // every other tick).
        let too_fast = s.moving && s.lowering && {
            let limit = s
                .reference
                .sat_abs()
                .sat_add(s.reference.sat_abs().scale(const { Ratio::lit("0.5") }))
                .sat_add(s.cruise.scale(const { Ratio::lit("0.25") }));
            s.speed.sat_neg() > limit
        };
        if count(&mut self.fast_lowering, too_fast) >= l.runaway_ticks {
            return Some(FaultKind::Runaway);
        }
        let no_count = s.moving && s.delta == 0;
        let turning = s.emf_speed.sat_abs() > l.turning_speed;
        if count(&mut self.blind, no_count && turning) >= l.stall_ticks {
            return Some(FaultKind::EncoderLost);
        }
        // Stalled: moving, not turning by the voltage balance (most moving ticks end here),
        // pushing — high duty (Roboteq's rule), or sitting at the current limit (at standstill
        // the limit caps the duty at R·I/V, far below any useful duty threshold) — and no
        // progress in the direction of travel: less than `CREEP_COUNTS` forward since the
        // pushing began (a jammed screw under a load beyond the motor creeps back a count now
        // and then; a screw that does not break away at the current limit lets the rotor wind
        // the coupling up at ≈ 1 rad/s, a count every ≈ 0.1 s, host-sim lithium 2× drier at
        // 1300 kg: each count had restarted the count of still ticks, and the lift pushed at
        // the limit for as long as it was let).
        let stalled = s.moving
            && !turning
            && (s.duty.unsigned_abs() >= l.stall_duty.unsigned_abs()
                || s.current.sat_abs() >= l.stall_current
                || s.lagging)
            && {
                let forward = if s.lowering {
                    s.delta.saturating_neg()
                } else {
                    s.delta
                };
                self.crept = self.crept.saturating_add(forward.max(0));
                self.crept <= CREEP_COUNTS
            };
        if !stalled {
            self.crept = 0;
        }
        if count(&mut self.still, stalled) >= l.stall_ticks {
            return Some(FaultKind::Stall);
        }
        // The margin is a fraction of the model torque's size: lowering an overhauling load the
        // projected model torque is negative, and scaling it by (1 + margin) moved the limit
        // below the model, so a motor holding back *less* than the model tripped "overload".
        // Holding back less is also what any load lighter than the rated one does (a ball
        // screw lowering half its rated load tripped): an overhauling model's limit starts
        // from zero, so only pushing the lift down (an obstruction under it) trips.
        let limit = s
            .model_torque
            .max(NewtonMetres::ZERO)
            .sat_add(qmul::<_, _, NewtonMetres>(
                s.model_torque.sat_abs(),
                l.overload_margin,
            ));
        let over =
            s.overload_armed && s.measured_torque > limit.sat_add(const { NewtonMetres::lit("2") });
        if count(&mut self.overload, over) >= l.overload_ticks {
            return Some(FaultKind::Overload);
        }
        None
    }
}

/// Forward travel, counts, under which a pushing drive makes no progress (1/180 of a screw
/// turn with the default 2880 counts: 11 µm of nut; a creeping rotor winds the coupling 2–3
/// counts in `stall_ms`; a lift at 1/8 of the default 3 rad/s cruise covers 52).
pub const CREEP_COUNTS: i32 = 16;

/// Count consecutive ticks of `cond` (reset when it clears); returns the count.
fn count(c: &mut u32, cond: bool) -> u32 {
    *c = if cond { c.saturating_add(1) } else { 0 };
    *c
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> Limits {
        // 48 counts a motor turn, 60:1, 2 mm lead: the default drive.
        let counts_per_motor_rad_q16 = (48.0 / core::f64::consts::TAU * 65536.0) as i64;
        let nut_q40 = (0.002 / 2880.0 * (1u64 << 40) as f64) as i64;
        Limits::new(
            &ProtectionConfig::DEFAULT,
            1000,
            counts_per_motor_rad_q16,
            nut_q40,
            RadiansPerSecond::from_int(3),
        )
    }

    /// Lifting at the current limit, the voltage balance saying the motor stands, with a
    /// forward count every `every` ticks: the tick the stall trips, if it does in 2 s.
    fn pushing_with_a_count_every(every: u32) -> Option<u32> {
        let l = limits();
        let mut m = Monitors::default();
        for k in 1..=2000u32 {
            let s = Sample {
                moving: true,
                lowering: false,
                duty: 8100,
                delta: i32::from(k % every == 0),
                current: Amperes::from_int(40),
                supply: Volts::lit("12.6"),
                emf_speed: RadiansPerSecond::ZERO,
                speed: RadiansPerSecond::lit("0.02"),
                reference: RadiansPerSecond::lit("0.3"),
                cruise: RadiansPerSecond::from_int(3),
                travel_while_stopped: 0,
                measured_torque: NewtonMetres::ZERO,
                model_torque: NewtonMetres::ZERO,
                overload_armed: false,
                lagging: true,
            };
            if let Some(f) = m.check(&l, &s) {
                assert_eq!(f, FaultKind::Stall);
                return Some(k);
            }
        }
        None
    }

    #[test]
    fn a_rotor_creeping_at_the_current_limit_stalls() {
        // A count every 100 ticks (the rotor winding the coupling up at ≈ 1 rad/s): the
        // stall trips after `stall_ms` as if the encoder stood (each count used to restart it).
        assert_eq!(pushing_with_a_count_every(100), Some(300));
        assert_eq!(pushing_with_a_count_every(5000), Some(300));
        // A lift at 1/8 of cruise (a count every ≈ 6 ticks) makes progress: no stall.
        assert_eq!(pushing_with_a_count_every(6), None);
    }
}
