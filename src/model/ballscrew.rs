//! Ball-screw friction in fixed point (seed 002, Zhang, Zhou & Feng 2021): the f(τ) law, the
//! friction torque from the axial load (Eq 1) and its inverse, the friction coefficient from a
//! measured torque (Eq 2), so that the board can identify f online from motor current.
//!
//! Readings (docs/model.md, "Ball screw"):
//! - Eq 1 as printed gives `M_f = f·F·(r_m + r_b cos α)/sin α` (its `M·Q·cos β` cancels), while
//!   Eq 2 inverts `M_f = 2·f·F·(r_m + r_b cos α)/sin α`. We take Eq 2's factor 2 (each ball rubs
//!   on the screw *and* on the nut raceway), so that Eq 2 is exactly the inverse of our Eq 1:
//!   the identification loop (measure with Eq 2, predict with Eq 1) is then consistent whatever
//!   the factor really is.
//! - `F` is the axial force on the loaded balls: the preload plus |R|, the lift's axial load
//!   (seed 002: "when there is no external load … the preload is regarded as the axial load").
//! - τ = η₀·V/P (Eq 3) with P = F/(M sin α cos β) the normal load per ball (seed 002's Q) and V
//!   the ball-centre circle's speed r_m·|θ̇| (seed 002 says only "relative speed of the
//!   ball–raceway contact").
//! - The ball screw is not self-locking: the load alone turns it with torque `|R|·l/(2π)`
//!   ([`BallScrew::load_torque`]), against which only the friction torque holds.
//!
//! Every function has a float64 twin in `host_sim::physics::ballscrew` and a property test in
//! `tests/ballscrew_vs_float_twin.rs`.

// The ball-screw build uses every import; the lead-screw build only the configuration's.
#![cfg_attr(not(feature = "ball-screw"), allow(unused_imports))]
use crate::keys::{self, check_range, ConfigError};
use crate::model::friction::{CompiledLaw, FrictionLaw, LawVariable};
use crate::model::Scale;
use crate::units::{qmul, Angle, Metres, NewtonMetres, Newtons, RadiansPerSecond, Ratio, Q};
use fixed::types::{I16F16, I32F32};

/// The ball screw's geometry and lubricant, as the user gives them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BallScrewConfig {
    /// Radius of the ball-centre circle r_m, 2…100 mm.
    pub r_m: Metres,
    /// Ball radius r_b, 0.5…20 mm, less than r_m.
    pub r_b: Metres,
    /// Contact angle α, 20…80°.
    pub contact_angle_deg: I16F16,
    /// Lead l (travel per screw turn), 0.5…50 mm.
    pub lead: Metres,
    /// Number of loaded balls M, 1…1000.
    pub loaded_balls: u16,
    /// Preload F_p, 0…100 kN.
    pub preload: Newtons,
    /// Dynamic viscosity of the lubricant η₀, 10⁻⁴…10 Pa·s.
    pub viscosity: I32F32,
    /// The friction law; must be written in τ ([`LawVariable::Lubrication`]).
    pub law: FrictionLaw,
}

impl BallScrewConfig {
    /// Seed 001's 4008-3 ball screw (r_m = 20 mm, ball Ø4.763 mm, α = 45°, lead 8 mm, 78 balls,
    /// no preload) in ISO VG100 oil (η₀ ≈ 0.09 Pa·s at 40 °C, the oil of seed 002's tests) with
    /// seed 002's law.
    pub const SEED_001_4008: BallScrewConfig = BallScrewConfig {
        r_m: Metres::lit("0.020"),
        r_b: Metres::lit("0.0023815"),
        contact_angle_deg: I16F16::lit("45"),
        lead: Metres::lit("0.008"),
        loaded_balls: 78,
        preload: Newtons::ZERO,
        viscosity: I32F32::lit("0.09"),
        law: FrictionLaw::BALL_SCREW,
    };

    /// Validate and quantise once.
    #[cfg(feature = "ball-screw")]
    pub fn compile(&self) -> Result<BallScrew, ConfigError> {
        check_range(
            self.r_m,
            const { Metres::lit("0.002") },
            const { Metres::lit("0.1") },
            &keys::BALLSCREW_R_M,
        )?;
        check_range(
            self.r_b,
            const { Metres::lit("0.0005") },
            const { Metres::lit("0.02") },
            &keys::BALLSCREW_R_B,
        )?;
        if self.r_b >= self.r_m {
            return Err(keys::BALLSCREW_R_B.conflict("must be less than ballscrew.r_m"));
        }
        check_range(
            self.contact_angle_deg,
            const { I16F16::lit("20") },
            const { I16F16::lit("80") },
            &keys::BALLSCREW_CONTACT_ANGLE,
        )?;
        check_range(
            self.lead,
            const { Metres::lit("0.0005") },
            const { Metres::lit("0.05") },
            &keys::BALLSCREW_LEAD,
        )?;
        check_range(self.loaded_balls, 1, 1000, &keys::BALLSCREW_BALLS)?;
        check_range(
            self.preload,
            Newtons::ZERO,
            const { Newtons::lit("100000") },
            &keys::BALLSCREW_PRELOAD,
        )?;
        check_range(
            self.viscosity,
            const { I32F32::lit("0.0001") },
            const { I32F32::lit("10") },
            &keys::BALLSCREW_VISCOSITY,
        )?;
        if self.law.variable != LawVariable::Lubrication {
            return Err(ConfigError::Conflict {
                field: "ballscrew.law",
                reason: "a ball-screw law is written in tau = eta0*V/P",
            });
        }
        // The law's r_m/cos λ only matter for sliding-speed laws: any valid values do. Its
        // refusals name the `ballscrew.f_*` keys (the law's own name the estimator's).
        let law = self.law.compile_keyed(
            self.r_m,
            Ratio::ONE,
            &[
                &keys::BALLSCREW_F_BASE,
                &keys::BALLSCREW_F_AMP,
                &keys::BALLSCREW_F_RATE,
                &keys::BALLSCREW_F_SLOPE,
                &keys::BALLSCREW_F_S_MAX,
            ],
        )?;

        // Design in integers (no floating point linked into the firmware): lengths in Q24,
        // cos α and sin α in Q28, rationals in i128, quantised once by `Scale::from_ratio`.
        let (cos_a, sin_a) = Angle::from_degrees(self.contact_angle_deg).cos_sin();
        let (rm, rb) = (i128::from(self.r_m.bits()), i128::from(self.r_b.bits()));
        let lead = i128::from(self.lead.bits());
        let (ca, sa) = (i128::from(cos_a.bits()), i128::from(sin_a.bits()).max(1));
        // Eq 1 (with Eq 2's factor 2): M_f = f·F·arm, arm = 2(r_m + r_b cos α)/sin α; arm in
        // Q52/Q28 = num52/sa in Q24.
        let num52 = 2 * ((rm << 28) + rb * ca);
        // f·F (N, Q8) → N·m (Q16): ×arm·2^8 = num52/(sa·2^16).
        let arm_scale = Scale::from_ratio(num52, sa << 16);
        // Lever l/(2π): F (Q8) → N·m (Q16) is ×lever·2^8 = lead/(2^16·2π).
        let lever_scale = Scale::from_ratio(lead << 60, TWO_PI_Q60 << 16);
        // Through the one out-of-line `div128` (an inline `/` on i128 expands a long division at each use).
        let lever_q24 = crate::math::div128(lead << 60, TWO_PI_Q60);
        // Helix angle β: cos β = 2π r_m / √((2π r_m)² + l²), lengths in Q32 (≤ 0.63 m).
        let circ = (rm * TWO_PI_Q60) >> 52;
        let l32 = lead << 8;
        let hyp = i128::from(crate::math::isqrt_u64((circ * circ + l32 * l32) as u64)).max(1);
        // sin α·cos β in Q28.
        let sa_cb = sa * circ / hyp;
        // τ (Q28) = η₀·r_m·M·sin α·cos β · |θ̇| / F: numerator constant c (N·s), |θ̇| in Q16,
        // F in Q8 → τ_bits = c·2^20·θ̇_bits / F_bits, c·2^20 = η(Q32)·r_m(Q24)·M·(sa_cb)(Q28)/2^64.
        let eta = i128::from(self.viscosity.to_bits());
        let mul = crate::math::mul128;
        let tau_num = mul(mul(eta * rm, i128::from(self.loaded_balls)), sa_cb);
        let tau_scale = Scale::from_ratio(tau_num, 1i128 << 64);
        Ok(BallScrew {
            preload: self.preload,
            law,
            arm_scale,
            lever_scale,
            tau_scale,
            arm: Metres::from_raw(crate::units::sat32((num52 / sa) as i64)),
            lever: Metres::from_raw(crate::units::sat32(lever_q24 as i64)),
        })
    }

    /// [`BallScrewConfig::equivalent_thread_law`] in fixed point, for `law` (a law in τ, the
    /// estimator's) on this ball screw at axial force `f_axial`: what the ball-screw firmware
    /// gives its estimator when `drive.screw = ball` and the estimator's law is written in τ
    /// (configuration time only; no floating point). Validates this ball screw's settings and
    /// the result as a law in the screw rate (refusals name the `friction.*` keys). Error
    /// against the float64 twin: each parameter within 10⁻⁶ relative plus 2 LSB of its format
    /// (`thread_law_fixed_matches_the_twin`).
    #[cfg(feature = "ball-screw")]
    pub fn thread_law_fixed(
        &self,
        law: &FrictionLaw,
        f_axial: Newtons,
    ) -> Result<FrictionLaw, ConfigError> {
        let bs = self.compile()?;
        // F in Q8: at least 1 N.
        if f_axial.bits() < 1 << 8 {
            return Err(ConfigError::OutOfRange {
                field: "ballscrew.reference_force",
                range: ">= 1 N",
            });
        }
        let eq = bs.thread_law(self.r_m, law, f_axial);
        eq.compile(self.r_m, Ratio::ONE)?;
        Ok(eq)
    }

    /// The ball screw as a thread for the lead-screw model (estimator and plant): the friction
    /// law in the screw rate whose thread friction torque μ·W·r_m equals Eq 1's `f·F·arm` at
    /// axial force `f_axial`: `μ_eq(θ̇) = (arm/r_m)·f(τ)` with `τ = η₀ r_m M sin α cos β·|θ̇|/F`.
    /// The thread model adds `μ tan λ` (≈ 0.1 %) and `tan²λ` (≈ 0.4 %) corrections the ball
    /// screw does not have; τ's dependence on the load is frozen at `f_axial` (docs/model.md).
    /// Configuration time only.
    pub fn equivalent_thread_law(&self, f_axial: Newtons) -> Result<FrictionLaw, ConfigError> {
        let fa = f_axial.to_f64();
        if fa < 1.0 {
            return Err(ConfigError::OutOfRange {
                field: "ballscrew.reference_force",
                range: ">= 1 N",
            });
        }
        let law = self.thread_law_float(fa);
        // Validate the result as a law in its own right.
        law.compile(self.r_m, Ratio::ONE)?;
        Ok(law)
    }

    /// [`BallScrewConfig::equivalent_thread_law`] before validation, at `fa` ≥ 1 N (float64;
    /// the twin of [`BallScrewConfig::thread_law_fixed`]).
    fn thread_law_float(&self, fa: f64) -> FrictionLaw {
        let (k, c) = self.float_design();
        let tau_per_rate = c / fa;
        let l = &self.law;
        FrictionLaw {
            base: Ratio::from_f64(l.base.to_f64() * k),
            amp: Ratio::from_f64(l.amp.to_f64() * k),
            rate: I32F32::saturating_from_num(l.rate.to_num::<f64>() * tau_per_rate),
            slope: I32F32::saturating_from_num(l.slope.to_num::<f64>() * k * tau_per_rate),
            s_max: if l.s_max == I32F32::MAX {
                I32F32::MAX
            } else {
                I32F32::saturating_from_num(l.s_max.to_num::<f64>() / tau_per_rate)
            },
            variable: LawVariable::ScrewRate,
        }
    }

    /// arm/r_m and η₀ r_m M sin α cos β in float64, for [`BallScrewConfig::equivalent_thread_law`]
    /// (configuration time on the host; not linked into the firmware).
    fn float_design(&self) -> (f64, f64) {
        let alpha = Angle::from_degrees(self.contact_angle_deg);
        let (cos_a, sin_a) = alpha.cos_sin();
        let (ca, sa) = (cos_a.to_f64(), sin_a.to_f64());
        let (rm, rb, lead) = (self.r_m.to_f64(), self.r_b.to_f64(), self.lead.to_f64());
        let tan_b = lead / (2.0 * core::f64::consts::PI * rm);
        let cos_b = 1.0 / sqrt_f64(1.0 + tan_b * tan_b);
        let arm = 2.0 * (rm + rb * ca) / sa;
        let c = self.viscosity.to_num::<f64>() * rm * f64::from(self.loaded_balls) * sa * cos_b;
        (arm / rm, c)
    }
}

/// A scale's constant in a format of `frac` fractional bits (≤ 32), floored, saturated to
/// `i32` (the Q28 ratios: μ ≤ 8).
#[cfg(feature = "ball-screw")]
fn scale_bits(s: Scale, frac: u32) -> i32 {
    let (m, sh) = s.parts();
    let v = if sh <= frac {
        i64::from(m) << (frac - sh)
    } else {
        i64::from(m) >> (sh - frac)
    };
    crate::units::sat32(v)
}

/// A scale's constant as `I32F32`, floored; a saturated scale (±2^31) is `I32F32::MAX`/`MIN`,
/// as the float64 twin's `saturating_from_num`.
#[cfg(feature = "ball-screw")]
fn scale_q32(s: Scale) -> I32F32 {
    let (m, sh) = s.parts();
    if sh == 0 && m.unsigned_abs() == i32::MAX as u32 {
        return if m < 0 { I32F32::MIN } else { I32F32::MAX };
    }
    I32F32::from_bits(if sh <= 32 {
        i64::from(m) << (32 - sh)
    } else {
        i64::from(m) >> (sh - 32)
    })
}

/// 2π in Q60.
#[cfg(feature = "ball-screw")]
const TWO_PI_Q60: i128 = 7_244_019_458_077_122_842;

/// √x for configuration time without libm (`core` has no `f64::sqrt`): Newton from above,
/// to the last bit for 1 ≤ x ≤ 10⁶.
fn sqrt_f64(x: f64) -> f64 {
    let mut s = if x > 1.0 { x } else { 1.0 };
    for _ in 0..64 {
        let next = 0.5 * (s + x / s);
        if next >= s {
            break;
        }
        s = next;
    }
    s
}

/// A compiled ball screw: every per-tick operation is a few integer multiplies.
#[cfg(feature = "ball-screw")]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BallScrew {
    /// F_p (the rest of the configuration is compiled into the constants below; the
    /// controller keeps the configuration itself).
    preload: Newtons,
    law: CompiledLaw,
    arm_scale: Scale,
    lever_scale: Scale,
    tau_scale: Scale,
    arm: Metres,
    lever: Metres,
}

#[cfg(feature = "ball-screw")]
impl BallScrew {
    /// The preload F_p it was compiled with.
    pub fn preload(&self) -> Newtons {
        self.preload
    }

    /// The equivalent thread law of `law` (a law in τ) at axial force `f_axial` (≥ 1 N) for a
    /// thread of pitch radius `r_m` (this screw's), before validation
    /// ([`BallScrewConfig::thread_law_fixed`]): μ_eq = k·f(τ), τ = t·|θ̇|, with k = arm/r_m and
    /// t = η₀ r_m M sin α cos β/F from the compiled scales (31 significant bits each), every
    /// parameter a product of scales ([`Scale::times`]), floored into its format.
    pub fn thread_law(&self, r_m: Metres, law: &FrictionLaw, f_axial: Newtons) -> FrictionLaw {
        // arm_scale = arm·2^8 and r_m = r_bits/2^24: k = arm_scale·2^16/r_bits.
        let k = self.arm_scale.times(1 << 16, r_m.bits().max(1).into());
        // tau_scale = c·2^20 and F = F_bits/2^8: t·2^16 = tau_scale·2^4/F_bits, within
        // 7·10⁻⁹…7·10⁷ over the validated ranges (c ≤ 10³ N·s, 1 N ≤ F ≤ 150 kN): all 31 bits.
        let t16 = self.tau_scale.times(1 << 4, f_axial.bits().max(1).into());
        let (t_mant, t_shift) = t16.parts();
        let (k_mant, k_shift) = k.parts();
        let ratio = |v: Ratio| Ratio::from_raw(scale_bits(k.times(v.bits().into(), 1 << 28), 28));
        FrictionLaw {
            base: ratio(law.base),
            amp: ratio(law.amp),
            // rate·t = rate_bits·t16/2^48.
            rate: scale_q32(t16.times(law.rate.to_bits().into(), 1 << 48)),
            slope: scale_q32(
                t16.times(law.slope.to_bits().into(), 1 << 48)
                    .times(k_mant.into(), crate::math::shl128(1, k_shift)),
            ),
            s_max: if law.s_max == I32F32::MAX {
                I32F32::MAX
            } else {
                // s_max/t = s_max_bits/(t16·2^16).
                scale_q32(Scale::from_ratio(
                    crate::math::shl128(law.s_max.to_bits().into(), t_shift),
                    i128::from(t_mant) << 16,
                ))
            },
            variable: LawVariable::ScrewRate,
        }
    }

    /// Moment arm of Eq 1, 2(r_m + r_b cos α)/sin α.
    pub fn arm(&self) -> Metres {
        self.arm
    }

    /// Lead lever l/(2π): screw torque per newton of axial force without friction.
    pub fn lever(&self) -> Metres {
        self.lever
    }

    /// Axial force on the loaded balls: preload + |R|, saturating.
    #[inline]
    pub fn axial_force(&self, load: Newtons) -> Newtons {
        self.preload.sat_add(load.sat_abs())
    }

    /// τ = η₀·V/P (Eq 3) at screw rate θ̇ and axial force `f_axial` (Q28; saturates at 8 for a
    /// vanishing force). Error: ≤ 2·10⁻⁹ relative plus 1 LSB (3.7·10⁻⁹) from the truncating
    /// division (test against the twin: 10⁻⁶ relative or 10⁻⁸ absolute).
    #[inline]
    pub fn tau(&self, theta_dot: RadiansPerSecond, f_axial: Newtons) -> Ratio {
        let w = theta_dot.bits().unsigned_abs().min(i32::MAX as u32) as i32;
        let num = self.tau_scale.apply(w); // τ·F_bits
        let den = i64::from(f_axial.bits().max(0));
        if den == 0 {
            return if num > 0 { Ratio::MAX } else { Ratio::ZERO };
        }
        let t = num / den;
        Ratio::from_raw(t.min(i64::from(i32::MAX)) as i32)
    }

    /// f at τ (the configured law, seed 002 Eq 3); error ≤ 2·10⁻⁸ (the law's, see
    /// [`CompiledLaw`]).
    #[inline]
    pub fn coefficient(&self, tau: Ratio) -> Ratio {
        self.law.mu_at_tau(tau)
    }

    /// Friction torque M_f = f·F·arm (Eq 1 with Eq 2's factor 2), always ≥ 0 for f, F ≥ 0.
    /// Error: f·F is rounded to 1/256 N, so ≤ arm/256 N·m (0.24 mN·m for the 4008) plus 0.01 %.
    #[inline]
    pub fn friction_torque(&self, f: Ratio, f_axial: Newtons) -> NewtonMetres {
        let ff: Newtons = qmul(f, f_axial);
        NewtonMetres::from_raw(self.arm_scale.apply32(ff.bits()))
    }

    /// The friction coefficient from a friction torque (Eq 2): f = M_f / (F·arm).
    /// `None` below 1 N of axial force (the quotient means nothing there). Saturates at the
    /// `Ratio` range; error ≤ 10⁻⁵ relative plus 1 LSB for F ≥ 1 N (test).
    #[inline]
    pub fn coefficient_from_torque(&self, torque: NewtonMetres, f_axial: Newtons) -> Option<Ratio> {
        if f_axial < const { Newtons::lit("1") } {
            return None;
        }
        let den = self.arm_scale.apply(f_axial.bits()); // F·arm in N·m, Q16
        if den <= 0 {
            return None;
        }
        let num = i64::from(torque.bits()) << 28;
        let q = num / den;
        Some(Ratio::from_raw(crate::units::sat32(q)))
    }

    /// Screw torque the axial force alone produces, F·l/(2π) (≥ 0): what back-drives a ball
    /// screw, and what the motor must hold when it stands still.
    #[inline]
    pub fn load_torque(&self, f_axial: Newtons) -> NewtonMetres {
        NewtonMetres::from_raw(self.lever_scale.apply32(f_axial.bits()))
    }

    /// The friction torque in a measured screw torque (positive = lifting direction) under a
    /// signed axial load R = `f_axial` (without the preload):
    /// `T_screw − R·l/(2π)` when lifting; `R·l/(2π) − T_screw` when lowering (the load then
    /// drives, friction helps the motor hold it back, so the motor brakes with less than the
    /// load torque). Saturating.
    #[inline]
    pub fn friction_in(
        &self,
        screw_torque: NewtonMetres,
        f_axial: Newtons,
        lifting: bool,
    ) -> NewtonMetres {
        let tl = self.load_torque(f_axial);
        if lifting {
            screw_torque.sat_sub(tl)
        } else {
            tl.sat_sub(screw_torque)
        }
    }

    /// Eq 2 online: f from the screw torque the motor delivers (current × k_t × gear ratio ×
    /// efficiency, measured at steady speed) and the axial load R. `None` when the force is too
    /// small for the quotient to mean anything. The load torque is R·l/(2π) with R signed (negative
    /// when the motor must push the nut down, e.g. against the lift's pin friction): the
    /// preload is internal to the nut (it loads the balls, hence the friction, but turns
    /// nothing).
    #[inline]
    pub fn identify(
        &self,
        screw_torque: NewtonMetres,
        load: Newtons,
        lifting: bool,
    ) -> Option<Ratio> {
        let fa = self.axial_force(load);
        self.coefficient_from_torque(self.friction_in(screw_torque, load, lifting), fa)
    }

    /// The law's minimum on τ ∈ [0, 0.01] (seed 002's turning point between mixed and
    /// hydrodynamic lubrication), located on the fixed-point law itself by golden-section search
    /// (configuration time, ≈ 60 law evaluations): `(τ*, f(τ*))`.
    pub fn turning_point(&self) -> (Ratio, Ratio) {
        let (mut lo, mut hi) = (0i64, const { Ratio::lit("0.01") }.bits() as i64);
        // Ternary search on a unimodal integer function; the law is flat to 1 LSB near the
        // minimum, so stop at a 64-LSB bracket and scan it.
        while hi - lo > 64 {
            let m1 = lo + (hi - lo) / 3;
            let m2 = hi - (hi - lo) / 3;
            let f1 = self.coefficient(Ratio::from_raw(m1 as i32));
            let f2 = self.coefficient(Ratio::from_raw(m2 as i32));
            if f1 <= f2 {
                hi = m2;
            } else {
                lo = m1;
            }
        }
        let mut best = (
            Ratio::from_raw(lo as i32),
            self.coefficient(Ratio::from_raw(lo as i32)),
        );
        for t in lo..=hi {
            let r = Ratio::from_raw(t as i32);
            let f = self.coefficient(r);
            if f < best.1 {
                best = (r, f);
            }
        }
        best
    }
}

/// Online estimate of the ball screw's friction coefficient from motor current (Eq 2): an
/// exponential average of [`BallScrew::identify`] over the samples taken at steady speed under
/// load, `f ← f + (f_sample − f)/2^shift`.
#[cfg(feature = "ball-screw")]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrictionIdentifier {
    estimate: Ratio,
    samples: u32,
    shift: u32,
    min_force: Newtons,
}

#[cfg(feature = "ball-screw")]
impl FrictionIdentifier {
    /// Start from `initial` (e.g. the law's value), average over about 2^`shift` samples
    /// (`shift` ≤ 16), and ignore samples below `min_force` of axial force.
    pub fn new(initial: Ratio, shift: u32, min_force: Newtons) -> Self {
        Self {
            estimate: initial,
            samples: 0,
            shift: shift.min(16),
            min_force,
        }
    }

    /// Feed one measurement (screw torque, axial load R, direction). Returns whether it was used.
    pub fn update(
        &mut self,
        bs: &BallScrew,
        screw_torque: NewtonMetres,
        load: Newtons,
        lifting: bool,
    ) -> bool {
        let fa = bs.axial_force(load);
        if fa < self.min_force {
            return false;
        }
        let Some(f) = bs.identify(screw_torque, load, lifting) else {
            return false;
        };
        // The first sample replaces the initial guess's weight faster: plain average of the
        // first 2^shift samples, then the exponential average.
        let n = self.samples.saturating_add(1);
        let w = if n < (1 << self.shift) {
            n
        } else {
            1 << self.shift
        };
        let d = i64::from(f.bits()) - i64::from(self.estimate.bits());
        let next = i64::from(self.estimate.bits()) + d / i64::from(w);
        self.estimate = Ratio::from_raw(crate::units::sat32(next));
        self.samples = n;
        true
    }

    /// The current estimate of f.
    pub fn estimate(&self) -> Ratio {
        self.estimate
    }

    /// Samples used so far (saturating).
    pub fn samples(&self) -> u32 {
        self.samples
    }
}

#[cfg(all(test, feature = "ball-screw"))]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// |fixed − twin| within 10⁻⁶ of |twin| plus 2 LSB of the format (`lsb`).
    fn close(what: &str, fixed: f64, twin: f64, lsb: f64) -> Result<(), TestCaseError> {
        let bound = 1e-6 * twin.abs() + 2.0 * lsb;
        prop_assert!(
            (fixed - twin).abs() <= bound,
            "{what}: fixed {fixed:e} vs twin {twin:e} (bound {bound:e})"
        );
        Ok(())
    }

    /// A log-uniform value in lo..hi.
    fn log_range(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
        (lo.ln()..hi.ln()).prop_map(f64::exp)
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

        /// The fixed-point equivalent thread law (`BallScrew::thread_law`, what the ball-screw
        /// firmware gives its estimator for a τ law) against its float64 twin
        /// (`thread_law_float`, `equivalent_thread_law`) over the ball-screw settings'
        /// validated ranges, any law within the law's ranges and axial forces 1 N…150 kN
        /// (100 kN preload plus the 5 t rated load): each parameter within 10⁻⁶ relative plus
        /// 2 LSB of its format (Q28 for base and amp, Q32 for rate, slope and s_max).
        #[test]
        fn thread_law_fixed_matches_the_twin(
            r_m in 0.002f64..0.1,
            r_b_frac in 0.0f64..1.0,
            alpha in 20.0f64..80.0,
            lead in log_range(0.0005, 0.05),
            balls in 1u16..=1000,
            eta in log_range(1e-4, 10.0),
            fa in log_range(1.0, 150_000.0),
            base in 0.0f64..1.0,
            amp in -1.0f64..1.0,
            rate in prop_oneof![Just(0.0), log_range(1e-3, 1e6)],
            slope in -1000.0f64..1000.0,
            s_max in prop_oneof![Just(None), log_range(1e-6, 1e6).prop_map(Some)],
        ) {
            let r_m = Metres::from_f64(r_m);
            // r_b within 0.5…20 mm and below r_m.
            let hi = (r_m.to_f64() - 1e-6).min(0.02);
            let r_b = Metres::from_f64(0.0005 + r_b_frac * (hi - 0.0005));
            let law = FrictionLaw {
                base: Ratio::from_f64(base),
                amp: Ratio::from_f64(amp),
                rate: I32F32::from_num(rate),
                slope: I32F32::from_num(slope),
                s_max: s_max.map_or(I32F32::MAX, I32F32::from_num),
                variable: LawVariable::Lubrication,
            };
            let cfg = BallScrewConfig {
                r_m,
                r_b,
                contact_angle_deg: I16F16::from_num(alpha),
                lead: Metres::from_f64(lead),
                loaded_balls: balls,
                preload: Newtons::ZERO,
                viscosity: I32F32::from_num(eta),
                law,
            };
            prop_assume!(cfg.compile().is_ok());
            let f = Newtons::from_f64(fa).max(Newtons::from_int(1));
            let fixed = cfg.compile().unwrap().thread_law(cfg.r_m, &law, f);
            let twin = cfg.thread_law_float(f.to_f64());
            let (q28, q32) = (2f64.powi(-28), 2f64.powi(-32));
            close("base", fixed.base.to_f64(), twin.base.to_f64(), q28)?;
            close("amp", fixed.amp.to_f64(), twin.amp.to_f64(), q28)?;
            close("rate", fixed.rate.to_num(), twin.rate.to_num(), q32)?;
            close("slope", fixed.slope.to_num(), twin.slope.to_num(), q32)?;
            if twin.s_max == I32F32::MAX {
                prop_assert_eq!(fixed.s_max, I32F32::MAX);
            } else {
                close("s_max", fixed.s_max.to_num(), twin.s_max.to_num(), q32)?;
            }
            prop_assert_eq!(fixed.variable, LawVariable::ScrewRate);
            // Validation agrees wherever no parameter is within the bound of a range's end.
            let ok = |l: &FrictionLaw| l.compile(cfg.r_m, Ratio::ONE).is_ok();
            let near = |v: f64, end: f64| (v - end).abs() <= 1e-6 * end.abs() + 1e-8;
            let edge = [
                near(twin.base.to_f64(), 0.0), near(twin.base.to_f64(), 1.0),
                near(twin.amp.to_f64(), 1.0), near(twin.amp.to_f64(), -1.0),
                near(twin.rate.to_num(), 1e6), near(twin.slope.to_num(), 1000.0),
                near(twin.slope.to_num(), -1000.0), near(twin.s_max.to_num(), 1e6),
                near(twin.s_max.to_num(), 0.0),
            ];
            if !edge.iter().any(|&e| e) {
                prop_assert_eq!(ok(&fixed), ok(&twin));
            }
        }
    }

    /// The `ball` preset's equivalent stays within the `friction.*` ranges at the corners of
    /// the validated settings that make it steepest (the largest η₀, r_m, M, r_b, cos β, no
    /// preload, the smallest rated load, 10 kg; α = 80° the largest t ∝ sin α, α = 20° the
    /// largest k·t ∝ r_m + r_b cos α), as docs/console.md says.
    #[test]
    fn ball_preset_equivalent_is_always_valid() {
        let f = crate::model::geometry::Geometry::weight(crate::units::Kilograms::lit("10"));
        for alpha in [I16F16::lit("20"), I16F16::lit("80")] {
            let c = BallScrewConfig {
                r_m: Metres::lit("0.1"),
                r_b: Metres::lit("0.02"),
                contact_angle_deg: alpha,
                lead: Metres::lit("0.0005"),
                loaded_balls: 1000,
                preload: Newtons::ZERO,
                viscosity: I32F32::lit("10"),
                law: FrictionLaw::BALL_SCREW,
            };
            let eq = c.thread_law_fixed(&c.law, f).unwrap();
            assert!(eq.rate < I32F32::lit("90000"), "{eq:?}");
            assert!(eq.slope < I32F32::lit("25"), "{eq:?}");
        }
    }

    /// The fixed-point conversion refuses a reference force below 1 N and validates its result.
    #[test]
    fn thread_law_fixed_refuses_what_the_twin_refuses() {
        let c = BallScrewConfig::SEED_001_4008;
        let e = c
            .thread_law_fixed(&c.law, Newtons::from_f64(0.5))
            .unwrap_err();
        assert_eq!(
            e,
            c.equivalent_thread_law(Newtons::from_f64(0.5)).unwrap_err()
        );
        // 10 Pa·s at 1 N: τ ≈ 11·|θ̇| s/rad, so a rate of 10⁶ per unit of τ is ≈ 10⁷ s/rad.
        let mut steep = c;
        steep.viscosity = I32F32::lit("10");
        steep.law.rate = I32F32::lit("1000000");
        let f = Newtons::from_int(1);
        assert_eq!(
            steep.thread_law_fixed(&steep.law, f).unwrap_err(),
            steep.equivalent_thread_law(f).unwrap_err()
        );
        // The 4008 at the rated load: both taken.
        let f = Newtons::from_int(9807);
        let fixed = c.thread_law_fixed(&c.law, f).unwrap();
        let twin = c.equivalent_thread_law(f).unwrap();
        let (a, b) = (fixed.slope.to_num::<f64>(), twin.slope.to_num::<f64>());
        assert!(
            (a - b).abs() <= 1e-6 * b.abs() + 2f64.powi(-31),
            "{a:e} vs {b:e}"
        );
    }
}
