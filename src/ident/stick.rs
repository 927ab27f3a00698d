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
//! mobilised on average. With ρ₀ = r_m·tan λ (the lead alone), the thread torque at ρ is, to
//! first order, T(ρ) = T₀ + ρ·(P − T₀) with T₀ = ρ₀·M·G_R (the load's push R alone, no pin
//! friction: G_R = (G_up + G_down)/2), and the friction torque ρ·T_cap with
//! T_cap = P − ρ₀·M·G_d = P·(1 − ρ₀/ρ₁). Both are linear in ρ, so their means are too:
//! T̄_r = T_cap·(T̄ − T₀)/(P − T₀), T̄ the mean measured thread torque.

use crate::units::{sat32, Kilograms, NewtonMetres, Q};

/// The load and the mean T_r of a stick-slipping lift, from the mean breakaway thread torque
/// `peak` P and the mean thread torque `mean` T̄ (Q16 N·m), ρ₁ = ρ_up(μ(0)) and ρ₀ = r_m·tan λ
/// (`rho1`, `rho0`, Q32 m, from `pair::rho_q32`), G_up and G_R (`g_d`, `g_r`, Q23 N/kg).
/// `drop` is the slips' fall of the torque (over the motion: 2·(P − T̄)): a stick
/// from rest unwinds the coupling from the breakaway P to about the lead's T₀ (the slip is
/// nearly free); a fall under half the span P − T₀ is a ripple of a thread that keeps sliding
/// (micro stick-slip, noise), whose peaks are no breakaways: `None`. `None` as well where it
/// is undefined (P ≤ T₀, ρ₁ ≤ ρ₀, G ≤ 0) or out of range. Divisions: at the status, not in
/// the control tick.
#[inline(never)]
pub fn lift(
    peak: i64,
    mean: i64,
    drop: i64,
    rho1: i64,
    rho0: i64,
    g_d: i64,
    g_r: i64,
) -> Option<(Kilograms, NewtonMetres)> {
    if rho1 <= rho0 || rho0 < 0 || g_d <= 0 || g_r <= 0 || peak <= 0 {
        return None;
    }
    // W = P/ρ₁ in Q8 N: P (Q16, < 2^31)·2^24 / ρ₁ (Q32).
    let w = (peak << 24).checked_div(rho1)?;
    // M = W/G_d in Q12 kg: W (Q8)·2^27 / G (Q23).
    let m = w.checked_mul(1 << 27)?.checked_div(g_d)?;
    // P·ρ₀/ρ₁ (Q16): the lead's share of the breakaway torque; T₀ = P·(ρ₀/ρ₁)·(G_R/G_d).
    let lead = peak.checked_mul(rho0)?.checked_div(rho1)?;
    let t0 = lead.checked_mul(g_r)?.checked_div(g_d)?;
    let cap = peak - lead;
    let span = peak - t0;
    if span <= 0 || drop.saturating_mul(2) < span {
        return None;
    }
    let tr = (mean - t0).checked_mul(cap)?.checked_div(span)?;
    Some((
        Kilograms::from_raw(i32::try_from(m).ok()?),
        NewtonMetres::from_raw(sat32(tr)),
    ))
}
