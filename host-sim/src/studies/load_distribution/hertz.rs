//! Hertz point contact with the elliptic-integral coefficients computed, not read off a chart.
//!
//! For two bodies touching at a point, with principal curvatures summed per direction
//! (`1/R_x`, `1/R_y`, convex positive), Hertz's solution (in the form of Hamrock & Brewe, as used
//! by Harris, *Rolling Bearing Analysis*) is
//!
//! - curvature sum `Σρ = 1/R_x + 1/R_y`, `R = 1/Σρ`, curvature difference `Γ = R·|1/R_x − 1/R_y|`;
//! - ellipticity `κ = a/b ≥ 1` from `Γ = ((κ²+1)·𝓔(m) − 2·𝓕(m)) / ((κ²−1)·𝓔(m))`, `m = 1 − 1/κ²`,
//!   where 𝓕 and 𝓔 are the complete elliptic integrals of the first and second kind;
//! - approach `δ = 𝓕·[ (9/(2·𝓔·R))·(Q/(π·κ·E'))² ]^(1/3)`, i.e. `Q = K·δ^(3/2)` with
//!   `K = π·κ·E'·√(2·𝓔·R / (9·𝓕³))`, `E' = 2 / ((1−ν₁²)/E₁ + (1−ν₂²)/E₂)`.
//!
//! Seed 001's Eq 14 is this `K` for the screw and the nut contacts in series (its printed form
//! is garbled; the series law `K = [K_s^(−2/3) + K_n^(−2/3)]^(−3/2)` is what its brackets say).

use std::f64::consts::PI;

/// Complete elliptic integrals 𝓕(m) and 𝓔(m) of parameter `m = k²` (0 ≤ m < 1) by the
/// arithmetic-geometric mean (Abramowitz & Stegun 17.6): quadratic convergence, full double
/// precision in ≤ 6 steps for m ≤ 1 − 10⁻¹².
pub fn elliptic_ke(m: f64) -> (f64, f64) {
    let mut a = 1.0f64;
    let mut b = (1.0 - m).sqrt();
    let mut pow = 0.5; // 2^(n−1), n = 0
    let mut sum = pow * m; // c₀² = m
    for _ in 0..40 {
        if (a - b).abs() <= 1e-16 * a {
            break;
        }
        let an = 0.5 * (a + b);
        let bn = (a * b).sqrt();
        let c = 0.5 * (a - b);
        a = an;
        b = bn;
        pow *= 2.0;
        sum += pow * c * c;
    }
    let k = PI / (2.0 * a);
    (k, k * (1.0 - sum))
}

/// `Γ(κ)`: the curvature difference that gives ellipticity `κ` (increasing from 0 at κ = 1 to
/// 1 as κ → ∞).
pub fn curvature_difference_of(kappa: f64) -> f64 {
    let k2 = kappa * kappa;
    if k2 - 1.0 < 1e-12 {
        return 0.0;
    }
    let (kk, ee) = elliptic_ke(1.0 - 1.0 / k2);
    ((k2 + 1.0) * ee - 2.0 * kk) / ((k2 - 1.0) * ee)
}

/// Ellipticity `κ = a/b` for curvature difference `Γ` (0 ≤ Γ < 1): Newton on ln κ from Hamrock &
/// Brewe's fit, kept inside a bisection bracket. Γ(κ) is inverted to 10⁻¹² for Γ ≥ 0.01 (test);
/// nearer a circular contact the cancellation in Γ(κ) costs digits (ball-screw contacts have
/// Γ ≈ 0.92).
pub fn ellipticity(gamma: f64) -> f64 {
    if gamma <= 1e-12 {
        return 1.0;
    }
    let gamma = gamma.min(1.0 - 1e-12);
    // Bracket in t = ln κ.
    let (mut lo, mut hi) = (0.0f64, 30.0f64);
    // Hamrock & Brewe: κ ≈ 1.0339·(R_y/R_x)^0.636 with R_y/R_x = (1+Γ)/(1−Γ).
    let mut t = (1.0339f64.ln() + 0.636 * ((1.0 + gamma) / (1.0 - gamma)).ln()).clamp(1e-6, 29.0);
    for _ in 0..100 {
        let f = curvature_difference_of(t.exp()) - gamma;
        if f > 0.0 {
            hi = t;
        } else {
            lo = t;
        }
        let h = 1e-7 * t.max(1e-3);
        let df = (curvature_difference_of((t + h).exp()) - curvature_difference_of((t - h).exp()))
            / (2.0 * h);
        let mut next = if df > 0.0 { t - f / df } else { f64::NAN };
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        if (next - t).abs() <= 1e-14 * t.max(1.0) || hi - lo <= 1e-15 * hi.max(1.0) {
            return next.exp();
        }
        t = next;
    }
    t.exp()
}

/// A Hertz point contact: `Q = k·δ^(3/2)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    /// Curvature sum Σρ, 1/m.
    pub sum_rho: f64,
    /// Curvature difference Γ.
    pub gamma: f64,
    /// Ellipticity κ = a/b.
    pub kappa: f64,
    /// 𝓕(m), first kind.
    pub k_first: f64,
    /// 𝓔(m), second kind.
    pub e_second: f64,
    /// Load-deflection coefficient K, N/m^1.5.
    pub k: f64,
}

/// The contact of two bodies with principal curvatures summed per direction
/// (`rho_x = ρ_I,x + ρ_II,x`, `rho_y` likewise, 1/m, convex positive) and effective modulus
/// `e_prime = 2/((1−ν₁²)/E₁ + (1−ν₂²)/E₂)`, Pa.
pub fn contact(rho_x: f64, rho_y: f64, e_prime: f64) -> Contact {
    let sum_rho = rho_x + rho_y;
    let gamma = ((rho_x - rho_y) / sum_rho).abs();
    let kappa = ellipticity(gamma);
    let (k_first, e_second) = elliptic_ke(1.0 - 1.0 / (kappa * kappa));
    let r = 1.0 / sum_rho;
    let k = PI * kappa * e_prime * (2.0 * e_second * r / (9.0 * k_first.powi(3))).sqrt();
    Contact {
        sum_rho,
        gamma,
        kappa,
        k_first,
        e_second,
        k,
    }
}

/// Two Hertz contacts in series (the ball against the screw and against the nut carry the same
/// Q; their approaches add): `K = [K₁^(−2/3) + K₂^(−2/3)]^(−3/2)`.
pub fn series(k1: f64, k2: f64) -> f64 {
    (k1.powf(-2.0 / 3.0) + k2.powf(-2.0 / 3.0)).powf(-1.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elliptic_integrals_match_tabulated_values() {
        // A&S Table 17.1 / DLMF: K(0.5) = 1.854074677301372, E(0.5) = 1.350643881047675;
        // K(0.9) = 2.578092113348173, E(0.9) = 1.104774732704073.
        let (k, e) = elliptic_ke(0.5);
        assert!((k - 1.854_074_677_301_372).abs() < 1e-14, "{k}");
        assert!((e - 1.350_643_881_047_675).abs() < 1e-14, "{e}");
        let (k, e) = elliptic_ke(0.9);
        assert!((k - 2.578_092_113_348_173).abs() < 1e-13, "{k}");
        assert!((e - 1.104_774_732_704_073).abs() < 1e-13, "{e}");
        let (k, e) = elliptic_ke(0.0);
        assert!((k - PI / 2.0).abs() < 1e-15 && (e - PI / 2.0).abs() < 1e-15);
    }

    #[test]
    fn ellipticity_inverts_the_curvature_difference() {
        for g in [0.01, 0.1, 0.5, 0.9, 0.93, 0.99, 0.9999] {
            let k = ellipticity(g);
            assert!(
                (curvature_difference_of(k) - g).abs() < 1e-12,
                "{g}: κ = {k}"
            );
        }
    }

    #[test]
    fn sphere_on_flat_is_classical_hertz() {
        // F = (4/3)·E*·√R·δ^1.5 with 1/E* = 2(1−ν²)/E, R the sphere radius.
        let (e, nu, r) = (205e9, 0.3, 2.3815e-3);
        let e_prime = e / (1.0 - nu * nu);
        let c = contact(1.0 / r, 1.0 / r, e_prime);
        let e_star = e / (2.0 * (1.0 - nu * nu));
        let want = 4.0 / 3.0 * e_star * r.sqrt();
        assert!((c.k - want).abs() < 1e-9 * want, "{} vs {want}", c.k);
        assert!((c.kappa - 1.0).abs() < 1e-12);
    }
}
