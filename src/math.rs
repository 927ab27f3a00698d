//! Integer kernels behind the fixed-point model: e^(−y), √, 1/d.
//!
//! Each states its error bound; `tests` below prove it against `f64` over the whole input range.
//! Trigonometry comes from `idsp` (see [`crate::units::Angle`]).

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
/// Error ≤ max(3·10⁻⁹ relative, 2 LSB). One 32-bit division (`UDIV`, 2–12 cycles) and one Newton step.
#[inline]
pub fn recip_q30(d: u32) -> u32 {
    if d < (1 << 20) {
        return u32::MAX >> 1;
    }
    // Normalise d to [2^31, 2^32).
    let sh = d.leading_zeros();
    let dn = d << sh;
    // 16-bit-accurate seed: 2^47/dn ≈ (2^63/dn)>>16 from a 32/16 division.
    let seed = (u32::MAX / (dn >> 16)) as u64; // ≈ 2^48/dn, Q? see below
                                               // seed ≈ 2^32 · 2^16/ (dn>>16) / 2^16 = 2^48/dn (less than 2^17). Refine r ≈ 2^63/dn:
    let r0 = seed << 15; // ≈ 2^63/dn, 32 bits
                         // Newton: r1 = r0·(2 − dn·r0/2^63).
    let e = (u128::from(dn) * u128::from(r0)) >> 31; // dn·r0/2^31 ≈ 2^32
    let two = 1u128 << 33;
    let r1 = ((u128::from(r0) * (two - e)) >> 32) as u64; // ≈ 2^63/dn
                                                          // 1/d in Q28 = 2^28·2^30/d = 2^58/d = 2^58·2^sh/dn = r1 >> (5 − sh)... 2^63/dn >> (5 - sh).
    let out = if sh <= 5 {
        r1 >> (5 - sh)
    } else {
        r1 << (sh - 5)
    };
    if out > u64::from(u32::MAX >> 1) {
        u32::MAX >> 1
    } else {
        out as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
