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
    /// Number of samples (0: a breakaway's, `LoadIdent::breakaway_pair`).
    pub n: u32,
    /// The motion stick-slipped (its mean friction over stick and slip is below the law's
    /// sliding friction): a pair with it may not conclude a wetter thread than configured.
    pub slipped: bool,
}

/// A motion's mean breakaway: the thread torque P (signed, as the motor drives the screw) when
/// the stuck thread broke away, and the axial force per kilogram G_d (Q23 N/kg) at its pose.
/// The nut stands (D = 0), so P = M·ρ_d(μ(0))·G_d: a lift's and a lowering's make a pair
/// (`LoadIdent::breakaway_pair`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Breakaway {
    /// P, Q16 N·m.
    pub torque: NewtonMetres,
    /// G_d, Q23 N/kg.
    pub g_per_kg: i32,
}

impl Breakaway {
    /// As a pair's means in direction `dir`, for the law's μ(0) at scale 1 `mu0` (no samples:
    /// `n` = 0).
    pub fn means(self, dir: i8, mu0: Ratio) -> MotionMeans {
        MotionMeans {
            dir,
            torque: self.torque,
            g_per_kg: self.g_per_kg,
            free: Newtons::ZERO,
            mu: mu0,
            n: 0,
            slipped: false,
        }
    }
}

/// `v·2^k/x` through x's normalised reciprocal ([`super::recip16`]: 17 significant bits,
/// ≤ 2^-15 relative) and one product: a 32-bit division instead of a 64-bit one. `None` when x
/// is 0 or beyond 32 bits, or the product overflows.
#[inline(never)]
pub fn div_scaled(v: i64, x: i64, k: i32) -> Option<i64> {
    let ax = u32::try_from(x.unsigned_abs()).ok().filter(|&a| a != 0)?;
    let (inv, sh) = super::recip16(ax);
    let q = super::shift_right(v.checked_mul(i64::from(inv))?, 32 + sh - k);
    Some(if x < 0 { -q } else { q })
}

/// r_m·ξ_d(μ) for direction `dir` on the loaded flank, Q32 metres (ρ ≤ 0.05 m·4.4·1.5 <
/// 0.33 m: fits i64 with room). `None` when 1 − d·μ·tan λ is not positive (μ beyond 1/tan λ).
pub fn rho_q32(screw: &ScrewModel, mu: Ratio, dir: i8) -> Option<i64> {
    let tan = i64::from(screw.tan_lambda().bits());
    let mu_s = i64::from(mu.bits()) * i64::from(dir.signum());
    let num = tan + mu_s; // Q28
    let den = (1i64 << 28) - ((mu_s * tan) >> 28); // Q28
    if den <= 0 {
        return None;
    }
    let r = i64::from(screw.pitch_radius().bits()); // Q24
                                                    // r·num (Q52) over den (Q28) → Q24; Q32 is 8 bits more (r·num pre-shifted by 16).
    div_scaled(r.checked_mul(num)? >> 16, den, 24)
}

/// A lowering's load read on the reversed flank: `M = (T/ρ_up(μ) − D)/G_d` where the mean
/// thread torque puts the axial demand W = T/ρ_up between D and 0. A light lowering's D is
/// negative (the structure's damping resists the descent more than the load pushes), so below
/// M* = −D/G_d the thread carries on its other flank, whose r_m·ξ is lifting's. The thread
/// torque is then V-shaped in M: from r_m·ξ_up·D at an empty head to the support torque at M*,
/// then down the loaded flank's much flatter slope (PTFE at 150 mm: 0 kg and 26 kg give the same
/// torque). The loaded-flank solve reads an empty lift as the far branch's load; this one gives
/// the near branch's (the smaller load that explains the same torque). `mu` is the law in force
/// at the samples' speed (its scale included). `None` lifting, where D ≥ 0, or where the torque
/// lies outside the reversed flank's range (the load is on the loaded flank). Two 32-bit
/// divisions; not in the tick.
#[inline(never)]
pub fn reversed_flank_load(screw: &ScrewModel, m: &MotionMeans) -> Option<i64> {
    let d = i64::from(m.free.bits()) << 8; // Q16 N
    if m.dir >= 0 || d >= 0 || m.g_per_kg <= 0 {
        return None;
    }
    let rho = rho_q32(screw, m.mu, 1)?;
    // W = T/ρ in Q16 N: T (Q16 N·m)·2^32/ρ (Q32 m).
    let axial = div_scaled(i64::from(m.torque.bits()), rho, 32)?;
    // Down to 1.5·D: an empty head's torque read with the current's accuracy (≈ 0.01 N·m at
    // the screw, a third of an empty PTFE head's 0.027 N·m), which the near branch reads as 0.
    if axial > 0 || axial < d + d / 2 {
        return None;
    }
    // kg Q12 = N (Q16)·2^19 / G (Q23).
    div_scaled((axial - d).max(0), i64::from(m.g_per_kg), 19)
}

/// The load one motion's means give at friction scale `scale` (on the configured law):
/// `M = (T/ρ_d(s·μ) − D)/G_d`. `None` where it is not defined (ρ or G zero, overflow).
/// Not clamped: a pair solve needs the sign and the slope. Three 32-bit divisions.
#[inline(never)]
pub fn load_at_scale(screw: &ScrewModel, m: &MotionMeans, scale: Ratio) -> Option<i64> {
    let mu = scaled_mu(m.mu, scale)?;
    let rho = rho_q32(screw, mu, m.dir)?;
    // T/ρ in Q16 N: T (Q16 N·m)·2^32/ρ (Q32 m).
    let axial = div_scaled(i64::from(m.torque.bits()), rho, 32)?;
    let net = axial.checked_sub(i64::from(m.free.bits()) << 8)?; // Q16 N
                                                                 // kg Q12 = N (Q16)·2^19 / G (Q23).
    div_scaled(net, i64::from(m.g_per_kg), 19)
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

/// Grid points of a search's first pass (then bisection).
const GRID: u8 = 32;
/// A search's step index during the bisection, and at its final evaluation.
const BISECT: u8 = GRID + 1;
const FINAL: u8 = GRID + 2;

/// A lift/lowering pair solved for the friction scale and the load, spread over the ticks at
/// rest: each [`PairSearch::step`] evaluates one motion's load at one scale
/// ([`load_at_scale`], a few 64-bit divisions), so no tick pays the whole solve (≈ 100
/// steps). [`solve`] runs it to the end at once.
///
/// It looks for the s in [`SCALE_MIN`]…[`SCALE_MAX`] where `M_up(s) = M_down(s)`, to 2^-20
/// of s. `M_down` falls faster with s than `M_up` (lowering weighs friction against the lead:
/// ρ_down ∝ tan(φ − λ)), so `h = M_up − M_down` rises through zero, once where the load's push
/// dominates the load-free demand D: h → −∞ just above the self-locking point, where the
/// search starts. A light load whose D rivals M·G_down can cross twice: the pair is then
/// ambiguous and refused (the board keeps its scale). So the first crossing from below is
/// found on a grid of 32 steps, then bisected; a second crossing refuses the pair.
/// Refused also: means that do not bracket a solution (no s in range explains both, e.g. a
/// different car, an obstruction), a lowering that is not self-locking over the whole range
/// (its torque then carries no friction sign), and a lowering whose load sensitivity is under
/// 1/8 of the lift's (at high arm angles the pins take nearly the whole push of the load while
/// lowering: G_down = g·(cos α − 2μ_b)/sin α → 0, and the lowering's torque no longer weighs
/// the load).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PairSearch {
    /// The grid's ends, then the bisection's bracket (Q28 scale).
    lo: i64,
    hi: i64,
    /// Grid spacing.
    grid: i64,
    /// 0: the start point; 1…[`GRID`]: the grid; then [`BISECT`], [`FINAL`].
    k: u8,
    /// The grid's first bracket of the crossing.
    bracket: Option<(i64, i64)>,
    /// `M_up` at the point under evaluation (the first half of a step).
    m_up: Option<i64>,
}

/// What a [`PairSearch::step`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SearchStep {
    /// More steps to go.
    Pending,
    /// Finished: the solution, or `None` (refused, see [`PairSearch`]).
    Done(Option<PairSolution>),
}

impl PairSearch {
    /// A search for a lift `up` and a lowering `down` of the same car; `None` when the pair
    /// cannot have a solution (directions, load sensitivities, an empty scale range).
    pub fn new(screw: &ScrewModel, up: &MotionMeans, down: &MotionMeans) -> Option<PairSearch> {
        if up.dir <= 0 || down.dir >= 0 || up.g_per_kg <= 0 || down.g_per_kg < up.g_per_kg >> 3 {
            return None;
        }
        // Lowering is self-locking (ρ_down < 0) only above s·μ = tan λ: start just above it.
        let tan = i64::from(screw.tan_lambda().bits());
        let mu_dn = i64::from(down.mu.bits()).max(1);
        let s_lock = ((tan << 28) / mu_dn) * 1025 / 1024;
        let lo = s_lock.max(i64::from(SCALE_MIN.bits()));
        // A thread's μ beyond MU_PAIR_MAX (a seized, galling thread) is not a lubrication
        // state a pair should explain: the search stops there (and at the model's μ_max).
        let mu_top = i64::from(screw.mu_max().min(MU_PAIR_MAX).bits());
        let mu_big = i64::from(up.mu.bits()).max(mu_dn).max(1);
        let hi = i64::from(SCALE_MAX.bits()).min((mu_top << 28) / mu_big);
        (lo < hi).then_some(PairSearch {
            lo,
            hi,
            grid: (hi - lo) / i64::from(GRID),
            k: 0,
            bracket: None,
            m_up: None,
        })
    }

    /// The scale the step under way evaluates.
    fn point(&self) -> i64 {
        match self.k {
            GRID => self.hi,
            BISECT => self.lo + (self.hi - self.lo) / 2,
            FINAL => self.lo,
            k => self.lo + self.grid * i64::from(k),
        }
    }

    /// One load evaluation, on the means the search was made for.
    pub fn step(&mut self, screw: &ScrewModel, up: &MotionMeans, down: &MotionMeans) -> SearchStep {
        self.advance(screw, up, down)
            .unwrap_or(SearchStep::Done(None))
    }

    fn advance(
        &mut self,
        screw: &ScrewModel,
        up: &MotionMeans,
        down: &MotionMeans,
    ) -> Option<SearchStep> {
        let s = self.point();
        let scale = Ratio::from_raw(i32::try_from(s).ok()?);
        let Some(m_up) = self.m_up.take() else {
            self.m_up = Some(load_at_scale(screw, up, scale)?);
            return Some(SearchStep::Pending);
        };
        let m_down = load_at_scale(screw, down, scale)?;
        let h = m_up - m_down;
        match self.k {
            0 if h >= 0 => return None,
            0 => {}
            FINAL => {
                let load = ((m_up + m_down) / 2)
                    .max(0)
                    .min(i64::from(crate::estimator::LOAD_MAX.bits()));
                return Some(SearchStep::Done(Some(PairSolution {
                    scale,
                    load: Kilograms::from_raw(load as i32),
                })));
            }
            BISECT => {
                if h < 0 {
                    self.lo = s;
                } else {
                    self.hi = s;
                }
            }
            k => match self.bracket {
                None if h > 0 => self.bracket = Some((self.lo + self.grid * i64::from(k - 1), s)),
                // A second crossing: ambiguous.
                Some(_) if h < 0 => return None,
                _ => {}
            },
        }
        self.k = match self.k {
            GRID => {
                (self.lo, self.hi) = self.bracket?;
                BISECT
            }
            BISECT => BISECT,
            k => k + 1,
        };
        if self.k == BISECT && self.hi - self.lo <= 1 << 8 {
            self.k = FINAL;
        }
        Some(SearchStep::Pending)
    }
}

/// [`PairSearch`] run to its end at once (tests and host tools; the board spreads it over the
/// ticks at rest).
pub fn solve(screw: &ScrewModel, up: &MotionMeans, down: &MotionMeans) -> Option<PairSolution> {
    let mut search = PairSearch::new(screw, up, down)?;
    loop {
        if let SearchStep::Done(sol) = search.step(screw, up, down) {
            return sol;
        }
    }
}

/// ρ_d(s₀·μ)/ρ_d(s·μ) in Q28: the factor that takes a load identified at friction scale s₀
/// to the load at scale s, ignoring the load-free demand D (a few tens of newtons against
/// kilonewtons). `None` if undefined.
pub fn load_factor(screw: &ScrewModel, mu: Ratio, dir: i8, s0: Ratio, s: Ratio) -> Option<Ratio> {
    let a = rho_q32(screw, scaled_mu(mu, s0)?, dir)?;
    let b = rho_q32(screw, scaled_mu(mu, s)?, dir)?;
    i32::try_from(div_scaled(a, b, 28)?)
        .ok()
        .map(Ratio::from_raw)
}
