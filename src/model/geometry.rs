//! Scissor geometry (Eq 1), pin friction (Eq 6) and structure damping (Eq 4, Table 1).
//!
//! The lift is a rhombus of four arms with the lead screw on its horizontal diagonal; `L` is
//! Eq 1's length (the diagonal, twice the arm length): `x = L·(cos α₀ − cos α)`,
//! `h = h₀ + L·sin α` (docs/model.md). The motor encoder sees θ_i; at the resolution of a
//! control tick the coupling's twist is ignored for position (θ ≈ θ_i: 160 N·m/rad gives
//! ≤ 0.05 mm of nut travel at 50 N·m).

use crate::keys::{self, check_range, ConfigError};
use crate::math::{first_quadrant_angle, mul128, sqrt_rsqrt_q30};
use crate::model::Scale;
use crate::units::{sat32, Angle, Kilograms, KilogramsPerSecond, Metres, Newtons, Ratio, Q};
use fixed::types::I16F16;

/// Standard gravity in Q16 m/s².
const G_Q16: i64 = 642_689; // 9.80665·2^16

/// Table 1 of seed 000: (α in degrees, c_x in kg/s), Eq 4 with ζ = 0.3, m_eq = 1000 kg.
pub const DAMPING_TABLE: [(i32, i32); 3] = [(15, 58_544), (45, 28_878), (65, 23_175)];

/// cos α of a Table 1 angle (degrees), as the model interpolates the table in cos α.
pub const fn damping_table_cos(deg: i32) -> Ratio {
    Angle::from_degrees(I16F16::from_bits(deg << 16))
        .cos_sin()
        .0
}

/// [`DAMPING_TABLE`] as [`Geometry`] interpolates it: (cos α, c_x, slope of c_x per unit of
/// cos α below the row's, Q24), at compile time (it depends on no setting, so no
/// `Geometry::new` builds it).
const DAMPING: [(Ratio, KilogramsPerSecond, i64); 3] = {
    let mut damping = [(Ratio::ZERO, KilogramsPerSecond::ZERO, 0i64); 3];
    let mut i = 0;
    while i < 3 {
        let (deg, cx) = DAMPING_TABLE[i];
        damping[i] = (damping_table_cos(deg), KilogramsPerSecond::from_int(cx), 0);
        i += 1;
    }
    let mut i = 0;
    while i < 2 {
        // cos α falls as α rises: the slope is per unit of cos α below the row's.
        let dcos = (damping[i].0.to_bits() - damping[i + 1].0.to_bits()) as i64;
        let dc = (damping[i + 1].1.to_bits() - damping[i].1.to_bits()) as i64;
        damping[i].2 = (dc << 24) / dcos;
        i += 1;
    }
    damping
};

/// Lift geometry as the user configures it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GeometryConfig {
    /// Eq 1's length L (rhombus diagonal = twice the arm length), 0.05…2 m.
    pub length: Metres,
    /// Arm angle fully down α₀, 12…60°.
    pub alpha0_deg: I16F16,
    /// Largest arm angle of the mechanism, α₀ + 5° … 89°.
    pub alpha_max_deg: I16F16,
    /// Height of the head with the rhombus collapsed (base + head), 0…1 m.
    pub h0: Metres,
    /// Pin friction coefficient μ_b (Eq 6), 0…1.
    pub mu_pin: Ratio,
}

/// Drive train as the user configures it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DriveConfig {
    /// Encoder counts per motor revolution (quadrature edges), 4…65 536.
    pub counts_per_rev: u32,
    /// Gear ratio, motor turns per screw turn, 1…1000.
    pub gear_ratio: I16F16,
    /// Pitch radius r_m, 1…50 mm.
    pub pitch_radius: Metres,
    /// Lead angle λ, 0.5…20°.
    pub lead_angle_deg: I16F16,
}

impl GeometryConfig {
    /// The default lift: L = 0.4 m (0.2 m arms), α₀ = 15°, α_max = 75°, h₀ = 30 mm, μ_b = 0.3.
    pub const DEFAULT: GeometryConfig = GeometryConfig {
        length: Metres::lit("0.4"),
        alpha0_deg: I16F16::lit("15"),
        alpha_max_deg: I16F16::lit("75"),
        h0: Metres::lit("0.03"),
        mu_pin: Ratio::lit("0.3"),
    };
}

impl DriveConfig {
    /// The default drive: 48 counts per motor turn (12-line Hall encoder ×4), 60:1 gearbox,
    /// seed 000's S12x2 screw (r_m = 4.265 mm, λ = 3.47°).
    pub const DEFAULT: DriveConfig = DriveConfig {
        counts_per_rev: 48,
        gear_ratio: I16F16::lit("60"),
        pitch_radius: Metres::lit("0.004265"),
        lead_angle_deg: I16F16::lit("3.47"),
    };
}

/// Validated geometry with its per-tick constants.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Geometry {
    cfg: GeometryConfig,
    cos_a0: Ratio,
    /// Valid band of cos α: [cos 89.5°, cos(α₀ − 5°)].
    cos_lo: Ratio,
    cos_hi: Ratio,
    /// 1/L in Q24 per metre.
    inv_len_q24: i32,
    /// Nut travel per motor encoder count: x_Q24 = counts·metres_per_count.
    metres_per_count: Scale,
    /// x/L per motor count, as a scale from counts to Q28: cos α = cos α₀ − counts·this.
    cos_per_count: Scale,
    /// Motor counts per metre of nut travel (inverse of the above).
    counts_per_metre: Scale,
    /// Screw radians per motor count, as a scale from counts to Q16 radians.
    screw_rad_per_count: Scale,
    /// Damping table as (cos α, c_x, slope per Q28 LSB of cos α in Q8·2^-24 kg/s): Table 1
    /// interpolated linearly in cos α (docs/model.md), so that the per-tick model needs no α.
    damping: [(Ratio, KilogramsPerSecond, i64); 3],
    alpha_max: Angle,
    alpha0: Angle,
}

/// Where the lift is, derived from one position.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pose {
    /// Nut travel from fully down, m.
    pub x: Metres,
    /// cos α.
    pub cos_alpha: Ratio,
    /// sin α.
    pub sin_alpha: Ratio,
    /// 1/sin α.
    pub inv_sin_alpha: Ratio,
    /// Arm angle α.
    pub alpha: Angle,
    /// Head height, m.
    pub height: Metres,
    /// The position lay outside the mechanism (below α₀ − 5° or above 89.5°) and was clamped.
    pub clamped: bool,
}

impl Geometry {
    /// Validate a configuration once; every later call is total.
    pub fn new(cfg: GeometryConfig, drive: DriveConfig) -> Result<Geometry, ConfigError> {
        check_range(
            cfg.length,
            const { Metres::lit("0.05") },
            const { Metres::lit("2") },
            &keys::GEOMETRY_LENGTH,
        )?;
        check_range(
            cfg.alpha0_deg,
            const { I16F16::lit("12") },
            const { I16F16::lit("60") },
            &keys::GEOMETRY_ALPHA0,
        )?;
        check_range(
            cfg.alpha_max_deg,
            cfg.alpha0_deg.saturating_add(const { I16F16::lit("5") }),
            const { I16F16::lit("89") },
            &keys::GEOMETRY_ALPHA_MAX,
        )?;
        check_range(
            cfg.h0,
            Metres::ZERO,
            const { Metres::lit("1") },
            &keys::GEOMETRY_H0,
        )?;
        check_range(cfg.mu_pin, Ratio::ZERO, Ratio::ONE, &keys::GEOMETRY_MU_PIN)?;
        check_range(drive.counts_per_rev, 4, 65_536, &keys::DRIVE_COUNTS_PER_REV)?;
        check_range(
            drive.gear_ratio,
            I16F16::ONE,
            const { I16F16::lit("1000") },
            &keys::DRIVE_GEAR_RATIO,
        )?;
        check_range(
            drive.pitch_radius,
            const { Metres::lit("0.001") },
            const { Metres::lit("0.05") },
            &keys::DRIVE_PITCH_RADIUS,
        )?;
        check_range(
            drive.lead_angle_deg,
            const { I16F16::lit("0.5") },
            const { I16F16::lit("20") },
            &keys::DRIVE_LEAD_ANGLE,
        )?;

        let alpha0 = Angle::from_degrees(cfg.alpha0_deg);
        let (cos_a0, _) = alpha0.cos_sin();
        let (cos_hi, _) =
            Angle::from_degrees(cfg.alpha0_deg - const { I16F16::lit("5") }).cos_sin();
        let (cos_lo, _) = const { Angle::from_degrees(I16F16::lit("89.5")).cos_sin() };
        let inv_len_q24 = ((1i64 << 48) / i64::from(cfg.length.bits())) as i32;

        // Nut travel per count = r_m·tanλ·2π / (counts_per_rev·gear_ratio).
        let (cl, sl) = Angle::from_degrees(drive.lead_angle_deg).cos_sin();
        // sin and cos of a validated lead angle (0.5…20°) are positive.
        let tan_q28 = i128::from(crate::math::mul_div_u64(
            sl.bits().unsigned_abs().into(),
            1 << 28,
            cl.bits().unsigned_abs().into(),
        ));
        const TWO_PI_Q28: i128 = 1_686_629_713; // 2π·2^28
                                                // r_m(Q24)·tan(Q28)·2π(Q28) over counts·ratio(Q16); the extra 2^16 below cancels the ratio's Q16.
        let den = i128::from(drive.counts_per_rev) * i128::from(drive.gear_ratio.to_bits());
        let num = mul128(
            mul128(i128::from(drive.pitch_radius.bits()), tan_q28),
            TWO_PI_Q28,
        );
        // metres_per_count applied to counts (Q0) gives Q24 metres: value·2^24 = num/den / 2^56.
        let metres_per_count = Scale::from_ratio(num << 16, den << 56);
        let counts_per_metre = Scale::from_ratio(den << 56, num << 16);
        // x/L per count in Q28 = num/(den·2^64)·2^28/(L_bits/2^24) = num/(den·L_bits·2^12).
        let cos_per_count =
            Scale::from_ratio(num, mul128(den, i128::from(cfg.length.bits())) << 12);
        // Screw radians per count in Q16: 2π·2^16/(counts·ratio) → num 2π(Q28)·2^16·2^16 / (den·2^28).
        let screw_rad_per_count = Scale::from_ratio(TWO_PI_Q28 << 32, den << 28);

        Ok(Geometry {
            cfg,
            cos_a0,
            cos_lo,
            cos_hi,
            inv_len_q24,
            metres_per_count,
            cos_per_count,
            counts_per_metre,
            screw_rad_per_count,
            damping: DAMPING,
            alpha_max: Angle::from_degrees(cfg.alpha_max_deg),
            alpha0,
        })
    }

    /// The configuration this geometry was built from.
    pub fn config(&self) -> &GeometryConfig {
        &self.cfg
    }

    /// Arm angle fully down, α₀.
    pub fn alpha0(&self) -> Angle {
        self.alpha0
    }

    /// Largest arm angle of the mechanism.
    pub fn alpha_max(&self) -> Angle {
        self.alpha_max
    }

    /// Nut travel for a motor encoder position (counts from fully down).
    #[inline]
    pub fn travel(&self, counts: i32) -> Metres {
        Metres::from_raw(self.metres_per_count.apply32(counts))
    }

    /// Screw angle θ in Q16 radians for a motor encoder position.
    #[inline]
    pub fn screw_angle_q16(&self, counts: i32) -> i32 {
        self.screw_rad_per_count.apply32(counts)
    }

    /// Scale from motor counts to screw radians in Q16 (for speed filters).
    pub fn screw_rad_per_count(&self) -> Scale {
        self.screw_rad_per_count
    }

    /// The pose for a motor encoder position (counts from fully down). Total: positions outside
    /// the mechanism are clamped and flagged.
    /// x/L straight from the count (one scale), not through the travel `x`, which the pose
    /// reports but the per-tick model does not need (dead code in the estimator's step).
    #[inline(always)]
    pub fn pose(&self, counts: i32) -> Pose {
        self.pose_with(self.travel(counts), self.cos_per_count.apply32(counts))
    }

    /// The pose for a nut travel `x` (Eq 1: cos α = cos α₀ − x/L).
    #[inline]
    pub fn pose_at_travel(&self, x: Metres) -> Pose {
        // x/L in Q28: x(Q24)·invL(Q24) → Q48 → >> 20.
        let x_over_l = sat32((i64::from(x.bits()) * i64::from(self.inv_len_q24)) >> 20);
        self.pose_with(x, x_over_l)
    }

    /// The pose for a travel `x` and its x/L in Q28.
    #[inline(always)]
    fn pose_with(&self, x: Metres, x_over_l: i32) -> Pose {
        let (c, s_q30, inv_s_q28, clamped) = self.cos_sin_with(x_over_l);
        let s = Ratio::from_raw((s_q30 >> 2) as i32);
        let inv_s = Ratio::from_raw(inv_s_q28 as i32);
        let cos_alpha = Ratio::from_raw(c);
        // c ∈ [cos 89.5°, cos 7°] here, so c·2^3 and s·2 are Q31 values below 2^31 (s rounds
        // to at most 2^30 in Q30).
        let alpha = Angle(first_quadrant_angle((c as u32) << 3, s_q30 << 1));
        // h = h₀ + L·sin α ≤ 1 m + 2 m (validated), far inside Metres' range: no saturation.
        let height = Metres::from_raw(
            self.cfg.h0.bits()
                + ((i64::from(self.cfg.length.bits()) * i64::from(s.bits())) >> 28) as i32,
        );
        Pose {
            x,
            cos_alpha,
            sin_alpha: s,
            inv_sin_alpha: inv_s,
            alpha,
            height,
            clamped,
        }
    }

    /// (cos α in Q28, sin α in Q30, 1/sin α in Q28, clamped) for x/L in Q28: cos α clamped to
    /// the band, then one √/1/√ kernel.
    #[inline(always)]
    fn cos_sin_with(&self, x_over_l: i32) -> (i32, u32, u32, bool) {
        let mut c = self.cos_a0.bits().saturating_sub(x_over_l);
        let mut clamped = false;
        if c > self.cos_hi.bits() {
            c = self.cos_hi.bits();
            clamped = true;
        } else if c < self.cos_lo.bits() {
            c = self.cos_lo.bits();
            clamped = true;
        }
        // sin α = √(1 − c²) and 1/sin α from one kernel: c in Q28 → c² in Q56 → 1 − c² in Q30.
        let c2_q30 = ((i64::from(c) * i64::from(c)) >> 26) as u32;
        let (s_q30, inv_s_q28) = sqrt_rsqrt_q30((1u32 << 30) - c2_q30);
        (c, s_q30, inv_s_q28, clamped)
    }

    /// The part of [`Self::pose`] the estimator's pose nodes read, the same bits: (height,
    /// cos α, 1/sin α, clamped), without the travel and α (one scale and one kernel).
    #[inline(always)]
    pub fn pose_node(&self, counts: i32) -> (Metres, Ratio, Ratio, bool) {
        let (c, s_q30, inv_s_q28, clamped) = self.cos_sin_with(self.cos_per_count.apply32(counts));
        let s = (s_q30 >> 2) as i32;
        let height = Metres::from_raw(
            self.cfg.h0.bits() + ((i64::from(self.cfg.length.bits()) * i64::from(s)) >> 28) as i32,
        );
        (
            height,
            Ratio::from_raw(c),
            Ratio::from_raw(inv_s_q28 as i32),
            clamped,
        )
    }

    /// Motor encoder position (counts from fully down) at which the head is at `height`;
    /// `None` if the height is outside α₀ … α_max.
    pub fn counts_for_height(&self, height: Metres) -> Option<i32> {
        // sin α = (h − h₀)/L.
        let dh = i64::from(height.bits()) - i64::from(self.cfg.h0.bits());
        if dh <= 0 {
            return None;
        }
        let s_q28 = (dh << 28) / i64::from(self.cfg.length.bits());
        let (_, s_min) = self.alpha0.cos_sin();
        let (_, s_max) = self.alpha_max.cos_sin();
        if s_q28 < i64::from(s_min.bits()) - 1 || s_q28 > i64::from(s_max.bits()) + 1 {
            return None;
        }
        let c2 = (1i64 << 56) - s_q28 * s_q28; // Q56
        let (c_q30, _) = sqrt_rsqrt_q30((c2 >> 26) as u32);
        let c = i64::from(c_q30 >> 2);
        // x = L·(cos α₀ − c).
        let x_q24 = (i64::from(self.cfg.length.bits()) * (i64::from(self.cos_a0.bits()) - c)) >> 28;
        Some(sat32(self.counts_per_metre.apply(sat32(x_q24))))
    }

    /// The load's weight M·g.
    #[inline]
    pub fn weight(mass: Kilograms) -> Newtons {
        Newtons::from_raw(sat32((i64::from(mass.bits()) * G_Q16) >> 20))
    }

    /// Axial load on the nut (Eq 1): R = M·g/tan α = M·g·cos α/sin α.
    #[inline]
    pub fn axial_load(&self, pose: &Pose, weight: Newtons) -> Newtons {
        weight.scale(pose.cos_alpha).scale(pose.inv_sin_alpha)
    }

    /// Pin friction on the translating part (Eq 6): F₀ = 2·μ_b·M·g/sin α.
    #[inline]
    pub fn pin_friction(&self, pose: &Pose, weight: Newtons) -> Newtons {
        let f = weight.scale(self.cfg.mu_pin).scale(pose.inv_sin_alpha);
        f.sat_add(f)
    }

    /// R (Eq 1) and F₀ (Eq 6) together, sharing the product M·g/sin α: three products
    /// instead of four. Each is within one LSB of [`Self::axial_load`] / [`Self::pin_friction`].
    #[inline]
    pub fn axial_and_pin(&self, pose: &Pose, weight: Newtons) -> (Newtons, Newtons) {
        let w_inv_s = weight.scale(pose.inv_sin_alpha);
        let f = w_inv_s.scale(self.cfg.mu_pin);
        (w_inv_s.scale(pose.cos_alpha), f.sat_add(f))
    }

    /// Structure damping c_x(α) (Eq 4, Table 1) at the pose with cosine `cos_alpha`: linear in
    /// cos α between the table's angles (docs/model.md "Structure damping"), held constant
    /// outside them.
    #[inline(always)]
    pub fn structure_damping(&self, cos_alpha: Ratio) -> KilogramsPerSecond {
        let t = &self.damping;
        let c = cos_alpha.bits();
        if c >= t[0].0.bits() {
            return t[0].1;
        }
        let i = if c >= t[1].0.bits() {
            0
        } else if c >= t[2].0.bits() {
            1
        } else {
            return t[2].1;
        };
        let dcos = i64::from(t[i].0.bits() - c);
        KilogramsPerSecond::from_raw(t[i].1.bits().saturating_add(((dcos * t[i].2) >> 24) as i32))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn geo() -> Geometry {
        match Geometry::new(GeometryConfig::DEFAULT, DriveConfig::DEFAULT) {
            Ok(g) => g,
            Err(e) => panic!("{e}"),
        }
    }

    #[test]
    fn default_geometry_is_valid_and_fully_down_is_alpha0() {
        let p = geo().pose(0);
        assert!((p.alpha.to_radians_f64().to_degrees() - 15.0).abs() < 1e-4);
        assert!(!p.clamped);
    }

    #[test]
    fn out_of_range_settings_are_refused_with_their_field() {
        let mut c = GeometryConfig::DEFAULT;
        c.alpha0_deg = I16F16::lit("5");
        let e = Geometry::new(c, DriveConfig::DEFAULT).unwrap_err();
        assert_eq!(
            e,
            ConfigError::OutOfRange {
                field: "geometry.alpha0",
                range: "12..60 deg"
            }
        );
    }

    #[test]
    fn height_to_counts_round_trips() {
        let g = geo();
        for h_mm in [140, 200, 300, 400] {
            let h = Metres::from_f64(f64::from(h_mm) / 1000.0);
            let counts = g.counts_for_height(h).unwrap();
            let back = g.pose(counts).height;
            // One motor count moves the head by up to cot α₀·1.85 µm ≈ 7 µm.
            assert!(
                (back.to_f64() - h.to_f64()).abs() < 8e-6,
                "{h_mm}: {}",
                back.to_f64()
            );
        }
        assert_eq!(g.counts_for_height(Metres::lit("0.9")), None);
    }

    /// The compile-time damping table is what `Geometry::new` computed at run time before.
    #[test]
    fn damping_table_is_the_run_time_one() {
        let mut damping = [(Ratio::ZERO, KilogramsPerSecond::ZERO, 0i64); 3];
        for (i, &(deg, cx)) in DAMPING_TABLE.iter().enumerate() {
            let c = Angle::from_degrees(I16F16::from_num(deg)).cos_sin().0;
            damping[i] = (c, KilogramsPerSecond::from_f64(f64::from(cx)), 0);
        }
        for i in 0..2 {
            let dcos = i64::from(damping[i].0.bits() - damping[i + 1].0.bits());
            let dc = i64::from(damping[i + 1].1.bits() - damping[i].1.bits());
            damping[i].2 = (dc << 24) / dcos;
        }
        assert_eq!(DAMPING, damping);
        assert_eq!(geo().damping, damping);
    }

    #[test]
    fn damping_follows_table_one() {
        let g = geo();
        for (deg, cx) in DAMPING_TABLE {
            let c = damping_table_cos(deg);
            assert!((g.structure_damping(c).to_f64() - f64::from(cx)).abs() < 1.0);
        }
    }
}
