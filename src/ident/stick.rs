//! A stick-slipping lift (docs/model.md "Stick-slip"): the load and the mean friction torque
//! from the breakaways.
//!
//! While the thread sticks the screw stands and the coupling winds up; the static forces of
//! the thread, the pins and the supports are statically indeterminate and taken as mobilised
//! to one common fraction ρ ∈ [0, 1] of their breakaway capacity (the model's rule, continuous
//! with both breakaways). Each stick ends at ρ = 1: the thread torque is then
//! P = ρ₁·M·G_d, ρ₁ = ρ_d(μ(0)) (D = 0: the nut stands), which gives the load. A slip lasts a
//! millisecond at hundreds of rad/s, where μ is far below the law's cruise value: the mean
//! torque says nothing about the law's sliding friction, but it says how far the sticks were
//! mobilised on average: the thread torque at ρ is τ_up(ρ) = r_m·ξ_up(ρ·μ(0))·(G_R + ρ·G_F) per
//! kilogram (the pins resist lifting with ρ of their capacity: G_R = (G_up + G_down)/2 the load's
//! push, G_F = (G_up − G_down)/2 the pins'), and the friction torque ρ·μ(0)·|N|·r_m·cos λ; the
//! mean T_r is that at ρ̄ where M·τ_up(ρ̄) = T̄ ([`lift_friction`]; a lowering's
//! [`StuckLowering::friction`] averages T_r over the sticks' wind-up instead, where the pins
//! bend T_r against T). Its first-order form, T_r linear in T between the lead's
//! T₀ = ρ₀·M·G_R (ρ₀ = r_m·tan λ) and P, read 1…2 % heavier (host-sim, dry lifts: 1000 kg
//! +1.6 → −1.6 %, 700 kg from 200 mm +3.0 → +1.5 %, 1.5× drier +4.2…+5.2 → +3.2…+4.3 %).

use crate::math::div_pow2_i64;
use crate::model::screw::ScrewModel;
use crate::units::{sat32, Kilograms, NewtonMetres, Ratio, Q};

/// The load of a stick-slipping lift, from the mean breakaway thread torque `peak` P (Q16
/// N·m): M = P/(ρ₁·G_up), ρ₁ = ρ_up(μ(0)) and ρ₀ = r_m·tan λ (`rho1`, `rho0`, Q32 m, from
/// `pair::rho_q32`), G_up and G_R (`g_d`, `g_r`, Q23 N/kg). `drop` is the slips' fall of the
/// torque (over the motion: 2·(P − T̄)): a stick from rest unwinds the coupling from the
/// breakaway P to about the lead's T₀ = P·(ρ₀/ρ₁)·(G_R/G_up) (the slip is nearly free); a fall
/// under half the span P − T₀ is a ripple of a thread that keeps sliding (micro stick-slip,
/// noise), whose peaks are no breakaways: `None`. `None` as well where it is undefined
/// (P ≤ T₀, ρ₁ ≤ ρ₀, G ≤ 0) or out of range. Divisions: at the status, not in the control
/// tick.
#[inline(never)]
pub fn lift(peak: i64, drop: i64, rho1: i64, rho0: i64, g_d: i64, g_r: i64) -> Option<Kilograms> {
    if rho1 <= rho0 || rho0 < 0 || g_r <= 0 {
        return None;
    }
    let m = load(peak, rho1, g_d)?;
    // P·ρ₀/ρ₁ (Q16): the lead's share of the breakaway torque; T₀ = P·(ρ₀/ρ₁)·(G_R/G_d).
    let lead = peak.checked_mul(rho0)?.checked_div(rho1)?;
    let t0 = lead.checked_mul(g_r)?.checked_div(g_d)?;
    let span = peak - t0;
    if span <= 0 || drop.saturating_mul(2) < span {
        return None;
    }
    Some(m)
}

/// The load whose breakaway thread torque is `peak` P (Q16 N·m): M = P/(ρ₁·G_up), `rho1` Q32 m
/// and `g_d` Q23 N/kg as [`lift`]'s, without its test of the fall (a fast stick-slip's
/// breakaway from its period, `Controller::stick_slip_lift`). `None` where undefined or out
/// of range.
pub fn load(peak: i64, rho1: i64, g_d: i64) -> Option<Kilograms> {
    if rho1 <= 0 || g_d <= 0 || peak <= 0 {
        return None;
    }
    // W = P/ρ₁ in Q8 N: P (Q16, < 2^31)·2^24 / ρ₁ (Q32).
    let w = peak.checked_mul(1 << 24)?.checked_div(rho1)?;
    // M = W/G_d in Q12 kg: W (Q8)·2^27 / G (Q23).
    let m = w.checked_mul(1 << 27)?.checked_div(g_d)?;
    Some(Kilograms::from_raw(i32::try_from(m).ok()?))
}

/// A fast stick-slip's breakaway thread torque P (Q16 N·m; `Controller::stick_slip_lift`): the
/// torque is a sawtooth whose mean is the motion's `mean` T̄ (Q16 N·m) and whose period is
/// `period_q8` (Q8 ticks of `tick_us` µs). Each stick winds the coupling (`kc`, Q16 N·m/rad)
/// at the reference speed `w` (Q16 rad/s) until the breakaway; the slip, half a period of the
/// screw (`inertia_ukgm2`, µkg·m²) on the coupling, t_s = π·√(I/k_c), lets it fall. The fall
/// is k_c·ω·(T − t_s) and P = T̄ + k_c·ω·(T − t_s)/2. `None` where undefined (k_c ≤ 0, a
/// negative inertia) or out of range. At the status, not in the tick (divisions, a root).
pub fn periodic_breakaway(
    mean: i64,
    period_q8: i32,
    kc: i64,
    w: i64,
    tick_us: u32,
    inertia_ukgm2: i32,
) -> Option<i64> {
    if kc <= 0 || inertia_ukgm2 < 0 || tick_us == 0 {
        return None;
    }
    let tick = i64::from(tick_us);
    // √(I/k_c) in ms is √(I[µkg·m²]/k_c[N·m/rad]): the ratio in Q24 (I ≤ 2^17 ·2^40 / k_c's
    // Q16), its root in Q12 ms.
    let ratio_q24 = i64::from(inertia_ukgm2).checked_mul(1 << 40)? / kc;
    let root_q12 = i64::from(crate::math::isqrt_u64(u64::try_from(ratio_q24).ok()?));
    // t_s = π·root (π ≈ 355/113), in Q16 ticks: Q12 ms · 1000 / tick µs · 2^4 (one division).
    let slip_q16 = root_q12.checked_mul(355 * 1000 * 16)? / (113 * tick);
    let stuck_q16 = (i64::from(period_q8) << 8).saturating_sub(slip_q16).max(0);
    // k_c·ω per tick (Q16 N·m): Q16·Q16 → Q32 · µs / 10^6 → >> 16.
    let per_tick = kc.checked_mul(w.abs())?.checked_mul(tick)? / (1_000_000i64 << 16);
    let fall = per_tick.checked_mul(stuck_q16)? >> 16;
    Some(mean.saturating_add(fall / 2))
}

/// The mean T_r of a stick-slipping lift of load `load` whose mean thread torque is `mean`
/// (Q16 N·m), at a pose whose axial force per kilogram lifting and lowering is `g_up`,
/// `g_down` (Q23 N/kg), for the law in force's μ(0) `mu0`: the mobilisation ρ̄ where
/// M·τ_up(ρ̄) = T̄, τ_up(ρ) = r_m·ξ_up(ρ·μ(0))·(G_R + ρ·G_F) (the pins resist lifting; τ_up
/// rises with ρ: bisection, 16 steps, clamped to [0, 1]), and the friction torque there,
/// T_r = M·r_m·ρ̄μ₀·(G_R + ρ̄·G_F)/(1 − ρ̄μ₀·tan λ) (the plant's μ_s·|N|·r_m·cos λ). `None`
/// out of range. At the status, not in the tick.
#[inline(never)]
pub fn lift_friction(
    screw: &ScrewModel,
    mu0: Ratio,
    g_up: i64,
    g_down: i64,
    load: Kilograms,
    mean: i64,
) -> Option<NewtonMetres> {
    let m = i64::from(load.bits());
    if m <= 0 {
        return None;
    }
    // The lift's statics are the lowering's mirrored (ρ resists lifting): its model, d = +1
    // (its ρ_x and breakaway are the lowering's, unused here).
    let s = StuckLowering::start(screw, mu0, g_up, g_down)?;
    // T̄ per kilogram, Q16·2^36 / Q12 = Q40.
    let per_kg = mean.checked_mul(1 << 36)?.checked_div(m)?;
    let (_, tr) = s.node(screw, s.mobilisation(screw, per_kg, 1)?, 1)?;
    // Q40 per kg · M (Q12) → Q16.
    Some(NewtonMetres::from_raw(sat32(tr.checked_mul(m)? >> 36)))
}

/// The mobilisation ρ (Q16) in [0, `hi`] where `below(ρ)` (the thread torque short of the
/// mean's on the monotone branch) turns false: 16 bisection steps. `None` where `below` is.
fn bisect_mobilisation(hi: i64, below: impl Fn(i64) -> Option<bool>) -> Option<i64> {
    let (mut lo, mut hi) = (0i64, hi);
    for _ in 0..16 {
        let mid = (lo + hi) >> 1;
        if below(mid)? {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some((lo + hi) >> 1)
}

/// The stuck thread's friction torque per kilogram, Q40 N·m (its magnitude), at the mobilised
/// coefficient `mu` = ρ·μ(0) under the axial force per kilogram `w` (Q23 N/kg), lifting (`dir`
/// +1) or lowering (−1): r_m·μ·w/(1 − dir·μ·tan λ), the plant's μ_s·|N|·r_m·cos λ.
fn stuck_friction(screw: &ScrewModel, mu: Ratio, w: i64, dir: i64) -> Option<i64> {
    // r_m·μ/(1 ∓ μ·tan λ): Q24·Q28 → Q32 (>> 20), over the Q28 denominator.
    let mu = i64::from(mu.bits());
    let t = i64::from(screw.tan_lambda().bits());
    let r = i64::from(screw.pitch_radius().bits());
    let den = (1i64 << 28) - dir * ((mu * t) >> 28);
    let f = ((r * mu) >> 20).checked_mul(1 << 28)?.checked_div(den)?;
    // Q32·Q23 → Q40 per kg.
    Some(f.checked_mul(w)? >> 15)
}

/// A stuck lowering (docs/model.md "A stick-slipping lowering"): the thread torque per
/// kilogram on the head at mobilisation ρ ∈ [0, 1] (the common fraction of the thread's, the
/// pins' and the supports' static capacity), signed as the screw sees it (negative: the motor
/// drives the screw down):
///
///   τ(ρ) = r_m·ξ_down(ρ·μ(0))·(G_R − ρ·G_F),  ξ_down(μ) = (tan λ − μ)/(1 + μ·tan λ),
///
/// with G_R = (G_up + G_down)/2 the load's push and G_F = (G_up − G_down)/2 the pins' static
/// capacity per kilogram (the nut stands: D = 0). The screw breaks away when the coupling's
/// torque overcomes the thread and the pins at full static friction, ρ = 1:
/// P = M·τ(1) = M·ρ_down(μ(0))·G_down, as lifting's P = M·ρ_up(μ(0))·G_up (host-sim's coupling
/// at the breakaways of a 0.3 rad/s creep: dry 700…1300 kg from 150 and 200 mm, within 0.6 % of
/// M·|τ(1)|; the largest |τ|, inside at ρ_x < 1, is 1.5…3.9 % above it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StuckLowering {
    /// μ(0) of the law in force.
    mu0: Ratio,
    /// G_R and G_F, Q23 N/kg.
    g_r: i64,
    g_f: i64,
    /// Where |τ| peaks (the end of the monotone branch a stick winds up along), ρ_x Q16; and
    /// the breakaway's |τ(1)|, Q40 N·m per kg.
    rho_x: i64,
    tau_b: i64,
}

impl StuckLowering {
    /// At a pose whose axial force per kilogram lifting and lowering is `g_up`, `g_down` (Q23
    /// N/kg, `Estimator::g_per_kg`), for the law in force's μ(0) `mu0`. |τ|'s peak maximises
    /// the product's numerator (the denominator 1 + ρ·μ(0)·tan λ moves by ≈ 1 % over ρ and
    /// shifts it by less than 0.1 % of |τ|, where |τ| is flat):
    /// d/dρ [(ρμ₀ − t)(G_R − ρG_F)] = 0 at ρ_x = (μ₀·G_R + t·G_F)/(2·μ₀·G_F), clamped to [0, 1]
    /// (1 where the pins carry no friction). `None` where the thread does not self-lock at
    /// μ(0) (τ(1) ≥ 0: nothing to break away) or out of range. At the creep's end and the
    /// status, not in the tick.
    #[inline(never)]
    pub fn new(screw: &ScrewModel, mu0: Ratio, g_up: i64, g_down: i64) -> Option<StuckLowering> {
        let mut s = Self::start(screw, mu0, g_up, g_down)?;
        s.finish(screw).then_some(s)
    }

    /// [`Self::new`]'s first half (ρ_x: one 32-bit division), for a control tick's budget; its
    /// breakaway torque is 0 until [`Self::finish`].
    #[inline(never)]
    pub fn start(screw: &ScrewModel, mu0: Ratio, g_up: i64, g_down: i64) -> Option<StuckLowering> {
        // (Halved by a shift: a 64-bit `/` is a runtime call at "z", and this runs in a creep tick.)
        let (g_r, g_f) = (
            div_pow2_i64(g_up + g_down, 1),
            div_pow2_i64(g_up - g_down, 1),
        );
        let mu = i64::from(mu0.bits());
        if mu <= 0 || g_r <= 0 || g_f < 0 {
            return None;
        }
        let t = i64::from(screw.tan_lambda().bits());
        // Q28·Q23 = Q51 (μ₀ < 16, G < 2^8·2^23: < 2^62).
        let num = mu.checked_mul(g_r)?.checked_add(t.checked_mul(g_f)?)?;
        let den = (2 * mu).checked_mul(g_f)?;
        // num·2^16/den through den's normalised reciprocal (both Q51 → Q27: 32 bits): a 32-bit
        // division, not a 64-bit one (the creep's start runs in control ticks).
        let rho_x = match super::pair::div_scaled(num >> 24, den >> 24, 16) {
            Some(r) if den >> 24 > 0 => r.clamp(0, ONE),
            _ => ONE,
        };
        Some(StuckLowering {
            mu0,
            g_r,
            g_f,
            rho_x,
            tau_b: 0,
        })
    }

    /// [`Self::new`]'s second half: the breakaway's |τ(1)|. False where the thread does not
    /// self-lock at μ(0) (nothing to break away) or out of range (the load then stays
    /// unknown: [`Self::load`] gives `None`).
    #[inline(never)]
    pub fn finish(&mut self, screw: &ScrewModel) -> bool {
        // |τ(1)| in Q32 N·m per kg must fit 32 bits for `load`'s reciprocal.
        self.tau_b = match self.torque(screw, ONE, -1) {
            Some(t) if t < 0 && (-t) >> 8 <= i64::from(u32::MAX) => -t,
            _ => 0,
        };
        self.tau_b != 0
    }

    /// The stuck thread's torque per kilogram at mobilisation ρ (Q16) resisting the motion
    /// `d` (−1: lowering, τ(ρ); +1: lifting, the mirror
    /// τ_up(ρ) = r_m·ξ_up(ρ·μ(0))·(G_R + ρ·G_F)), Q40 N·m, signed. Out of line: the bisection
    /// and the sweep's nodes share it.
    #[inline(never)]
    fn torque(&self, screw: &ScrewModel, rho: i64, d: i64) -> Option<i64> {
        let r = super::pair::rho_q32(screw, self.mu_at(rho), d as i8)?;
        // Q32·Q23 = Q55 → Q40.
        Some(r.checked_mul(self.w_at(rho, d))? >> 15)
    }

    /// [`Self::torque`] and the friction torque there, d·r_m·ρμ₀·w/(1 − d·ρμ₀·tan λ) (the
    /// plant's μ_s·|N|·r_m·cos λ, signed as the friction resists), per kilogram, Q40 N·m.
    #[inline(never)]
    fn node(&self, screw: &ScrewModel, rho: i64, d: i64) -> Option<(i64, i64)> {
        let tr = stuck_friction(screw, self.mu_at(rho), self.w_at(rho, d), d)?;
        Some((self.torque(screw, rho, d)?, d * tr))
    }

    /// The mobilisation ρ (Q16) where [`Self::torque`] resisting `d` is `t` (Q40 per kg), on
    /// its monotone branch: lowering [0, ρ_x], lifting [0, 1] (τ_up rises with ρ). Bisection,
    /// 16 steps, clamped to the branch's ends.
    #[inline(never)]
    fn mobilisation(&self, screw: &ScrewModel, t: i64, d: i64) -> Option<i64> {
        let hi = if d < 0 { self.rho_x } else { ONE };
        bisect_mobilisation(hi, |mid| Some(d * self.torque(screw, mid, d)? < d * t))
    }

    /// ∫T_r dT along the branch resisting `d` from mobilisation `from` to `to` (Q16) in
    /// [`WINDUP_SEGMENTS`] equal steps of ρ, the trapezoid rule on the curve (τ, T_r)(ρ)
    /// ([`Self::node`]), added to `acc`: the area (Q48: 2·T_r·|ΔT| summed, both Q24 per kg)
    /// and the span Σ 2·|ΔT| (Q24), whose ratio is the mean T_r over the span, Q24 per
    /// kilogram. Where nothing has spanned yet (T̄ at P), T_r at `to` over a unit span.
    #[inline(never)]
    fn sweep(
        &self,
        screw: &ScrewModel,
        from: i64,
        to: i64,
        d: i64,
        acc: (i64, i64),
    ) -> Option<(i64, i64)> {
        let (mut area, mut span) = acc;
        let (mut t0, mut r0) = self.node(screw, from, d)?;
        for k in 1..=WINDUP_SEGMENTS {
            // (Floored: exact at the last node.)
            let rho = from + (((to - from) * k) >> WINDUP_LOG2);
            let (t1, r1) = self.node(screw, rho, d)?;
            let dt = ((t1 - t0) >> 16).abs();
            area = area.checked_add(((r0 + r1) >> 16).checked_mul(dt)?)?;
            span = span.checked_add(2 * dt)?;
            (t0, r0) = (t1, r1);
        }
        Some(if span == 0 {
            (r0 >> 16, 1)
        } else {
            (area, span)
        })
    }

    /// The axial force per kilogram at mobilisation ρ (Q16) resisting `d`, G_R + d·ρ·G_F
    /// (Q23 N/kg): the pins take ρ of their capacity against the motion.
    fn w_at(&self, rho: i64, d: i64) -> i64 {
        self.g_r + d * ((self.g_f * rho) >> 16)
    }

    /// ρ·μ(0) (ρ Q16).
    fn mu_at(&self, rho: i64) -> Ratio {
        Ratio::from_raw(sat32((i64::from(self.mu0.bits()) * rho) >> 16))
    }

    /// Where |τ| peaks, ρ_x Q16.
    pub fn peak_mobilisation(&self) -> i64 {
        self.rho_x
    }

    /// The breakaway thread torque |P| = M·|τ(1)| of load `load` (Q16 N·m): one product.
    pub fn breakaway_torque(&self, load: Kilograms) -> i64 {
        // Q32 per kg (< 2^32, `finish`) · Q12 kg (< 2^25) = Q44 → Q16.
        ((self.tau_b >> 8).saturating_mul(i64::from(load.bits().max(0)))) >> 28
    }

    /// The load whose breakaway thread torque is `peak` (its magnitude, Q16 N·m):
    /// M = |P|/|τ(1)|. `None` for a peak ≤ 0 or out of range.
    pub fn load(&self, peak: i64) -> Option<Kilograms> {
        if peak <= 0 || self.tau_b == 0 {
            return None;
        }
        // Q16·2^28 / Q32 = Q12 kg, through |τ|'s normalised reciprocal (a 32-bit division:
        // the creep's end runs in a control tick).
        let m = super::pair::div_scaled(peak, self.tau_b >> 8, 28)?;
        Some(Kilograms::from_raw(i32::try_from(m).ok()?))
    }

    /// The mean friction torque T̄_r of a stick-slipping lowering of load `load` whose mean
    /// thread torque is `mean` T̄ (signed, Q16 N·m). Each stick winds the coupling up at the
    /// reference speed, uniformly in time, from the slip's trough to the breakaway
    /// P = M·τ(1) (the slip is nearly free, so the trough is 2·T̄ − P), and the mean T_r is the
    /// mean over that span of the stuck thread's T_r at each torque: along τ's monotone branch
    /// from the breakaway's ρ_P (τ(ρ_P) = τ(1), ρ_P ≤ ρ_x) back to the trough's ρ, where
    /// T_r = −M·r_m·ρμ₀·(G_R − ρ·G_F)/(1 + ρμ₀·tan λ) (the plant's μ_s·|N|·r_m·cos λ); a trough
    /// above the load's push alone (τ(0)) goes on along the lifting branch, the statics then
    /// holding the screw against lifting (the plant's ρ < 0), and stops at its
    /// breakaway. The integral ∫T_r dT runs over [`WINDUP_SEGMENTS`] equal steps of ρ on each
    /// branch (the trapezoid rule on the curve (T(ρ), T_r(ρ)): no inversion but the ends').
    /// T_r is curved in T where the pins take much of the push (ρ's slope steepens towards
    /// ρ_x), so T_r at the mean torque is not the mean T_r (host-sim, dry 1000 kg lowering from
    /// 150 mm, seed 102: the thread stands 98 % of the cruise, the coupling's torque spread
    /// evenly over −9.0…+4.2 N·m; T_r at the mean torque read −9.00 N·m against the plant's
    /// mean −8.72). A mean beyond the breakaway (noise) reads the span from P to τ's peak.
    /// `None` out of range. At the status, not in the tick.
    #[inline(never)]
    pub fn friction(&self, screw: &ScrewModel, load: Kilograms, mean: i64) -> Option<NewtonMetres> {
        let m = i64::from(load.bits());
        if m <= 0 || self.tau_b == 0 {
            return None;
        }
        // Per kilogram, Q40 N·m: T̄ (Q16·2^36 / Q12), P = −|τ(1)|, the trough 2·T̄ − P.
        let mean = mean.checked_mul(1 << 36)?.checked_div(m)?;
        let p = -self.tau_b;
        let trough = mean.saturating_mul(2).saturating_sub(p);
        // Along the lowering branch from P to the trough, or to the push alone (ρ = 0).
        let from = self.mobilisation(screw, trough, -1)?;
        let to = self.mobilisation(screw, p, -1)?;
        let mut acc = self.sweep(screw, from, to, -1, (0, 0))?;
        if trough > self.torque(screw, 0, -1)? {
            let to = self.mobilisation(screw, trough, 1)?;
            acc = self.sweep(screw, 0, to, 1, acc)?;
        }
        let (area, span) = acc;
        // The mean T_r per kilogram (Q24) · M (Q12) → Q16.
        let tr = (area / span).checked_mul(m)? >> 20;
        Some(NewtonMetres::from_raw(sat32(tr)))
    }
}

/// How many equal steps of ρ [`StuckLowering::friction`] integrates each branch of a wind-up
/// over, and its log2.
pub const WINDUP_SEGMENTS: i64 = 1 << WINDUP_LOG2;
const WINDUP_LOG2: u32 = 3;

/// Q16 one (a mobilisation of 1).
const ONE: i64 = 1 << 16;
