//! The screw-nut contact (seed 000, Eqs 7–10) in fixed point, one equation for both directions.
//!
//! With `W = m·ẍ + R + F₀·sgn θ̇ + c_x·ẋ` the axial force the thread must deliver to the nut and
//! μ_s = μ·sgn θ̇: on the loaded flank (W ≥ 0) `N = W/(cos λ − μ_s sin λ)`,
//! `ξ = (tan λ + μ_s)/(1 − μ_s tan λ)`; when the net axial force reverses (W < 0) the other flank
//! carries it: `N = W/(cos λ + μ_s sin λ)`, `ξ = (tan λ − μ_s)/(1 + μ_s tan λ)`. Thread torque
//! `r_m·W·ξ`; friction torque about the screw axis `T_r = μ_s·|N|·r_m·cos λ`
//! (= μ_s·|W|·r_m/(1 ∓ μ_s tan λ): cos λ cancels). docs/model.md derives it.

use crate::keys::{self, ConfigError};
use crate::model::geometry::DriveConfig;
use crate::model::Scale;
use crate::units::{narrow, sat32};
use crate::units::{
    qmul, Angle, Kilograms, KilogramsPerSecond, Metres, MetresPerSecond, NewtonMetres, Newtons,
    RadiansPerSecond, RadiansPerSecond2, Ratio, Q,
};

/// Mechanical constants of the screw assembly (seed 000).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MechanicsConfig {
    /// Screw inertia I in µkg·m² (seed 000: 3), 0…10⁵.
    pub inertia_ukgm2: i32,
    /// Screw support damping c in µN·m·s/rad (seed 000: 400), 0…10⁶.
    pub damping_unms: i32,
    /// Support friction torque T₀ (seed 000: 0.01 N·m), 0…10 N·m.
    pub support_torque: NewtonMetres,
    /// Translating (nut) mass m (seed 000: ≈ 1 kg), 0…5 kg.
    pub nut_mass: Kilograms,
    /// Torsional stiffness k of the coupling between gear output and screw, N·m/rad
    /// (DESIGN.md: 160), 1…10 000. The encoder sees the gear side: under torque T the screw
    /// lags it by T/k, which the halt planner corrects for.
    pub coupling_stiffness: NewtonMetres,
}

impl MechanicsConfig {
    /// Seed 000's values.
    pub const DEFAULT: MechanicsConfig = MechanicsConfig {
        inertia_ukgm2: 3,
        damping_unms: 400,
        support_torque: NewtonMetres::lit("0.01"),
        nut_mass: Kilograms::lit("1"),
        coupling_stiffness: NewtonMetres::lit("160"),
    };
}

/// Validated screw constants.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScrewModel {
    r_m: Metres,
    tan_l: Ratio,
    sec_l: Ratio,
    cos_l: Ratio,
    /// The mechanics as configured: the diagnostic forms' scales (lead, m·r_m·tan λ, I, c)
    /// are computed from them on demand, off the tick path (the estimator's step has its own
    /// constants), so `new` does not build four scales no firmware path reads.
    mech: MechanicsConfig,
    /// Largest μ the contact evaluates: min(4, 1/(3·tan λ)), so that 1 ∓ μ_s·tan λ stays in
    /// [⅔, 4/3] (docs/model.md "Numeric envelope"). A law that gives more is clamped and flagged.
    mu_max: Ratio,
}

/// The per-tick core of the contact ([`ScrewModel::torques`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct ContactCore {
    /// 1/(1 ∓ μ_s·tan λ) in Q16.
    pub inv_q16: u32,
    /// tan λ ± μ_s (ξ's numerator).
    pub num: Ratio,
    /// T_r = μ_s·|W|·r_m/(1 ∓ μ_s·tan λ).
    pub friction_torque: NewtonMetres,
    /// r_m·W·ξ.
    pub thread_torque: NewtonMetres,
}

/// The contact state at one tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Contact {
    /// Signed friction coefficient μ_s = μ·sgn θ̇ (Eq 7).
    pub mu_s: Ratio,
    /// ξ of the flank in contact.
    pub xi: Ratio,
    /// Axial demand W on the thread.
    pub axial: Newtons,
    /// Thread normal force N (negative: the other flank carries the load).
    pub normal: Newtons,
    /// Friction torque about the screw axis T_r (Eq 10 with the strict arm r_m·cos λ).
    pub friction_torque: NewtonMetres,
    /// Torque the thread contact takes from the screw, r_m·W·ξ.
    pub thread_torque: NewtonMetres,
}

impl ScrewModel {
    /// Validate and quantise once.
    pub fn new(drive: &DriveConfig, mech: &MechanicsConfig) -> Result<ScrewModel, ConfigError> {
        if !(0..=100_000).contains(&mech.inertia_ukgm2) {
            return Err(keys::MECH_INERTIA.out_of_range());
        }
        if !(0..=1_000_000).contains(&mech.damping_unms) {
            return Err(keys::MECH_DAMPING.out_of_range());
        }
        if !(mech.support_torque >= NewtonMetres::ZERO
            && mech.support_torque <= const { NewtonMetres::lit("10") })
        {
            return Err(keys::MECH_SUPPORT_TORQUE.out_of_range());
        }
        if !(mech.nut_mass >= Kilograms::ZERO && mech.nut_mass <= const { Kilograms::lit("5") }) {
            return Err(keys::MECH_NUT_MASS.out_of_range());
        }
        if !(mech.coupling_stiffness >= const { NewtonMetres::lit("1") }
            && mech.coupling_stiffness <= const { NewtonMetres::lit("10000") })
        {
            return Err(keys::MECH_COUPLING_STIFFNESS.out_of_range());
        }
        if !(drive.pitch_radius >= const { Metres::lit("0.001") }
            && drive.pitch_radius <= const { Metres::lit("0.05") })
        {
            return Err(keys::DRIVE_PITCH_RADIUS.out_of_range());
        }
        let lambda = Angle::from_degrees(drive.lead_angle_deg);
        if !(lambda >= Angle::from_degrees(const { fixed::types::I16F16::lit("0.5") })
            && lambda <= Angle::from_degrees(const { fixed::types::I16F16::lit("20") }))
        {
            return Err(keys::DRIVE_LEAD_ANGLE.out_of_range());
        }
        let (cos_l, sin_l) = lambda.cos_sin();
        let tan_q28 = (i64::from(sin_l.bits()) << 28) / i64::from(cos_l.bits());
        let sec_q28 = (1i64 << 56) / i64::from(cos_l.bits());
        // 1/(3·tan λ) in Q28 (tan λ ≥ tan 0.5° > 2^-7: at most 2^36/3, below 2^34), then ≤ 4.
        let mu_max = ((1i64 << 56) / (3 * tan_q28)).min(4 << 28) as i32;
        Ok(ScrewModel {
            r_m: drive.pitch_radius,
            tan_l: Ratio::from_raw(tan_q28 as i32),
            sec_l: Ratio::from_raw(sec_q28 as i32),
            cos_l,
            mech: *mech,
            mu_max: Ratio::from_raw(mu_max),
        })
    }

    /// Largest μ the contact evaluates (see the field): min(4, 1/(3·tan λ)).
    pub fn mu_max(&self) -> Ratio {
        self.mu_max
    }

    /// tan λ.
    pub fn tan_lambda(&self) -> Ratio {
        self.tan_l
    }

    /// cos λ.
    pub fn cos_lambda(&self) -> Ratio {
        self.cos_l
    }

    /// Pitch radius r_m.
    pub fn pitch_radius(&self) -> Metres {
        self.r_m
    }

    /// Nut speed ẋ = r_m·tan λ·θ̇.
    #[inline]
    pub fn nut_speed(&self, theta_dot: RadiansPerSecond) -> MetresPerSecond {
        MetresPerSecond::from_raw(self.lead().apply32(theta_dot.bits()))
    }

    /// Axial demand W = m·ẍ + R + F₀·dir + c_x·ẋ, with dir = sgn θ̇ ∈ {−1, 0, 1}.
    #[inline]
    pub fn axial_demand(
        &self,
        theta_dot: RadiansPerSecond,
        theta_ddot: RadiansPerSecond2,
        dir: i8,
        axial_load: Newtons,
        pin_friction: Newtons,
        c_x: KilogramsPerSecond,
    ) -> Newtons {
        let inertial = Newtons::from_raw(self.mass_lead().apply32(theta_ddot.bits()));
        let damping: Newtons = qmul(c_x, self.nut_speed(theta_dot));
        let pins = match dir {
            d if d > 0 => pin_friction,
            d if d < 0 => pin_friction.sat_neg(),
            _ => Newtons::ZERO,
        };
        inertial.sat_add(axial_load).sat_add(pins).sat_add(damping)
    }

    /// The per-tick core of the contact for a signed friction coefficient `mu_s` with
    /// |μ_s| ≤ [`Self::mu_max`] (the caller clamps) and axial demand `w`: the reciprocal of
    /// 1 ∓ μ_s·tan λ, ξ's numerator and the two torques.
    ///
    /// Range (docs/model.md "Numeric envelope"): |μ_s·tan λ| ≤ ⅓, so the denominator lies in
    /// [⅔, 4/3], its reciprocal in [¾, 3/2] (one `UDIV`, [`crate::math::recip_q16_fast`]) and |tan λ ± μ_s|
    /// < 4.4: none of these can overflow. Only the torques can leave `NewtonMetres` (±32 768
    /// N·m) for a large |W| with a large screw; they saturate, and the caller flags it.
    #[inline(always)]
    pub fn torques(&self, mu_s: Ratio, w: Newtons) -> ContactCore {
        let tan = self.tan_l.bits();
        let mt = narrow((i64::from(mu_s.bits()) * i64::from(tan)) >> 28);
        let loaded = w >= Newtons::ZERO;
        // μ_s·sgn W (|μ_s| ≤ 4: no overflow): T_r = μ_s·|wk| = (μ_s·sgn W)·wk below, one
        // 32×32 product instead of a 64-bit absolute value and product (the same bits).
        let (den, num) = if loaded {
            ((1 << 28) - mt, tan + mu_s.bits())
        } else {
            ((1 << 28) + mt, tan - mu_s.bits())
        };
        // Negated branch-free in i32 by W's sign (s = 0 or −1: (μ ^ s) − s).
        let s = w.bits() >> 31;
        let mu_w = (mu_s.bits() ^ s) - s;
        // [`crate::math::recip_q16_fast`] without its saturating add, which cannot act here: den ∈ [⅔, 4/3]·
        // 2^28, so den + 2^11 cannot wrap (the same bits; the floor at 2^15 keeps a caller that
        // breaks the contract from dividing by zero).
        let inv_q16 = u32::MAX / (((den as u32).wrapping_add(1 << 11) >> 12).max(1 << 15));
        // r_m/(1 ∓ μ_s tan λ) in Q32: Q16·Q24 = Q40 → Q32; ≤ 1.5·0.05 m·2^32 < 2^29.
        let k = narrow(((u64::from(inv_q16) * u64::from(self.r_m.bits() as u32)) >> 8) as i64);
        // r_m·W/(1 ∓ μ_s tan λ) once (Q8·Q32 = Q40 → Q16): T_r = μ_s·|that|, thread torque
        // r_m·W·ξ = that·num.
        let wk = sat32((i64::from(w.bits()) * i64::from(k)) >> 24);
        // wk has W's sign (k > 0), or is 0.
        let friction = sat32((i64::from(wk) * i64::from(mu_w)) >> 28);
        let thread = sat32((i64::from(wk) * i64::from(num)) >> 28);
        ContactCore {
            inv_q16,
            num: Ratio::from_raw(num),
            friction_torque: NewtonMetres::from_raw(friction),
            thread_torque: NewtonMetres::from_raw(thread),
        }
    }

    /// The contact for friction magnitude `mu` (clamped to 0…[`Self::mu_max`]), direction
    /// `dir` = sgn θ̇ and axial demand `w`.
    #[inline]
    pub fn contact(&self, mu: Ratio, dir: i8, w: Newtons) -> Contact {
        let mu = mu.clamp(Ratio::ZERO, self.mu_max);
        let mu_s = match dir {
            d if d > 0 => mu,
            d if d < 0 => mu.sat_neg(),
            _ => Ratio::ZERO,
        };
        let core = self.torques(mu_s, w);
        self.contact_from(mu_s, w, &core)
    }

    /// The full contact (ξ, N: diagnostics) from its per-tick core.
    #[inline]
    pub fn contact_from(&self, mu_s: Ratio, w: Newtons, core: &ContactCore) -> Contact {
        let inv = i64::from(core.inv_q16);
        let xi = Ratio::from_raw(sat32((i64::from(core.num.bits()) * inv) >> 16));
        let w_inv = sat32((i64::from(w.bits()) * inv) >> 16);
        let normal = Newtons::from_raw(sat32(
            (i64::from(w_inv) * i64::from(self.sec_l.bits())) >> 28,
        ));
        Contact {
            mu_s,
            xi,
            axial: w,
            normal,
            friction_torque: core.friction_torque,
            thread_torque: core.thread_torque,
        }
    }

    /// Torque the coupling must deliver to the screw: I·θ̈ + c·θ̇ + T₀·dir + thread torque.
    #[inline]
    pub fn required_torque(
        &self,
        theta_dot: RadiansPerSecond,
        theta_ddot: RadiansPerSecond2,
        dir: i8,
        contact: &Contact,
    ) -> NewtonMetres {
        let inertia = NewtonMetres::from_raw(self.inertia().apply32(theta_ddot.bits()));
        let damping = NewtonMetres::from_raw(self.damping().apply32(theta_dot.bits()));
        let support = match dir {
            d if d > 0 => self.mech.support_torque,
            d if d < 0 => self.mech.support_torque.sat_neg(),
            _ => NewtonMetres::ZERO,
        };
        inertia
            .sat_add(damping)
            .sat_add(support)
            .sat_add(contact.thread_torque)
    }

    /// r_m·tan λ (Q24·Q28 bits, value·2^52).
    fn r_tan(&self) -> i128 {
        crate::math::mul128(i128::from(self.r_m.bits()), i128::from(self.tan_l.bits()))
    }

    /// Nut travel per screw radian r_m·tan λ as a scale: θ̇ (Q16) → ẋ (Q24) (r_m tan λ =
    /// r·t/2^52, so the scale is r·t·2^24/(2^52·2^16)).
    pub fn lead(&self) -> Scale {
        Scale::from_ratio(self.r_tan(), 1i128 << 44)
    }

    /// m·r_m·tan λ as a scale: θ̈ (Q8) → N (Q8) (m in Q12: m·r·t/2^64).
    pub fn mass_lead(&self) -> Scale {
        let m = i128::from(self.mech.nut_mass.bits());
        Scale::from_ratio(crate::math::mul128(m, self.r_tan()), 1i128 << 64)
    }

    /// I as a scale: θ̈ (Q8) → N·m (Q16) (I in µkg·m²: I·10⁻⁶·2^16/2^8).
    pub fn inertia(&self) -> Scale {
        Scale::from_ratio(i128::from(self.mech.inertia_ukgm2) << 8, 1_000_000)
    }

    /// c as a scale: θ̇ (Q16) → N·m (Q16) (c·10⁻⁶).
    pub fn damping(&self) -> Scale {
        Scale::from_ratio(i128::from(self.mech.damping_unms), 1_000_000)
    }

    /// Self-locking margin μ − tan λ: the screw holds its load at rest while it is positive.
    pub fn self_locking_margin(&self, mu: Ratio) -> Ratio {
        mu.sat_sub(self.tan_l)
    }

    /// Drive efficiency lifting, tan λ·(1 − μ tan λ)/(tan λ + μ) (power-screw formula).
    pub fn efficiency_lifting(&self, mu: Ratio) -> Ratio {
        let one_minus: Ratio = Ratio::ONE.sat_sub(qmul(mu, self.tan_l));
        crate::units::qdiv(
            qmul::<Ratio, Ratio, Ratio>(self.tan_l, one_minus),
            self.tan_l.sat_add(mu),
        )
    }

    /// Back-drive efficiency tan(λ − φ)/tan λ: negative while the screw is self-locking.
    pub fn efficiency_backdrive(&self, mu: Ratio) -> Ratio {
        let num = self.tan_l.sat_sub(mu);
        let den: Ratio = qmul(Ratio::ONE.sat_add(qmul(mu, self.tan_l)), self.tan_l);
        crate::units::qdiv(num, den)
    }
}
