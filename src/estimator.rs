//! The real-time friction-torque estimator: `step(now, measurements) -> Estimate`.
//!
//! Every control tick it turns the motor encoder position and current into the model's view of
//! the screw-nut contact (α, R, F₀, μ_s, N, T_r, the torque the model says the motor needs) and
//! compares it with the torque the motor actually delivers (k_t·i through the gearbox). The
//! residual is the basis of overload, obstruction and lubrication diagnostics.
//!
//! Speed and acceleration come from a fading-memory α-β-γ tracking filter on the encoder count
//! (three coincident discrete poles at `e^(−2π·f_b·T)`): it has no lag for constant acceleration,
//! and its bandwidth `f_b` (default 40 Hz at a 1 kHz tick) trades count-quantisation noise against
//! lag. docs/model.md gives the design and the measured step response.

use crate::math::{div128, exp_neg_q16};
use crate::model::friction::{CompiledLaw, FrictionLaw};
use crate::model::geometry::{DriveConfig, Geometry, GeometryConfig, Pose};
use crate::model::screw::{Contact, MechanicsConfig, ScrewModel};
use crate::model::Scale;
use crate::units::{
    qmul, sat32, Amperes, Factor, Instant, Kilograms, KilogramsPerSecond, NewtonMetres, Newtons,
    RadiansPerSecond, RadiansPerSecond2, Ratio, Q,
};
use crate::ConfigError;

/// Motor and gearbox constants.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotorConfig {
    /// Torque constant k_t, N·m/A (0.001…1).
    pub torque_constant: Ratio,
    /// Gearbox efficiency, 0.1…1.
    pub gear_efficiency: Ratio,
    /// Resistance of the motor loop (armature + bridge + battery + leads), Ω, 0.001…4: the
    /// speed loop's feed-forward needs it to turn a torque into a voltage.
    pub resistance: Ratio,
}

impl MotorConfig {
    /// A 12 V gear motor of the jack class: k_t = 0.04 N·m/A, gearbox efficiency 0.85, loop
    /// resistance 0.091 Ω (60 mΩ armature + 16 mΩ bridge + 15 mΩ battery): the default board's
    /// motor, the same values as host-sim's drive (docs/plant.md).
    pub const DEFAULT: MotorConfig = MotorConfig {
        torque_constant: Ratio::lit("0.04"),
        gear_efficiency: Ratio::lit("0.85"),
        resistance: Ratio::lit("0.091"),
    };
}

/// Everything the estimator needs, as configured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EstimatorConfig {
    /// Scissor geometry.
    pub geometry: GeometryConfig,
    /// Encoder, gearbox and screw.
    pub drive: DriveConfig,
    /// Screw assembly mechanics.
    pub mechanics: MechanicsConfig,
    /// Friction law of the screw-nut contact.
    pub law: FrictionLaw,
    /// Motor and gearbox.
    pub motor: MotorConfig,
    /// Control tick period, µs (100…10 000).
    pub tick_us: u32,
    /// Speed-filter pole frequency, Hz (1…tick rate/10).
    pub speed_bandwidth_hz: u32,
    /// Below this screw speed the contact counts as at rest, rad/s.
    pub rest_speed: RadiansPerSecond,
}

impl EstimatorConfig {
    /// The default lift with dry/boundary friction at 1 kHz.
    pub const DEFAULT: EstimatorConfig = EstimatorConfig {
        geometry: GeometryConfig::DEFAULT,
        drive: DriveConfig::DEFAULT,
        mechanics: MechanicsConfig::DEFAULT,
        law: FrictionLaw::DRY,
        motor: MotorConfig::DEFAULT,
        tick_us: 1000,
        speed_bandwidth_hz: 40,
        rest_speed: RadiansPerSecond::lit("0.5"),
    };
}

/// What the board measured this tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Measurements {
    /// Motor encoder position, counts from fully down.
    pub position_counts: i32,
    /// Motor current, signed (positive drives lifting).
    pub motor_current: Amperes,
    /// The load the model assumes (the rated load unless the caller knows better).
    pub load: Kilograms,
    /// Commanded direction (−1, 0, +1): the friction direction while the screw is at rest.
    pub commanded_dir: i8,
}

/// Conditions the estimate was computed under (bit set).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct EstimateFlags(pub u8);

impl EstimateFlags {
    /// The position lay outside the mechanism and was clamped.
    pub const POSE_CLAMPED: u8 = 1 << 0;
    /// The screw is at rest: friction direction taken from the command (or zero).
    pub const AT_REST: u8 = 1 << 1;
    /// A quantity hit its saturation bound: the numbers are bounds, not values.
    pub const SATURATED: u8 = 1 << 2;
    /// The tick came late (more than 1.5 periods after the previous one).
    pub const LATE_TICK: u8 = 1 << 3;
    /// The other thread flank carries the load (net axial force reversed).
    pub const FLANK_REVERSED: u8 = 1 << 4;

    /// Whether `flag` is set.
    pub fn has(self, flag: u8) -> bool {
        self.0 & flag != 0
    }
}

/// The estimator's output for one tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Estimate {
    /// Geometry at the measured position (α, height, travel).
    pub pose: Pose,
    /// Screw speed θ̇ from the tracking filter.
    pub screw_speed: RadiansPerSecond,
    /// Screw acceleration θ̈ from the tracking filter.
    pub screw_accel: RadiansPerSecond2,
    /// Axial load R (Eq 1).
    pub axial_load: Newtons,
    /// Pin friction F₀ (Eq 6).
    pub pin_friction: Newtons,
    /// Structure damping c_x(α).
    pub structure_damping: KilogramsPerSecond,
    /// Friction coefficient magnitude μ.
    pub mu: Ratio,
    /// Contact: μ_s, ξ, N, T_r, thread torque.
    pub contact: Contact,
    /// Torque the model says the screw needs from the coupling.
    pub model_screw_torque: NewtonMetres,
    /// The same at the motor shaft (through gear ratio and efficiency).
    pub model_motor_torque: NewtonMetres,
    /// Torque the motor delivers to the screw, from its current.
    pub measured_screw_torque: NewtonMetres,
    /// measured − model, at the screw.
    pub residual: NewtonMetres,
    /// μ − tan λ (self-locking while positive).
    pub self_locking_margin: Ratio,
    /// Conditions of this estimate.
    pub flags: EstimateFlags,
}

/// The estimator's configuration and state.
#[derive(Clone, Debug)]
pub struct Estimator {
    geometry: Geometry,
    screw: ScrewModel,
    law: CompiledLaw,
    kt: Ratio,
    /// n·η, n/η as factors; η/n, 1/(n·η) as ratios.
    n_eta: Factor,
    n_over_eta: Factor,
    eta_over_n: Ratio,
    inv_n_eta: Ratio,
    rest_speed: RadiansPerSecond,
    /// α, β, 2γ in Q28 (each ≤ 1).
    gains: [i32; 3],
    speed_scale: Scale,
    accel_scale: Scale,
    /// A tick later than this (1.5 periods, µs) is flagged late.
    late_us: u32,
    // Filter state: the last count; position relative to it, speed and acceleration in Q16
    // counts, counts/tick, counts/tick².
    last_counts: i32,
    q: i32,
    v: i32,
    a: i32,
    last: Option<Instant>,
}

impl Estimator {
    /// Validate the configuration and quantise it once.
    pub fn new(cfg: &EstimatorConfig) -> Result<Estimator, ConfigError> {
        let geometry = Geometry::new(cfg.geometry, cfg.drive)?;
        let screw = ScrewModel::new(&cfg.drive, &cfg.mechanics)?;
        let law = cfg
            .law
            .compile(cfg.drive.pitch_radius, screw.cos_lambda())?;
        let m = &cfg.motor;
        if !(m.torque_constant >= const { Ratio::lit("0.001") } && m.torque_constant <= Ratio::ONE)
        {
            return Err(ConfigError::OutOfRange {
                field: "motor.kt",
                range: "0.001..1 Nm/A",
            });
        }
        if !(m.gear_efficiency >= const { Ratio::lit("0.1") } && m.gear_efficiency <= Ratio::ONE) {
            return Err(ConfigError::OutOfRange {
                field: "motor.gear_efficiency",
                range: "0.1..1",
            });
        }
        if !(m.resistance >= const { Ratio::lit("0.001") }
            && m.resistance <= const { Ratio::lit("4") })
        {
            return Err(ConfigError::OutOfRange {
                field: "motor.resistance",
                range: "0.001..4 ohm",
            });
        }
        if !(100..=10_000).contains(&cfg.tick_us) {
            return Err(ConfigError::OutOfRange {
                field: "control.tick_us",
                range: "100..10000 us",
            });
        }
        let tick_hz = 1_000_000 / cfg.tick_us;
        if cfg.speed_bandwidth_hz < 1 || cfg.speed_bandwidth_hz > tick_hz / 10 {
            return Err(ConfigError::OutOfRange {
                field: "control.speed_bandwidth",
                range: "1..tick rate/10 Hz",
            });
        }
        if !(cfg.rest_speed >= RadiansPerSecond::ZERO
            && cfg.rest_speed <= const { RadiansPerSecond::lit("50") })
        {
            return Err(ConfigError::OutOfRange {
                field: "control.rest_speed",
                range: "0..50 rad/s",
            });
        }
        let n = i128::from(cfg.drive.gear_ratio.to_bits()); // Q16
        let eta = i128::from(m.gear_efficiency.bits()); // Q28
        let n_eta = Factor::from_raw(((n * eta) >> 28) as i32);
        let n_over_eta = Factor::from_raw(div128(n << 28, eta) as i32);
        let eta_over_n = Ratio::from_raw(div128(eta << 16, n) as i32);
        let inv_n_eta = Ratio::from_raw(div128(1i128 << 72, n * eta) as i32);

        // Fading-memory α-β-γ gains, θ = e^(−2π f_b T), in Q28.
        const TWO_PI_Q16: u64 = 411_775;
        let wt_q16 = (TWO_PI_Q16 * u64::from(cfg.speed_bandwidth_hz) * u64::from(cfg.tick_us)
            / 1_000_000) as u32;
        let theta = i128::from(exp_neg_q16(wt_q16)) >> 4; // Q28
        let one = 1i128 << 28;
        let om = one - theta; // 1 − θ
        let alpha = one - (theta * theta >> 28) * theta / one;
        let beta = 3 * (om * om >> 28) * (one + theta) / (2 * one);
        let gamma2 = (om * om >> 28) * om >> 28;
        // Screw rad/s (Q16) from counts/tick (Q16): × rad/count × ticks/s.
        let rpc = geometry.screw_rad_per_count(); // counts → Q16 rad
        let speed_scale = rpc.times(i128::from(tick_hz), 1 << 16);
        // Screw rad/s² (Q8) from counts/tick² (Q16): × rad/count × ticks²/s² / 2^8.
        let accel_scale = rpc.times(i128::from(tick_hz) * i128::from(tick_hz), 1 << 24);
        Ok(Estimator {
            geometry,
            screw,
            law,
            kt: m.torque_constant,
            n_eta,
            n_over_eta,
            eta_over_n,
            inv_n_eta,
            rest_speed: cfg.rest_speed,
            gains: [alpha as i32, beta as i32, gamma2 as i32],
            speed_scale,
            accel_scale,
            late_us: cfg.tick_us * 3 / 2,
            last_counts: 0,
            q: 0,
            v: 0,
            a: 0,
            last: None,
        })
    }

    /// The validated geometry.
    pub fn geometry(&self) -> &Geometry {
        &self.geometry
    }

    /// The validated screw model.
    pub fn screw(&self) -> &ScrewModel {
        &self.screw
    }

    /// The compiled friction law.
    pub fn law(&self) -> &CompiledLaw {
        &self.law
    }

    /// Restart the speed filter at a position, at rest (after a fault or a re-home).
    pub fn reset(&mut self, position_counts: i32) {
        self.last_counts = position_counts;
        self.q = 0;
        self.v = 0;
        self.a = 0;
        self.last = None;
    }

    /// One estimator tick. Total: no panic, no wrap, whatever the inputs.
    ///
    /// `#[inline]` with [`Self::estimate`]: the firmware has one caller (the control tick),
    /// which then builds the estimate in place instead of copying 100 bytes out of a temporary.
    #[inline]
    pub fn step(&mut self, now: Instant, m: &Measurements) -> Estimate {
        self.step_at(now, m, 0)
    }

    /// One estimator tick with the speed filter fed the position between counts: `fraction`
    /// (Q16 of a count, from the encoder's edge times: `crate::control::edges`) above
    /// `m.position_counts`. `step` is this with 0, the bare count.
    #[inline]
    pub fn step_at(&mut self, now: Instant, m: &Measurements, fraction: u16) -> Estimate {
        let mut flags = 0u8;
        match self.last {
            None => self.reset(m.position_counts),
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
        // The residual is saturated to i32 (±32 768 counts per tick, beyond any drive), so
        // each correction is one 32×32→64 product and the gains (≤ 1 in Q28) keep it in i32.
        let moved = i64::from(m.position_counts) - i64::from(self.last_counts);
        self.last_counts = m.position_counts;
        let predicted = i64::from(self.q) + i64::from(self.v) + i64::from(self.a >> 1);
        let r = sat32((moved << 16) + i64::from(fraction) - predicted);
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
        self.estimate(m, speed, accel, flags)
    }

    /// The model's estimate at a given speed and acceleration (no filtering): the function the
    /// float64 twin is held to.
    #[inline]
    pub fn estimate(
        &self,
        m: &Measurements,
        speed: RadiansPerSecond,
        accel: RadiansPerSecond2,
        mut flags: u8,
    ) -> Estimate {
        let pose = self.geometry.pose(m.position_counts);
        if pose.clamped {
            flags |= EstimateFlags::POSE_CLAMPED;
        }
        let dir: i8 = if speed > self.rest_speed {
            1
        } else if speed < self.rest_speed.sat_neg() {
            -1
        } else {
            flags |= EstimateFlags::AT_REST;
            m.commanded_dir.signum()
        };
        let weight = Geometry::weight(m.load);
        let (axial_load, pin_friction) = self.geometry.axial_and_pin(&pose, weight);
        let c_x = self.geometry.structure_damping(pose.alpha);
        let mu = self.law.mu(speed);
        let w = self
            .screw
            .axial_demand(speed, accel, dir, axial_load, pin_friction, c_x);
        let contact = self.screw.contact(mu, dir, w);
        if w < Newtons::ZERO {
            flags |= EstimateFlags::FLANK_REVERSED;
        }
        let model_screw_torque = self.screw.required_torque(speed, accel, dir, &contact);
        // Power flows motor → screw when the torque and the motion agree (or at rest).
        let motoring = (model_screw_torque >= NewtonMetres::ZERO) == (dir >= 0) || dir == 0;
        let model_motor_torque: NewtonMetres = if motoring {
            qmul(model_screw_torque, self.inv_n_eta)
        } else {
            qmul(model_screw_torque, self.eta_over_n)
        };
        let motor_torque: NewtonMetres = qmul(m.motor_current, self.kt);
        let measured_motoring = (motor_torque >= NewtonMetres::ZERO) == (dir >= 0) || dir == 0;
        let measured_screw_torque: NewtonMetres = if measured_motoring {
            qmul(motor_torque, self.n_eta)
        } else {
            qmul(motor_torque, self.n_over_eta)
        };
        let residual = measured_screw_torque.sat_sub(model_screw_torque);
        // On a saturation bound (MAX or MIN): v ^ (v >> 31) is MAX for both. Non-short-circuit
        // `|` keeps the sweep branch-free.
        let on_bound = |v: i32| (v ^ (v >> 31)) == i32::MAX;
        if on_bound(axial_load.bits())
            | on_bound(pin_friction.bits())
            | on_bound(w.bits())
            | on_bound(contact.normal.bits())
            | on_bound(model_screw_torque.bits())
            | on_bound(contact.friction_torque.bits())
            | on_bound(measured_screw_torque.bits())
            | on_bound(speed.bits())
            | on_bound(accel.bits())
        {
            flags |= EstimateFlags::SATURATED;
        }
        Estimate {
            pose,
            screw_speed: speed,
            screw_accel: accel,
            axial_load,
            pin_friction,
            structure_damping: c_x,
            mu,
            contact,
            model_screw_torque,
            model_motor_torque,
            measured_screw_torque,
            residual,
            self_locking_margin: self.screw.self_locking_margin(mu),
            flags: EstimateFlags(flags),
        }
    }
}
