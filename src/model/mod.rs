//! The fixed-point screw-nut model of seed 000 (Eqs 1–14), configured once, evaluated per tick.
//!
//! - [`geometry`]: encoder counts → θ → x → α → height and back; R (Eq 1), F₀ (Eq 6), c_x (Eq 4).
//! - [`friction`]: the friction laws (Eqs 11, 13, 14; seed 002 Eq 3) as one compiled shape.
//! - [`screw`]: ξ, N, T_r and the torque balance (Eqs 7–10) for both directions and flanks.
//! - [`ballscrew`]: the ball-screw variant (seed 002): f(τ), friction torque (Eq 1), f from a
//!   measured torque (Eq 2) and its online identification.
//!
//! Every function here has a float64 twin in `host-sim::physics` and a property test in
//! `tests/model_vs_float_twin.rs` bounding its error over the operating envelope.

pub mod ballscrew;
pub mod friction;
pub mod geometry;
pub mod screw;

/// A positive constant stored as `mant·2^−shift` so that it keeps 31 significant bits whatever
/// its magnitude (rates from 10⁻⁵ to 10⁴ per unit): the "quantise once" form of a coefficient.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Scale {
    mant: i32,
    shift: u32,
}

impl Scale {
    /// The constant `num/den · 2^out_frac` as a scale applied to raw bits (computed in `i128`).
    /// `den ≤ 0` or a zero value gives the zero scale.
    pub fn from_ratio(num: i128, den: i128) -> Scale {
        if den <= 0 || num == 0 {
            return Scale::default();
        }
        // Find the largest shift ≤ 62 with |num·2^shift/den| < 2^31, i.e. |num|·2^shift <
        // den·2^31 (a comparison instead of a 128-bit division per step; a den·2^31 beyond
        // u128 exceeds every shifted |num| the quotient test could see). `shifted` is
        // |num|·2^shift, kept by one-bit shifts (a variable 128-bit shift per
        // step is a call and a dozen instructions on this core).
        let mut shift = 0u32;
        let mut shifted = num.unsigned_abs();
        let den_u = den as u128;
        let limit = (den_u.leading_zeros() >= 31).then_some(den_u << 31);
        while shift < 62 && limit.is_none_or(|l| (shifted << 1) < l) {
            shifted <<= 1;
            shift += 1;
        }
        let m = crate::math::udiv128(shifted, den_u);
        if m >= 1u128 << 31 {
            // The constant is ≥ 2^31 in the units asked for: saturate.
            return Scale {
                mant: if num < 0 { -i32::MAX } else { i32::MAX },
                shift: 0,
            };
        }
        let m = m as i32;
        Scale {
            mant: if num < 0 { -m } else { m },
            shift,
        }
    }

    /// This constant times `ratio` (Q28, positive), renormalised to 31 significant bits
    /// (saturated as [`Self::from_ratio`] saturates).
    pub fn times_ratio(self, ratio: i32) -> Scale {
        let mut m = (i64::from(self.mant) * i64::from(ratio)) >> 28;
        let mut shift = self.shift;
        while m.unsigned_abs() >= 1 << 31 && shift > 0 {
            m >>= 1;
            shift -= 1;
        }
        while m != 0 && m.unsigned_abs() < 1 << 30 && shift < 62 {
            m <<= 1;
            shift += 1;
        }
        match i32::try_from(m) {
            Ok(mant) => Scale { mant, shift },
            Err(_) => Scale {
                mant: if m < 0 { -i32::MAX } else { i32::MAX },
                shift: 0,
            },
        }
    }

    /// `v·constant` for a 32-bit input, in `i64` (one `SMULL` and a shift; cannot overflow).
    #[inline]
    pub fn apply(self, v: i32) -> i64 {
        (i64::from(v) * i64::from(self.mant)) >> self.shift
    }

    /// `v·constant` for a 32-bit input, saturated to `i32`.
    ///
    /// Constants below ½ (shift ≥ 32, the usual case) take the high word of the product
    /// (`SMULL`) and an `i32` shift: floor(floor(p/2^32)/2^(s−32)) = floor(p/2^s), and
    /// |p/2^32| < 2^30 cannot overflow. Larger constants shift the `i64` and saturate.
    #[inline]
    pub fn apply32(self, v: i32) -> i32 {
        let p = i64::from(v) * i64::from(self.mant);
        let hi = (p >> 32) as i32;
        if self.shift >= 32 {
            // from_ratio keeps shift ≤ 62, so the mask never changes it.
            hi >> ((self.shift - 32) & 31)
        } else {
            // p >> s for s < 32 by its two words (the compiler's 64-bit shift by a variable
            // amount also handles s ≥ 32: ≈ 6 instructions more): the low word takes s bits
            // of the high one ((hi << 1) << (31 − s): nothing for s = 0), and the result fits
            // in i32 iff the shifted high word is the low word's sign.
            let s = self.shift & 31;
            let lo = (((p as u32) >> s) | (((hi as u32) << 1) << (31 - s))) as i32;
            let top = hi >> s;
            if top == lo >> 31 {
                lo
            } else {
                (top >> 31) ^ i32::MAX
            }
        }
    }

    /// `v·constant` for `v ≥ 0` and a non-negative constant, saturated to `u32` (a negative
    /// product, impossible under that contract, gives 0).
    #[inline]
    pub fn apply_u32(self, v: i32) -> u32 {
        let p = i64::from(v) * i64::from(self.mant);
        let hi = (p >> 32) as i32;
        if self.shift >= 32 {
            (hi >> ((self.shift - 32) & 31)).max(0) as u32
        } else {
            // By words, as in `apply32`: the result is the low word iff the high word is 0.
            let s = self.shift & 31;
            let lo = ((p as u32) >> s) | (((hi as u32) << 1) << (31 - s));
            match hi >> s {
                0 => lo,
                t if t < 0 => 0,
                _ => u32::MAX,
            }
        }
    }

    /// This constant times `num/den` (exact integer arithmetic, configuration time only).
    pub fn times(self, num: i128, den: i128) -> Scale {
        Scale::from_ratio(
            crate::math::mul128(i128::from(self.mant), num),
            crate::math::shl128(den, self.shift),
        )
    }

    /// Mantissa and shift: the constant is `mant·2^−shift`.
    pub fn parts(self) -> (i32, u32) {
        (self.mant, self.shift)
    }

    /// The constant as `f64` (tests, display).
    pub fn to_f64(self) -> f64 {
        f64::from(self.mant) / (1u64 << self.shift) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::Scale;

    proptest::proptest! {
        /// The word-wise slow paths of `apply32`/`apply_u32` are the clamped `apply` for every
        /// shift.
        #[test]
        fn apply32_is_the_saturated_product(
            v in proptest::prelude::any::<i32>(),
            mant in proptest::prelude::any::<i32>(),
            shift in 0u32..=62,
        ) {
            let k = Scale { mant, shift };
            proptest::prop_assert_eq!(k.apply32(v), crate::units::sat32(k.apply(v)));
            proptest::prop_assert_eq!(
                k.apply_u32(v),
                k.apply(v).clamp(0, i64::from(u32::MAX)) as u32
            );
        }
    }

    /// `from_ratio` as it was, with a variable shift of |num| per step.
    fn from_ratio_before(num: i128, den: i128) -> Scale {
        if den <= 0 || num == 0 {
            return Scale::default();
        }
        let mut shift = 0u32;
        let mag = num.unsigned_abs();
        let den_u = den as u128;
        let limit = (den_u.leading_zeros() >= 31).then_some(den_u << 31);
        while shift < 62 && limit.is_none_or(|l| (mag << (shift + 1)) < l) {
            shift += 1;
        }
        let m = crate::math::udiv128(mag << shift, den_u);
        if m >= 1u128 << 31 {
            return Scale {
                mant: if num < 0 { -i32::MAX } else { i32::MAX },
                shift: 0,
            };
        }
        let m = m as i32;
        Scale {
            mant: if num < 0 { -m } else { m },
            shift,
        }
    }

    /// Bit for bit the same as before over every pair of magnitudes (1…127 bits of |num|,
    /// 1…127 bits of den, pseudo-random low bits, both signs), the wrapping corners included.
    #[test]
    fn from_ratio_is_unchanged_by_the_one_bit_shifts() {
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            u128::from(x) << 64 | u128::from(x.rotate_left(29))
        };
        for num_bits in 1..=127u32 {
            for den_bits in 1..=127u32 {
                let num = (next() >> (128 - num_bits) | 1u128 << (num_bits - 1)) as i128;
                let den = (next() >> (128 - den_bits) | 1u128 << (den_bits - 1)) as i128;
                for num in [num, -num] {
                    assert_eq!(
                        Scale::from_ratio(num, den),
                        from_ratio_before(num, den),
                        "{num}/{den}"
                    );
                }
            }
        }
        for (num, den) in [
            (i128::MIN, 1),
            (i128::MAX, 1),
            (1, i128::MAX),
            (5, 0),
            (0, 5),
            (3, -1),
        ] {
            assert_eq!(
                Scale::from_ratio(num, den),
                from_ratio_before(num, den),
                "{num}/{den}"
            );
        }
    }
}
