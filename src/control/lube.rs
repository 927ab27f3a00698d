//! Online identification of a ball screw's friction coefficient f from the motor current
//! (seed 002's Eq 2, [`BallScrew::identify`]), and the lubrication/wear warning built on it.
//!
//! **Why lifting *and* lowering.** At steady speed the screw torque is `T = W·l/(2π) ± f·F·arm`
//! (+ lifting, − lowering; F = preload + W): one equation in two unknowns, the friction f and
//! the axial load W, which depends on the car on the lift and is not measured. A lift and the
//! following lowering carry the same car, so together they determine both: with
//! `W = x·W_rated` (x the load as a fraction of the model's rated-load axial force at the same
//! pose), Eq 2 applied to the lift's mean torque gives `f_up(x)`, falling with x, and applied to
//! the lowering's gives `f_down(x)`, rising with x; the identified x is where they agree
//! (bisection), and f is their value there. A constant drive friction the model does not know
//! (motor brushes, gearbox no-load torque) raises the lift's torque and lowers the lowering's,
//! just like screw friction: it must be in `mech.support_torque` (referred to the screw) for f
//! to be unbiased.
//!
//! **Where the current means something.** A tick is a sample only while driving at a constant
//! reference (cruise, not ramping) of at least `ballscrew.ident_min_speed`, for
//! [`SETTLE_MS`] since the reference became constant (the coupling winds up and the speed
//! filter settles), with the measured speed within 50 % of the reference (stick-slip bursts
//! are kept: the mean torque over them is the mean friction). From each sample it keeps the measured *thread* torque (the measured
//! screw torque less the model's support, damping and inertia torques) and the model's axial
//! demand at the rated load; a motion's means are its samples' sums over their count.
//!
//! **Pairing.** When a motion with at least [`MIN_SAMPLES`] ends, its means replace the last
//! ones of its direction; when both directions have means, the pair is solved (a few dozen
//! integer divisions, once per motion). A motion that ends at the lower stop forgets both: the
//! car may be changed there. A motion that ends in a fault is dropped.
//!
//! **Warning.** The identified f is compared with the law's f(τ) at the pair's mean speed and
//! identified axial force; outside `law·(1 ± ballscrew.lube_band)` the controller reports
//! [`crate::control::Event::Lubrication`] (the console prints a `warning:` line).

// The ball-screw build uses every import; the lead-screw build only the configuration's.
#![cfg_attr(not(feature = "ball-screw"), allow(unused_imports))]
use crate::estimator::MotorConfig;
use crate::keys::{self, check_range, ConfigError};
#[cfg(feature = "ball-screw")]
use crate::model::ballscrew::{BallScrew, FrictionIdentifier};
use crate::units::{
    qmul, sat32, Amperes, Kilograms, NewtonMetres, Newtons, RadiansPerSecond, Ratio, Q,
};
use fixed::types::I16F16;

/// The identification's and the warning's settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LubeConfig {
    /// Warn when the identified f leaves `law·(1 ± band)`, 0.05…4.
    pub band: Ratio,
    /// Slowest reference speed at which the current is used, 0.05…20 rad/s.
    pub min_speed: RadiansPerSecond,
    /// Motor current with the gearbox output uncoupled, at the cruise speed, 0…20 A: the
    /// drive's own friction (motor and gearbox), which the identification removes at the screw
    /// as k_t·I₀·n·η lifting and k_t·I₀·n/η lowering.
    pub no_load_current: Amperes,
}

impl LubeConfig {
    /// ±50 % around the law; samples at 0.5 rad/s and faster; the default motor's no-load
    /// current at a 1.5 rad/s cruise (0.02 N·m Coulomb + 2·10⁻⁵ N·m·s/rad × 90 rad/s over
    /// k_t = 0.04 N·m/A, docs/plant.md). Without it the identified f came out 76 % (rated load)
    /// and 180 % (half load) too high in host-sim: the lowering's friction torque is little
    /// more than the drive's own.
    pub const DEFAULT: LubeConfig = LubeConfig {
        band: Ratio::lit("0.5"),
        min_speed: RadiansPerSecond::lit("0.5"),
        no_load_current: Amperes::lit("0.545"),
    };

    /// Check the ranges.
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range(
            self.band,
            const { Ratio::lit("0.05") },
            const { Ratio::lit("4") },
            &keys::BALLSCREW_LUBE_BAND,
        )?;
        check_range(
            self.min_speed,
            const { RadiansPerSecond::lit("0.05") },
            const { RadiansPerSecond::lit("20") },
            &keys::BALLSCREW_IDENT_MIN_SPEED,
        )?;
        check_range(
            self.no_load_current,
            Amperes::ZERO,
            const { Amperes::lit("20") },
            &keys::BALLSCREW_NO_LOAD_CURRENT,
        )
    }
}

/// Time a constant reference must have lasted before the current is used, ms.
#[cfg(feature = "ball-screw")]
pub const SETTLE_MS: u32 = 200;
/// Fewest samples that make a motion's means usable (0.2 s at 1 kHz).
#[cfg(feature = "ball-screw")]
pub const MIN_SAMPLES: u32 = 200;

/// One motion's sums.
#[cfg(feature = "ball-screw")]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Sums {
    torque: i64,
    axial: i64,
    speed: i64,
    n: u32,
}

#[cfg(feature = "ball-screw")]
impl Sums {
    fn add(&mut self, torque: NewtonMetres, axial: Newtons, speed: RadiansPerSecond) {
        self.torque = self.torque.saturating_add(i64::from(torque.bits()));
        self.axial = self.axial.saturating_add(i64::from(axial.bits()));
        self.speed = self
            .speed
            .saturating_add(i64::from(speed.bits().unsigned_abs().min(i32::MAX as u32)));
        self.n = self.n.saturating_add(1);
    }

    fn mean(&self, sum: i64) -> i32 {
        sat32(sum / i64::from(self.n.max(1)))
    }

    fn torque(&self) -> NewtonMetres {
        NewtonMetres::from_raw(self.mean(self.torque))
    }

    fn axial(&self) -> Newtons {
        Newtons::from_raw(self.mean(self.axial))
    }

    fn speed(&self) -> RadiansPerSecond {
        RadiansPerSecond::from_raw(self.mean(self.speed))
    }
}

/// What a solved lift/lowering pair says.
#[cfg(feature = "ball-screw")]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LubeReport {
    /// Identified friction coefficient (average of the pairs, see [`FrictionIdentifier`]).
    pub f: Ratio,
    /// Of the latest pair alone.
    pub f_last: Ratio,
    /// The law's f(τ) at the latest pair's mean speed and identified axial force.
    pub law: Ratio,
    /// The load on the lift identified with it (the rated load times the identified fraction).
    pub load: Kilograms,
    /// Pairs solved since boot.
    pub pairs: u32,
    /// The latest pair's f is outside the band around the law.
    pub out_of_band: bool,
}

/// Solve a lift's and a lowering's means for the load fraction x and f (see the module doc).
/// `None` when no x in 0.02…4 makes them agree (not a pair of the same load, or a model that
/// does not fit: no warning is drawn from it).
#[cfg(feature = "ball-screw")]
fn solve(bs: &BallScrew, up: &Sums, down: &Sums) -> Option<(Ratio, Ratio, Ratio)> {
    solve_pair(bs, (up.torque(), up.axial()), (down.torque(), down.axial()))
}

/// The pair solve on mean values: `up` and `down` are (thread torque, rated-load axial demand)
/// of a lift and a lowering. Returns the load fraction x (to 1 LSB, by bisection on
/// 0.02…4) and Eq 2's f of each direction there. `None` when no x in that range makes them
/// agree, when either demand is not positive, or when the f it needs is negative. Error
/// against the float64 twin: `tests/ballscrew_vs_float_twin.rs`.
#[cfg(feature = "ball-screw")]
pub fn solve_pair(
    bs: &BallScrew,
    up: (NewtonMetres, Newtons),
    down: (NewtonMetres, Newtons),
) -> Option<(Ratio, Ratio, Ratio)> {
    let ((tu, wu), (td, wd)) = (up, down);
    // Both directions must be load-driven, the lowering by at least 1/8 of the lift's demand:
    // where the pins' friction takes nearly all of the load's push while lowering (high arm
    // angles), the lowering's friction torque drowns in the drive's own and the two no longer
    // tell load and friction apart (beyond it the lowering needs torque like a lift does).
    if wu <= Newtons::ZERO || wd < Newtons::from_raw(wu.bits() >> 3) {
        return None;
    }
    let at = |x: Ratio| -> Option<(Ratio, Ratio)> {
        let fu = bs.identify(tu, qmul(x, wu), true)?;
        let fd = bs.identify(td, qmul(x, wd), false)?;
        Some((fu, fd))
    };
    let (mut lo, mut hi) = (
        const { Ratio::lit("0.02") }.bits(),
        const { Ratio::lit("4") }.bits(),
    );
    let (fu, fd) = at(Ratio::from_raw(lo))?;
    if fu < fd {
        return None;
    }
    let (fu, fd) = at(Ratio::from_raw(hi))?;
    if fu > fd {
        return None;
    }
    // f_up − f_down falls with x: halve the bracket to 1 LSB of x (≤ 32 steps).
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        let (fu, fd) = at(Ratio::from_raw(mid))?;
        if fu >= fd {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let x = Ratio::from_raw(lo);
    let (fu, fd) = at(x)?;
    // Friction is never negative: a pair that needs it is not a lift and a lowering of one load.
    if fu < Ratio::ZERO || fd < Ratio::ZERO {
        return None;
    }
    Some((x, fu, fd))
}

/// The identification's state (kept by the controller in ball-screw mode).
#[cfg(feature = "ball-screw")]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LubeMonitor {
    run: Sums,
    run_lifting: bool,
    /// The last usable lift's and lowering's sums (n = 0: none).
    up: Sums,
    down: Sums,
    steady_ticks: u32,
    prev_reference: RadiansPerSecond,
    settle_ticks: u32,
    min_samples: u32,
    identifier: FrictionIdentifier,
    report: Option<LubeReport>,
    in_motion: bool,
    /// The drive's no-load torque at the screw, lifting (×n·η) and lowering (×n/η).
    drive_up: NewtonMetres,
    drive_down: NewtonMetres,
}

/// What the controller hands the monitor each tick.
#[cfg(feature = "ball-screw")]
#[derive(Clone, Copy, Debug)]
pub struct LubeInputs {
    /// Lifting or lowering, driven by the bridge on the previous tick.
    pub driving: bool,
    /// Lifting (else lowering).
    pub lifting: bool,
    /// The profile's speed reference (signed).
    pub reference: RadiansPerSecond,
    /// Estimated screw speed (signed).
    pub speed: RadiansPerSecond,
    /// Measured screw torque less the model's support, damping and inertia torques.
    pub thread_torque: NewtonMetres,
    /// The model's axial demand at the rated load.
    pub axial_rated: Newtons,
}

#[cfg(feature = "ball-screw")]
impl LubeMonitor {
    /// A monitor for (validated) settings: the drive friction's no-load current (`cfg`), the
    /// motor's k_t and gear efficiency, the gear ratio and the tick.
    pub fn new(cfg: &LubeConfig, m: &MotorConfig, gear_ratio: I16F16, tick_us: u32) -> LubeMonitor {
        let t = |ms: u32| crate::units::ms_to_ticks(ms, tick_us);
        // k_t·I₀·n at the screw (Q16), then through the gearbox either way.
        let t_motor: NewtonMetres = qmul(cfg.no_load_current, m.torque_constant);
        let n = i64::from(gear_ratio.to_bits()); // Q16
        let t0 = NewtonMetres::from_raw(sat32((i64::from(t_motor.bits()) * n) >> 16));
        let eta = m.gear_efficiency.max(const { Ratio::lit("0.1") });
        LubeMonitor {
            run: Sums::default(),
            run_lifting: true,
            up: Sums::default(),
            down: Sums::default(),
            steady_ticks: 0,
            prev_reference: RadiansPerSecond::ZERO,
            settle_ticks: t(SETTLE_MS),
            min_samples: t(MIN_SAMPLES).max(1),
            // Averages the last few pairs (both directions' f of each), min. 100 N of force.
            identifier: FrictionIdentifier::new(Ratio::ZERO, 2, const { Newtons::lit("100") }),
            report: None,
            in_motion: false,
            drive_up: qmul(t0, eta),
            drive_down: crate::units::qdiv(t0, eta),
        }
    }

    /// One tick while moving: add a sample if the measurement is valid.
    pub fn sample(&mut self, cfg: &LubeConfig, x: &LubeInputs) {
        self.in_motion = true;
        if self.run.n > 0 && self.run_lifting != x.lifting {
            // A reversal without a rest between: the other direction's samples are not mixed in.
            self.run = Sums::default();
        }
        self.run_lifting = x.lifting;
        let constant = x.reference == self.prev_reference;
        self.prev_reference = x.reference;
        let r = x.reference.sat_abs();
        if !(x.driving && constant && r >= cfg.min_speed) {
            self.steady_ticks = 0;
            return;
        }
        self.steady_ticks = self.steady_ticks.saturating_add(1);
        // Eq 1 with |R| = R: only where the load pushes the nut the way the model says.
        if self.steady_ticks <= self.settle_ticks || x.axial_rated <= Newtons::ZERO {
            return;
        }
        // Following the reference (a jammed or current-limited screw is not at steady speed):
        // within 50 %. Stick-slip bursts stay in: the mean torque over them is still the
        // screw's mean friction (rejecting the fast or slow ticks would bias it).
        let err = x.speed.sat_sub(x.reference).sat_abs();
        if err > RadiansPerSecond::from_raw(r.bits() >> 1) {
            return;
        }
        // The drive's friction opposes the motion: it raised the lift's measured torque and
        // lowered the lowering's.
        let t = if x.lifting {
            x.thread_torque.sat_sub(self.drive_up)
        } else {
            x.thread_torque.sat_add(self.drive_down)
        };
        self.run.add(t, x.axial_rated, x.speed);
    }

    /// The lift came to rest (or faulted): close the motion's sums, solve a pair if there is
    /// one, and forget both directions if it stopped at the lower stop. Returns the new report
    /// when a pair was solved. Out of line: it runs once per motion, and inlined it would sit in
    /// the control task's poll with the tick.
    #[inline(never)]
    pub fn end_motion(
        &mut self,
        bs: &BallScrew,
        cfg: &LubeConfig,
        rated: Kilograms,
        at_lower_stop: bool,
    ) -> Option<LubeReport> {
        self.steady_ticks = 0;
        self.in_motion = false;
        self.prev_reference = RadiansPerSecond::ZERO;
        let run = core::mem::take(&mut self.run);
        let mut solved = None;
        if run.n >= self.min_samples {
            if self.run_lifting {
                self.up = run;
            } else {
                self.down = run;
            }
            if self.up.n > 0 && self.down.n > 0 {
                let (up, down) = (self.up, self.down);
                solved = self.solve_pair(bs, cfg, rated, &up, &down);
            }
        }
        if at_lower_stop {
            self.up = Sums::default();
            self.down = Sums::default();
        }
        solved
    }

    fn solve_pair(
        &mut self,
        bs: &BallScrew,
        cfg: &LubeConfig,
        rated: Kilograms,
        up: &Sums,
        down: &Sums,
    ) -> Option<LubeReport> {
        let (x, fu, fd) = solve(bs, up, down)?;
        let (lu, ld): (Newtons, Newtons) = (qmul(x, up.axial()), qmul(x, down.axial()));
        self.identifier.update(bs, up.torque(), lu, true);
        self.identifier.update(bs, down.torque(), ld, false);
        let f_last = Ratio::from_raw(sat32((i64::from(fu.bits()) + i64::from(fd.bits())) / 2));
        let speed = RadiansPerSecond::from_raw(sat32(
            (i64::from(up.speed().bits()) + i64::from(down.speed().bits())) / 2,
        ));
        let law = bs.coefficient(bs.tau(speed, bs.axial_force(lu)));
        let dev = f_last.sat_sub(law).sat_abs();
        let allowed: Ratio = qmul(law, cfg.band);
        let report = LubeReport {
            f: self.identifier.estimate(),
            f_last,
            law,
            load: qmul(x, rated),
            pairs: self.report.map_or(0, |r| r.pairs).saturating_add(1),
            out_of_band: dev > allowed,
        };
        self.report = Some(report);
        Some(report)
    }

    /// Drop the motion under way (it ended in a fault); the pairs kept so far stay.
    pub fn abort_motion(&mut self) {
        self.run = Sums::default();
        self.in_motion = false;
        self.steady_ticks = 0;
        self.prev_reference = RadiansPerSecond::ZERO;
    }

    /// The latest report, if a pair has been solved.
    pub fn report(&self) -> Option<LubeReport> {
        self.report
    }

    /// Samples in the motion under way.
    pub fn samples(&self) -> u32 {
        self.run.n
    }

    /// A motion has been sampled (valid or not) since the last [`LubeMonitor::end_motion`].
    pub fn in_motion(&self) -> bool {
        self.in_motion
    }
}

#[cfg(all(test, feature = "ball-screw"))]
mod tests {
    use super::*;
    use crate::model::ballscrew::BallScrewConfig;

    /// Means of one direction for a true load `w` N (at a rated-load demand `w_rated`) and a
    /// true f: the screw torque seed 002's Eq 1 gives.
    fn sums(bs: &BallScrew, f: f64, w: f64, w_rated: f64, lifting: bool) -> Sums {
        let fa = bs.preload().to_f64() + w;
        let lever = bs.lever().to_f64();
        let mf = f * fa * bs.arm().to_f64();
        let t = if lifting {
            w * lever + mf
        } else {
            w * lever - mf
        };
        let mut s = Sums::default();
        for _ in 0..1000 {
            s.add(
                NewtonMetres::from_f64(t),
                Newtons::from_f64(w_rated),
                RadiansPerSecond::from_f64(if lifting { 1.5 } else { -1.5 }),
            );
        }
        s
    }

    #[test]
    fn a_pair_recovers_load_and_f_with_and_without_preload() {
        for preload in [0.0, 2000.0] {
            let mut c = BallScrewConfig::SEED_001_4008;
            c.preload = Newtons::from_f64(preload);
            let bs = c.compile().unwrap();
            for (f, frac) in [(0.005, 1.0), (0.005, 0.5), (0.012, 0.3), (0.002, 1.7)] {
                // Pin friction makes the lift's demand larger than the lowering's.
                let (wu, wd) = (10_400.0, 9_200.0);
                let up = sums(&bs, f, frac * wu, wu, true);
                let down = sums(&bs, f, frac * wd, wd, false);
                let (x, fu, fd) = solve(&bs, &up, &down).unwrap();
                assert!(
                    (x.to_f64() - frac).abs() < 1e-3 * frac,
                    "{preload} {f} {frac}: x {x:?}"
                );
                for g in [fu, fd] {
                    assert!(
                        (g.to_f64() - f).abs() < 2e-3 * f + 1e-6,
                        "{f} {frac}: {g:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn inconsistent_means_are_not_solved() {
        let bs = BallScrewConfig::SEED_001_4008.compile().unwrap();
        // Lowering needs more torque than lifting: no load and f ≥ 0 explain that.
        let up = sums(&bs, 0.005, 5000.0, 10_000.0, false);
        let down = sums(&bs, 0.005, 5000.0, 10_000.0, true);
        assert_eq!(solve(&bs, &up, &down), None);
    }

    /// Feed `ticks` ticks of one steady motion (after a 100-tick ramp) at the torque Eq 1 gives.
    fn motion(m: &mut LubeMonitor, bs: &BallScrew, lifting: bool, w: f64, ticks: u32) {
        let cfg = LubeConfig::DEFAULT;
        let s = sums(bs, 0.005, w, 10_000.0, lifting);
        let cruise = if lifting { 1.5 } else { -1.5 };
        for k in 0..ticks + 100 {
            // Ramping for 100 ticks: the reference changes every tick, no sample.
            let r = cruise * f64::from(k.min(100)) / 100.0;
            m.sample(
                &cfg,
                &LubeInputs {
                    driving: true,
                    lifting,
                    reference: RadiansPerSecond::from_f64(r),
                    speed: RadiansPerSecond::from_f64(r),
                    thread_torque: s.torque(),
                    axial_rated: Newtons::from_f64(10_000.0),
                },
            );
        }
    }

    #[test]
    fn a_lift_and_a_lowering_make_a_pair_and_the_lower_stop_forgets_them() {
        let bs = BallScrewConfig::SEED_001_4008.compile().unwrap();
        let e = crate::estimator::EstimatorConfig::DEFAULT;
        let cfg = LubeConfig {
            no_load_current: Amperes::ZERO,
            ..LubeConfig::DEFAULT
        };
        let mut m = LubeMonitor::new(&cfg, &e.motor, e.drive.gear_ratio, 1000);
        let rated = Kilograms::lit("1000");
        // The reference is constant from tick 101: 200 settling ticks, then 149 samples: too few.
        motion(&mut m, &bs, true, 6000.0, 350);
        assert_eq!(m.samples(), 149);
        assert_eq!(m.end_motion(&bs, &cfg, rated, false), None);
        // Enough, but one direction only.
        motion(&mut m, &bs, true, 6000.0, 600);
        assert_eq!(m.samples(), 399);
        assert_eq!(m.end_motion(&bs, &cfg, rated, false), None);
        motion(&mut m, &bs, false, 6000.0, 600);
        let r = m.end_motion(&bs, &cfg, rated, true).expect("a pair");
        assert!((r.f.to_f64() - 0.005).abs() < 1e-5, "{r:?}");
        assert!((r.load.to_f64() - 600.0).abs() < 1.0, "{r:?}");
        assert!(!r.out_of_band && r.pairs == 1);
        assert_eq!(m.report(), Some(r));
        // It stopped at the lower stop: the next lowering alone is no pair.
        motion(&mut m, &bs, false, 6000.0, 600);
        assert_eq!(m.end_motion(&bs, &cfg, rated, false), None);
        // A lift that ends in a fault is dropped: still no pair.
        motion(&mut m, &bs, true, 6000.0, 600);
        m.abort_motion();
        assert!(!m.in_motion());
        assert_eq!(m.end_motion(&bs, &cfg, rated, false), None);
    }

    #[test]
    fn band_is_validated() {
        let mut c = LubeConfig::DEFAULT;
        c.validate().unwrap();
        c.band = Ratio::lit("0.01");
        assert!(c.validate().is_err());
        c = LubeConfig::DEFAULT;
        c.no_load_current = Amperes::lit("-1");
        assert!(c.validate().is_err());
    }
}
