//! The real-time friction-torque estimator: `step(now, measurements) -> TickEstimate`, and
//! `details` for the whole [`Estimate`] of a tick.
//!
//! Every control tick it turns the motor encoder position and current into the model's view of
//! the screw-nut contact (height, T_r, the torque the model says the screw and the motor need)
//! and the torque the motor actually delivers (k_t·i through the gearbox); on demand the rest
//! (α, R, F₀, μ_s, ξ, N, the residual measured − model, the self-locking margin). The residual
//! is the basis of overload, obstruction and lubrication diagnostics.
//!
//! Speed and acceleration come from a fading-memory α-β-γ tracking filter on the encoder count
//! (three coincident discrete poles at `e^(−2π·f_b·T)`): it has no lag for constant acceleration,
//! and its bandwidth `f_b` (default 40 Hz at a 1 kHz tick) trades count-quantisation noise against
//! lag. docs/model.md gives the design and the measured step response.

use crate::math::{div128, exp_neg_q16};
use crate::model::friction::{CompiledLaw, FrictionLaw, MuTable};
use crate::model::geometry::{
    damping_table_cos, DriveConfig, Geometry, GeometryConfig, Pose, DAMPING_TABLE,
};
use crate::model::screw::{Contact, ContactCore, MechanicsConfig, ScrewModel};
use crate::model::Scale;
use crate::units::{
    narrow, qmul, sat32, Amperes, Factor, Instant, Kilograms, KilogramsPerSecond, Metres,
    NewtonMetres, Newtons, RadiansPerSecond, RadiansPerSecond2, Ratio, Q,
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

/// What the control tick reads of an estimate, every tick ([`Estimator::step`]); the whole
/// [`Estimate`] of the same tick comes from [`Estimator::details`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TickEstimate {
    /// Head height.
    pub height: Metres,
    /// Screw speed θ̇ from the tracking filter (clamped to ±[`SPEED_MAX`]).
    pub screw_speed: RadiansPerSecond,
    /// Screw acceleration θ̈ from the tracking filter (clamped to ±[`ACCEL_MAX`]).
    pub screw_accel: RadiansPerSecond2,
    /// Friction torque T_r about the screw axis.
    pub friction_torque: NewtonMetres,
    /// Axial demand W on the thread (the ball-screw identification reads it).
    pub axial: Newtons,
    /// Torque the thread contact takes from the screw, r_m·W·ξ.
    pub thread_torque: NewtonMetres,
    /// Torque the model says the screw needs from the coupling.
    pub model_screw_torque: NewtonMetres,
    /// The same at the motor shaft.
    pub model_motor_torque: NewtonMetres,
    /// Torque the motor delivers to the screw, from its current.
    pub measured_screw_torque: NewtonMetres,
    /// Conditions of this estimate.
    pub flags: EstimateFlags,
}

/// The estimator's configuration and state.
#[derive(Clone, Debug)]
pub struct Estimator {
    geometry: Geometry,
    screw: ScrewModel,
    law: CompiledLaw,
    /// The law tabulated over |θ̇|, interpolated in the segments where that is exact enough
    /// and the exact law, out of line, in the others ([`MuTable::build`]).
    mu_table: MuTable,
    kt: Ratio,
    /// n·η, n/η as factors; η/n, 1/(n·η) as ratios.
    n_eta: Factor,
    n_over_eta: Factor,
    eta_over_n: Ratio,
    inv_n_eta: Ratio,
    rest_speed: RadiansPerSecond,
    /// 2·μ_b (pin friction, Eq 6).
    two_mu_pin: Ratio,
    /// Per-tick constants in fixed formats (no run-time shift amounts, docs/model.md
    /// "Numeric envelope"): m·r_m·tan λ in Q32 (≤ 0.091 N per rad/s²), I in Q32 (≤ 0.1
    /// kg·m²), c in Q30 (≤ 1 N·m·s/rad).
    mass_lead_q32: i32,
    inertia_q32: i32,
    damping_q30: i32,
    /// Table 1 times the lead r_m·tan λ: (cos α in Q28, c_x·r_m·tan λ in Q20 N per rad/s,
    /// slope per Q28 LSB of cos α in Q20·2^-24), so that the damping force c_x·ẋ is one
    /// product with θ̇. Interpolated in cos α as [`Geometry::structure_damping`]: no α per tick.
    damping_lead: [(i32, i32, i32); 3],
    /// Support friction torque T₀, raw N·m bits.
    screw_support: i32,
    /// α, β, 2γ in Q28 (each ≤ 1).
    gains: [i32; 3],
    speed_scale: Scale,
    accel_scale: Scale,
    /// A tick later than this (1.5 periods, µs) is flagged late.
    late_us: u32,
    /// The pose between exact nodes every 2^`pose_shift` counts ([`PoseSegment`]); 0: the
    /// exact pose at every count (the configuration's encoder is too coarse for it).
    pose_shift: u32,
    /// 2^(32 − `pose_shift`) (unused while it is 0).
    pose_frac: u32,
    /// The pose segments, a ring by index: segment `i` in slot `i & 3`, tagged with its
    /// index ([`PoseSegment::EMPTY`]: none). The step reads the slot of its count's segment
    /// if the tag matches and refills it from two exact nodes otherwise
    /// ([`Self::refill_slot`]); [`Self::prepare`] fills the neighbours of the last step's
    /// segment ahead, so that a count entering one costs the step nothing.
    segments: [PoseSegment; 4],
    /// Exact nodes at segment boundaries, a ring by boundary (`b` in slot `b & 3`, tagged in
    /// `node_tags`, [`NO_NODE`]: none): those of the neighbours, computed one per
    /// [`Self::prepare`] call.
    nodes: [Node; 4],
    node_tags: [i32; 4],
    /// The segment whose neighbours are both prepared ([`NO_NODE`]: not known): `prepare`
    /// returns at once while the count stays in it.
    prepared: i32,
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
        // c_x·r_m·tan λ in Q20: c_x (kg/s)·r (Q24)·t (Q28) / 2^32 (≤ 58 544·0.0182·2^20).
        let r_bits = i128::from(screw.pitch_radius().bits());
        let tan_bits = i128::from(screw.tan_lambda().bits());
        let mut damping_lead = [(0i32, 0i32, 0i32); 3];
        for (i, &(deg, cx)) in DAMPING_TABLE.iter().enumerate() {
            damping_lead[i].0 = damping_table_cos(deg).bits();
            damping_lead[i].1 = (i128::from(cx) * r_bits * tan_bits >> 32) as i32;
        }
        for i in 0..2 {
            // 2^-24 per Q28 LSB of cos α: |Δc| < 2^30 (≤ 29 666 kg/s · 0.0182 m · 2^20) over
            // Δcos ≥ cos 45° − cos 65° > 2^26, so |slope| < 2^28; the smallest lead (r_m tan λ
            // ≥ 8.7 µm) keeps 13 significant bits.
            let dcos = i64::from(damping_lead[i].0 - damping_lead[i + 1].0);
            let dc = i64::from(damping_lead[i + 1].1 - damping_lead[i].1);
            damping_lead[i].2 = ((dc << 24) / dcos) as i32;
        }
        // m·r_m·tan λ (Q12·Q24·Q28 = value·2^64 → Q32; ≤ 5·0.05·0.364·2^32).
        let mass_lead_q32 =
            (i128::from(cfg.mechanics.nut_mass.bits()) * r_bits * tan_bits >> 32) as i32;
        // The pose segments' node spacing, from the configuration alone ([`PoseCtx`]).
        let two_mu_pin = Ratio::from_raw(cfg.geometry.mu_pin.bits() * 2);
        let budget = PoseBudget::new(&screw, &law, mass_lead_q32);
        let pose_shift = PoseCtx {
            geometry: &geometry,
            two_mu_pin,
            damping_lead: &damping_lead,
            pose_shift: 0,
            pose_frac: 0,
        }
        .choose_pose_shift(&budget);
        let n = i128::from(cfg.drive.gear_ratio.to_bits()); // Q16
        let eta = i128::from(m.gear_efficiency.bits()); // Q28
                                                        // n·η in i64 (two i32 factors: it fits), once.
        let n_eta_q44 = i128::from(
            i64::from(cfg.drive.gear_ratio.to_bits()) * i64::from(m.gear_efficiency.bits()),
        );
        let n_eta = Factor::from_raw((n_eta_q44 >> 28) as i32);
        let n_over_eta = Factor::from_raw(div128(n << 28, eta) as i32);
        let eta_over_n = Ratio::from_raw(div128(eta << 16, n) as i32);
        // 1/(n·η) in Q28 must stay below 8: n·η > 1/8 (2^41 in Q44). Each factor alone is in
        // range (n ≥ 1, η ≥ 0.1), but a direct drive with a lossy coupling is not.
        if n_eta_q44 <= 1i128 << 41 {
            return Err(ConfigError::Conflict {
                field: "motor.gear_efficiency",
                reason: "drive.gear_ratio x motor.gear_efficiency must exceed 0.125",
            });
        }
        let inv_n_eta = Ratio::from_raw(div128(1i128 << 72, n_eta_q44) as i32);

        // Fading-memory α-β-γ gains, θ = e^(−2π f_b T), in Q28.
        const TWO_PI_Q16: u64 = 411_775;
        let wt_q16 = (TWO_PI_Q16 * u64::from(cfg.speed_bandwidth_hz) * u64::from(cfg.tick_us)
            / 1_000_000) as u32;
        // In i64: 0 ≤ θ ≤ 2^28, so every product stays below 2^59 (the i128 form it replaces
        // gives the same bits; 128-bit multiplies are long inline code on the board).
        let theta = i64::from(exp_neg_q16(wt_q16)) >> 4; // Q28
        let one = 1i64 << 28;
        let om = one - theta; // 1 − θ
        let alpha = one - ((theta * theta >> 28) * theta >> 28);
        let beta = 3 * (om * om >> 28) * (one + theta) >> 29;
        let gamma2 = (om * om >> 28) * om >> 28;
        // Screw rad/s (Q16) from counts/tick (Q16): × rad/count × ticks/s.
        let rpc = geometry.screw_rad_per_count(); // counts → Q16 rad
        let speed_scale = rpc.times(i128::from(tick_hz), 1 << 16);
        // Screw rad/s² (Q8) from counts/tick² (Q16): × rad/count × ticks²/s² / 2^8.
        let accel_scale = rpc.times(i128::from(tick_hz) * i128::from(tick_hz), 1 << 24);
        let mu_table = MuTable::build(&law);
        Ok(Estimator {
            geometry,
            screw,
            law,
            mu_table,
            kt: m.torque_constant,
            n_eta,
            n_over_eta,
            eta_over_n,
            inv_n_eta,
            rest_speed: cfg.rest_speed,
            two_mu_pin,
            mass_lead_q32,
            inertia_q32: ((i64::from(cfg.mechanics.inertia_ukgm2) << 32) / 1_000_000) as i32,
            damping_q30: ((i64::from(cfg.mechanics.damping_unms) << 30) / 1_000_000) as i32,
            damping_lead,
            screw_support: cfg.mechanics.support_torque.bits(),
            gains: [alpha as i32, beta as i32, gamma2 as i32],
            speed_scale,
            accel_scale,
            late_us: cfg.tick_us * 3 / 2,
            pose_shift,
            pose_frac: PoseCtx::frac_for(pose_shift),
            segments: [PoseSegment::EMPTY; 4],
            nodes: [Node::BAD; 4],
            node_tags: [NO_NODE; 4],
            prepared: NO_NODE,
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

    /// Whether the model reads μ from the law's table ([`MuTable`]) in at least one segment
    /// rather than the exact law everywhere.
    pub fn mu_tabulated(&self) -> bool {
        !self.mu_table.all_exact()
    }

    /// Whether the model evaluates the exact law (bit for bit) at law input `x` (|θ̇| in Q16)
    /// rather than interpolating the law's table there.
    pub fn mu_exact_at(&self, x: u32) -> bool {
        self.mu_table.is_exact(x)
    }

    /// log2 of the pose's node spacing in counts ([`PoseSegment`]); 0: the exact pose at every
    /// count.
    pub fn pose_shift(&self) -> u32 {
        self.pose_shift
    }

    /// The index of the pose segment the last step read (count >> [`Self::pose_shift`]; the
    /// QEMU harness checks with it that a step it counts entered a new segment).
    #[doc(hidden)]
    pub fn pose_segment_index(&self) -> i32 {
        self.last_counts >> self.pose_shift
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
    /// Returns the fields the control tick reads ([`TickEstimate`]); [`Self::details`] gives
    /// the whole [`Estimate`] of the same tick on demand (telemetry, tests). `#[inline]`: the
    /// firmware has one caller (the control tick), which then builds the result in place.
    #[inline]
    pub fn step(&mut self, now: Instant, m: &Measurements) -> TickEstimate {
        self.step_at(now, m, 0)
    }

    /// One estimator tick with the speed filter fed the position between counts: `fraction`
    /// (Q16 of a count, from the encoder's edge times: `crate::control::edges`) above
    /// `m.position_counts`. `step` is this with 0, the bare count.
    #[inline]
    pub fn step_at(&mut self, now: Instant, m: &Measurements, fraction: u16) -> TickEstimate {
        let (speed, accel, flags) = self.filter(now, m.position_counts, fraction);
        let slot = self.track_segment(m.position_counts >> self.pose_shift);
        let x = self.model(m, &self.segments[slot], speed, accel, flags);
        TickEstimate {
            height: x.height,
            screw_speed: x.speed,
            screw_accel: x.accel,
            friction_torque: x.core.friction_torque,
            axial: x.w,
            thread_torque: x.core.thread_torque,
            model_screw_torque: x.model_screw_torque,
            model_motor_torque: x.model_motor_torque,
            measured_screw_torque: x.measured_screw_torque,
            flags: EstimateFlags(x.flags),
        }
    }

    /// The whole estimate of a tick that [`Self::step`] returned `tick` for, with `m` its
    /// measurements: the same numbers (bit for bit) plus the diagnostics (pose, R, F₀, c_x, μ,
    /// ξ, N, residual, self-locking margin). Recomputed from the tick's inputs (the pose
    /// segment's two nodes and the exact pose: ≈ 2.8 steps), for telemetry and tests rather
    /// than every tick.
    pub fn details(&self, m: &Measurements, tick: &TickEstimate) -> Estimate {
        self.estimate(m, tick.screw_speed, tick.screw_accel, tick.flags.0)
    }

    /// The α-β-γ tracking filter: (speed, acceleration, flags) for this tick.
    #[inline(always)]
    fn filter(
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

    /// The model's estimate at a given speed and acceleration (no filtering): the function the
    /// float64 twin is held to. Every field; [`Self::step`] computes the same numbers for the
    /// fields it returns.
    #[inline]
    pub fn estimate(
        &self,
        m: &Measurements,
        speed: RadiansPerSecond,
        accel: RadiansPerSecond2,
        flags: u8,
    ) -> Estimate {
        let index = m.position_counts >> self.pose_shift;
        let mut segment = PoseSegment::EMPTY;
        self.pose_ctx().refill(&mut segment, index);
        let x = self.model(m, &segment, speed, accel, flags);
        // The pose's diagnostics exact, its height the model's (interpolated between exact
        // nodes, as in the step); R and F₀ from the exact pose (W's interpolated R + F₀·dir is
        // within [`PoseBudget`]'s error of them, docs/model.md "Pose between nodes").
        let exact = self.geometry.pose(m.position_counts);
        let pose = Pose {
            height: x.height,
            ..exact
        };
        let weight = i64::from(Geometry::weight(m.load.clamp(Kilograms::ZERO, LOAD_MAX)).bits());
        let ws = sat32((weight * i64::from(pose.inv_sin_alpha.bits())) >> 28);
        // Diagnostics, off the tick path: they saturate freely.
        let axial_load = Newtons::from_raw(sat32(
            (i64::from(ws) * i64::from(pose.cos_alpha.bits())) >> 28,
        ));
        let pin_friction = Newtons::from_raw(sat32(
            (i64::from(ws) * i64::from(self.two_mu_pin.bits())) >> 28,
        ));
        Estimate {
            pose,
            screw_speed: x.speed,
            screw_accel: x.accel,
            axial_load,
            pin_friction,
            structure_damping: self.geometry.structure_damping(pose.cos_alpha),
            mu: x.mu,
            contact: self.screw.contact_from(x.mu_s, x.w, &x.core),
            model_screw_torque: x.model_screw_torque,
            model_motor_torque: x.model_motor_torque,
            measured_screw_torque: x.measured_screw_torque,
            residual: x.measured_screw_torque.sat_sub(x.model_screw_torque),
            self_locking_margin: self.screw.self_locking_margin(x.mu),
            flags: EstimateFlags(x.flags),
        }
    }

    /// The model shared by [`Self::step`] and [`Self::estimate`]: inlined into each, so a step
    /// computes only what its result needs.
    ///
    /// Saturate once (docs/model.md "Numeric envelope"): the inputs are clamped to the
    /// envelope (load 0…[`LOAD_MAX`], |θ̇| ≤ [`SPEED_MAX`], |θ̈| ≤ [`ACCEL_MAX`], μ ≤
    /// `mu_max`; a clamp sets `SATURATED`), and within it no force can leave `Newtons`
    /// for any validated configuration, so the force chain is plain 32×32→64 products and
    /// adds. Only the torques, which a large screw under a large W can push past ±32 768 N·m,
    /// saturate (and are flagged).
    #[inline(always)]
    fn model(
        &self,
        m: &Measurements,
        seg: &PoseSegment,
        speed: RadiansPerSecond,
        accel: RadiansPerSecond2,
        mut flags: u8,
    ) -> Model {
        let speed_c = speed.clamp(SPEED_MAX.sat_neg(), SPEED_MAX);
        let accel_c = accel.clamp(ACCEL_MAX.sat_neg(), ACCEL_MAX);
        let load = m.load.clamp(Kilograms::ZERO, LOAD_MAX);
        let mut clamped = (speed_c != speed) | (accel_c != accel) | (load != m.load);
        let (speed, accel) = (speed_c, accel_c);
        let dir: i8 = if speed > self.rest_speed {
            1
        } else if speed < self.rest_speed.sat_neg() {
            -1
        } else {
            flags |= EstimateFlags::AT_REST;
            m.commanded_dir.signum()
        };
        let pose = self.pose_on(seg, m.position_counts, dir);
        if pose.clamped {
            flags |= EstimateFlags::POSE_CLAMPED;
        }
        let dir32 = i32::from(dir);
        // R + F₀·dir = M·g·(cos α + 2μ_b·dir)/sin α: the load (≤ 10 t, Q12) times the pose's
        // factor (|…| ≤ 3·8·9.81 N/kg in Q23, sin α ≥ sin 7°, 1/sin α saturates at 8), one
        // product: ≤ 2.4 MN (Q12·Q23 = Q35 → Q8).
        let r_f0 = narrow((i64::from(load.bits()) * i64::from(pose.g)) >> 27);
        // c_x·ẋ = (c_x·r_m·tan λ)·θ̇: ≤ 1066 N·s/rad · 2000 rad/s < 2.2 MN (Q20·Q16 → Q8).
        let cxl = pose.cxl;
        let damping = narrow((i64::from(cxl) * i64::from(speed.bits())) >> 28);
        // m·r_m·tan λ·θ̈ < 0.091·65 536 < 6 kN: the high word of Q8·Q32.
        let inertial = narrow((i64::from(accel.bits()) * i64::from(self.mass_lead_q32)) >> 32);
        // |W| < 4.6 MN < 2^23 N: no overflow in the sum (Q8: < 2^31).
        let w = Newtons::from_raw(narrow(
            i64::from(inertial) + i64::from(r_f0) + i64::from(damping),
        ));
        // μ from the law's table (one product); in a segment the table cannot follow closely
        // enough the law is evaluated exactly, out of line.
        let x = speed.bits().unsigned_abs();
        let mu_law = Ratio::from_raw(self.mu_table.lookup(&self.law, x));
        let mu = mu_law.min(self.screw.mu_max());
        clamped |= mu != mu_law;
        // |μ| ≤ 4: dir·μ cannot overflow.
        let mu_s = Ratio::from_raw(dir32 * mu.bits());
        let core = self.screw.torques(mu_s, w);
        if w < Newtons::ZERO {
            flags |= EstimateFlags::FLANK_REVERSED;
        }
        // I·θ̈ + c·θ̇ + T₀·dir: ≤ 6554 + 2000 + 10 N·m within the envelope (I ≤ 0.1 kg·m²,
        // c ≤ 1 N·m·s/rad), so only the thread torque's add saturates.
        let inertia = narrow((i64::from(accel.bits()) * i64::from(self.inertia_q32)) >> 24);
        let damping = narrow((i64::from(speed.bits()) * i64::from(self.damping_q30)) >> 30);
        let own =
            narrow(i64::from(inertia) + i64::from(damping) + i64::from(dir32 * self.screw_support));
        let model_screw_torque = NewtonMetres::from_raw(own).sat_add(core.thread_torque);
        // Power flows motor → screw when the torque and the motion agree (or at rest).
        let motoring = (model_screw_torque >= NewtonMetres::ZERO) == (dir >= 0) || dir == 0;
        let model_motor_torque: NewtonMetres = if motoring {
            qmul(model_screw_torque, self.inv_n_eta)
        } else {
            qmul(model_screw_torque, self.eta_over_n)
        };
        // k_t ≤ 1: |i·k_t| ≤ 32 768 N·m, no overflow; the gearbox factor can (saturated).
        let motor_torque = NewtonMetres::from_raw(narrow(
            (i64::from(m.motor_current.bits()) * i64::from(self.kt.bits())) >> 28,
        ));
        let measured_motoring = (motor_torque >= NewtonMetres::ZERO) == (dir >= 0) || dir == 0;
        let measured_screw_torque: NewtonMetres = if measured_motoring {
            qmul(motor_torque, self.n_eta)
        } else {
            qmul(motor_torque, self.n_over_eta)
        };
        // On a saturation bound (MAX or MIN): v ^ (v >> 31) is MAX for both. Non-short-circuit
        // `|` keeps the sweep branch-free.
        let on_bound = |v: i32| (v ^ (v >> 31)) == i32::MAX;
        if clamped
            | on_bound(core.friction_torque.bits())
            | on_bound(core.thread_torque.bits())
            | on_bound(model_screw_torque.bits())
            | on_bound(model_motor_torque.bits())
            | on_bound(measured_screw_torque.bits())
        {
            flags |= EstimateFlags::SATURATED;
        }
        Model {
            height: pose.height,
            speed,
            accel,
            mu,
            mu_s,
            w,
            core,
            model_screw_torque,
            model_motor_torque,
            measured_screw_torque,
            flags,
        }
    }
}

/// The pose values the per-tick model reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct FastPose {
    height: Metres,
    /// g_n·(cos α + 2μ_b·dir)/sin α in Q23 N/kg (≤ 235.4): R + F₀·dir per kilogram of load.
    g: i32,
    /// c_x(α)·r_m·tan λ in Q20 ([`PoseCtx::damping_lead`]).
    cxl: i32,
    clamped: bool,
}

/// The pose between two exact nodes, at counts `index·2^k` and `(index + 1)·2^k`
/// (k = [`Estimator`]'s `pose_shift`): the height, R + F₀·dir per kilogram of load as
/// g_n·cos α/sin α + dir·g_n·2μ_b/sin α, and c_x·r_m·tan λ, interpolated linearly in the count (docs/model.md "Pose
/// between nodes"). cos α is linear in the count (Eq 1), so only the curvature of h and g in
/// cos α costs accuracy; k is chosen per configuration so that it stays within a tenth of the
/// budgets ([`PoseCtx::choose_pose_shift`]). A segment that touches the clamp band's edges,
/// 1/sin α's saturation (below ≈ 7.2°) or a row of Table 1 (where c_x's slope changes) is
/// `exact`: the exact pose at the count. Only what the step reads: the nodes themselves
/// (cos α, unusable) serve the classification, when the segment is filled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct PoseSegment {
    /// The segment's index (count >> k); [`NO_NODE`] in an empty slot.
    index: i32,
    exact: bool,
    /// The values ([`NODE_HEIGHT`], [`NODE_G`], [`NODE_PIN`], [`NODE_CXL`], raw bits) at the
    /// segment's start, and their rise from start to end.
    v0: [i32; 4],
    dv: [i32; 4],
}

/// Indices into a segment's values.
/// Height, Q24 m.
const NODE_HEIGHT: usize = 0;
/// g_n·cos α/sin α, Q23 N/kg.
const NODE_G: usize = 1;
/// g_n·2μ_b/sin α, Q23 N/kg.
const NODE_PIN: usize = 2;
/// c_x·r_m·tan λ, Q20 N per rad/s.
const NODE_CXL: usize = 3;

/// An exact node: [`PoseSegment`]'s four values, cos α (for Table 1's rows), whether it is
/// unusable (clamped, saturated, beyond i32 counts), whether the pose was clamped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Node {
    v: [i32; 4],
    cos: i32,
    bad: bool,
    clamped: bool,
}

impl Node {
    /// Beyond i32 counts: unusable.
    const BAD: Node = Node {
        v: [0; 4],
        cos: 0,
        bad: true,
        clamped: true,
    };
}

impl PoseSegment {
    /// Value `j` at the Q31 fraction `f` of the segment: v0 + dv·f, the high word of dv·f
    /// being half the rise (1 LSB of rounding).
    #[inline(always)]
    fn at(&self, f: i32, j: usize) -> i32 {
        self.v0[j] + ((((i64::from(self.dv[j]) * i64::from(f)) >> 32) as i32) << 1)
    }

    /// An empty slot: no segment's index where nodes are used (k ≥ 1: indices are counts >> k).
    /// With k = 0 the count i32::MIN matches it, and every segment is exact then, as this.
    const EMPTY: PoseSegment = PoseSegment {
        index: NO_NODE,
        exact: true,
        v0: [0; 4],
        dv: [0; 4],
    };
}

/// The tag of an empty segment slot or node slot: no segment's index or boundary where nodes
/// are used (counts >> k, k ≥ 1).
const NO_NODE: i32 = i32::MIN;

/// Standard gravity in Q16 m/s² (as [`Geometry::weight`]).
const G_N_Q16: i64 = 642_689;

/// Interpolation error of the height allowed between nodes, a tenth of its budget
/// (docs/model.md): 5 µm (Q24 m). R + F₀·dir: [`PoseBudget`].
const POSE_HEIGHT_TOL: i32 = 84; // 5·10⁻⁶·2^24
/// The operating envelope T_r's budget holds over (issue 3, docs/model.md "Pose between
/// nodes"): |θ̇| ≤ 400 rad/s, |θ̈| ≤ 2000 rad/s² (the twin proptests' range), load ≤
/// [`LOAD_MAX`] (2× the largest rated load a configuration accepts, 5 t).
const BUDGET_SPEED: u32 = 400;
const BUDGET_ACCEL: u64 = 2000;
/// A tenth of T_r's budget: 0.5 mN·m/10 = 5·10⁻⁵ N·m (×2^32, rounded down), and 0.2 %/10 =
/// 1/5000.
const TORQUE_FLOOR_TENTH_Q32: u64 = 214_748;
const REL_TENTH_INV: u64 = 5000;
/// Most segments the spacing search walks over all the spacings it tries (the default lift: 630;
/// ≤ 3·8192 poses, ≈ 5 M instructions at configuration time).
const POSE_WALK_MAX: u32 = 8192;
/// Largest node spacing tried, 2^16 counts.
const POSE_SHIFT_MAX: u32 = 16;

/// What the error of W's pose term may be, so that T_r (and the thread torque) stays within a
/// tenth of its budget, max(0.2 %·|T_r|, 0.5 mN·m), over the operating envelope (docs/model.md
/// "Pose between nodes"). W = M·G(dir) + D with G(dir) = R + F₀·dir per kilogram (the
/// interpolated term) and |D| ≤ c_x·r_m·tan λ·400 + m·r_m·tan λ·2000 (damping and inertia at the
/// envelope's bounds); T_r and the thread torque move by at most K·ΔW, K = r_m·(tan λ + μ_hi)/
/// (1 − μ_hi·tan λ) with μ_hi the law's largest μ over the envelope's speeds. An error e of
/// G(dir) per kilogram is within a tenth of the budget for every load M ≤ [`LOAD_MAX`] if
/// (1) e·LOAD_MAX ≤ A = 5·10⁻⁵ N·m/K (the absolute floor's tenth, at the heaviest load), or
/// (2) e·(5000·A + D) ≤ A·|G(dir)| (for M·e ≤ A the floor holds; for larger M,
/// |W| ≥ M·|G| − D ≥ (A/e)·|G| − D, and then M·e ≤ |W|/5000).
struct PoseBudget {
    /// A in Q24 N.
    a: u64,
    /// The largest e (Q23 N/kg) that passes (1): e·2^-23·`LOAD_MAX` ≤ A.
    e_abs: u32,
    /// 5000·A + m·r_m·tan λ·2000 (D's inertial part), Q24 N.
    c0: u64,
}

impl PoseBudget {
    /// In u64 (every quantity below bounded): the configuration-time i128 forms cost 850 B of
    /// flash.
    fn new(screw: &ScrewModel, law: &CompiledLaw, mass_lead_q32: i32) -> PoseBudget {
        // μ_hi ≥ μ(x) for |θ̇| ≤ 400 rad/s (law input x, Q16): μ = base + amp·e^(−y) +
        // lin(min(x, x_max)) with 0 < e^(−y) ≤ 1 and lin linear, so μ ≤ max(amp, 0) +
        // max(base, μ(x_400) + max(−amp, 0)) (base + lin at either end of the range).
        let given = law.law();
        let amp = i64::from(given.amp.bits());
        let end = i64::from(law.mu_unfloored_call(BUDGET_SPEED << 16));
        let mu_hi = (amp.max(0) + i64::from(given.base.bits()).max(end + (-amp).max(0)))
            .clamp(0, i64::from(screw.mu_max().bits())) as u64;
        let tan = screw.tan_lambda().bits() as u64;
        // K = r_m·num/den (Q24·Q28/Q28); μ_hi·tan λ ≤ 1/3 (`mu_max`): den ≥ ⅔·2^28.
        let num = tan + mu_hi;
        let den = (1u64 << 28) - (mu_hi * tan >> 28);
        let r = screw.pitch_radius().bits() as u64;
        // A·2^24 = 5·10⁻⁵·2^32·2^16·den/(r_q24·num) (numerator < 2^62): ≤ 2^27 (r_m ≥ 1 mm,
        // tan λ ≥ tan 0.5°), ≥ 2^11 (r_m ≤ 5 cm, μ_hi ≤ 4).
        let a = (TORQUE_FLOOR_TENTH_Q32 << 16) * den / (r * num);
        let load_max = u64::from(LOAD_MAX.bits() as u32 >> 12);
        PoseBudget {
            a,
            e_abs: (a / (2 * load_max)) as u32,
            // mass_lead ≥ 0 (Q32 → Q24): < 2^34; 5000·A < 2^40.
            c0: REL_TENTH_INV * a + (u64::from(mass_lead_q32 as u32) * BUDGET_ACCEL >> 8),
        }
    }

    /// Whether an interpolation error `e` of G(dir) (Q23 N/kg) at a pose whose G(dir) is `g`
    /// and c_x·r_m·tan λ is `cxl` (Q20 N per rad/s) keeps T_r within a tenth of its budget.
    fn holds(&self, e: i32, g: i32, cxl: i32) -> bool {
        let e = e.unsigned_abs();
        if e <= self.e_abs {
            return true;
        }
        // (2) fails beyond |G|/5000 < 2^19; below 2^20 the products fit: D = c_x·lead·400
        // (Q20 → Q24) < 2^43, c0 < 2^41, A·|G| < 2^58.
        let d = u64::from(cxl.unsigned_abs()) * u64::from(BUDGET_SPEED) << 4;
        e < 1 << 20 && u64::from(e) * (self.c0 + d) <= self.a * u64::from(g.unsigned_abs())
    }

    /// Whether G's error bound `e` (|ΔG₀| + |ΔG_b|, falling as α grows) passes (1): then every
    /// segment above passes.
    fn absolute_holds(&self, e: i32) -> bool {
        e.unsigned_abs() <= self.e_abs
    }
}

/// What the pose segments need of the estimator's configuration (borrowed): also usable
/// while `Estimator::new` is still choosing the node spacing, so that the estimator is built
/// once, in its caller's slot (a local adjusted and then moved into `Ok` was a second 1 KiB
/// copy on the frame of every caller of `new`).
struct PoseCtx<'a> {
    geometry: &'a Geometry,
    two_mu_pin: Ratio,
    damping_lead: &'a [(i32, i32, i32); 3],
    pose_shift: u32,
    pose_frac: u32,
}

/// [`PoseCtx`] of an estimator, built field by field: usable where a method's `&self` could not
/// be, beside a mutable borrow of the segment state ([`Estimator::refill_slot`],
/// [`Estimator::prepare`]).
macro_rules! pose_ctx {
    ($e:expr) => {
        PoseCtx {
            geometry: &$e.geometry,
            two_mu_pin: $e.two_mu_pin,
            damping_lead: &$e.damping_lead,
            pose_shift: $e.pose_shift,
            pose_frac: $e.pose_frac,
        }
    };
}

impl Estimator {
    /// The pose segments' view of this estimator.
    #[inline(always)]
    fn pose_ctx(&self) -> PoseCtx<'_> {
        pose_ctx!(self)
    }

    /// The slot of segment `index` (`index & 3`), refilled first unless it holds that segment
    /// (a neighbour [`Self::prepare`] filled, or the last step's): the step's one check.
    #[inline(always)]
    fn track_segment(&mut self, index: i32) -> usize {
        let slot = (index & 3) as usize;
        if self.segments[slot].index != index {
            self.refill_slot(index);
        }
        slot
    }

    /// The segment `index` filled into its slot from its two nodes, those not in the node
    /// ring computed (exact poses): the step's fallback when the count enters a segment that is
    /// not prepared (the first step, a jump, `prepare` not called or not done yet).
    #[inline(never)]
    fn refill_slot(&mut self, index: i32) {
        self.prepared = NO_NODE;
        while !self.fill_piece(index) {}
    }

    /// One piece of filling segment `j`'s slot: a node at its start or end missing from the
    /// ring computed (false), or both there and the segment filled from them (true; with k = 0
    /// no nodes: exact). Out of line: the step's refill and `prepare` share it (flash).
    #[inline(never)]
    fn fill_piece(&mut self, j: i32) -> bool {
        let ctx = pose_ctx!(self);
        let s0 = (j & 3) as usize;
        if ctx.pose_shift == 0 {
            ctx.refill(&mut self.segments[s0], j);
            return true;
        }
        // k ≥ 1: j + 1 stays in i32.
        let s1 = ((j + 1) & 3) as usize;
        let b = if self.node_tags[s0] != j {
            j
        } else if self.node_tags[s1] != j + 1 {
            j + 1
        } else {
            ctx.fill(&mut self.segments[s0], j, &self.nodes[s0], &self.nodes[s1]);
            return true;
        };
        let s = (b & 3) as usize;
        self.nodes[s] = ctx.node_at(b);
        self.node_tags[s] = b;
        false
    }

    /// One bounded piece of the pose segments' preparation, off the step's path: for the
    /// segments on either side of the last step's count (the one in the direction of motion
    /// first), one missing exact node (≈ the cost of one exact pose), or one segment filled from
    /// its two nodes (differences and classification). Returns at once when both neighbours
    /// are ready, as it does with k = 0 (no nodes). After it has run on the two or four ticks
    /// following a crossing, a step whose count enters either neighbour reads it as it reads
    /// its own segment: no exact pose on the step. Skipping it is safe: the step then refills
    /// the segment it enters ([`Self::refill_slot`]), the same bits more slowly.
    ///
    /// Call it once a tick after the tick's outputs are applied
    /// ([`crate::control::Controller::finish_tick`]), so that the node work of a crossing does
    /// not delay them.
    #[inline(never)]
    pub fn prepare(&mut self) {
        let k = self.pose_shift;
        let i = self.last_counts >> k;
        if i == self.prepared || k == 0 {
            return;
        }
        // The neighbour in the direction of motion first (k ≥ 1: indices ± 2 stay in i32).
        let d = if self.v < 0 { -1 } else { 1 };
        let missing = |e: &Estimator, j: i32| e.segments[(j & 3) as usize].index != j;
        let j = if missing(self, i + d) {
            i + d
        } else if missing(self, i - d) {
            i - d
        } else {
            self.prepared = i;
            return;
        };
        self.fill_piece(j);
    }

    /// [`PoseCtx::exact_pose`] for this estimator.
    #[inline(never)]
    fn exact_pose(&self, counts: i32, dir: i8) -> FastPose {
        self.pose_ctx().exact_pose(counts, dir)
    }

    /// The model's pose at `counts` for direction `dir` on `seg` (the segment holding it).
    #[inline(always)]
    fn pose_on(&self, seg: &PoseSegment, counts: i32, dir: i8) -> FastPose {
        if seg.exact {
            return self.exact_pose(counts, dir);
        }
        let f = fraction(self.pose_frac, counts);
        let at = |j: usize| seg.at(f, j);
        FastPose {
            height: Metres::from_raw(at(NODE_HEIGHT)),
            // |g_n·2μ_b/sin α| ≤ 157 N/kg (Q23 < 2^31): the sum stays within ±235.4.
            g: at(NODE_G) + i32::from(dir) * at(NODE_PIN),
            cxl: at(NODE_CXL),
            clamped: false,
        }
    }
}

/// The position of `counts` within its segment as a Q31 fraction, for `frac` = 2^(32−k): the
/// count's low k bits on top (a product: one `MUL`, where a variable shift is masked first).
#[inline(always)]
fn fraction(frac: u32, counts: i32) -> i32 {
    ((counts as u32).wrapping_mul(frac) >> 1) as i32
}

impl PoseCtx<'_> {
    /// (G₀, G_b) = (g_n·cos α/sin α, g_n·2μ_b/sin α) in Q23 N/kg for an exact pose's cos α and
    /// 1/sin α (Q28): g_n/sin α first (Q23, ≤ 8·9.81 < 2^30), then one product each (cos α ≤ 1,
    /// 2μ_b ≤ 2 in Q28): |G₀ ± G_b| ≤ 3·8·9.81 < 2^31 in Q23.
    #[inline(always)]
    fn g_parts(&self, cos: i32, inv_sin: i32) -> (i32, i32) {
        let g_inv = (i64::from(inv_sin) * G_N_Q16) >> 21;
        let part = |x: i32| ((g_inv * i64::from(x)) >> 28) as i32;
        (part(cos), part(self.two_mu_pin.bits()))
    }

    /// The exact node at `counts`: the pose's height, cos α and 1/sin α (one scale and one
    /// √/1/√ kernel, [`Geometry::pose_node`]), G₀ and G_b (three products) and Table 1's
    /// c_x·lead. Out of line: the segment's fill, the exact segments and the
    /// configuration-time spacing search share it (the search validates these nodes).
    #[inline(never)]
    fn pose_node(&self, counts: i32) -> Node {
        let (height, cos_alpha, inv_sin, clamped) = self.geometry.pose_node(counts);
        let (cos, inv) = (cos_alpha.bits(), inv_sin.bits());
        let (g0, gb) = self.g_parts(cos, inv);
        Node {
            v: [height.bits(), g0, gb, self.damping_lead(cos_alpha)],
            cos,
            bad: clamped || inv == i32::MAX,
            clamped,
        }
    }

    /// The node at segment boundary `i` (count i·2^k); unusable beyond i32 counts. Out of
    /// line: the refills and `prepare` share it (flash).
    #[inline(never)]
    fn node_at(&self, i: i32) -> Node {
        // i·2^k in i32 iff shifting back gives i (k ≤ 16): no 64-bit shift.
        let c = i.wrapping_shl(self.pose_shift);
        if c >> self.pose_shift == i {
            self.pose_node(c)
        } else {
            Node::BAD
        }
    }

    /// `seg` filled for the segment `index`, in place, from two exact nodes computed here
    /// (`estimate`, the spacing search; the estimator's slots keep their nodes,
    /// [`Estimator::refill_slot`]). A function of `index` alone: the nodes are exact poses at
    /// fixed counts.
    #[inline(never)]
    fn refill(&self, seg: &mut PoseSegment, index: i32) {
        if self.pose_shift == 0 {
            seg.index = index;
            seg.exact = true;
            return;
        }
        let n0 = self.node_at(index);
        let n1 = self.node_at(index.saturating_add(1));
        self.fill(seg, index, &n0, &n1);
    }

    /// `seg` for the segment `index` between nodes `n0`, `n1`: the start's values, their rise
    /// and whether it is evaluated exactly: an unusable node, a row of Table 1 strictly inside
    /// (cos α falls along the segment: c_x's slope changes there), or below count 0 (α₀ − 5° …
    /// α₀, outside the envelope the spacing is checked over). Out of line: the refill, the
    /// slot's refill and `prepare` share it (flash).
    #[inline(never)]
    fn fill(&self, seg: &mut PoseSegment, index: i32, n0: &Node, n1: &Node) {
        seg.index = index;
        seg.v0 = n0.v;
        // Nodes within the band: heights ≤ 3 m, |G| ≤ 235.4 (Q23), c_x·r_m·tan λ < 2^30: the
        // differences of usable nodes fit (an unusable one is never interpolated).
        seg.dv = core::array::from_fn(|j| n1.v[j].wrapping_sub(n0.v[j]));
        let kink = self
            .damping_lead
            .iter()
            .any(|&(c, _, _)| c < n0.cos && c > n1.cos);
        seg.exact = n0.bad || n1.bad || kink || index < 0;
    }

    /// The exact pose's values (segments at the band's edges and Table 1's rows, coarse
    /// encoders): the node's values at the count, the same arithmetic. Out of line: inlined,
    /// it cost the step's common path ≈ 25 instructions of register moves.
    #[inline(always)]
    fn exact_pose(&self, counts: i32, dir: i8) -> FastPose {
        let n = self.pose_node(counts);
        FastPose {
            height: Metres::from_raw(n.v[NODE_HEIGHT]),
            g: n.v[NODE_G] + i32::from(dir) * n.v[NODE_PIN],
            cxl: n.v[NODE_CXL],
            clamped: n.clamped,
        }
    }

    /// 2^(32 − k) for a node spacing 2^k (k ≥ 1), 0 for k = 0.
    fn frac_for(k: u32) -> u32 {
        if k == 0 {
            0
        } else {
            1u32 << (32 - k)
        }
    }

    /// The largest node spacing 2^k (k ≤ [`POSE_SHIFT_MAX`]) whose interpolation keeps the
    /// height within [`POSE_HEIGHT_TOL`] and T_r within a tenth of its budget ([`PoseBudget`]),
    /// checked at the midpoint of every usable segment from α₀ (count 0) up, where a segment's
    /// interpolation error peaks, for dir −1, 0, +1, until the error bound |ΔG₀| + |ΔG_b| passes
    /// the absolute test (1) on at least four segments. The curvatures of h, G₀ and G_b in cos α
    /// (1/sin³ α; 3 cos α/sin⁵ α; (1 + 2 cos² α)/sin⁵ α) fall as α grows, and cos α is linear
    /// in the count, so every segment above passes (1) and the height. 0 if none passes.
    /// Configuration time: three poses per segment walked (the default lift: 621 segments for
    /// the k it takes, ≈ 1 860 poses; a few for each larger k, which fail at α₀), at most
    /// [`POSE_WALK_MAX`] segments in all, beyond which it returns 0. Carrying the
    /// end node to the next segment saves a third of them but cost 100 B of flash and 320 B of
    /// the console task's stack. Out of line: its frame is not on `new`'s while the law's table
    /// is built.
    #[inline(never)]
    fn choose_pose_shift(&mut self, budget: &PoseBudget) -> u32 {
        let mut walk = POSE_WALK_MAX;
        'k: for k in (1..=POSE_SHIFT_MAX).rev() {
            self.pose_shift = k;
            self.pose_frac = Self::frac_for(k);
            // From the segment at α₀ (count 0; those below are exact), past any exact ones
            // (Table 1's rows), up to the band's top (indices < 2^31 >> k: no wrap).
            let mut seg = PoseSegment::EMPTY;
            let mut checked = 0;
            let mut index = 0i32;
            while index < i32::MAX >> k {
                // Configuration time stays bounded whatever the configuration: past the walk's
                // allowance, the exact pose at every count (always within the budgets).
                walk -= 1;
                if walk == 0 {
                    return 0;
                }
                self.refill(&mut seg, index);
                if seg.exact && self.node_at(index).bad {
                    break;
                }
                if !seg.exact {
                    // The midpoint, where a segment's interpolation error peaks.
                    let c = (index << k) + (1 << (k - 1));
                    let want = self.pose_node(c).v;
                    let f = fraction(self.pose_frac, c);
                    let err = |j: usize| seg.at(f, j) - want[j];
                    if err(NODE_HEIGHT).abs() > POSE_HEIGHT_TOL {
                        continue 'k;
                    }
                    for dir in [-1, 0, 1] {
                        let e = err(NODE_G) + dir * err(NODE_PIN);
                        if !budget.holds(e, want[NODE_G] + dir * want[NODE_PIN], want[NODE_CXL]) {
                            continue 'k;
                        }
                    }
                    checked += 1;
                    if checked >= 4
                        && budget.absolute_holds(err(NODE_G).abs() + err(NODE_PIN).abs())
                    {
                        break;
                    }
                }
                index += 1;
            }
            if checked > 0 {
                return k;
            }
        }
        0
    }

    /// c_x(α)·r_m·tan λ (Q20, N per rad/s) at the pose with cosine `cos_alpha`: Table 1 as
    /// [`Geometry::structure_damping`] interpolates it (linear in cos α between its angles,
    /// flat outside), times the lead.
    #[inline(always)]
    fn damping_lead(&self, cos_alpha: Ratio) -> i32 {
        let t = &self.damping_lead;
        let c = cos_alpha.bits();
        if c >= t[0].0 {
            return t[0].1;
        }
        let i = if c >= t[1].0 {
            0
        } else if c >= t[2].0 {
            1
        } else {
            return t[2].1;
        };
        // Within a segment: |Δcos·slope| ≤ |Δc|·2^24, so the sum stays between two entries.
        narrow(i64::from(t[i].1) + ((i64::from(t[i].0 - c) * i64::from(t[i].2)) >> 24))
    }
}

/// The envelope of the estimator's inputs (docs/model.md "Numeric envelope"): outside it an
/// input is clamped and the estimate flagged `SATURATED`. Far beyond any lift of the validated
/// configurations (rated load ≤ 5 t, cruise ≤ 20 rad/s).
pub const LOAD_MAX: Kilograms = Kilograms::lit("10000");
/// Largest screw speed the model evaluates, rad/s.
pub const SPEED_MAX: RadiansPerSecond = RadiansPerSecond::lit("2000");
/// Largest screw acceleration the model evaluates, rad/s².
pub const ACCEL_MAX: RadiansPerSecond2 = RadiansPerSecond2::lit("65536");

/// Everything [`Estimator::model`] computes; each caller keeps what it returns (the rest is
/// dead code after inlining).
struct Model {
    height: Metres,
    speed: RadiansPerSecond,
    accel: RadiansPerSecond2,
    mu: Ratio,
    mu_s: Ratio,
    w: Newtons,
    core: ContactCore,
    model_screw_torque: NewtonMetres,
    model_motor_torque: NewtonMetres,
    measured_screw_torque: NewtonMetres,
    flags: u8,
}

#[cfg(test)]
mod tests {
    use super::*;
    use fixed::types::I16F16;

    /// Configurations of very different node spacings: the default lift, a long lift at a
    /// low α₀ with a fine encoder, a short one at a high α₀ with a coarse encoder and a big
    /// screw, and heavy pin friction.
    fn configs() -> [EstimatorConfig; 4] {
        let d = EstimatorConfig::DEFAULT;
        let mut fine = d;
        fine.geometry.length = Metres::lit("2");
        fine.geometry.alpha0_deg = I16F16::lit("12");
        fine.geometry.alpha_max_deg = I16F16::lit("89");
        fine.drive.counts_per_rev = 4096;
        fine.drive.gear_ratio = I16F16::lit("100");
        let mut coarse = d;
        coarse.geometry.length = Metres::lit("0.05");
        coarse.geometry.alpha0_deg = I16F16::lit("60");
        coarse.geometry.alpha_max_deg = I16F16::lit("89");
        coarse.drive.counts_per_rev = 4;
        coarse.drive.gear_ratio = I16F16::lit("1");
        coarse.drive.pitch_radius = Metres::lit("0.05");
        coarse.drive.lead_angle_deg = I16F16::lit("20");
        let mut pins = d;
        pins.geometry.mu_pin = Ratio::ONE;
        [d, fine, coarse, pins]
    }

    /// Over the whole stroke (α₀ to the band's top, 4096 positions), the pose the model reads
    /// between nodes is within the tolerances the node spacing was chosen for, for both
    /// directions: the curvature falls as α grows, so the segments checked at α₀ bound all the
    /// others. Also: the same bits from a fresh segment as from a walked one (the nodes are
    /// functions of the count).
    #[test]
    fn the_pose_between_nodes_stays_within_its_tolerances_over_the_stroke() {
        for cfg in configs() {
            let mut est = Estimator::new(&cfg).unwrap();
            let k = est.pose_shift();
            let budget = PoseBudget::new(&est.screw, &est.law, est.mass_lead_q32);
            // The band's top: the first clamped count above 0.
            let (mut lo, mut hi) = (0i64, i64::from(i32::MAX));
            while hi - lo > 1 {
                let mid = (lo + hi) / 2;
                if est.geometry.pose(mid as i32).clamped {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            let top = lo as i32;
            let mut interpolated = 0;
            let mut neighbour = 0;
            // Up the stroke and back down, as the steps track the segment and `prepare` runs
            // between them (neighbours entered prepared: counted, and the same bits as a
            // fresh fill).
            for i in (0..4096i64).chain((0..4096).rev()) {
                let c = (i64::from(top) * i / 4096) as i32;
                let index = c >> k;
                let moved = index != est.last_counts >> k;
                neighbour +=
                    usize::from(moved && est.segments[(index & 3) as usize].index == index);
                let slot = est.track_segment(index);
                est.last_counts = c;
                // Enough calls for both neighbours (two nodes and two fills at most).
                for _ in 0..5 {
                    est.prepare();
                }
                let fresh = |j: i32| {
                    let mut seg = PoseSegment::EMPTY;
                    est.pose_ctx().refill(&mut seg, j);
                    seg
                };
                assert_eq!(fresh(index), est.segments[slot], "{c}");
                if k > 0 {
                    assert_eq!(est.prepared, index, "{c}");
                    for j in [index - 1, index + 1] {
                        assert_eq!(fresh(j), est.segments[(j & 3) as usize], "{c} {j}");
                    }
                }
                let seg = est.segments[slot];
                let exact = est.geometry.pose(c);
                let (cos, inv) = (exact.cos_alpha.bits(), exact.inv_sin_alpha.bits());
                let ctx = est.pose_ctx();
                let (g0, gb) = ctx.g_parts(cos, inv);
                let cxl = ctx.damping_lead(exact.cos_alpha);
                for dir in [-1i8, 0, 1] {
                    let got = est.pose_on(&seg, c, dir);
                    let dh = (got.height.bits() - exact.height.bits()).abs();
                    let g = g0 + i32::from(dir) * gb;
                    // The budget's test, with 4 LSB of rounding to spare.
                    let dg = ((got.g - g).abs() - 4).max(0);
                    assert!(dh <= POSE_HEIGHT_TOL + 2, "{k} {c} height {dh}");
                    assert!(budget.holds(dg, g, cxl), "{k} {c} g {dg} at {g}");
                    let dc = (got.cxl - cxl).abs();
                    assert!(dc <= 4, "{k} {c} c_x {dc}");
                }
                interpolated += usize::from(!seg.exact);
            }
            // The default lift and the fine encoder interpolate nearly everywhere.
            if k >= 4 {
                assert!(interpolated > 7800, "{k}: {interpolated}");
                // Both directions enter neighbours from the nodes computed ahead.
                assert!(neighbour > 100, "{k}: {neighbour}");
            }
        }
    }

    /// A step whose count enters a neighbour [`Estimator::prepare`] filled returns the bits of
    /// a step that fills its segment from two fresh exact nodes: up and down the stroke at
    /// motion speeds, reversals on a boundary, jumps (over segments, below count 0, to the
    /// clamp band and the ends of i32), for configurations of very different node spacings.
    /// Each `prepare` does at most one piece (one node, or one segment filled).
    #[test]
    fn entering_a_prepared_neighbour_gives_the_bits_of_a_fresh_refill() {
        for cfg in configs() {
            let mut prepared = Estimator::new(&cfg).unwrap();
            let mut fresh = Estimator::new(&cfg).unwrap();
            let k = prepared.pose_shift();
            let seg = 1i32 << k;
            // Counts: a climb at 1…3 counts a tick through several segments, a reversal on a
            // boundary (back and forth across it), a descent, jumps.
            let mut counts = Vec::new();
            let b = 40 * seg;
            let mut c = b - 5 * seg / 2;
            while c < b + 3 * seg {
                counts.push(c);
                c += 1 + (c & 1) * 2;
            }
            for j in 0..12 {
                counts.push(b - 1 + (j & 1));
                counts.push(b - 1 + (j & 1));
            }
            while c > b - 3 * seg {
                counts.push(c);
                c -= 2;
            }
            counts.extend([
                b + 7 * seg,
                b + 7 * seg + 1,
                -3 * seg,
                -3 * seg - 1,
                -seg,
                0,
                1,
            ]);
            counts.extend([
                i32::MAX,
                i32::MAX - 1,
                i32::MIN,
                i32::MIN + 1,
                b,
                b + seg,
                b,
            ]);
            let mut entered = [0usize; 2];
            for (t, &c) in counts.iter().enumerate() {
                let m = Measurements {
                    position_counts: c,
                    motor_current: Amperes::lit("20"),
                    load: Kilograms::lit("1000"),
                    commanded_dir: 1,
                };
                let now = Instant(1000 * t as u32);
                let index = c >> k;
                let was = prepared.last_counts >> k;
                if t > 0 && index != was && prepared.segments[(index & 3) as usize].index == index {
                    entered[usize::from(index < was)] += 1;
                }
                // The fresh one keeps no segment or node from one step to the next.
                fresh.segments = [PoseSegment::EMPTY; 4];
                fresh.node_tags = [NO_NODE; 4];
                let (p, f) = (prepared.step(now, &m), fresh.step(now, &m));
                assert_eq!(p, f, "k={k} count {c} (step {t})");
                for _ in 0..3 {
                    let tags = (prepared.segments.map(|s| s.index), prepared.node_tags);
                    prepared.prepare();
                    let changed = (0..4)
                        .filter(|&s| prepared.segments[s].index != tags.0[s])
                        .count()
                        + (0..4)
                            .filter(|&s| prepared.node_tags[s] != tags.1[s])
                            .count();
                    assert!(
                        changed <= 1,
                        "k={k} count {c}: {changed} pieces in one call"
                    );
                }
            }
            // Both directions entered prepared neighbours (k ≥ 1 has neighbours to prepare).
            if k > 0 {
                assert!(entered[0] >= 5 && entered[1] >= 5, "k={k}: {entered:?}");
            }
        }
    }
}
