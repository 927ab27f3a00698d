//! The estimator configurations at the corners of the validated ranges, shared by the golden
//! vectors ([`crate::config`]) and, through the root package's dev-dependency, the envelope
//! tests (tests/estimator_envelope.rs) and the float-twin cancellation search
//! (tests/model_vs_float_twin.rs): one definition, so all of them test the same corners.

use fixed::types::{I16F16, I32F32};
use liftfw::estimator::{EstimatorConfig, MotorConfig};
use liftfw::model::friction::{FrictionLaw, LawVariable};
use liftfw::model::geometry::{DriveConfig, GeometryConfig};
use liftfw::model::screw::MechanicsConfig;
use liftfw::units::{Kilograms, Metres, NewtonMetres, RadiansPerSecond, Ratio};

/// The friction law as high as it goes.
pub fn high_law() -> FrictionLaw {
    FrictionLaw {
        base: Ratio::ONE,
        amp: Ratio::ONE,
        rate: I32F32::lit("1000000"),
        slope: I32F32::lit("1000"),
        s_max: I32F32::MAX,
        variable: LawVariable::SlidingSpeed,
    }
}

/// The heaviest mechanics the ranges allow.
pub fn big_mech() -> MechanicsConfig {
    MechanicsConfig {
        inertia_ukgm2: 100_000,
        damping_unms: 1_000_000,
        support_torque: NewtonMetres::lit("10"),
        nut_mass: Kilograms::lit("5"),
        ..MechanicsConfig::DEFAULT
    }
}

/// The upper corner of every range, with the highest law.
pub fn upper() -> EstimatorConfig {
    EstimatorConfig {
        geometry: GeometryConfig {
            length: Metres::lit("2"),
            alpha0_deg: I16F16::lit("60"),
            alpha_max_deg: I16F16::lit("89"),
            h0: Metres::lit("1"),
            mu_pin: Ratio::ONE,
        },
        drive: DriveConfig {
            counts_per_rev: 65_536,
            gear_ratio: I16F16::lit("1000"),
            pitch_radius: Metres::lit("0.05"),
            lead_angle_deg: I16F16::lit("20"),
        },
        mechanics: big_mech(),
        law: high_law(),
        motor: MotorConfig {
            torque_constant: Ratio::ONE,
            gear_efficiency: Ratio::lit("0.1"),
            ..MotorConfig::DEFAULT
        },
        tick_us: 100,
        speed_bandwidth_hz: 1000,
        rest_speed: RadiansPerSecond::lit("50"),
    }
}

/// The lower corner of every range, with the lowest law (μ falling to −1 and below).
pub fn lower() -> EstimatorConfig {
    EstimatorConfig {
        geometry: GeometryConfig {
            length: Metres::lit("0.05"),
            alpha0_deg: I16F16::lit("12"),
            alpha_max_deg: I16F16::lit("17"),
            h0: Metres::ZERO,
            mu_pin: Ratio::ZERO,
        },
        drive: DriveConfig {
            counts_per_rev: 4,
            gear_ratio: I16F16::ONE,
            pitch_radius: Metres::lit("0.001"),
            lead_angle_deg: I16F16::lit("0.5"),
        },
        mechanics: MechanicsConfig {
            inertia_ukgm2: 0,
            damping_unms: 0,
            support_torque: NewtonMetres::ZERO,
            nut_mass: Kilograms::ZERO,
            ..MechanicsConfig::DEFAULT
        },
        law: FrictionLaw {
            base: Ratio::ZERO,
            amp: Ratio::ONE.sat_neg(),
            rate: I32F32::ZERO,
            slope: I32F32::lit("-1000"),
            s_max: I32F32::MAX,
            variable: LawVariable::ScrewRate,
        },
        motor: MotorConfig {
            torque_constant: Ratio::lit("0.001"),
            gear_efficiency: Ratio::ONE,
            ..MotorConfig::DEFAULT
        },
        tick_us: 10_000,
        speed_bandwidth_hz: 1,
        rest_speed: RadiansPerSecond::ZERO,
    }
}

/// The configuration that maximises the forces: steepest arms, largest screw and lead,
/// heaviest nut, μ_b = 1, the highest law.
pub fn forces() -> EstimatorConfig {
    EstimatorConfig {
        geometry: GeometryConfig {
            alpha0_deg: I16F16::lit("12"),
            mu_pin: Ratio::ONE,
            ..GeometryConfig::DEFAULT
        },
        drive: DriveConfig {
            counts_per_rev: 4,
            // The smallest n with η = 0.1 that `Estimator::new` accepts (n·η > 1/8).
            gear_ratio: I16F16::lit("1.25002"),
            pitch_radius: Metres::lit("0.05"),
            lead_angle_deg: I16F16::lit("20"),
        },
        mechanics: big_mech(),
        law: high_law(),
        motor: MotorConfig {
            torque_constant: Ratio::ONE,
            gear_efficiency: Ratio::lit("0.1"),
            ..MotorConfig::DEFAULT
        },
        ..EstimatorConfig::DEFAULT
    }
}
