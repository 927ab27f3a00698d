//! Scissor geometry (Eq 1), pin friction (Eq 6) and structure damping (Eq 4, Table 1).
//!
//! The lift is a rhombus of four arms; the lead screw lies on its horizontal diagonal, with one
//! end pinned to the thrust bearing and the nut on the other corner. With `L` the diagonal length
//! of Eq 1 (twice the arm length), the horizontal diagonal is `L·cos α` and the vertical one
//! `L·sin α`, so the nut travel is `x = L·(cos α₀ − cos α)` (Eq 1) and the head height is
//! `h = h₀ + L·sin α`.

use super::G;

/// Lift geometry and load parameters (SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Geometry {
    /// Eq 1's length `L`, m: the rhombus diagonal, twice the arm length.
    pub length: f64,
    /// Arm angle to the screw axis with the lift fully down, rad (seed 000: 15°).
    pub alpha0: f64,
    /// Largest arm angle the mechanism reaches, rad.
    pub alpha_max: f64,
    /// Height of the head with the rhombus collapsed to zero (base + head thickness), m.
    pub h0: f64,
    /// Pin friction coefficient μ_b (seed 000: 0.3 steel pins, 0 for the ideal case).
    pub mu_pin: f64,
}

impl Geometry {
    /// The default lift: 0.2 m arms (L = 0.4 m), α₀ = 15°, α_max = 75°, h₀ = 30 mm, μ_b = 0.3.
    pub fn paper() -> Self {
        Self {
            length: 0.4,
            alpha0: 15f64.to_radians(),
            alpha_max: 75f64.to_radians(),
            h0: 0.03,
            mu_pin: 0.3,
        }
    }

    /// cos α for nut travel `x` (Eq 1).
    pub fn cos_alpha(&self, x: f64) -> f64 {
        self.alpha0.cos() - x / self.length
    }

    /// Arm angle α for nut travel `x`, rad.
    pub fn alpha(&self, x: f64) -> f64 {
        self.cos_alpha(x).clamp(-1.0, 1.0).acos()
    }

    /// Nut travel for arm angle α, m.
    pub fn travel(&self, alpha: f64) -> f64 {
        self.length * (self.alpha0.cos() - alpha.cos())
    }

    /// Head height for arm angle α, m.
    pub fn height(&self, alpha: f64) -> f64 {
        self.h0 + self.length * alpha.sin()
    }

    /// Arm angle for head height `h`, rad (inverse of [`Geometry::height`] on 0…90°).
    pub fn alpha_of_height(&self, h: f64) -> f64 {
        ((h - self.h0) / self.length).clamp(-1.0, 1.0).asin()
    }

    /// Axial load on the nut, N (Eq 1): R = M·g / tan α.
    pub fn axial_load(&self, mass: f64, alpha: f64) -> f64 {
        mass * G / alpha.tan()
    }

    /// Pin friction force on the translating part, N (Eq 6): F₀ = 2·μ_b·M·g / sin α.
    pub fn pin_friction(&self, mass: f64, alpha: f64) -> f64 {
        2.0 * self.mu_pin * mass * G / alpha.sin()
    }
}

/// Structure damping c_x(α), kg/s: Eq 4 with Table 1 (ζ = 0.3, m_eq = 1000 kg), linear in α
/// between the table's angles and held constant outside them.
pub fn structure_damping(alpha: f64) -> f64 {
    let deg = alpha.to_degrees();
    let t = &DAMPING_TABLE;
    if deg <= t[0].0 {
        return t[0].1;
    }
    for w in t.windows(2) {
        let ((a0, c0), (a1, c1)) = (w[0], w[1]);
        if deg <= a1 {
            return c0 + (c1 - c0) * (deg - a0) / (a1 - a0);
        }
    }
    t[t.len() - 1].1
}

/// Structure damping c_x, kg/s, as the fixed-point estimator reads Table 1: linear in cos α
/// between the table's angles (the per-tick model has cos α, not α: docs/model.md "Structure
/// damping"), held constant outside them. The same values as [`structure_damping`] at the
/// table's angles; between them within 8 % of it (the plant keeps the α reading).
pub fn structure_damping_cos(cos_alpha: f64) -> f64 {
    let t = &DAMPING_TABLE;
    let cos = |deg: f64| deg.to_radians().cos();
    if cos_alpha >= cos(t[0].0) {
        return t[0].1;
    }
    for w in t.windows(2) {
        let ((a0, c0), (a1, c1)) = (w[0], w[1]);
        if cos_alpha >= cos(a1) {
            return c0 + (c1 - c0) * (cos(a0) - cos_alpha) / (cos(a0) - cos(a1));
        }
    }
    t[t.len() - 1].1
}

/// Table 1 of seed 000: (α in degrees, c_x in kg/s).
pub const DAMPING_TABLE: [(f64, f64); 3] = [(15.0, 58_544.0), (45.0, 28_878.0), (65.0, 23_175.0)];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn travel_and_angle_are_inverse() {
        let g = Geometry::paper();
        for deg in [15.0f64, 30.0, 45.0, 65.0, 75.0, 89.0] {
            let a = deg.to_radians();
            assert!((g.alpha(g.travel(a)) - a).abs() < 1e-12);
            assert!((g.alpha_of_height(g.height(a)) - a).abs() < 1e-12);
        }
    }

    #[test]
    fn damping_matches_table_one_and_eq_four() {
        // c_x = 2ζ·sqrt(k_eq·m_eq) with k_eq = 9520 N/mm at 15°.
        let eq4 = 2.0 * 0.3 * (9520e3f64 * 1000.0).sqrt();
        assert!((structure_damping(15f64.to_radians()) - eq4).abs() / eq4 < 1e-4);
        assert_eq!(structure_damping(45f64.to_radians()), 28_878.0);
        assert_eq!(structure_damping(80f64.to_radians()), 23_175.0);
        // The cos α reading agrees at the rows and stays within 8 % between them.
        for deg in [10.0f64, 15.0, 45.0, 65.0, 80.0] {
            let (a, c) = (deg.to_radians(), deg.to_radians().cos());
            assert!((structure_damping_cos(c) - structure_damping(a)).abs() < 1e-6);
        }
        for deg in (15..=65).map(f64::from) {
            let (a, c) = (deg.to_radians(), deg.to_radians().cos());
            let rel =
                (structure_damping_cos(c) - structure_damping(a)).abs() / structure_damping(a);
            assert!(rel < 0.08, "{deg}: {rel}");
        }
    }
}
