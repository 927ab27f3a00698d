//! The screw-nut dynamics of DESIGN.md in one equation for lifting and lowering, with a real
//! stick/slip treatment of the sign discontinuities.
//!
//! Slipping in direction `d = sgn θ̇ ≠ 0` (μ_s = μ(|θ̇|)·d), with `T_c = k(θ_i − θ)` the coupling
//! torque, `A = T_c − c·θ̇ − T₀·d` and `W₀ = R + F₀·d + c_x·ẋ`:
//!
//! `I·θ̈ = A − r_m·ξ·W`, `W = m·ẍ + W₀ = m·r_m·tanλ·θ̈ + W₀`
//! ⇒ `(I + r_m²·tanλ·ξ·m)·θ̈ = A − r_m·ξ·W₀` (solved exactly; ξ of the carrying flank).
//!
//! Which flank carries `W` looks implicit (ξ depends on the sign of W, W on θ̈), but substituting
//! θ̈ gives `W = (m·lead·A + I·W₀)/(I + r_m·ξ·m·lead)` whose denominator is positive for any
//! sane μ (I = 3·10⁻⁶ ≫ r_m·m·lead·|ξ| ≈ 3·10⁻⁷), so the flank is `sgn(m·lead·A + I·W₀)` — exact,
//! no iteration. θ̈ is continuous across the flank switch (both give θ̈ = −W₀/(m·lead) at W = 0).
//!
//! Stuck (θ̇ = 0, θ̈ = 0): the thread, the pins and the supports hold with static friction. The
//! screw breaks away in direction d when the slip equation evaluated at θ̇ = 0 with the breakaway
//! coefficient μ(0) and full pin and support friction accelerates it in direction d
//! ([`ScrewNut::breakaway_accel`]); otherwise it stays stuck. While stuck the static forces are
//! statically indeterminate (thread, pins and supports share them); we record them by the rule
//! that all three are mobilised to the same fraction ρ ∈ [−1, 1] of their breakaway capacity
//! (ρ > 0: they resist lifting), which is continuous with both breakaway points.

use crate::twin::physics::{
    friction::FrictionLaw, geometry::structure_damping, Contact, Geometry, Screw, G,
};

/// How the structure damping c_x is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StructureDamping {
    /// c_x(α) from Table 1 / Eq 4 ([`structure_damping`]): the default.
    Table1,
    /// A constant c_x in kg/s (the paper's text value is 10⁶).
    Constant(f64),
}

/// The lift's mechanics downstream of the coupling: geometry, screw, friction law, load.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScrewNut {
    /// Scissor geometry and pin friction μ_b.
    pub geometry: Geometry,
    /// Screw, nut mass, supports and coupling stiffness.
    pub screw: Screw,
    /// Thread friction law μ(θ̇).
    pub law: FrictionLaw,
    /// Lifted mass M, kg.
    pub load: f64,
    /// Structure damping c_x.
    pub damping: StructureDamping,
}

/// Direction of slip.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Dir {
    /// θ̇ > 0.
    Up,
    /// θ̇ < 0.
    Down,
}

impl Dir {
    /// +1 or −1.
    pub fn sign(self) -> f64 {
        match self {
            Dir::Up => 1.0,
            Dir::Down => -1.0,
        }
    }
    /// The other direction.
    pub fn reverse(self) -> Dir {
        match self {
            Dir::Up => Dir::Down,
            Dir::Down => Dir::Up,
        }
    }
}

/// Stick/slip phase of the thread contact.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Phase {
    /// θ̇ = 0, held by static friction.
    Stick,
    /// Sliding in the given direction.
    Slip(Dir),
}

impl Phase {
    /// Short label for traces: `stick`, `slip+`, `slip-`.
    pub fn label(self) -> &'static str {
        match self {
            Phase::Stick => "stick",
            Phase::Slip(Dir::Up) => "slip+",
            Phase::Slip(Dir::Down) => "slip-",
        }
    }
}

/// Which thread flank carries the axial force.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Flank {
    /// The flank facing the load (W ≥ 0): the normal case.
    Loaded,
    /// The other flank (W < 0): pins and damping hold back more than the load pushes.
    Reversed,
}

/// Position-dependent loads at screw angle θ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Loads {
    /// Nut travel x, m.
    pub x: f64,
    /// Arm angle α, rad.
    pub alpha: f64,
    /// Head height, m.
    pub height: f64,
    /// Axial load R, N (Eq 1).
    pub r: f64,
    /// Pin friction F₀, N (Eq 6).
    pub f0: f64,
    /// Structure damping c_x, kg/s.
    pub c_x: f64,
}

/// The screw's mechanics at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mechanics {
    /// θ̈, rad/s².
    pub theta_ddot: f64,
    /// Axial force the thread delivers to the nut W, N.
    pub w: f64,
    /// Thread contact (μ, μ_s, N, T_r, thread torque). While stuck: the static share.
    pub contact: Contact,
    /// Carrying flank.
    pub flank: Flank,
    /// Pin friction force acting, N (signed: + resists lifting).
    pub pin_force: f64,
    /// Support friction torque acting, N·m (signed: + resists lifting).
    pub support_torque: f64,
    /// Static mobilisation ρ ∈ [−1, 1] while stuck; ±1 while slipping.
    pub mobilisation: f64,
}

/// Power flows at one instant, W (all ≥ 0 except the load's).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Powers {
    /// Thread friction μ·|N|·|v_s|.
    pub thread: f64,
    /// Support friction T₀·|θ̇| plus support damping c·θ̇².
    pub support: f64,
    /// Pin friction F₀·|ẋ|.
    pub pins: f64,
    /// Structure damping c_x·ẋ².
    pub structure: f64,
}

impl ScrewNut {
    /// Seed 000's lift with load `mass` (kg), lubricant law and Table 1 damping.
    pub fn paper(law: FrictionLaw, mass: f64) -> Self {
        Self {
            geometry: Geometry::paper(),
            screw: Screw::paper(),
            law,
            load: mass,
            damping: StructureDamping::Table1,
        }
    }

    /// Screw angle at which the arms stand at α, rad.
    pub fn theta_at_alpha(&self, alpha: f64) -> f64 {
        self.geometry.travel(alpha) / self.screw.lead_per_rad()
    }

    /// Loads at screw angle θ.
    pub fn loads(&self, theta: f64) -> Loads {
        let x = self.screw.lead_per_rad() * theta;
        let alpha = self.geometry.alpha(x);
        let c_x = match self.damping {
            StructureDamping::Table1 => structure_damping(alpha),
            StructureDamping::Constant(c) => c,
        };
        Loads {
            x,
            alpha,
            height: self.geometry.height(alpha),
            r: self.geometry.axial_load(self.load, alpha),
            f0: self.geometry.pin_friction(self.load, alpha),
            c_x,
        }
    }

    /// ξ of the flank carrying a force of sign `w_sign`, for coefficient `mu` and direction `d`.
    fn xi(&self, mu: f64, d: f64, w_sign: f64) -> f64 {
        self.screw.contact(mu, d, w_sign).xi
    }

    /// θ̈ and the axial force for sliding in direction `d` (±1) with coefficient `mu`, at
    /// screw rate `theta_dot`, coupling torque `t_c`, and static-share fraction `rho` applied to
    /// pins and supports (1 when sliding: full Coulomb friction).
    fn accel(&self, l: &Loads, theta_dot: f64, t_c: f64, d: f64, mu: f64) -> (f64, f64, f64) {
        let s = &self.screw;
        let lead = s.lead_per_rad();
        let a = t_c - s.damping * theta_dot - s.support_torque * d;
        let w0 = l.r + l.f0 * d + l.c_x * lead * theta_dot;
        let w_sign = if s.nut_mass * lead * a + s.inertia * w0 >= 0.0 {
            1.0
        } else {
            -1.0
        };
        let xi = self.xi(mu, d, w_sign);
        let theta_ddot = (a - s.r_m * xi * w0) / (s.inertia + s.r_m * xi * s.nut_mass * lead);
        let w = s.axial_demand(theta_dot, theta_ddot, d, l.r, l.f0, l.c_x);
        (theta_ddot, w, xi)
    }

    /// Mechanics while slipping in direction `dir` at rate `theta_dot` under coupling torque
    /// `t_c` (the rate's sign is not looked at: the phase decides the direction, so the
    /// right-hand side stays smooth inside an integration step).
    pub fn slipping(&self, l: &Loads, theta_dot: f64, t_c: f64, dir: Dir) -> Mechanics {
        let d = dir.sign();
        let mu = self
            .law
            .mu_at_rate(theta_dot, self.screw.r_m, self.screw.lambda);
        let (theta_ddot, w, _) = self.accel(l, theta_dot, t_c, d, mu);
        let contact = self.screw.contact(mu, d, w);
        Mechanics {
            theta_ddot,
            w,
            contact,
            flank: if w >= 0.0 {
                Flank::Loaded
            } else {
                Flank::Reversed
            },
            pin_force: l.f0 * d,
            support_torque: self.screw.support_torque * d,
            mobilisation: d,
        }
    }

    /// The acceleration the screw would get on breaking away in `dir` from rest under coupling
    /// torque `t_c` (μ = μ(0), full pin and support friction). It breaks away iff this has the
    /// sign of `dir`.
    pub fn breakaway_accel(&self, l: &Loads, t_c: f64, dir: Dir) -> f64 {
        let mu0 = self.law.mu_at_rate(0.0, self.screw.r_m, self.screw.lambda);
        self.accel(l, 0.0, t_c, dir.sign(), mu0).0
    }

    /// The direction the stuck screw breaks away in under coupling torque `t_c`, if any.
    pub fn breakaway(&self, l: &Loads, t_c: f64) -> Option<Dir> {
        if self.breakaway_accel(l, t_c, Dir::Up) > 0.0 {
            Some(Dir::Up)
        } else if self.breakaway_accel(l, t_c, Dir::Down) < 0.0 {
            Some(Dir::Down)
        } else {
            None
        }
    }

    /// Signed breakaway margin: > 0 when the stuck screw breaks away (in either direction).
    /// Continuous in `t_c`, so an event locator can find where it crosses 0.
    pub fn breakaway_margin(&self, l: &Loads, t_c: f64) -> f64 {
        let up = self.breakaway_accel(l, t_c, Dir::Up);
        let down = -self.breakaway_accel(l, t_c, Dir::Down);
        up.max(down)
    }

    /// Static torque balance residual at mobilisation ρ (support + thread torque − T_c), with
    /// μ_s = ρ·μ₀ and W = R + ρ·F₀: the thread torque is r_m·ξ·W with ξ of the carrying flank,
    /// written out so the stuck phase's right-hand side stays cheap.
    fn static_residual(&self, l: &Loads, t_c: f64, mu0: f64, tan_l: f64, rho: f64) -> f64 {
        let mu_s = mu0 * rho;
        let w = l.r + rho * l.f0;
        let xi = if w >= 0.0 {
            (tan_l + mu_s) / (1.0 - mu_s * tan_l)
        } else {
            (tan_l - mu_s) / (1.0 + mu_s * tan_l)
        };
        rho * self.screw.support_torque + self.screw.r_m * xi * w - t_c
    }

    /// Mechanics while stuck under coupling torque `t_c` (θ̇ = θ̈ = 0), with the static forces
    /// shared by the equal-mobilisation rule (module docs). Valid only when
    /// [`ScrewNut::breakaway`] is `None`; ρ is clamped to [−1, 1] otherwise.
    pub fn stuck(&self, l: &Loads, t_c: f64) -> Mechanics {
        let mu0 = self.law.mu_at_rate(0.0, self.screw.r_m, self.screw.lambda);
        let tan_l = self.screw.lambda.tan();
        let lo = self.static_residual(l, t_c, mu0, tan_l, -1.0);
        let hi = self.static_residual(l, t_c, mu0, tan_l, 1.0);
        let rho = if lo >= 0.0 {
            -1.0
        } else if hi <= 0.0 {
            1.0
        } else {
            let (a, b) = crate::twin::solver::bracket_root(
                &mut |r| self.static_residual(l, t_c, mu0, tan_l, r),
                -1.0,
                1.0,
                lo,
                hi,
                1e-12,
                60,
            );
            0.5 * (a + b)
        };
        let d = if rho >= 0.0 { 1.0 } else { -1.0 };
        let w = l.r + rho * l.f0;
        let mut contact = self.screw.contact(mu0 * rho.abs(), d, w);
        // `contact` reports μ as the coefficient in use; keep the magnitude mobilised.
        contact.mu = mu0 * rho.abs();
        Mechanics {
            theta_ddot: 0.0,
            w,
            contact,
            flank: if w >= 0.0 {
                Flank::Loaded
            } else {
                Flank::Reversed
            },
            pin_force: rho * l.f0,
            support_torque: rho * self.screw.support_torque,
            mobilisation: rho,
        }
    }

    /// Dissipated powers while slipping at rate `theta_dot`.
    pub fn powers(&self, l: &Loads, theta_dot: f64, m: &Mechanics) -> Powers {
        let s = &self.screw;
        let xd = s.lead_per_rad() * theta_dot;
        Powers {
            thread: m.contact.mu * m.contact.normal.abs() * s.sliding_speed(theta_dot).abs(),
            support: s.support_torque * theta_dot.abs() + s.damping * theta_dot * theta_dot,
            pins: l.f0 * xd.abs(),
            structure: l.c_x * xd * xd,
        }
    }

    /// Potential energy of the load at screw angle θ relative to θ = 0, J. The screw lies on the
    /// rhombus' horizontal diagonal, so the nut moves horizontally: its own potential energy
    /// does not change and only the load's counts.
    pub fn potential_energy(&self, theta: f64) -> f64 {
        self.load * G * (self.loads(theta).height - self.loads(0.0).height)
    }

    /// Kinetic energy of screw and nut at rate θ̇, J.
    pub fn kinetic_energy(&self, theta_dot: f64) -> f64 {
        let xd = self.screw.lead_per_rad() * theta_dot;
        0.5 * self.screw.inertia * theta_dot * theta_dot + 0.5 * self.screw.nut_mass * xd * xd
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lift() -> ScrewNut {
        ScrewNut::paper(FrictionLaw::dry(), 1000.0)
    }

    #[test]
    fn slip_acceleration_satisfies_both_equations_of_motion() {
        let p = lift();
        let l = p.loads(p.theta_at_alpha(20f64.to_radians()));
        for (td, tc, dir) in [
            (15.0, 80.0, Dir::Up),
            (15.0, 60.0, Dir::Up),
            (-15.0, -10.0, Dir::Down),
            (-3.0, 20.0, Dir::Down),
        ] {
            let m = p.slipping(&l, td, tc, dir);
            let lhs = p.screw.inertia * m.theta_ddot;
            let rhs = tc
                - p.screw.damping * td
                - p.screw.support_torque * dir.sign()
                - m.contact.thread_torque;
            assert!(
                (lhs - rhs).abs() < 1e-9 * tc.abs().max(1.0),
                "{td} {tc}: {lhs} {rhs}"
            );
        }
    }

    #[test]
    fn flank_switches_when_pins_hold_more_than_the_load() {
        // Lowering near 65° with μ_b = 0.3: F₀ > R, the other flank carries the force.
        let p = lift();
        let l = p.loads(p.theta_at_alpha(65f64.to_radians()));
        assert!(l.f0 > l.r);
        let m = p.slipping(&l, -15.0, -2.0, Dir::Down);
        assert_eq!(m.flank, Flank::Reversed);
        assert!(m.contact.normal < 0.0 && m.contact.friction_torque < 0.0);
    }

    #[test]
    fn stuck_share_is_continuous_with_breakaway() {
        let p = lift();
        let l = p.loads(0.0);
        // Find the upward breakaway torque by bisection on the breakaway test.
        let (mut a, mut b) = (0.0, 200.0);
        for _ in 0..80 {
            let m = 0.5 * (a + b);
            if p.breakaway(&l, m) == Some(Dir::Up) {
                b = m
            } else {
                a = m
            }
        }
        let stuck = p.stuck(&l, a);
        assert!(
            (stuck.mobilisation - 1.0).abs() < 1e-6,
            "{}",
            stuck.mobilisation
        );
        let slip = p.slipping(&l, 0.0, b, Dir::Up);
        assert!((stuck.contact.friction_torque - slip.contact.friction_torque).abs() < 1e-6);
        // Self-locking: with the coupling relaxed the screw stays put.
        assert_eq!(p.breakaway(&l, 0.0), None);
    }
}
