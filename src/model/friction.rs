//! Friction-coefficient laws, compiled once into a per-tick form.
//!
//! Every law of seeds 000 and 002 is an instance of
//! `μ(s) = base + amp·e^(−rate·s) + slope·min(s, s_max)`, floored at 0 (docs/model.md), with `s`
//! the screw rate |θ̇| (Eq 13), the sliding speed |v_s| = r_m|θ̇|/cos λ (Eqs 11, 12, 14) or the
//! lubrication parameter τ = η₀V/P (seed 002, Eq 3). Users give the law in its own variable;
//! [`CompiledLaw`] folds the variable's conversion into the constants so that a tick costs one
//! e^(−y), two 32×32 products and a clamp.

use crate::keys::{self, ConfigError, Key};
use crate::math::exp_neg_q16;
use crate::model::Scale;
use crate::units::{Metres, RadiansPerSecond, Ratio, Q};
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

    /// The law's validated ranges (refusals name `keys`: base, amp, rate, slope, s_max).
    #[inline(never)]
    fn check_ranges(&self, keys: &[&'static Key; 5]) -> Result<(), ConfigError> {
        let in_range = |v: I32F32, lo: I32F32, hi: I32F32| v >= lo && v <= hi;
        if !(self.base >= Ratio::ZERO && self.base <= Ratio::ONE) {
            return Err(keys[0].out_of_range());
        }
        if !(self.amp >= Ratio::ONE.sat_neg() && self.amp <= Ratio::ONE) {
            return Err(keys[1].out_of_range());
        }
        if !in_range(self.rate, I32F32::ZERO, const { I32F32::lit("1000000") }) {
            return Err(keys[2].out_of_range());
        }
        if !in_range(
            self.slope,
            const { I32F32::lit("-1000") },
            const { I32F32::lit("1000") },
        ) {
            return Err(keys[3].out_of_range());
        }
        // Above 10⁶ only "none" (the largest value): every setting's value then has at most 18
        // significant digits, as the console's 64-bit number parser takes them.
        if self.s_max <= I32F32::ZERO
            || (self.s_max > const { I32F32::lit("1000000") } && self.s_max != I32F32::MAX)
        {
            return Err(keys[4].out_of_range());
        }
        Ok(())
    }

    /// Validate and compile for a screw of pitch radius `r_m` and lead angle cosine `cos_lambda`.
    /// Refusals name the `friction.*` keys.
    pub fn compile(&self, r_m: Metres, cos_lambda: Ratio) -> Result<CompiledLaw, ConfigError> {
        self.compile_keyed(r_m, cos_lambda, &FRICTION_KEYS)
    }

    /// [`FrictionLaw::compile`] with the refusals naming `keys` (base, amp, rate, slope,
    /// s_max): the ball screw's law is the same shape under its `ballscrew.f_*` keys (a key
    /// table instead of renaming the refusal by string compares afterwards).
    #[inline(never)]
    pub(crate) fn compile_keyed(
        &self,
        r_m: Metres,
        cos_lambda: Ratio,
        keys: &[&'static Key; 5],
    ) -> Result<CompiledLaw, ConfigError> {
        self.check_ranges(keys)?;
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
        let shl = crate::math::shl128;
        let exp_scale = Scale::from_ratio(mul(rate, k_num), shl(k_den, 16 + in_frac));
        // μ (Q28) = slope·s → scale = slope(Q32)·k·2^28/2^(32+in_frac).
        let slope = i128::from(self.slope.to_bits());
        let lin_scale = Scale::from_ratio(mul(slope, k_num), shl(k_den, 4 + in_frac));
        // s_max in input bits = s_max(Q32)/k·2^in_frac/2^32.
        let smax = i128::from(self.s_max.to_bits());
        let in_max = if self.s_max == I32F32::MAX {
            u32::MAX
        } else {
            let v = crate::math::div128(shl(mul(smax, k_den), in_frac), k_num << 32);
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

/// The estimator's law's keys, in [`FrictionLaw::compile_keyed`]'s order.
pub(crate) const FRICTION_KEYS: [&Key; 5] = [
    &keys::FRICTION_BASE,
    &keys::FRICTION_AMP,
    &keys::FRICTION_RATE,
    &keys::FRICTION_SLOPE,
    &keys::FRICTION_S_MAX,
];

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
    /// This law times `ratio` (Q28: the friction scale's change, μ' = ratio·μ), as the law
    /// `law` (this one's law with base, amplitude and slope scaled) compiles, without
    /// compiling: base and amplitude are `law`'s, the slope's scale this one's times `ratio`
    /// (a product and a renormalisation instead of the compile's 128-bit divisions), the
    /// exponential's scale and s_max unchanged. Refused when `law` leaves the validated ranges.
    pub fn rescaled(&self, law: &FrictionLaw, ratio: Ratio) -> Result<CompiledLaw, ConfigError> {
        law.check_ranges(&FRICTION_KEYS)?;
        Ok(CompiledLaw {
            law: *law,
            base: law.base,
            amp: law.amp,
            exp_scale: self.exp_scale,
            lin_scale: self.lin_scale.times_ratio(ratio.bits()),
            in_max: self.in_max,
        })
    }

    /// The law as given.
    pub fn law(&self) -> &FrictionLaw {
        &self.law
    }

    /// μ from the magnitude of the input in the law's input format (|θ̇| Q16, τ Q28).
    #[inline(always)]
    pub fn mu_raw(&self, input: u32) -> Ratio {
        Ratio::from_raw(self.mu_unfloored(input).max(0))
    }

    /// [`Self::mu_unfloored`] out of line: one copy of the law's code for the callers that
    /// run it at configuration time or as a fallback: on the tick only a [`MuTable`] segment
    /// marked exact and the stick-slip detector's branch test reach it.
    #[inline(never)]
    pub fn mu_unfloored_call(&self, input: u32) -> i32 {
        self.mu_unfloored(input)
    }

    /// The law's value before its floor at 0 (Q28 bits, saturated to `i32`): [`Self::mu_raw`]
    /// is this floored at 0. [`MuTable`] interpolates it, so that the floor stays exact.
    #[inline(always)]
    pub fn mu_unfloored(&self, input: u32) -> i32 {
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
        crate::units::sat32(mu)
    }

    /// μ at screw rate θ̇ (its magnitude), for the lead-screw laws: [`Self::mu_raw`] through
    /// the law's one out-of-line copy ([`Self::mu_unfloored_call`]).
    #[inline]
    pub fn mu(&self, theta_dot: RadiansPerSecond) -> Ratio {
        Ratio::from_raw(
            self.mu_unfloored_call(theta_dot.bits().unsigned_abs())
                .max(0),
        )
    }

    /// μ at lubrication parameter τ (Q28 ratio), for the ball-screw law (as [`Self::mu`]).
    #[inline]
    pub fn mu_at_tau(&self, tau: Ratio) -> Ratio {
        Ratio::from_raw(self.mu_unfloored_call(tau.bits().unsigned_abs()).max(0))
    }
}

/// First octave of [`MuTable`]: inputs below 2^8 (|θ̇| < 3.9 mrad/s in Q16) share one segment.
const MU_OCT0: u32 = 8;
/// Inputs the table covers: below 2^27 (|θ̇| < 2048 rad/s, beyond the estimator's 2000 rad/s
/// clamp).
const MU_TOP: u32 = 27;
/// Nodes: 0, then 8 per octave from 2^8 to 2^27 (log-spaced, found by a leading-zero count).
pub const MU_TABLE_LEN: usize = 2 + (((MU_TOP - MU_OCT0) << 3) as usize);

/// Segments of [`MuTable`]: node `i` to node `i + 1` (inputs from 2^27 on clamp into the last).
const MU_SEGMENTS: usize = MU_TABLE_LEN - 1;

/// [`MuTable`]'s nodes lie within −2…4.25 (Q28; μ_max ≤ 4): any two differ by less than 2^31.
/// A node beyond that is clamped there and both its segments keep the exact law.
const NODE_LO: i32 = -(1 << 29);
/// See [`NODE_LO`].
const NODE_HI: i32 = (1 << 30) + (1 << 28);

/// A friction law tabulated once over its input (|θ̇| in Q16 for the lead-screw laws) from the
/// exact fixed-point law ([`CompiledLaw::mu_raw`]) and interpolated linearly in the input between
/// log-spaced nodes (8 per octave): one leading-zero count, two loads and one product per tick
/// instead of e^(−y), two scales and a clamp.
///
/// A segment is only interpolated where that is exact enough ([`MuTable::build`]): the
/// interpolation is checked against the exact law at every segment's midpoint and at the viscous
/// term's kink (in the segment that holds it), within μ/8192 (0.012 %; T_r's budget is
/// 0.2 %, docs/model.md) or, where μ is near 0, the exact law's own step (|amp|·2^-16: it quantises e^(−y)'s
/// argument to 2^-16). The exponential term is smooth and the viscous term linear between nodes,
/// so the midpoint is where a segment's error peaks (up to e^(rate·h) times more elsewhere in a
/// segment of width h, where e^(−rate·s) is already below 10⁻³). The table holds the law before
/// its floor at 0 (clamped to −2…4.25, beyond μ_max ≤ 4) and the lookup floors the interpolated
/// value, so that the floor is exact. A segment that fails (one that holds a kink such as lithium
/// grease's s_max, a Stribeck drop too sharp for it, a node beyond the clamp) is marked exact (a
/// bit per segment): inputs in it evaluate the exact law, out of line.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MuTable {
    nodes: [i32; MU_TABLE_LEN],
    /// Bit `i % 32` of word `i / 32`: segment `i` evaluates the exact law.
    exact: [u32; MU_SEGMENTS.div_ceil(32)],
}

impl MuTable {
    /// The input (law bits) of node `i`.
    fn node_input(i: usize) -> u32 {
        if i == 0 {
            return 0;
        }
        let k = (i - 1) as u32;
        let o = MU_OCT0 + (k >> 3);
        (1 << o) + ((k & 7) << (o - 3))
    }

    /// The table of `law`, each segment interpolated if that reproduces the law within μ/8192
    /// there and marked exact otherwise (struct docs). Configuration time: ≈ 460 evaluations of
    /// the law. Out of line, with the law behind one call ([`CompiledLaw::mu_unfloored_call`]):
    /// one copy of the law's code.
    #[inline(never)]
    pub fn build(law: &CompiledLaw) -> MuTable {
        let mut t = MuTable {
            nodes: [0; MU_TABLE_LEN],
            exact: [0; MU_SEGMENTS.div_ceil(32)],
        };
        for i in 0..MU_TABLE_LEN {
            let n = law.mu_unfloored_call(Self::node_input(i));
            t.nodes[i] = n.clamp(NODE_LO, NODE_HI);
            if n != t.nodes[i] {
                t.mark(i.saturating_sub(1));
                t.mark(i.min(MU_SEGMENTS - 1));
            }
        }
        // The nodes are the law (floored at 0 by the lookup as the law floors itself); checked:
        // each segment's midpoint and the viscous term's kink where it is in range.
        for i in 0..MU_SEGMENTS {
            t.check(law, Self::node_input(i) / 2 + Self::node_input(i + 1) / 2);
        }
        if law.in_max < 1 << MU_TOP {
            t.check(law, law.in_max);
        }
        t
    }

    /// Nodes `from..to` of the table of the law times `ratio` (Q28), from this one: the nodes
    /// scaled (a node beyond the clamp clamped, its segments then exact, as [`Self::build`]
    /// does); the exact marks kept, since the interpolation's error and its bound (|μ|/8192,
    /// the law's own step |amp|·2^-16) scale alike. One product per node instead of a law
    /// evaluation per node and check: what a friction scale identified at rest does to the
    /// table, spread over several ticks (the table is part old, part new meanwhile).
    pub fn rescale_nodes(&mut self, ratio: i32, from: usize, to: usize) {
        for i in from..to.min(MU_TABLE_LEN) {
            let n = (i64::from(self.nodes[i]) * i64::from(ratio)) >> 28;
            let c = n.clamp(i64::from(NODE_LO), i64::from(NODE_HI)) as i32;
            self.nodes[i] = c;
            if i64::from(c) != n {
                self.mark(i.saturating_sub(1));
                self.mark(i.min(MU_SEGMENTS - 1));
            }
        }
    }

    /// Marks the segment holding input `x` exact unless its interpolation is within |μ|/8192 at
    /// `x` before the floor (the floor takes nothing from the bound: it is 1-Lipschitz, and a
    /// floored comparison would hide a segment that crosses 0), or within the exact law's own
    /// step where μ is near 0: it quantises e^(−y)'s argument to 2^-16, i.e. steps of
    /// |amp|·2^-16 in μ (and 2 LSB).
    fn check(&mut self, law: &CompiledLaw, x: u32) {
        let (i, f) = Self::segment(x);
        let exact = law.mu_unfloored_call(x);
        let step = (law.amp.bits().unsigned_abs() >> 16) as i32 + 2;
        let err = i64::from(self.interpolate(i, f)) - i64::from(exact);
        if err.abs() > i64::from((exact.unsigned_abs() >> 13) as i32).max(i64::from(step)) {
            self.mark(i);
        }
    }

    fn mark(&mut self, i: usize) {
        if let Some(w) = self.exact.get_mut(i >> 5) {
            *w |= 1 << (i & 31);
        }
    }

    /// Whether input `x` is in a segment that evaluates the exact law.
    #[inline(always)]
    pub fn is_exact(&self, x: u32) -> bool {
        self.segment_is_exact(Self::segment(x).0)
    }

    #[inline(always)]
    fn segment_is_exact(&self, i: usize) -> bool {
        self.exact
            .get(i >> 5)
            .is_some_and(|w| (w >> (i & 31)) & 1 != 0)
    }

    /// Whether every segment evaluates the exact law (no segment is interpolated).
    pub fn all_exact(&self) -> bool {
        (0..MU_SEGMENTS).all(|i| self.segment_is_exact(i))
    }

    /// μ (Q28 bits, floored at 0, before the contact's clamp) for a law input: interpolated, or
    /// `law` (the law the table was built from) out of line in a segment marked exact.
    #[inline(always)]
    pub fn lookup(&self, law: &CompiledLaw, input: u32) -> i32 {
        let (i, f) = Self::segment(input);
        if self.segment_is_exact(i) {
            law.mu_unfloored_call(input).max(0)
        } else {
            self.interpolate(i, f).max(0)
        }
    }

    /// The segment of an input and the position in it as a Q32 fraction: from the leading
    /// zeros and the next three bits. Inputs from 2^27 on are clamped into the last segment
    /// (read at its end).
    #[inline(always)]
    fn segment(input: u32) -> (usize, u32) {
        let x = input.min((1 << MU_TOP) - 1);
        if x < 1 << MU_OCT0 {
            (0, x << (32 - MU_OCT0))
        } else {
            // The leading one at bit o = 31 − lz ≥ 8: segment 1 + 8·(o − 8) + the next three
            // bits; the bits below them are the fraction (x << (lz + 4): lz ≤ 23).
            let lz = x.leading_zeros();
            let seg = (((31 - MU_OCT0 - lz) << 3) | ((x >> (28 - lz)) & 7)) + 1;
            (seg as usize, x << (lz + 4))
        }
    }

    /// The interpolated law before its floor in segment `i` at fraction `f`: one product.
    #[inline(always)]
    fn interpolate(&self, i: usize, f: u32) -> i32 {
        match self.nodes.get(i..i + 2) {
            // Between two nodes (each in −2…4.25): |b − a| < 2^31, the sum stays between.
            Some(&[a, b]) => a + ((i64::from(b - a) * i64::from(f >> 1)) >> 31) as i32,
            _ => self.nodes[MU_TABLE_LEN - 1],
        }
    }
}
