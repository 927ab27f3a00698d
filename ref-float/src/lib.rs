//! Floating-point references of the liftfw estimator step, for benchmarks only.
//!
//! The product computes in fixed point (`liftfw::estimator`). Issue 3 item 8 and issue 8 ask
//! what that buys against the obvious alternatives on the same chip, so this crate holds the
//! *same* step written in floating point, once, generic over [`Real`]:
//!
//! - [`EstimatorF32`]: `f32` with `micromath`'s approximations of acos/sin/exp, what a
//!   Cortex-M4F build would use to stay on the single-precision FPU;
//! - [`EstimatorF64`]: `f64` with `libm` (soft-float on a Cortex-M4F: every operation is a
//!   call into `compiler_builtins`).
//!
//! Same equations as the fixed-point step, in the same order: α-β-γ filter on the encoder count,
//! pose from the count (x → cos α → α = acos, sin α), R, F₀, c_x(cos α), the friction law with its
//! exponential, the contact on either flank, the screw and motor torques, the residual and the
//! self-locking margin. Configuration is taken from the core's own [`EstimatorConfig`] (and
//! validated by it), converted once in `f64`.
//!
//! Floats are allowed here because this crate is a reference, never linked into the firmware.
#![no_std]
#![forbid(unsafe_code)]

use core::ops::{Add, Div, Mul, Neg, Sub};
use liftfw::estimator::{EstimateFlags, Estimator, EstimatorConfig};
use liftfw::model::friction::LawVariable;
use liftfw::model::geometry::DAMPING_TABLE;
use liftfw::ConfigError;

/// The arithmetic the float step needs: the field operations plus acos, sin and exp.
pub trait Real:
    Copy
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// Zero.
    const ZERO: Self;
    /// One.
    const ONE: Self;
    /// From `f64` (configuration time).
    fn of(v: f64) -> Self;
    /// From an integer (encoder counts).
    fn of_i32(v: i32) -> Self;
    /// To `f64` (tests and display).
    fn to_f64(self) -> f64;
    /// arccos, in [0, π].
    fn acos(self) -> Self;
    /// sine.
    fn sin(self) -> Self;
    /// e^x.
    fn exp(self) -> Self;
    /// |x|.
    fn abs(self) -> Self {
        if self < Self::ZERO {
            -self
        } else {
            self
        }
    }
    /// The smaller of two values.
    fn min(self, o: Self) -> Self {
        if o < self {
            o
        } else {
            self
        }
    }
    /// The larger of two values.
    fn max(self, o: Self) -> Self {
        if o > self {
            o
        } else {
            self
        }
    }
}

impl Real for f32 {
    const ZERO: f32 = 0.0;
    const ONE: f32 = 1.0;
    #[inline]
    fn of(v: f64) -> f32 {
        v as f32
    }
    #[inline]
    fn of_i32(v: i32) -> f32 {
        v as f32
    }
    #[inline]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    // Called through the trait so that a host build with std linked in cannot pick std's
    // inherent (libm-exact) methods instead of micromath's approximations.
    #[inline]
    fn acos(self) -> f32 {
        micromath::F32Ext::acos(self)
    }
    #[inline]
    fn sin(self) -> f32 {
        micromath::F32Ext::sin(self)
    }
    #[inline]
    fn exp(self) -> f32 {
        micromath::F32Ext::exp(self)
    }
}

impl Real for f64 {
    const ZERO: f64 = 0.0;
    const ONE: f64 = 1.0;
    #[inline]
    fn of(v: f64) -> f64 {
        v
    }
    #[inline]
    fn of_i32(v: i32) -> f64 {
        f64::from(v)
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline]
    fn acos(self) -> f64 {
        libm::acos(self)
    }
    #[inline]
    fn sin(self) -> f64 {
        libm::sin(self)
    }
    #[inline]
    fn exp(self) -> f64 {
        libm::exp(self)
    }
}

/// What the board measured this tick, in float units (the fixed-point step's `Measurements`).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct FloatMeasurements<T> {
    /// Motor encoder position, counts from fully down.
    pub position_counts: i32,
    /// Motor current, A (positive drives lifting).
    pub motor_current: T,
    /// Load the model assumes, kg.
    pub load: T,
    /// Commanded direction (−1, 0, +1).
    pub commanded_dir: i8,
}

impl<T: Real> FloatMeasurements<T> {
    /// The same measurements as the fixed-point step sees them.
    pub fn from_fixed(m: &liftfw::estimator::Measurements) -> Self {
        FloatMeasurements {
            position_counts: m.position_counts,
            motor_current: T::of(m.motor_current.to_f64()),
            load: T::of(m.load.to_f64()),
            commanded_dir: m.commanded_dir,
        }
    }
}

/// The float step's output: the fixed-point `TickEstimate`'s fields in SI units (what the
/// control tick reads; [`FloatEstimator::details`] gives the rest, as the core's `details`).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct FloatTick<T> {
    /// Head height, m.
    pub height: T,
    /// Screw speed θ̇, rad/s.
    pub screw_speed: T,
    /// Screw acceleration θ̈, rad/s².
    pub screw_accel: T,
    /// Friction torque T_r, N·m.
    pub friction_torque: T,
    /// Axial demand W, N.
    pub axial: T,
    /// Thread torque r_m·W·ξ, N·m.
    pub thread_torque: T,
    /// Torque the model says the screw needs, N·m.
    pub model_screw_torque: T,
    /// The same at the motor shaft, N·m.
    pub model_motor_torque: T,
    /// Torque the motor delivers to the screw, N·m.
    pub measured_screw_torque: T,
    /// `liftfw::estimator::EstimateFlags` bits (no SATURATED: floats do not saturate).
    pub flags: u8,
}

/// The float model's whole output: the fixed-point `Estimate`'s fields in SI units.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct FloatEstimate<T> {
    /// Arm angle α, rad.
    pub alpha: T,
    /// Head height, m.
    pub height: T,
    /// Screw speed θ̇, rad/s.
    pub screw_speed: T,
    /// Screw acceleration θ̈, rad/s².
    pub screw_accel: T,
    /// Axial load R, N.
    pub axial_load: T,
    /// Pin friction F₀, N.
    pub pin_friction: T,
    /// Structure damping c_x, kg/s.
    pub structure_damping: T,
    /// Friction coefficient μ.
    pub mu: T,
    /// Signed friction coefficient μ_s.
    pub mu_s: T,
    /// ξ of the flank in contact.
    pub xi: T,
    /// Axial demand W, N.
    pub axial: T,
    /// Thread normal force N, N.
    pub normal: T,
    /// Friction torque T_r, N·m.
    pub friction_torque: T,
    /// Thread torque r_m·W·ξ, N·m.
    pub thread_torque: T,
    /// Torque the model says the screw needs, N·m.
    pub model_screw_torque: T,
    /// The same at the motor shaft, N·m.
    pub model_motor_torque: T,
    /// Torque the motor delivers to the screw, N·m.
    pub measured_screw_torque: T,
    /// measured − model, N·m.
    pub residual: T,
    /// μ − tan λ.
    pub self_locking_margin: T,
    /// `liftfw::estimator::EstimateFlags` bits (no SATURATED: floats do not saturate).
    pub flags: u8,
}

/// The estimator step in floating point, generic over the float type.
#[derive(Clone, Debug)]
pub struct FloatEstimator<T> {
    // Geometry.
    metres_per_count: T,
    inv_len: T,
    length: T,
    h0: T,
    cos_a0: T,
    cos_lo: T,
    cos_hi: T,
    two_mu_pin: T,
    /// (cos α, c_x, slope per unit of cos α below the row's): Table 1 linear in cos α, as
    /// the fixed-point model reads it.
    damping: [(T, T, T); 3],
    // Friction law: μ = base + amp·e^(−rate·k·|θ̇|) + slope·k·min(|θ̇|, s_max/k).
    law_base: T,
    law_amp: T,
    law_rate_k: T,
    law_slope_k: T,
    law_rate_max: T,
    // Screw.
    r_m: T,
    tan_l: T,
    sec_l: T,
    lead: T,
    mass_lead: T,
    inertia: T,
    damping_c: T,
    support_torque: T,
    // Motor.
    kt: T,
    n_eta: T,
    n_over_eta: T,
    eta_over_n: T,
    inv_n_eta: T,
    // Filter.
    tick_us: u32,
    rest_speed: T,
    gains: [T; 3],
    speed_scale: T,
    accel_scale: T,
    p: T,
    v: T,
    a: T,
    last: Option<u32>,
}

/// The f32 step with micromath (hardware single-precision FPU on a Cortex-M4F).
pub type EstimatorF32 = FloatEstimator<f32>;
/// The f64 step with libm (soft-float on a Cortex-M4F).
pub type EstimatorF64 = FloatEstimator<f64>;

const G: f64 = 9.806_65;

impl<T: Real> FloatEstimator<T> {
    /// Validate the configuration through the fixed-point core (same refusals), then convert
    /// it once in `f64`.
    pub fn new(cfg: &EstimatorConfig) -> Result<Self, ConfigError> {
        Estimator::new(cfg)?;
        let deg = core::f64::consts::PI / 180.0;
        let g = &cfg.geometry;
        let d = &cfg.drive;
        let mech = &cfg.mechanics;
        let lambda = d.lead_angle_deg.to_num::<f64>() * deg;
        let (tan_l, cos_l) = (libm::tan(lambda), libm::cos(lambda));
        let r_m = d.pitch_radius.to_f64();
        let gear = d.gear_ratio.to_num::<f64>();
        let counts_per_screw_rad =
            f64::from(d.counts_per_rev) * gear / (2.0 * core::f64::consts::PI);
        let rad_per_count = 1.0 / counts_per_screw_rad;
        let length = g.length.to_f64();
        let alpha0 = g.alpha0_deg.to_num::<f64>() * deg;

        let mut damping = [(T::ZERO, T::ZERO, T::ZERO); 3];
        let cos_deg = |a: i32| libm::cos(f64::from(a) * deg);
        for i in 0..3 {
            let (a0, c0) = DAMPING_TABLE[i];
            let slope = if i < 2 {
                let (a1, c1) = DAMPING_TABLE[i + 1];
                f64::from(c1 - c0) / (cos_deg(a0) - cos_deg(a1))
            } else {
                0.0
            };
            damping[i] = (T::of(cos_deg(a0)), T::of(f64::from(c0)), T::of(slope));
        }

        let law = &cfg.law;
        // s = k·|θ̇|, in the law's own variable. The fixed-point core reads the Q16 speed bits as
        // a Q28 τ for a lubrication law, i.e. τ = |θ̇|/4096: the same here.
        let k = match law.variable {
            LawVariable::ScrewRate => 1.0,
            LawVariable::SlidingSpeed => r_m / cos_l,
            LawVariable::Lubrication => 1.0 / 4096.0,
        };
        let rate = law.rate.to_num::<f64>();
        let slope = law.slope.to_num::<f64>();
        let s_max = law.s_max.to_num::<f64>();

        let n = gear;
        let eta = cfg.motor.gear_efficiency.to_f64();
        let tick_hz = 1e6 / f64::from(cfg.tick_us);
        let theta = libm::exp(
            -2.0 * core::f64::consts::PI
                * f64::from(cfg.speed_bandwidth_hz)
                * f64::from(cfg.tick_us)
                / 1e6,
        );
        let om = 1.0 - theta;
        Ok(FloatEstimator {
            metres_per_count: T::of(r_m * tan_l * rad_per_count),
            inv_len: T::of(1.0 / length),
            length: T::of(length),
            h0: T::of(g.h0.to_f64()),
            cos_a0: T::of(libm::cos(alpha0)),
            cos_lo: T::of(libm::cos(89.5 * deg)),
            cos_hi: T::of(libm::cos(alpha0 - 5.0 * deg)),
            two_mu_pin: T::of(2.0 * g.mu_pin.to_f64()),
            damping,
            law_base: T::of(law.base.to_f64()),
            law_amp: T::of(law.amp.to_f64()),
            law_rate_k: T::of(rate * k),
            law_slope_k: T::of(slope * k),
            law_rate_max: T::of(s_max / k),
            r_m: T::of(r_m),
            tan_l: T::of(tan_l),
            sec_l: T::of(1.0 / cos_l),
            lead: T::of(r_m * tan_l),
            mass_lead: T::of(mech.nut_mass.to_f64() * r_m * tan_l),
            inertia: T::of(f64::from(mech.inertia_ukgm2) * 1e-6),
            damping_c: T::of(f64::from(mech.damping_unms) * 1e-6),
            support_torque: T::of(mech.support_torque.to_f64()),
            kt: T::of(cfg.motor.torque_constant.to_f64()),
            n_eta: T::of(n * eta),
            n_over_eta: T::of(n / eta),
            eta_over_n: T::of(eta / n),
            inv_n_eta: T::of(1.0 / (n * eta)),
            tick_us: cfg.tick_us,
            rest_speed: T::of(cfg.rest_speed.to_f64()),
            gains: [
                T::of(1.0 - theta * theta * theta),
                T::of(1.5 * om * om * (1.0 + theta)),
                T::of(om * om * om),
            ],
            speed_scale: T::of(rad_per_count * tick_hz),
            accel_scale: T::of(rad_per_count * tick_hz * tick_hz),
            p: T::ZERO,
            v: T::ZERO,
            a: T::ZERO,
            last: None,
        })
    }

    /// Restart the speed filter at a position, at rest.
    pub fn reset(&mut self, position_counts: i32) {
        self.p = T::of_i32(position_counts);
        self.v = T::ZERO;
        self.a = T::ZERO;
        self.last = None;
    }

    /// One estimator tick (`now` in µs, wrapping), as `liftfw::estimator::Estimator::step`.
    pub fn step(&mut self, now_us: u32, m: &FloatMeasurements<T>) -> FloatTick<T> {
        let mut flags = 0u8;
        match self.last {
            None => self.reset(m.position_counts),
            Some(prev) => {
                if u64::from(now_us.wrapping_sub(prev)) * 2 > u64::from(self.tick_us) * 3 {
                    flags |= EstimateFlags::LATE_TICK;
                }
            }
        }
        self.last = Some(now_us);
        let half = T::of(0.5);
        self.p = self.p + self.v + self.a * half;
        self.v = self.v + self.a;
        let r = T::of_i32(m.position_counts) - self.p;
        self.p = self.p + r * self.gains[0];
        self.v = self.v + r * self.gains[1];
        self.a = self.a + r * self.gains[2];
        let speed = self.v * self.speed_scale;
        let accel = self.a * self.accel_scale;
        // The same scope as the fixed-point step: the model inlined, only the tick's fields
        // kept (the diagnostics are dead code).
        let e = self.estimate(m, speed, accel, flags);
        FloatTick {
            height: e.height,
            screw_speed: e.screw_speed,
            screw_accel: e.screw_accel,
            friction_torque: e.friction_torque,
            axial: e.axial,
            thread_torque: e.thread_torque,
            model_screw_torque: e.model_screw_torque,
            model_motor_torque: e.model_motor_torque,
            measured_screw_torque: e.measured_screw_torque,
            flags: e.flags,
        }
    }

    /// The whole estimate of a tick [`Self::step`] returned `tick` for (as the core's
    /// `Estimator::details`).
    pub fn details(&self, m: &FloatMeasurements<T>, tick: &FloatTick<T>) -> FloatEstimate<T> {
        self.estimate(m, tick.screw_speed, tick.screw_accel, tick.flags)
    }

    /// The model at a given speed (rad/s) and acceleration (rad/s²), without the filter.
    #[inline(always)]
    pub fn estimate(
        &self,
        m: &FloatMeasurements<T>,
        speed: T,
        accel: T,
        mut flags: u8,
    ) -> FloatEstimate<T> {
        // Pose (Eq 1): cos α = cos α₀ − x/L, clamped to the mechanism.
        let x = T::of_i32(m.position_counts) * self.metres_per_count;
        let mut c = self.cos_a0 - x * self.inv_len;
        if c > self.cos_hi {
            c = self.cos_hi;
            flags |= EstimateFlags::POSE_CLAMPED;
        } else if c < self.cos_lo {
            c = self.cos_lo;
            flags |= EstimateFlags::POSE_CLAMPED;
        }
        let alpha = c.acos();
        let s = alpha.sin();
        let inv_s = T::ONE / s;
        let height = self.h0 + self.length * s;

        let dir: i8 = if speed > self.rest_speed {
            1
        } else if speed < -self.rest_speed {
            -1
        } else {
            flags |= EstimateFlags::AT_REST;
            m.commanded_dir.signum()
        };
        let dir_t = T::of_i32(i32::from(dir));

        // R (Eq 1), F₀ (Eq 6), c_x (Eq 4, Table 1 linear in cos α).
        let ws = m.load * T::of(G) * inv_s;
        let axial_load = ws * c;
        let pin_friction = ws * self.two_mu_pin;
        let t = &self.damping;
        let c_x = if c >= t[0].0 {
            t[0].1
        } else if c >= t[1].0 {
            t[0].1 + (t[0].0 - c) * t[0].2
        } else if c >= t[2].0 {
            t[1].1 + (t[1].0 - c) * t[1].2
        } else {
            t[2].1
        };

        // Friction law.
        let w_abs = speed.abs();
        let mu = (self.law_base
            + self.law_amp * (-(self.law_rate_k * w_abs)).exp()
            + self.law_slope_k * w_abs.min(self.law_rate_max))
        .max(T::ZERO);

        // Contact (Eqs 7–10), either flank.
        // R + F₀·dir in one product, as the fixed-point step.
        let w =
            self.mass_lead * accel + ws * (c + self.two_mu_pin * dir_t) + c_x * self.lead * speed;
        let mu_s = mu * dir_t;
        let mt = mu_s * self.tan_l;
        let loaded = w >= T::ZERO;
        if !loaded {
            flags |= EstimateFlags::FLANK_REVERSED;
        }
        let (den, num) = if loaded {
            (T::ONE - mt, self.tan_l + mu_s)
        } else {
            (T::ONE + mt, self.tan_l - mu_s)
        };
        let inv = T::ONE / den;
        let xi = num * inv;
        let w_inv = w * inv;
        let normal = w_inv * self.sec_l;
        let friction_torque = w_inv.abs() * mu_s * self.r_m;
        let thread_torque = w * xi * self.r_m;

        let model_screw_torque = self.inertia * accel
            + self.damping_c * speed
            + self.support_torque * dir_t
            + thread_torque;
        let motoring = (model_screw_torque >= T::ZERO) == (dir >= 0) || dir == 0;
        let model_motor_torque = if motoring {
            model_screw_torque * self.inv_n_eta
        } else {
            model_screw_torque * self.eta_over_n
        };
        let motor_torque = m.motor_current * self.kt;
        let measured_motoring = (motor_torque >= T::ZERO) == (dir >= 0) || dir == 0;
        let measured_screw_torque = if measured_motoring {
            motor_torque * self.n_eta
        } else {
            motor_torque * self.n_over_eta
        };
        FloatEstimate {
            alpha,
            height,
            screw_speed: speed,
            screw_accel: accel,
            axial_load,
            pin_friction,
            structure_damping: c_x,
            mu,
            mu_s,
            xi,
            axial: w,
            normal,
            friction_torque,
            thread_torque,
            model_screw_torque,
            model_motor_torque,
            measured_screw_torque,
            residual: measured_screw_torque - model_screw_torque,
            self_locking_margin: mu - self.tan_l,
            flags,
        }
    }
}
