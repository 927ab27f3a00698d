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
//!
//! `filter`: the speed filter; `pose`: the pose between exact nodes (segments, their
//! preparation off the step's path, the node spacing chosen per configuration); here: the
//! configuration, the step and the model.

mod filter;
mod pose;

use crate::keys::{self, ConfigError};
use crate::math::div128;
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
use pose::{Node, PoseBudget, PoseCtx, PoseSegment, NO_NODE};

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
    /// Inertia of the rotor and the gearbox's input stage at the motor shaft, µkg·m²
    /// (0…100 000): n²·η times it at the screw, where the current's acceleration torque is
    /// taken out of the load identification's samples (`control::loadid`).
    pub inertia_ukgm2: i32,
}

impl MotorConfig {
    /// A 12 V gear motor of the jack class: k_t = 0.04 N·m/A, gearbox efficiency 0.85, loop
    /// resistance 0.091 Ω (60 mΩ armature + 16 mΩ bridge + 15 mΩ battery): the default board's
    /// motor, the same values as host-sim's drive (docs/plant.md).
    pub const DEFAULT: MotorConfig = MotorConfig {
        torque_constant: Ratio::lit("0.04"),
        gear_efficiency: Ratio::lit("0.85"),
        resistance: Ratio::lit("0.091"),
        // Rotor 50 + gearbox input 10 µkg·m² (host-sim's drive).
        inertia_ukgm2: 60,
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

/// A friction scale being put in force at rest ([`Estimator::begin_friction_scale`]).
#[derive(Clone, Copy, Debug)]
struct Rescale {
    /// The scaled law, in force once the table is.
    law: CompiledLaw,
    scale: Ratio,
    /// The new scale over the one in force (Q28).
    ratio: Ratio,
    /// The next table node to scale.
    next: u8,
}

/// Table nodes a [`Estimator::rescale_step`] scales (≈ 30 instructions each).
const RESCALE_NODES: u8 = 24;

/// The estimator's configuration and state.
#[derive(Clone, Debug)]
pub struct Estimator {
    geometry: Geometry,
    screw: ScrewModel,
    law: CompiledLaw,
    /// The law tabulated over |θ̇|, interpolated in the segments where that is exact enough
    /// and the exact law, out of line, in the others ([`MuTable::build`]).
    mu_table: MuTable,
    /// The friction scale in force on the configured law (1 unless identified).
    scale: Ratio,
    /// A rescale under way at rest ([`Self::begin_friction_scale`]).
    rescale: Option<Rescale>,
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
            return Err(keys::MOTOR_KT.out_of_range());
        }
        if !(m.gear_efficiency >= const { Ratio::lit("0.1") } && m.gear_efficiency <= Ratio::ONE) {
            return Err(keys::MOTOR_GEAR_EFFICIENCY.out_of_range());
        }
        if !(m.resistance >= const { Ratio::lit("0.001") }
            && m.resistance <= const { Ratio::lit("4") })
        {
            return Err(keys::MOTOR_RESISTANCE.out_of_range());
        }
        if !(0..=100_000).contains(&m.inertia_ukgm2) {
            return Err(keys::MOTOR_INERTIA.out_of_range());
        }
        if !(100..=10_000).contains(&cfg.tick_us) {
            return Err(keys::CONTROL_TICK_US.out_of_range());
        }
        let tick_hz = 1_000_000 / cfg.tick_us;
        if cfg.speed_bandwidth_hz < 1 || cfg.speed_bandwidth_hz > tick_hz / 10 {
            return Err(keys::CONTROL_SPEED_BANDWIDTH.out_of_range());
        }
        if !(cfg.rest_speed >= RadiansPerSecond::ZERO
            && cfg.rest_speed <= const { RadiansPerSecond::lit("50") })
        {
            return Err(keys::CONTROL_REST_SPEED.out_of_range());
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
            return Err(keys::MOTOR_GEAR_EFFICIENCY
                .conflict("drive.gear_ratio x motor.gear_efficiency must exceed 0.125"));
        }
        let inv_n_eta = Ratio::from_raw(div128(1i128 << 72, n_eta_q44) as i32);

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
            scale: Ratio::ONE,
            rescale: None,
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
            gains: filter::gains(cfg.speed_bandwidth_hz, cfg.tick_us),
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

    /// log2 of the pose's node spacing in counts (`PoseSegment`); 0: the exact pose at every
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

    /// Run the law the estimator was built with scaled by `scale` (base, amplitude and slope
    /// times s: the friction
    /// scale a lift/lowering pair identified, or the store's at boot; the floor at 0
    /// commutes) from now on: [`Self::begin_friction_scale`] and every
    /// [`Self::rescale_step`] at once. The pose's node spacing, chosen for the configured
    /// law's μ, is kept. Refused (nothing changes) when the scaled law leaves the law's
    /// validated ranges.
    pub fn set_friction_scale(&mut self, scale: Ratio) -> Result<(), ConfigError> {
        self.begin_friction_scale(scale)?;
        self.finish_rescale();
        Ok(())
    }

    /// [`Self::set_friction_scale`] spread over the ticks at rest (`scale` on the law the
    /// estimator was built with): this call takes the law in force times the ratio of the
    /// scales ([`CompiledLaw::rescaled`]: no compile), each
    /// [`Self::rescale_step`] scales `RESCALE_NODES` (24) of its table's nodes
    /// ([`MuTable::rescale_nodes`]: the law is linear in its scale), and the last of them puts
    /// the law in force. Until then the table is part old, part new: [`Self::finish_rescale`]
    /// completes it before a motion. Refused (nothing changes) as [`Self::set_friction_scale`].
    pub fn begin_friction_scale(&mut self, scale: Ratio) -> Result<(), ConfigError> {
        self.finish_rescale();
        let old = i64::from(self.scale.bits()).max(1);
        let ratio = Ratio::from_raw(crate::units::sat32((i64::from(scale.bits()) << 28) / old));
        // The law in force (the configured law at the scale in force) times the ratio.
        let c = *self.law.law();
        let slope = c.slope.to_bits();
        // slope (Q32, |·| ≤ 1000·2^32 < 2^42) times the ratio (Q28, < 2^31), by halves.
        let r = i64::from(ratio.bits());
        let slope = (slope >> 28) * r + (((slope & ((1 << 28) - 1)) * r) >> 28);
        let law = FrictionLaw {
            base: qmul(c.base, ratio),
            amp: qmul(c.amp, ratio),
            slope: fixed::types::I32F32::from_bits(slope),
            ..c
        };
        let law = self.law.rescaled(&law, ratio)?;
        self.rescale = Some(Rescale {
            law,
            scale,
            ratio,
            next: 0,
        });
        Ok(())
    }

    /// One piece of a rescale under way: `RESCALE_NODES` nodes of the table; the last piece
    /// puts the scaled law in force. True when none is under way (any more).
    pub fn rescale_step(&mut self) -> bool {
        let Some(r) = self.rescale.as_mut() else {
            return true;
        };
        let to = r.next.saturating_add(RESCALE_NODES);
        self.mu_table
            .rescale_nodes(r.ratio.bits(), usize::from(r.next), usize::from(to));
        r.next = to;
        if usize::from(to) < crate::model::friction::MU_TABLE_LEN {
            return false;
        }
        if let Some(r) = self.rescale.take() {
            self.law = r.law;
            self.scale = r.scale;
        }
        true
    }

    /// Whether a rescale is under way.
    pub fn rescaling(&self) -> bool {
        self.rescale.is_some()
    }

    /// Complete a rescale under way at once (before a motion: its table must be one law's).
    pub fn finish_rescale(&mut self) {
        while !self.rescale_step() {}
    }

    /// The whole estimate of a tick that [`Self::step`] returned `tick` for, with `m` its
    /// measurements: the same numbers (bit for bit) plus the diagnostics (pose, R, F₀, c_x, μ,
    /// ξ, N, residual, self-locking margin). Recomputed from the tick's inputs (the pose
    /// segment's two nodes and the exact pose: ≈ 2.8 steps), for telemetry and tests rather
    /// than every tick.
    pub fn details(&self, m: &Measurements, tick: &TickEstimate) -> Estimate {
        self.estimate(m, tick.screw_speed, tick.screw_accel, tick.flags.0)
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
        // On a saturation bound (MAX or MIN): v ^ (v >> 31) is MAX for both, and as it is never
        // negative, it plus 1 has the sign bit set for exactly those two. One OR of the five
        // sums and one test of its sign: branch-free, and three instructions a value where a
        // compare and a conditional move for each were four (opt-level "z", docs/qemu.md).
        let on_bound = |v: i32| (v ^ (v >> 31)).wrapping_add(1);
        let bounds = on_bound(core.friction_torque.bits())
            | on_bound(core.thread_torque.bits())
            | on_bound(model_screw_torque.bits())
            | on_bound(model_motor_torque.bits())
            | on_bound(measured_screw_torque.bits());
        if clamped | (bounds < 0) {
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
