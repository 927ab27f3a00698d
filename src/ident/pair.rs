//! The screw-nut model solved for the load, and a lift/lowering pair solved for the thread's
//! friction scale (docs/model.md "Load and friction identification").
//!
//! At steady speed the thread torque the motor delivers in direction d is
//! `T = ρ_d(s·μ)·(M·G_d + D)`, with `ρ_d(μ) = r_m·(tan λ + d·μ)/(1 − d·μ·tan λ)` (r_m·ξ of the
//! loaded flank), `G_d = g·(cos α + 2μ_b·d)/sin α` the axial force per kilogram on the head
//! (R + F₀·d), `D = c_x·ẋ + m·ẍ` the load-free axial demand, μ the configured law's coefficient
//! and s the friction scale. Given s, one motion gives the load:
//! `M_d(s) = (T/ρ_d(s·μ) − D)/G_d`. One motion cannot give both: T ∝ M·ρ_d(s·μ) — a heavier car
//! and a drier thread raise the torque alike. Lifting and lowering weigh the friction
//! differently (ρ_up ≈ r_m·tan(λ + φ), ρ_down ≈ −r_m·tan(φ − λ): a 2× drier dry thread raises
//! the first by 1.8× and the second by 2.4×), so a lift and a lowering of the same car give
//! both: the s at which `M_up(s) = M_down(s)`.
//!
//! Everything here runs at rest (once per motion) or at configuration time: plain `i64`
//! arithmetic with divisions, checked, no floats. The float64 twin is in
//! `tests/ident_vs_float_twin.rs`.

use crate::model::screw::ScrewModel;
use crate::units::{Kilograms, NewtonMetres, Newtons, Ratio, Q};

/// The means of one motion's samples: what a pair solve needs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MotionMeans {
    /// +1 lifting, −1 lowering.
    pub dir: i8,
    /// Mean measured thread torque (the motor's torque at the screw less the model's screw
    /// inertia, damping and support torques and the drive's no-load torque), signed.
    pub torque: NewtonMetres,
    /// Mean axial force per kilogram on the head G_d, Q23 N/kg.
    pub g_per_kg: i32,
    /// Mean load-free axial demand D (structure damping, nut inertia).
    pub free: Newtons,
    /// Mean friction coefficient of the configured law (scale 1) over the samples.
    pub mu: Ratio,
    /// Number of samples.
    pub n: u32,
    /// The motion stick-slipped (its mean friction over stick and slip is below the law's
    /// sliding friction): a pair with it may not conclude a wetter thread than configured.
    pub slipped: bool,
}

/// r_m·ξ_d(μ) for direction `dir` on the loaded flank, Q32 metres (ρ ≤ 0.05 m·4.4·1.5 <
/// 0.33 m: fits i64 with room). `None` when 1 − d·μ·tan λ is not positive (μ beyond 1/tan λ).
#[inline(never)]
pub fn rho_q32(screw: &ScrewModel, mu: Ratio, dir: i8) -> Option<i64> {
    let tan = i64::from(screw.tan_lambda().bits());
    let mu_s = i64::from(mu.bits()) * i64::from(dir.signum());
    let num = tan + mu_s; // Q28
    let den = (1i64 << 28) - ((mu_s * tan) >> 28); // Q28
    if den <= 0 {
        return None;
    }
    let r = i64::from(screw.pitch_radius().bits()); // Q24
                                                    // r·num: ≤ 2^31·2^31 → Q52; over den (Q28) → Q24; then Q32: shift left 8 first.
    (r.checked_mul(num)?).checked_shl(8)?.checked_div(den)
}

/// The load one motion's means give at friction scale `scale` (on the configured law):
/// `M = (T/ρ_d(s·μ) − D)/G_d`. `None` where it is not defined (ρ or G zero, overflow).
/// Not clamped: a pair solve needs the sign and the slope.
#[inline(never)]
pub fn load_at_scale(screw: &ScrewModel, m: &MotionMeans, scale: Ratio) -> Option<i64> {
    let mu = scaled_mu(m.mu, scale)?;
    let rho = rho_q32(screw, mu, m.dir)?;
    if rho == 0 || m.g_per_kg == 0 {
        return None;
    }
    // T/ρ in Q16 N: T (Q16 N·m)·2^32/ρ(Q32 m). |T| < 2^31 → 2^63 overflows: split.
    let t = i64::from(m.torque.bits());
    let axial_q16 =
        (t << 16).checked_div(rho)?.checked_mul(1 << 16)? + ((t << 16) % rho << 16) / rho;
    let net = axial_q16.checked_sub(i64::from(m.free.bits()) << 8)?; // Q16 N
                                                                     // kg Q12 = N (Q16)·2^19 / G (Q23).
    net.checked_mul(1 << 19)?.checked_div(i64::from(m.g_per_kg))
}

/// s·μ in Q28, `None` beyond ±8.
fn scaled_mu(mu: Ratio, scale: Ratio) -> Option<Ratio> {
    let v = (i64::from(mu.bits()) * i64::from(scale.bits())) >> 28;
    i32::try_from(v).ok().map(Ratio::from_raw)
}

/// What a lift/lowering pair gives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PairSolution {
    /// Friction scale on the configured law that makes the lift and the lowering agree.
    pub scale: Ratio,
    /// The load they agree on.
    pub load: Kilograms,
}

/// Smallest and largest friction scale a pair may report.
pub const SCALE_MIN: Ratio = Ratio::lit("0.25");
/// See [`SCALE_MIN`].
pub const SCALE_MAX: Ratio = Ratio::lit("4");
/// Largest friction coefficient a pair may explain its torques with.
pub const MU_PAIR_MAX: Ratio = Ratio::lit("0.6");

/// Solve a lift and a lowering of the same car for the friction scale and the load: the s in
/// [`SCALE_MIN`]…[`SCALE_MAX`] where `M_up(s) = M_down(s)`, by bisection to 2^-20 of s.
///
/// `M_down` falls faster with s than `M_up` (lowering weighs friction against the lead:
/// ρ_down ∝ tan(φ − λ)), so `M_up − M_down` rises through zero, once where the load's push
/// dominates the load-free demand D. A light load whose D rivals M·G_down can cross twice: the
/// pair is then ambiguous and refused (the board keeps its scale). `None` also when the means do
/// not bracket a solution (no s in range explains both, e.g. a different car, an obstruction),
/// when the lowering is not self-locking over the whole range (its torque then carries no
/// friction sign), or when the lowering's load sensitivity is under 1/8 of the lift's (at high
/// arm angles the pins take nearly the whole push of the load while lowering:
/// G_down = g·(cos α − 2μ_b)/sin α → 0, and the lowering's torque no longer weighs the load).
pub fn solve(screw: &ScrewModel, up: &MotionMeans, down: &MotionMeans) -> Option<PairSolution> {
    if up.dir <= 0 || down.dir >= 0 || up.g_per_kg <= 0 || down.g_per_kg < up.g_per_kg >> 3 {
        return None;
    }
    // Lowering is self-locking (ρ_down < 0) only above s·μ = tan λ: start just above it.
    let tan = i64::from(screw.tan_lambda().bits());
    let mu_dn = i64::from(down.mu.bits()).max(1);
    let s_lock = ((tan << 28) / mu_dn) * 1025 / 1024;
    let mut lo = s_lock.max(i64::from(SCALE_MIN.bits()));
    // A thread's μ beyond MU_PAIR_MAX (a seized, galling thread) is not a lubrication state
    // a pair should explain: the search stops there (and at the model's μ_max).
    let mu_top = i64::from(screw.mu_max().min(MU_PAIR_MAX).bits());
    let mu_big = i64::from(up.mu.bits()).max(mu_dn).max(1);
    let mut hi = i64::from(SCALE_MAX.bits()).min((mu_top << 28) / mu_big);
    if lo >= hi {
        return None;
    }
    let h = |s: i64| -> Option<i64> {
        let s = Ratio::from_raw(i32::try_from(s).ok()?);
        Some(load_at_scale(screw, up, s)? - load_at_scale(screw, down, s)?)
    };
    // h → −∞ just above the self-locking point. With a large load-free demand against a light
    // load (D against M·G_down) h can turn down again at large s: the solution is the first
    // crossing from below, found on a grid of 32 steps, then bisected.
    if h(lo)? >= 0 {
        return None;
    }
    // A second crossing (h negative again after it) makes the pair ambiguous: refused.
    let step = (hi - lo) / 32;
    let mut bracket = None;
    let mut a = lo;
    for k in 1..=32 {
        let b = if k == 32 { hi } else { lo + step * k };
        let v = h(b)?;
        match bracket {
            None if v > 0 => bracket = Some((a, b)),
            Some(_) if v < 0 => return None,
            _ => {}
        }
        a = b;
    }
    (lo, hi) = bracket?;
    while hi - lo > 1 << 8 {
        let mid = lo + (hi - lo) / 2;
        if h(mid)? < 0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let scale = Ratio::from_raw(i32::try_from(lo).ok()?);
    let mu = load_at_scale(screw, up, scale)?;
    let md = load_at_scale(screw, down, scale)?;
    let load = ((mu + md) / 2).clamp(0, i64::from(crate::estimator::LOAD_MAX.bits()));
    Some(PairSolution {
        scale,
        load: Kilograms::from_raw(load as i32),
    })
}

/// ρ_d(s₀·μ)/ρ_d(s·μ) in Q28: the factor that takes a load identified at friction scale s₀
/// to the load at scale s, ignoring the load-free demand D (a few tens of newtons against
/// kilonewtons). `None` if undefined.
pub fn load_factor(screw: &ScrewModel, mu: Ratio, dir: i8, s0: Ratio, s: Ratio) -> Option<Ratio> {
    let a = rho_q32(screw, scaled_mu(mu, s0)?, dir)?;
    let b = rho_q32(screw, scaled_mu(mu, s)?, dir)?;
    if b == 0 {
        return None;
    }
    let q = a.checked_mul(1 << 28)? / b;
    i32::try_from(q).ok().map(Ratio::from_raw)
}

/// T_r(s)/T_r(s₀) at the same thread torque, Q28: T_r/T = μ_s/(tan λ + μ_s), μ_s = d·s·μ.
/// `None` if undefined.
pub fn friction_factor(
    screw: &ScrewModel,
    mu: Ratio,
    dir: i8,
    s0: Ratio,
    s: Ratio,
) -> Option<Ratio> {
    let tan = i64::from(screw.tan_lambda().bits());
    let part = |sc: Ratio| -> Option<(i64, i64)> {
        let m = i64::from(scaled_mu(mu, sc)?.bits()) * i64::from(dir.signum());
        Some((m, tan + m))
    };
    let (m0, d0) = part(s0)?;
    let (m1, d1) = part(s)?;
    // (m1/d1)/(m0/d0) = m1·d0/(d1·m0), each factor < 2^33.
    let num = m1.checked_mul(d0)?;
    // Q56 over Q28 (den ≈ 2^52 at the presets: 24 significant bits left).
    let den = d1.checked_mul(m0)? >> 28;
    if den == 0 {
        return None;
    }
    let q = num.checked_div(den)?;
    i32::try_from(q).ok().map(Ratio::from_raw)
}
