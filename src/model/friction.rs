//! Friction-coefficient laws, compiled once into a per-tick form.
//!
//! Every law of seeds 000 and 002 is an instance of
//! `μ(s) = base + amp·e^(−rate·s) + slope·min(s, s_max)`, floored at 0 (docs/model.md), with `s`
//! the screw rate |θ̇| (Eq 13), the sliding speed |v_s| = r_m|θ̇|/cos λ (Eqs 11, 12, 14) or the
//! lubrication parameter τ = η₀V/P (seed 002, Eq 3). Users give the law in its own variable;
//! [`CompiledLaw`] folds the variable's conversion into the constants so that a tick costs one
//! e^(−y), two 32×32 products and a clamp.

use crate::math::exp_neg_q16;
use crate::model::Scale;
use crate::units::{Metres, RadiansPerSecond, Ratio, Q};
use crate::ConfigError;
use fixed::types::I32F32;

/// The variable a law is written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LawVariable {
    /// |θ̇| in rad/s.
    ScrewRate,
    /// |v_s| = r_m·|θ̇|/cos λ in m/s.
    SlidingSpeed,
    /// τ = η₀·V/P (dimensionless).
    Lubrication,
}

/// A friction law as the user gives it: `μ(s) = base + amp·e^(−rate·s) + slope·min(s, s_max)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrictionLaw {
    /// Constant term, 0…1.
    pub base: Ratio,
    /// Exponential (Stribeck) amplitude, −1…1.
    pub amp: Ratio,
    /// Exponential rate per unit of `s`, 0…10⁶.
    pub rate: I32F32,
    /// Viscous slope per unit of `s`, −10³…10³.
    pub slope: I32F32,
    /// The viscous term is flat beyond this `s`, 0…10⁶ (`I32F32::MAX`: never).
    pub s_max: I32F32,
    /// Unit of `s`.
    pub variable: LawVariable,
}

impl FrictionLaw {
    /// Dry/boundary, seed 000 Eq 13: μ₁ = 0.218, μ₂ = 0.02, r₀ = 0.38 s/rad, μ₃ = −4.47·10⁻⁴ s/rad.
    pub const DRY: FrictionLaw = FrictionLaw {
        base: Ratio::lit("0.218"),
        amp: Ratio::lit("0.02"),
        rate: I32F32::lit("0.38"),
        slope: I32F32::lit("-0.000447"),
        s_max: I32F32::MAX,
        variable: LawVariable::ScrewRate,
    };
    /// PTFE dry spray, Eq 14: μ_max = 0.1961, μ_min = 0.0843, ϑ = 0.02 s/m.
    pub const PTFE: FrictionLaw = FrictionLaw {
        base: Ratio::lit("0.1961"),
        amp: Ratio::lit("-0.1118"),
        rate: I32F32::lit("0.02"),
        slope: I32F32::ZERO,
        s_max: I32F32::MAX,
        variable: LawVariable::SlidingSpeed,
    };
    /// Lithium grease, Eq 11 in our reading (docs/model.md): Tustin form of the Ghezzi data,
    /// Stribeck drop 0.016 over v₀ = 0.1 mm/s, viscous slope 0.013/1.9 per mm/s held flat beyond
    /// 2 mm/s where the data end.
    pub const LITHIUM: FrictionLaw = FrictionLaw {
        base: Ratio::lit("0.177"),
        amp: Ratio::lit("0.016"),
        rate: I32F32::lit("10000"),
        slope: I32F32::lit("6.842105263"),
        s_max: I32F32::lit("0.002"),
        variable: LawVariable::SlidingSpeed,
    };
    /// Ball screw, seed 002 Eq 3: f = 0.0026 + 0.9117·τ + 0.0028·e^(−8863·τ).
    pub const BALL_SCREW: FrictionLaw = FrictionLaw {
        base: Ratio::lit("0.0026"),
        amp: Ratio::lit("0.0028"),
        rate: I32F32::lit("8863"),
        slope: I32F32::lit("0.9117"),
        s_max: I32F32::MAX,
        variable: LawVariable::Lubrication,
    };

    /// Validate and compile for a screw of pitch radius `r_m` and lead angle cosine `cos_lambda`.
    pub fn compile(&self, r_m: Metres, cos_lambda: Ratio) -> Result<CompiledLaw, ConfigError> {
        let in_range = |v: I32F32, lo: I32F32, hi: I32F32| v >= lo && v <= hi;
        if !(self.base >= Ratio::ZERO && self.base <= Ratio::ONE) {
            return Err(ConfigError::OutOfRange {
                field: "friction.base",
                range: "0..1",
            });
        }
        if !(self.amp >= Ratio::ONE.sat_neg() && self.amp <= Ratio::ONE) {
            return Err(ConfigError::OutOfRange {
                field: "friction.amp",
                range: "-1..1",
            });
        }
        if !in_range(self.rate, I32F32::ZERO, const { I32F32::lit("1000000") }) {
            return Err(ConfigError::OutOfRange {
                field: "friction.rate",
                range: "0..1e6",
            });
        }
        if !in_range(
            self.slope,
            const { I32F32::lit("-1000") },
            const { I32F32::lit("1000") },
        ) {
            return Err(ConfigError::OutOfRange {
                field: "friction.slope",
                range: "-1000..1000",
            });
        }
        // Above 10⁶ only "none" (the largest value): every setting's value then has at most 18
        // significant digits, as the console's 64-bit number parser takes them.
        if self.s_max <= I32F32::ZERO
            || (self.s_max > const { I32F32::lit("1000000") } && self.s_max != I32F32::MAX)
        {
            return Err(ConfigError::OutOfRange {
                field: "friction.s_max",
                range: ">0..1e6",
            });
        }
        // The law's input bits: |θ̇| in Q16 for speed laws, τ in Q28 for the lubrication law.
        // k = s per unit of input (as num/den), in_frac = fractional bits of the input.
        let (k_num, k_den, in_frac): (i128, i128, u32) = match self.variable {
            LawVariable::ScrewRate => (1, 1, 16),
            // s = r_m/cos λ · |θ̇|: r_m in Q24, cos λ in Q28.
            LawVariable::SlidingSpeed => (
                i128::from(r_m.bits()) << 4,
                i128::from(cos_lambda.bits()),
                16,
            ),
            LawVariable::Lubrication => (1, 1, 28),
        };
        // y (Q16) = rate·s = rate(Q32)·k·in_bits/2^in_frac → scale = rate·k·2^16/2^(32+in_frac).
        let rate = i128::from(self.rate.to_bits());
        let mul = crate::math::mul128;
        let exp_scale = Scale::from_ratio(mul(rate, k_num), k_den << (16 + in_frac));
        // μ (Q28) = slope·s → scale = slope(Q32)·k·2^28/2^(32+in_frac).
        let slope = i128::from(self.slope.to_bits());
        let lin_scale = Scale::from_ratio(mul(slope, k_num), k_den << (4 + in_frac));
        // s_max in input bits = s_max(Q32)/k·2^in_frac/2^32.
        let smax = i128::from(self.s_max.to_bits());
        let in_max = if self.s_max == I32F32::MAX {
            u32::MAX
        } else {
            let v = crate::math::div128(mul(smax, k_den) << in_frac, k_num << 32);
            if v > i128::from(u32::MAX) {
                u32::MAX
            } else {
                v as u32
            }
        };
        Ok(CompiledLaw {
            law: *self,
            base: self.base,
            amp: self.amp,
            exp_scale,
            lin_scale,
            in_max,
        })
    }
}

/// A law with its variable folded into the constants: evaluated from raw input bits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CompiledLaw {
    law: FrictionLaw,
    base: Ratio,
    amp: Ratio,
    exp_scale: Scale,
    lin_scale: Scale,
    in_max: u32,
}

impl CompiledLaw {
    /// The law as given.
    pub fn law(&self) -> &FrictionLaw {
        &self.law
    }

    /// μ from the magnitude of the input in the law's input format (|θ̇| Q16, τ Q28).
    #[inline(always)]
    pub fn mu_raw(&self, input: u32) -> Ratio {
        let input = input.min(i32::MAX as u32) as i32;
        // input ≥ 0 and rate ≥ 0: y ≥ 0, saturated to u32 (e^(−y) is 0 long before).
        let y = self.exp_scale.apply_u32(input);
        // e^(−y) in Q31 (≤ 2^31 − 1), so amp·e is one signed 32×32 product.
        let e = (exp_neg_q16(y) >> 1) as i32;
        let exp_term = (i64::from(self.amp.bits()) * i64::from(e)) >> 31; // Q28
        let lin_in = input.min(self.in_max.min(i32::MAX as u32) as i32);
        // Saturated to i32: beyond ±8 − 2 (base and the exponential term are within ±1) μ is
        // clamped below anyway.
        let lin = self.lin_scale.apply32(lin_in);
        let mu = i64::from(self.base.bits()) + exp_term + i64::from(lin);
        Ratio::from_raw(mu.clamp(0, i64::from(i32::MAX)) as i32)
    }

    /// μ at screw rate θ̇ (its magnitude), for the lead-screw laws.
    #[inline]
    pub fn mu(&self, theta_dot: RadiansPerSecond) -> Ratio {
        self.mu_raw(theta_dot.bits().unsigned_abs())
    }

    /// μ at lubrication parameter τ (Q28 ratio), for the ball-screw law.
    #[inline]
    pub fn mu_at_tau(&self, tau: Ratio) -> Ratio {
        self.mu_raw(tau.bits().unsigned_abs())
    }
}
