//! The estimator's numeric envelope (docs/model.md "Numeric envelope"): inputs are clamped to
//! load 0…`LOAD_MAX`, |θ̇| ≤ `SPEED_MAX`, |θ̈| ≤ `ACCEL_MAX`, μ ≤ `mu_max`, and inside it the
//! force chain runs without saturation. The range analysis is asserted in debug builds at every
//! unsaturated narrowing (`liftfw::units::narrow`): these tests drive the model at the corners
//! of the envelope, for the corners of every validated configuration range, so a hole in the
//! analysis panics here. They also check that a clamp is flagged and that a step's tick fields
//! are the same bits as the whole estimate recomputed by `details`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use fixed::types::I16F16;
use liftfw::estimator::{
    EstimateFlags, Estimator, EstimatorConfig, Measurements, ACCEL_MAX, LOAD_MAX, SPEED_MAX,
};
use liftfw::model::friction::FrictionLaw;
use liftfw::units::{Amperes, Instant, Kilograms, RadiansPerSecond, RadiansPerSecond2, Ratio};
use liftfw_golden::corners;

/// The configurations whose constants bound the products: the default, the upper and lower
/// corners of every range, and the one that maximises the forces (steepest arms, largest
/// screw and lead, heaviest nut, μ_b = 1, the law as high as it goes).
fn configs() -> Vec<EstimatorConfig> {
    let d = EstimatorConfig::DEFAULT;
    let forces = corners::forces();
    let mut v = vec![d, corners::upper(), corners::lower(), forces];
    for law in [
        FrictionLaw::PTFE,
        FrictionLaw::LITHIUM,
        FrictionLaw::BALL_SCREW,
    ] {
        v.push(EstimatorConfig { law, ..d });
        v.push(EstimatorConfig { law, ..forces });
    }
    v
}

const fn speeds() -> [i32; 9] {
    let s = SPEED_MAX.to_bits();
    [i32::MIN, -s - 1, -s, -1, 0, 1, s, s + 1, i32::MAX]
}

#[test]
fn the_envelope_corners_neither_overflow_nor_go_unflagged() {
    let a = ACCEL_MAX.to_bits();
    let accels = [i32::MIN, -a - 1, -a, 0, a, a + 1, i32::MAX];
    let l = LOAD_MAX.to_bits();
    let loads = [i32::MIN, -1, 0, 1 << 12, l, l + 1, i32::MAX];
    let mut n = 0u32;
    for cfg in configs() {
        let est = Estimator::new(&cfg).unwrap();
        // Fully down, mid-stroke, at the top, and far outside either way.
        let top = {
            let g = est.geometry();
            let (mut lo, mut hi) = (0i64, i64::from(i32::MAX));
            while lo < hi {
                let mid = (lo + hi) / 2;
                if g.pose(mid as i32).alpha >= g.alpha_max() {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            lo as i32
        };
        let counts = [i32::MIN, -1, 0, top / 2, top, i32::MAX];
        for &c in &counts {
            for &w in &speeds() {
                for &acc in &accels {
                    for &load in &loads {
                        for current in [i32::MIN, 0, i32::MAX] {
                            for dir in [-1i8, 0, 1] {
                                let m = Measurements {
                                    position_counts: c,
                                    motor_current: Amperes::from_bits(current),
                                    load: Kilograms::from_bits(load),
                                    commanded_dir: dir,
                                };
                                let e = est.estimate(
                                    &m,
                                    RadiansPerSecond::from_bits(w),
                                    RadiansPerSecond2::from_bits(acc),
                                    0,
                                );
                                n += 1;
                                let outside = w.unsigned_abs() > SPEED_MAX.to_bits() as u32
                                    || acc.unsigned_abs() > a as u32
                                    || !(0..=l).contains(&load);
                                if outside {
                                    assert!(
                                        e.flags.has(EstimateFlags::SATURATED),
                                        "clamp not flagged: {m:?} {w} {acc}"
                                    );
                                }
                                assert!(e.screw_speed.sat_abs() <= SPEED_MAX);
                                assert!(e.screw_accel.sat_abs() <= ACCEL_MAX);
                                assert!(e.mu >= Ratio::ZERO && e.mu <= Ratio::lit("4"));
                                // T_r opposes the motion whatever the inputs (no wrap).
                                let tr = e.contact.friction_torque.to_f64();
                                assert!(tr * e.contact.mu_s.to_f64() >= 0.0, "{m:?}");
                            }
                        }
                    }
                }
            }
        }
    }
    assert!(n > 50_000, "{n}");
}

#[test]
fn a_direct_drive_with_a_lossy_coupling_is_refused_not_wrapped() {
    // 1/(n·η) would be 10 and wrap the Q28 factor the motor torque is scaled by.
    let mut cfg = EstimatorConfig::DEFAULT;
    cfg.drive.gear_ratio = I16F16::ONE;
    cfg.motor.gear_efficiency = Ratio::lit("0.1");
    match Estimator::new(&cfg) {
        Err(liftfw::ConfigError::Conflict { field, .. }) => {
            assert_eq!(field, "motor.gear_efficiency")
        }
        other => panic!("expected a conflict, got {:?}", other.map(|_| ())),
    }
    cfg.drive.gear_ratio = I16F16::lit("1.25002");
    assert!(Estimator::new(&cfg).is_ok());
}

#[test]
fn a_step_returns_the_same_bits_as_its_details() {
    for cfg in configs() {
        let mut est = Estimator::new(&cfg).unwrap();
        let mut x: u64 = 0x2545_F491_4F6C_DD1D;
        let mut counts = 10_000i32;
        for k in 0..400u32 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            // A motion with an occasional encoder glitch.
            counts = if k % 97 == 13 {
                x as i32
            } else {
                counts.wrapping_add((x % 5) as i32 - 1)
            };
            let m = Measurements {
                position_counts: counts,
                motor_current: Amperes::from_bits((x >> 32) as i32 >> 8),
                load: Kilograms::from_bits(((x >> 20) % (3000 << 12)) as i32),
                commanded_dir: (x % 3) as i8 - 1,
            };
            let t = est.step(Instant(k * cfg.tick_us), &m);
            let e = est.details(&m, &t);
            assert_eq!(t.height, e.pose.height);
            assert_eq!(t.screw_speed, e.screw_speed);
            assert_eq!(t.screw_accel, e.screw_accel);
            assert_eq!(t.friction_torque, e.contact.friction_torque);
            assert_eq!(t.axial, e.contact.axial);
            assert_eq!(t.thread_torque, e.contact.thread_torque);
            assert_eq!(t.model_screw_torque, e.model_screw_torque);
            assert_eq!(t.model_motor_torque, e.model_motor_torque);
            assert_eq!(t.measured_screw_torque, e.measured_screw_torque);
            assert_eq!(t.flags, e.flags);
        }
    }
}
