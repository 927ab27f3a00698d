//! Integer kernels behind the fixed-point model: e^(−y), √, 1/√, 1/d, and the angle of a
//! first-quadrant (cos, sin) pair.
//!
//! Each states its error bound; `tests` below prove it against `f64` over the whole input range.
//! Trigonometry comes from `idsp` (see [`crate::units::Angle`]).

/// `n / d` for `u128` (`d = 0` gives 0), for the configuration-time arithmetic in 128 bits.
///
/// One out-of-line copy on purpose: a 32-bit Arm core has no 128-bit divide and no runtime
/// routine for it, so the compiler expands every `/` on `i128`/`u128` inline (a long loop
/// each); configuration code (`Estimator::new`, `Controller::new`,
/// `Scale::from_ratio`, `Angle::cos_sin`) divides through this and [`div128`] instead. Never
/// on the tick path (a call and the generic loop).
///
/// Written out rather than `n / d`, whose generic expansion is longer: shift-and-subtract,
/// with `d` aligned under `n` one bit at a time (a leading-zeros count and one variable 128-bit
/// shift are more code than the loop), then one quotient bit per step: at most 127 + 128
/// steps of a compare, a subtract and one-bit shifts (a few thousand instructions at worst, at
/// configuration time), calling nothing, so it adds only its own frame to the stack of the
/// configuration path.
#[inline(never)]
pub fn udiv128(n: u128, d: u128) -> u128 {
    if d == 0 || n < d {
        return 0;
    }
    // Align: the largest d·2^k ≤ n (d ≤ n/2 keeps d·2 from overflowing).
    let (mut n, mut d, mut k) = (n, d, 0u32);
    while d <= n >> 1 {
        d <<= 1;
        k += 1;
    }
    // One quotient bit per step, from 2^k down.
    let mut q = 0u128;
    loop {
        q <<= 1;
        if n >= d {
            n -= d;
            q |= 1;
        }
        if k == 0 {
            return q;
        }
        d >>= 1;
        k -= 1;
    }
}

/// `a·b` like `*` on `i128`, out of line: Arm has no 128-bit multiply, so each `*` on `i128`
/// is expanded inline (≈ 10 multiplies and their carries); the configuration-time code
/// multiplies through this one copy instead. Not for the tick path (a call per product).
#[inline(never)]
pub const fn mul128(a: i128, b: i128) -> i128 {
    a * b
}

/// `v << n` like `<<` on `i128` (`n < 128`), out of line: a shift by a run-time amount is a
/// dozen instructions and two or three runtime calls on this core, so the configuration-time
/// code shifts through this one copy (constant shifts stay inline). Not for the tick path.
#[inline(never)]
pub fn shl128(v: i128, n: u32) -> i128 {
    v << n
}

/// `n / d` truncated toward zero like `/` on `i128` (`d = 0` gives 0, `i128::MIN / −1` wraps),
/// through the one [`udiv128`].
#[inline]
pub fn div128(n: i128, d: i128) -> i128 {
    let q = udiv128(n.unsigned_abs(), d.unsigned_abs()) as i128;
    if (n < 0) != (d < 0) {
        q.wrapping_neg()
    } else {
        q
    }
}

/// `⌊a·b/d⌋` for `u64` operands (the product in 128 bits), saturated to `u64::MAX`; `d = 0`
/// gives 0 (as [`udiv128`]). Out of line, for the configuration-time and once-per-stop
/// arithmetic of the ramp planner: three `u64` arguments and a `u64` result where
/// `div128(mul128(…), …)` passes and returns `i128`s (eight words and a return slot per call
/// site). Not for the tick path.
#[inline(never)]
pub fn mul_div_u64(a: u64, b: u64, d: u64) -> u64 {
    u64::try_from(udiv128(u128::from(a) * u128::from(b), u128::from(d))).unwrap_or(u64::MAX)
}

/// `x / 2^k` truncated toward zero, as `/` does, for `1 ≤ k ≤ 63`: a shift, with 2^k − 1
/// added to a negative `x` first (so the shift's floor truncates). For the per-tick
/// arithmetic: the core is built for size (opt-level "z"), where the compiler keeps a signed
/// 64-bit `/` by a constant as a call to the runtime's division routine (≈ 90 instructions
/// on a Cortex-M4); this is four or five. Test: `div_pow2_i64_is_the_division`.
#[inline(always)]
pub const fn div_pow2_i64(x: i64, k: u32) -> i64 {
    (x + ((x >> 63) as u64 >> (64 - k)) as i64) >> k
}

/// `2^(−k/32)` for k = 0…31 in Q0.32 (k = 0 saturates to `u32::MAX`), generated offline:
/// `round(2^(32 − k/32))`.
const EXP2_TABLE: [u32; 32] = {
    // Built at compile time from a degree-6 Taylor series of 2^(−f) in i128 fixed point, which
    // is exact to well below 1 LSB for f < 1 (checked by the tests below against f64).
    let mut t = [0u32; 32];
    let mut k = 0;
    while k < 32 {
        // x = k/32 · ln2, in Q60.
        const LN2_Q60: i128 = 799_144_290_325_165_979; // ln 2 · 2^60
        let x: i128 = LN2_Q60 * k as i128 / 32;
        // e^(−x) = Σ (−x)^n / n!, n = 0…12, in Q60.
        let one: i128 = 1 << 60;
        let mut term: i128 = one;
        let mut sum: i128 = one;
        let mut n = 1;
        while n <= 12 {
            term = -(term * x >> 60) / n;
            sum += term;
            n += 1;
        }
        let q32 = (sum + (1 << 27)) >> 28;
        t[k] = if q32 > u32::MAX as i128 {
            u32::MAX
        } else {
            q32 as u32
        };
        k += 1;
    }
    t
};

/// e^(−y) for y ≥ 0 given in Q16.16 (`y_q16 = y·2^16`), result in Q0.32 saturated below 1.
///
/// Method: y·log₂e = n + k/32 + r with r < 1/32; e^(−y) = 2^(−n)·2^(−k/32)·e^(−r·ln 2), the middle
/// factor from a 32-entry table, the last from a cubic. Error ≤ 10⁻⁸ absolute (tests), far below
/// the friction law's needs (10⁻⁶). About 25 instructions on a Cortex-M4.
#[inline]
pub fn exp_neg_q16(y_q16: u32) -> u32 {
    // log2(e) in Q2.30.
    const LOG2E_Q30: u64 = 1_549_082_005;
    // z = y·log2e in Q16.32 (u64): integer part n, fraction f in Q0.32.
    let z = u64::from(y_q16) * LOG2E_Q30 >> 14;
    let n = z >> 32;
    if n >= 32 {
        return 0;
    }
    let f = z as u32;
    let k = (f >> 27) as usize;
    // r·ln2 in Q0.32, r = remaining fraction of f below 1/32.
    const LN2_Q32: u64 = 2_977_044_472;
    let t = ((u64::from(f & ((1 << 27) - 1)) * LN2_Q32) >> 32) as u32; // < 2^27·ln2
                                                                       // e^(−t) ≈ 1 − t + t²/2 − t³/6 in Q0.32, t < 0.0217: error < t⁴/24 < 10⁻⁸.
    let t2 = ((u64::from(t) * u64::from(t)) >> 32) as u32;
    let t3 = ((u64::from(t2) * u64::from(t)) >> 32) as u32;
    let poly = (1u64 << 32) - u64::from(t) + u64::from(t2 >> 1) - u64::from(t3 / 6);
    let base = u64::from(EXP2_TABLE[k]);
    let v = (base * poly) >> 32;
    let v = if v > u64::from(u32::MAX) {
        u32::MAX
    } else {
        v as u32
    };
    v >> n
}

/// √v for v in Q2.30 (0 ≤ v < 4), result in Q2.30. Error ≤ 2 LSB (2·10⁻⁹).
///
/// A 16-step integer square root gives √ to Q.15, one Newton correction lifts it to Q.30.
#[inline]
pub fn sqrt_q30(v: u32) -> u32 {
    if v == 0 {
        return 0;
    }
    // Normalise so the Newton correction's second-order error stays below 1 LSB:
    // √(v·4^k) = √v·2^k.
    let k = v.leading_zeros() / 2;
    let v = v << (2 * k);
    // Integer square root of v (u32) → s15 = floor(√v) = √(v/2^30)·2^15.
    let mut rem = v;
    let mut root: u32 = 0;
    let mut bit: u32 = 1 << 30;
    while bit > rem {
        bit >>= 2;
    }
    while bit != 0 {
        if rem >= root + bit {
            rem -= root + bit;
            root = (root >> 1) + bit;
        } else {
            root >>= 1;
        }
        bit >>= 2;
    }
    // Now root² ≤ v < (root+1)², rem = v − root² ≤ 2·root.
    // √(v·2^30) ≈ root·2^15 + rem·2^15/(2·root).
    let corr = (u64::from(rem) << 14) / u64::from(root);
    (root << 15).saturating_add(corr as u32) >> k
}

/// 1/d for d in Q2.30 with 2⁻¹⁰ ≤ d < 4, result in Q4.28 (saturates for smaller d).
/// Error ≤ max(3·10⁻⁹ relative, 2 LSB). One 32-bit division (`UDIV`, 2–12 cycles) for a 16-bit
/// seed and one Newton step, all in 32×32→64 products (`UMULL`): ≈ 25 instructions.
#[inline]
pub fn recip_q30(d: u32) -> u32 {
    if d < (1 << 20) {
        return u32::MAX >> 1;
    }
    // Normalise d to dn ∈ [2^31, 2^32) (sh ≤ 11 as d ≥ 2^20).
    let sh = d.leading_zeros();
    let dn = d << sh;
    // Seed ≈ 2^48/dn from a 32/16 division (dn>>16 ∈ [2^15, 2^16); the OR only tells the
    // compiler the divisor is not zero): relative error < 2^-15. r0 ≈ 2^63/dn < 2^32 (the
    // seed is at most 131 071).
    let r0 = u64::from(u32::MAX / ((dn >> 16) | (1 << 15))) << 15;
    // Newton: r1 = r0·(2 − dn·r0/2^63); e = dn·r0/2^32 ≈ 2^31, so 2^32 − e ≈ 2^31 and both
    // products stay below 2^64. The error after the step is −(seed error)² ≈ 10⁻⁹.
    let e = (u64::from(dn) * r0) >> 32;
    let r1 = (r0 * ((1u64 << 32) - e)) >> 31; // ≈ 2^63/dn ∈ (2^31, 2^32]
    let r1 = r1.min(u64::from(u32::MAX)) as u32;
    // 1/d in Q28 = 2^58/d = 2^(58 + sh)/dn = r1·2^(sh − 5): from sh = 5 on it is ≥ 2^31.
    if sh >= 5 {
        u32::MAX >> 1
    } else {
        (r1 >> (5 - sh)).min(u32::MAX >> 1)
    }
}

/// 1/d for d in Q4.28 with ½ ≤ d < 2 (the screw contact's 1 ∓ μ_s·tan λ), result in Q16
/// (`2^16/d`, so 2^15 < result ≤ 2^17). One `UDIV`: d rounded to Q16 (17 significant bits),
/// then `(2^32 − 1)/d`. Error (test): ≤ 3.5·10⁻⁵ relative over [½, 2), far inside the model's
/// 0.2 % torque budget and ≈ 25 instructions cheaper than [`recip_q30`]'s Newton step.
/// Total: inputs below ½ are treated as ½ (no division by zero).
#[inline]
pub fn recip_q16_fast(d_q28: u32) -> u32 {
    let d = (d_q28.saturating_add(1 << 11) >> 12).max(1 << 15);
    u32::MAX / d
}

/// Seeds of 1/√u for u = m/2^30 ∈ [1, 4) in 192 steps of 1/64, in Q16: `⌊√(2^62/m_mid)⌋` at
/// the middle of each step, built at compile time. Relative error of a seed ≤ 0.39 %.
const RSQRT_SEED: [u16; 192] = {
    let mut t = [0u16; 192];
    let mut i = 0;
    while i < 192 {
        let m_mid = (((i as u64) + 64) << 24) + (1 << 23);
        t[i] = ((1u64 << 62) / m_mid).isqrt() as u16;
        i += 1;
    }
    t
};

/// √v and 1/√v for v in Q2.30 (0 ≤ v < 4): `(√v in Q2.30, 1/√v in Q4.28)`, the reciprocal
/// saturated to `i32::MAX` (below v ≈ 1/64) and `(0, i32::MAX)` for v = 0.
///
/// Method: normalise v by an even shift to m ∈ [1, 4), a 192-entry seed of 1/√m, two Newton
/// steps `y ← y·(3 − m·y²)/2` (relative error 0.39 % → 2.3·10⁻⁵ → 8·10⁻¹⁰, always from below),
/// then √m = m·(1/√m). About 40 instructions, no division: one call gives sin α and 1/sin α.
/// Error (tests): √ ≤ max(3·10⁻⁹ relative, 2 LSB of Q30), 1/√ ≤ max(3·10⁻⁹ relative, 2 LSB
/// of Q28).
#[inline(always)]
pub fn sqrt_rsqrt_q30(v: u32) -> (u32, u32) {
    if v == 0 {
        return (0, i32::MAX as u32);
    }
    let k = v.leading_zeros() & !1;
    let h = k / 2;
    let m = v << k; // [2^30, 2^32): u = m/2^30 ∈ [1, 4)
    let idx = ((m >> 24) - 64) as usize;
    // y ≈ 1/√u in Q31, ≤ 1 (the seed is at most 0.39 % high, the Newton steps end below).
    let y = u32::from(RSQRT_SEED.get(idx).copied().unwrap_or(1 << 15)) << 15;
    // Two steps written out (the loop's counter and branch cost ≈ 4 instructions a step).
    let y = rsqrt_newton(m, rsqrt_newton(m, y));
    // √v = √u·2^−h: m(Q30)·y(Q31) = √u in Q61 → Q30 (< 2^31) → >> h.
    let root = (((u64::from(m) * u64::from(y)) >> 31) as u32) >> h;
    // 1/√v = (1/√u)·2^h in Q28 = y·2^h/2^3: beyond 8 (h ≥ 4, as y ≥ ½ in Q31) it saturates.
    // y < 2^31 (it ends below 1/√u ≤ 1), so y >> (3 − h) is below i32::MAX as well.
    let inv = if h <= 3 {
        y >> (3 - h)
    } else {
        i32::MAX as u32
    };
    (root, inv)
}

/// One Newton step of 1/√u for u = m/2^30 ∈ [1, 4): y ← y·(3 − m·y²)/2 = y + y·d/2 with
/// d = 1 − m·y² (|d| < 1 %), y and d in Q31.
#[inline(always)]
fn rsqrt_newton(m: u32, y: u32) -> u32 {
    let y2 = ((u64::from(y) * u64::from(y)) >> 31) as u32; // y² in Q31, < 2^31
    let my2 = (u64::from(m) * u64::from(y2)) >> 30; // m·y² in Q31, ≈ 2^31
    let d = ((1u64 << 31) as i64 - my2 as i64) as i32;
    // y·d/2 in Q31 = (y·d)>>32: one SMMUL (y < 2^31 is a valid i32).
    (y as i32 + ((i64::from(y as i32) * i64::from(d)) >> 32) as i32) as u32
}

/// ⌊√n⌋ for any `u64`, exact. The [`sqrt_rsqrt_q30`] kernel on the top 32 bits of n
/// (normalised) gives √n to 3·10⁻⁹ relative, then ±1 steps, checked with exact products,
/// land on the floor: one or two steps for n < 2^54, at most 15 at the top of the range.
/// No division; ≈ 60 instructions for the ramp planner's braking root where `u64::isqrt`
/// takes several hundred on a Cortex-M4.
#[inline]
pub fn isqrt_u64(n: u64) -> u32 {
    if n == 0 {
        return 0;
    }
    let k = n.leading_zeros() & !1;
    // The top word of n << k ∈ [2^62, 2^64), by 32-bit words: a 64-bit shift by a run-time
    // amount is a call to a runtime routine where the core is built for size (opt-level "z").
    // `(lo >> 1) >> (31 − k)` is lo >> (32 − k) and nothing for k = 0.
    let (hi, lo) = ((n >> 32) as u32, n as u32);
    let top = if k >= 32 {
        lo << (k - 32)
    } else {
        (hi << k) | ((lo >> 1) >> (31 - k))
    };
    let (root_q30, _) = sqrt_rsqrt_q30(top);
    // √(top·2^32) = √top·2^16 = root_q30·2, then undo the normalisation: (2·root) >> (k/2),
    // in 32 bits but for k = 0.
    let h = k / 2;
    let mut r = if h == 0 {
        u64::from(root_q30) << 1
    } else {
        u64::from(root_q30 >> (h - 1))
    }
    .min(u64::from(u32::MAX));
    while r > 0 && r * r > n {
        r -= 1;
    }
    // (r + 1)² ≤ n without overflow: r < 2^32 − 1 here, so (r + 1)² ≤ 2^64 − 2^33 + 1.
    while r < u64::from(u32::MAX) && (r + 1) * (r + 1) <= n {
        r += 1;
    }
    r as u32
}

/// ⌊√n⌋ for any `u64`, exact, from a guess: when the guess is within 1 of the root, two or
/// three exact products decide (≈ 15 instructions); otherwise [`isqrt_u64`]. The ramp
/// planner's braking root moves almost linearly from tick to tick, so a guess extrapolated
/// from the last two roots is nearly always within 1.
#[inline]
pub fn isqrt_u64_near(n: u64, guess: u32) -> u32 {
    // g ≤ 2^32 − 3, so (g + 2)² < 2^64: every product below is exact.
    let g = u64::from(guess.min(u32::MAX - 2));
    let sq = g * g;
    if sq <= n {
        let next = sq + 2 * g + 1; // (g + 1)²
        if n < next {
            return g as u32;
        }
        if n < next + 2 * g + 3 {
            // (g + 1)² ≤ n < (g + 2)²
            return (g + 1) as u32;
        }
    } else if g > 0 && sq + 1 - 2 * g <= n {
        // (g − 1)² ≤ n < g²
        return (g - 1) as u32;
    }
    isqrt_u64(n)
}

/// Coefficients of asin(u) = u·P(u²) on 0 ≤ u ≤ sin 45°, P of degree 5 with non-negative
/// coefficients (least squares reweighted toward minimax under that constraint, offline: max
/// error 7.7·10⁻⁷ rad; the fit sets c₄ = 0), rescaled for the evaluation below:
/// `K_i = c_i·(2/π)·2^32` (2/π because the result is in binary turns, π = 2^31). All terms
/// non-negative: the Horner sum stays in `u32` and each step is one `UMULL`.
const ASIN_K: [u32; 6] = [
    2_734_287_292, // c0 = 1.0000095782078005
    455_055_196,   // c1 = 0.16642711820441544
    208_235_930,   // c2 = 0.0761580266627814
    130_326_409,   // c3 = 0.0476642150197742
    0,             // c4 = 0
    218_651_631,   // c5 = 0.07996735587576706
];

/// The angle in [0, π/2] whose cosine and sine are `c` and `s` (both in Q1.31, non-negative,
/// c² + s² ≈ 1), as a binary-turn [`crate::units::Angle`] raw value (π/2 = 2^30).
///
/// asin of the smaller one by an odd degree-11 polynomial (α = asin s below 45°,
/// π/2 − asin c above), six 32×32 high-word products: ≈ 20 instructions where idsp's atan2
/// takes ≈ 130. Error (test): ≤ 8·10⁻⁷ rad over the quadrant (atan2: 2.5·10⁻⁶).
#[inline]
pub fn first_quadrant_angle(c_q31: u32, s_q31: u32) -> i32 {
    let (u, from_cos) = if s_q31 <= c_q31 {
        (s_q31, false)
    } else {
        (c_q31, true)
    };
    // The smaller of two numbers whose squares add to 1 is ≤ sin 45°; the bound (√½ rounded
    // down in Q31) also keeps u² below ½ for any input.
    let u = u.min(0x5A82_7999);
    let umulh = |a: u32, b: u32| ((u64::from(a) * u64::from(b)) >> 32) as u32;
    // w = u² in Q32 = (u·u)>>30 with u in Q31.
    let w = ((u64::from(u) * u64::from(u)) >> 30) as u32;
    let mut acc = ASIN_K[5];
    acc = ASIN_K[4] + umulh(acc, w);
    acc = ASIN_K[3] + umulh(acc, w);
    acc = ASIN_K[2] + umulh(acc, w);
    acc = ASIN_K[1] + umulh(acc, w);
    acc = ASIN_K[0] + umulh(acc, w);
    // acc = P(w)·(2/π) in Q32 (≤ 0.71·2^32); asin(u) in binary turns = u·P(w)·2^31/π
    // = acc·u (Q32·Q31 → high word: ·2^31) / 2.
    let a = (umulh(acc, u) >> 1) as i32;
    if from_cos {
        (1 << 30) - a
    } else {
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `div_pow2_i64` against the exact quotient (in `i128`, truncated toward zero as `/`
    /// truncates) around 0, ±2^k and the ends of the `i64` range, for every k.
    #[test]
    fn div_pow2_i64_is_the_division_at_the_edges() {
        for k in 1..=63u32 {
            let d = 1i128 << k;
            for x in [-d - 1, -d, -d + 1, -3, -2, -1, 0, 1, 2, 3, d - 1, d, d + 1]
                .into_iter()
                .filter_map(|x| i64::try_from(x).ok())
                .chain([i64::MIN, i64::MIN + 1, i64::MAX - 1, i64::MAX])
            {
                assert_eq!(
                    i128::from(div_pow2_i64(x, k)),
                    i128::from(x) / d,
                    "{x} / 2^{k}"
                );
            }
        }
    }

    proptest::proptest! {
        /// Any `i64` over any power of two from 2 to 2^63: the quotient of `/`.
        #[test]
        fn div_pow2_i64_is_the_division(x in proptest::num::i64::ANY, k in 1u32..=63) {
            let exact = i128::from(x) / (1i128 << k);
            proptest::prop_assert_eq!(i128::from(div_pow2_i64(x, k)), exact, "{} / 2^{}", x, k);
        }
    }

    #[test]
    fn udiv128_is_division() {
        let cases: [(u128, u128); 10] = [
            (0, 1),
            (5, 0),
            (u128::MAX, 1),
            (u128::MAX, u128::MAX),
            (u128::MAX, 3),
            (u128::MAX, u128::from(u32::MAX)),
            (u128::MAX, u128::from(u32::MAX) + 1),
            (1 << 127, (1 << 127) - 1),
            (1 << 72, 7 << 40),
            (12345, 12346),
        ];
        for (n, d) in cases {
            assert_eq!(udiv128(n, d), n.checked_div(d).unwrap_or(0), "{n} / {d}");
        }
        for (n, d) in [
            (-7i128, 2i128),
            (7, -2),
            (-7, -2),
            (i128::MIN, -1),
            (i128::MIN, 3),
        ] {
            assert_eq!(div128(n, d), n.wrapping_div(d), "{n} / {d}");
        }
    }

    proptest::proptest! {
        #[test]
        fn udiv128_matches_native_division(
            n in proptest::prelude::any::<u128>(),
            d in proptest::prelude::any::<u128>(),
            dshift in 0u32..128,
            nshift in 0u32..128,
        ) {
            // Spread both over every magnitude (uniform u128s are almost all ~2^127).
            let (n, d) = (n >> nshift, d >> dshift);
            proptest::prop_assert_eq!(udiv128(n, d), n.checked_div(d).unwrap_or(0));
            let (sn, sd) = (n as i128, d as i128);
            proptest::prop_assert_eq!(
                div128(sn, sd),
                if sd == 0 { 0 } else { sn.wrapping_div(sd) }
            );
        }
    }

    #[test]
    fn exp_neg_is_within_1e8_over_its_whole_range() {
        let mut worst: f64 = 0.0;
        let mut y: u32 = 0;
        while y < 40 << 16 {
            let got = f64::from(exp_neg_q16(y)) / 4_294_967_296.0;
            let want = (-(f64::from(y) / 65536.0)).exp();
            worst = worst.max((got - want).abs());
            y += 7;
        }
        assert!(worst < 1e-8, "worst {worst:e}");
        assert_eq!(exp_neg_q16(u32::MAX), 0);
    }

    #[test]
    fn sqrt_is_within_two_lsb_over_its_whole_range() {
        let mut v: u32 = 0;
        loop {
            let got = f64::from(sqrt_q30(v)) / (1u64 << 30) as f64;
            let want = (f64::from(v) / (1u64 << 30) as f64).sqrt();
            assert!(
                (got - want).abs() <= 2.0 / (1u64 << 30) as f64,
                "{v}: {got} {want}"
            );
            match v.checked_add(9_973) {
                Some(n) => v = n,
                None => break,
            }
        }
    }

    #[test]
    fn sqrt_and_rsqrt_are_within_their_bounds_over_the_whole_range() {
        let q30 = (1u64 << 30) as f64;
        let q28 = (1u64 << 28) as f64;
        let mut worst = (0.0f64, 0.0f64);
        let mut check = |v: u32| {
            let (r, inv) = sqrt_rsqrt_q30(v);
            let want = (f64::from(v) / q30).sqrt();
            let e_root = (f64::from(r) / q30 - want).abs() * q30;
            let tol = (3e-9 * want * q30).max(2.0);
            assert!(e_root <= tol, "sqrt {v}: {r} vs {want} ({e_root} LSB)");
            if v == 0 {
                assert_eq!(inv, i32::MAX as u32);
                return;
            }
            let want_inv = 1.0 / want;
            let got_inv = f64::from(inv) / q28;
            if want_inv < f64::from(i32::MAX) / q28 {
                let e = (got_inv - want_inv).abs();
                let tol = (3e-9 * want_inv).max(2.0 / q28);
                assert!(e <= tol, "rsqrt {v}: {got_inv} vs {want_inv}");
                worst.1 = worst.1.max(e / want_inv);
            } else {
                // Saturated, or within the last LSBs below saturation.
                assert!(
                    got_inv >= f64::from(i32::MAX) / q28 - 2.0 / q28,
                    "rsqrt {v}"
                );
            }
            worst.0 = worst.0.max(e_root / (want * q30).max(1.0));
        };
        let mut v: u32 = 0;
        loop {
            check(v);
            match v.checked_add(997) {
                Some(n) => v = n,
                None => break,
            }
        }
        // Every seed interval's edges and the powers of two around the normalisation.
        for k in 0..32 {
            for d in [-1i64, 0, 1] {
                let v = (1i64 << k) + d;
                if (0..=i64::from(u32::MAX)).contains(&v) {
                    check(v as u32);
                }
            }
        }
        check(u32::MAX);
        println!(
            "worst relative error: sqrt {:e}, rsqrt {:e}",
            worst.0, worst.1
        );
    }

    proptest::proptest! {
        /// The product-quotient against `u128` arithmetic, over the whole `u64` range.
        #[test]
        fn mul_div_u64_is_the_saturated_quotient(
            a in proptest::prelude::any::<u64>(),
            b in proptest::prelude::any::<u64>(),
            d in proptest::prelude::any::<u64>(),
        ) {
            let want = (u128::from(a) * u128::from(b))
                .checked_div(u128::from(d))
                .map_or(0, |q| u64::try_from(q).unwrap_or(u64::MAX));
            proptest::prop_assert_eq!(mul_div_u64(a, b, d), want);
        }
    }

    #[test]
    fn mul_div_u64_edges() {
        assert_eq!(mul_div_u64(u64::MAX, u64::MAX, u64::MAX), u64::MAX);
        assert_eq!(mul_div_u64(u64::MAX, u64::MAX, 1), u64::MAX);
        assert_eq!(mul_div_u64(u64::MAX, 2, 2), u64::MAX);
        assert_eq!(mul_div_u64(7, 3, 0), 0);
        assert_eq!(mul_div_u64(1 << 40, 1 << 40, 1 << 30), 1 << 50);
    }

    #[test]
    fn isqrt_u64_near_is_exact_for_any_guess() {
        let check =
            |n: u64, g: u32| assert_eq!(u64::from(isqrt_u64_near(n, g)), n.isqrt(), "{n} {g}");
        let mut x: u64 = 0xD1B5_4A32_D192_ED03;
        for _ in 0..100_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let n = x >> (x % 64);
            let r = n.isqrt() as u32;
            // Guesses at and around the root (every branch), and far off (the fallback).
            for g in [
                r.wrapping_sub(2),
                r.wrapping_sub(1),
                r,
                r.wrapping_add(1),
                r.wrapping_add(2),
            ] {
                check(n, g);
            }
            check(n, (x >> 32) as u32);
        }
        for n in [
            0,
            1,
            2,
            3,
            4,
            u64::MAX,
            u64::MAX - 1,
            (u64::from(u32::MAX) - 1).pow(2),
        ] {
            for g in [0, 1, 2, u32::MAX - 3, u32::MAX - 2, u32::MAX - 1, u32::MAX] {
                check(n, g);
            }
        }
    }

    #[test]
    fn isqrt_u64_is_exact() {
        let check = |n: u64| {
            let r = u64::from(isqrt_u64(n));
            assert!(r * r <= n, "{n}: {r}");
            assert!((r + 1).checked_mul(r + 1).is_none_or(|s| s > n), "{n}: {r}");
            assert_eq!(r, n.isqrt(), "{n}");
        };
        for k in 0..64 {
            for d in [-2i128, -1, 0, 1, 2] {
                let n = (1i128 << k) + d;
                if (0..=i128::from(u64::MAX)).contains(&n) {
                    check(n as u64);
                }
            }
        }
        for r in [1u64, 2, 3, 1000, 65_535, 65_536, 1 << 27, (1 << 32) - 1] {
            for n in [r * r - 1, r * r, r * r + 1, r * r + 2 * r] {
                check(n);
            }
        }
        check(u64::MAX);
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        for _ in 0..200_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            check(x >> (x % 64));
        }
    }

    #[test]
    fn first_quadrant_angle_is_within_8e7_rad() {
        let q31 = (1u64 << 31) as f64;
        let mut worst: f64 = 0.0;
        for i in 0..=90_000 {
            let a = f64::from(i) / 1000.0 * core::f64::consts::PI / 180.0;
            let c = ((a.cos() * q31) as u32).min(u32::MAX >> 1);
            let s = ((a.sin() * q31) as u32).min(u32::MAX >> 1);
            let got = f64::from(first_quadrant_angle(c, s)) * core::f64::consts::PI / q31;
            worst = worst.max((got - a).abs());
        }
        assert!(worst < 8e-7, "{worst:e}");
        // Nonsense inputs stay in the quadrant.
        for (c, s) in [(0, 0), (u32::MAX, u32::MAX), (0, u32::MAX), (u32::MAX, 0)] {
            let a = first_quadrant_angle(c, s);
            assert!((0..=1 << 30).contains(&a), "{c} {s}: {a}");
        }
    }

    #[test]
    fn fast_reciprocal_is_within_3_5e5_relative_over_half_to_two() {
        let mut worst: f64 = 0.0;
        let mut d: u32 = 1 << 27;
        while d < 1 << 29 {
            let got = f64::from(recip_q16_fast(d)) / 65_536.0;
            let want = (1u64 << 28) as f64 / f64::from(d);
            worst = worst.max((got - want).abs() / want);
            d += 997;
        }
        assert!(worst <= 3.5e-5, "{worst:e}");
        // Below the range: clamped, no division by zero.
        assert_eq!(recip_q16_fast(0), u32::MAX >> 15);
        assert!(recip_q16_fast(u32::MAX) > 0);
    }

    #[test]
    fn reciprocal_is_within_3e9_relative_or_two_lsb() {
        let mut d: u32 = 1 << 20;
        while d < u32::MAX - 100_003 {
            let got = f64::from(recip_q30(d)) / (1u64 << 28) as f64;
            let want = (1u64 << 30) as f64 / f64::from(d);
            if want < 7.9 {
                let tol = (3e-9 * want).max(2.0 / (1u64 << 28) as f64);
                assert!((got - want).abs() <= tol, "{d}: {got} {want}");
            }
            d += 100_003;
        }
    }
}
