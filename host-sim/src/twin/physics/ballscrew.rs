//! Ball-screw friction of seed 002 in float64: the twin of `liftfw::model::ballscrew`.
//!
//! Same readings as the core (docs/model.md, "Ball screw"): Eq 1 with Eq 2's factor 2 (both
//! raceway contacts of every ball), F = preload + |R|, τ = η₀·r_m|θ̇|/P with
//! P = F/(M sin α cos β).

use super::FrictionLaw;
use std::f64::consts::PI;

/// A ball screw's friction model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BallScrewFriction {
    /// Ball-centre radius r_m, m.
    pub r_m: f64,
    /// Ball radius r_b, m.
    pub r_b: f64,
    /// Contact angle α, rad.
    pub alpha: f64,
    /// Lead l, m.
    pub lead: f64,
    /// Loaded balls M.
    pub balls: f64,
    /// Preload F_p, N.
    pub preload: f64,
    /// Dynamic viscosity η₀, Pa·s.
    pub viscosity: f64,
    /// f(τ).
    pub law: FrictionLaw,
}

impl BallScrewFriction {
    /// Seed 001's 4008-3 in VG100 oil with seed 002's law (the core's `SEED_001_4008`).
    pub fn seed_001_4008() -> Self {
        Self {
            r_m: 0.020,
            r_b: 0.0023815,
            alpha: 45f64.to_radians(),
            lead: 0.008,
            balls: 78.0,
            preload: 0.0,
            viscosity: 0.09,
            law: FrictionLaw::ball_screw(),
        }
    }

    /// Helix angle β = atan(l/(2π r_m)).
    pub fn helix(&self) -> f64 {
        (self.lead / (2.0 * PI * self.r_m)).atan()
    }

    /// Moment arm of Eq 1: 2(r_m + r_b cos α)/sin α, m.
    pub fn arm(&self) -> f64 {
        2.0 * (self.r_m + self.r_b * self.alpha.cos()) / self.alpha.sin()
    }

    /// Axial force on the loaded balls: preload + |R|, N.
    pub fn axial_force(&self, load: f64) -> f64 {
        self.preload + load.abs()
    }

    /// Normal load per ball P = F/(M sin α cos β) (seed 002's Q), N.
    pub fn ball_load(&self, f_axial: f64) -> f64 {
        f_axial / (self.balls * self.alpha.sin() * self.helix().cos())
    }

    /// τ = η₀·V/P with V = r_m|θ̇|.
    pub fn tau(&self, theta_dot: f64, f_axial: f64) -> f64 {
        self.viscosity * self.r_m * theta_dot.abs() / self.ball_load(f_axial)
    }

    /// f(τ), seed 002 Eq 3.
    pub fn coefficient(&self, tau: f64) -> f64 {
        self.law.mu_of(tau)
    }

    /// Friction torque, Eq 1 with Eq 2's factor 2: M_f = 2·f·F·(r_m + r_b cos α)/sin α, N·m.
    pub fn friction_torque(&self, f: f64, f_axial: f64) -> f64 {
        f * f_axial * self.arm()
    }

    /// Eq 2 as printed: f = M_test·sin α / (2·F_p·(r_m + r_b cos α)).
    pub fn coefficient_from_torque(&self, torque: f64, f_axial: f64) -> f64 {
        torque * self.alpha.sin() / (2.0 * f_axial * (self.r_m + self.r_b * self.alpha.cos()))
    }

    /// Torque of the axial force alone, F·l/(2π), N·m.
    pub fn load_torque(&self, f_axial: f64) -> f64 {
        f_axial * self.lead / (2.0 * PI)
    }

    /// Screw torque at steady speed θ̇ under axial load R (positive = lifting direction):
    /// lifting `|R|·l/(2π) + M_f`, lowering `|R|·l/(2π) − M_f` (the preload, internal to the
    /// nut, adds friction through F but no load torque).
    pub fn steady_screw_torque(&self, theta_dot: f64, load: f64) -> f64 {
        let fa = self.axial_force(load);
        let mf = self.friction_torque(self.coefficient(self.tau(theta_dot, fa)), fa);
        if theta_dot >= 0.0 {
            self.load_torque(load.abs()) + mf
        } else {
            self.load_torque(load.abs()) - mf
        }
    }
}

impl BallScrewFriction {
    /// The ball screw as a thread for the plant's lead-screw mechanics: the law in the screw
    /// rate whose thread friction torque μ·W·r_m equals M_f at axial force `f_axial`,
    /// `μ_eq(θ̇) = (arm/r_m)·f(η₀ r_m M sin α cos β·|θ̇|/F)` (twin of the core's
    /// `BallScrewConfig::equivalent_thread_law`; τ's load dependence frozen at `f_axial`).
    pub fn equivalent_law(&self, f_axial: f64) -> FrictionLaw {
        let k = self.arm() / self.r_m;
        let tau_per_rate = self.tau(1.0, f_axial);
        FrictionLaw {
            base: self.law.base * k,
            amp: self.law.amp * k,
            rate: self.law.rate * tau_per_rate,
            slope: self.law.slope * k * tau_per_rate,
            s_max: self.law.s_max / tau_per_rate,
            variable: super::friction::Variable::ScrewRate,
        }
    }

    /// The plant's screw for this ball screw: pitch radius r_m, lead angle atan(l/(2π r_m)),
    /// the inertia of a Ø35 mm × 0.4 m steel shaft (4.6·10⁻⁴ kg·m²); supports, nut mass and
    /// coupling as `base`.
    pub fn plant_screw(&self, base: super::Screw) -> super::Screw {
        super::Screw {
            r_m: self.r_m,
            lambda: self.helix(),
            inertia: 4.6e-4,
            ..base
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equivalent_thread_friction_equals_eq_1() {
        let b = BallScrewFriction::seed_001_4008();
        let fa = 9806.65;
        let law = b.equivalent_law(fa);
        for w in [0.0, 0.5, 2.0, 20.0] {
            let mu = law.mu_of(w);
            let mf = b.friction_torque(b.coefficient(b.tau(w, fa)), fa);
            assert!((mu * fa * b.r_m - mf).abs() < 1e-12 * mf, "{w}");
        }
        // Not self-locking: μ_eq < tan λ at rest.
        assert!(law.mu_of(0.0) < b.helix().tan());
    }

    #[test]
    fn eq2_inverts_eq1() {
        let b = BallScrewFriction::seed_001_4008();
        for (f, fa) in [(0.003, 1000.0), (0.01, 36_600.0), (0.2, 5.0)] {
            let t = b.friction_torque(f, fa);
            assert!((b.coefficient_from_torque(t, fa) - f).abs() < 1e-15);
        }
    }

    #[test]
    fn the_4008_is_not_self_locking_and_about_80_percent_efficient() {
        let b = BallScrewFriction::seed_001_4008();
        // At lift loads and speeds τ is deep in the mixed regime: f ≈ 0.0054.
        let fa = 20_000.0;
        let f = b.coefficient(b.tau(1.0, fa));
        assert!(f > 0.004 && f < 0.006, "{f}");
        let (tl, mf) = (b.load_torque(fa), b.friction_torque(f, fa));
        assert!(mf < tl, "friction must not hold the load");
        let eff = tl / (tl + mf);
        // 2·f·(r_m + r_b cos α)/sin α = 0.065 mm of arm per 1.27 mm of lever: ≈ 80 %.
        assert!(eff > 0.75 && eff < 0.85, "{eff}");
    }
}
