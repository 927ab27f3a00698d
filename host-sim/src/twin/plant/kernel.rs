//! The run loop's hot path: [`ScrewNut`]'s mechanics with every constant trigonometric factor
//! computed once, and the stuck phase's static share solved in closed form.
//!
//! [`ScrewNut`] (and the `physics` module under it) reads like the equations and calls `tan λ`,
//! `sin λ`, `acos` and a root finder on every evaluation; the profile of a paper run showed those
//! calls and the stuck phase's Illinois iteration taking ≈ 80 % of the time. [`Kernel`] computes
//! the same quantities from the same formulas, rearranged only where it avoids a transcendental
//! call: `cos α` straight from Eq 1 (no `acos` except for Table 1's c_x, which is tabulated in
//! degrees), `tan α = sin α/cos α`, and the equal-mobilisation share ρ as the root of a
//! quadratic. The test `kernel_matches_the_reference_mechanics` holds it to [`ScrewNut`] to
//! 10⁻¹⁰ relative over both phases, both flanks and the lift's whole range.
//!
//! Built once per run from the configuration; it does not see later edits of the `ScrewNut`.

use super::screw_nut::{Dir, Flank, Loads, Mechanics, Powers, ScrewNut, StructureDamping};
use crate::twin::physics::friction::Variable;
use crate::twin::physics::geometry::DAMPING_TABLE;
use crate::twin::physics::{Contact, G};

/// [`ScrewNut`] with its constant factors precomputed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kernel {
    /// The plant this kernel was built from.
    pub plant: ScrewNut,
    sin_l: f64,
    cos_l: f64,
    tan_l: f64,
    /// r_m·tan λ, m/rad.
    lead: f64,
    /// Speed variable of the friction law per rad/s of screw rate.
    law_scale: f64,
    /// μ at rest (the breakaway coefficient).
    mu0: f64,
    cos_a0: f64,
    inv_length: f64,
    /// M·g, N.
    weight: f64,
    /// 2·μ_b·M·g, N.
    pin_weight: f64,
    /// Table 1 in radians: (α, c_x, slope to the next row per rad).
    damping_rad: [(f64, f64, f64); 3],
}

impl Kernel {
    /// Precomputes the constants of `plant`.
    pub fn new(plant: ScrewNut) -> Self {
        let s = &plant.screw;
        let (sin_l, cos_l) = s.lambda.sin_cos();
        let law_scale = match plant.law.variable {
            Variable::ScrewRate => 1.0,
            Variable::SlidingSpeed => s.r_m / s.lambda.cos(),
            Variable::Lubrication => 0.0,
        };
        let g = &plant.geometry;
        let t = DAMPING_TABLE;
        let mut damping_rad = [(0.0, 0.0, 0.0); 3];
        for (i, row) in damping_rad.iter_mut().enumerate() {
            let next = t[(i + 1).min(t.len() - 1)];
            let slope = if i + 1 < t.len() {
                (next.1 - t[i].1) / (next.0 - t[i].0).to_radians()
            } else {
                0.0
            };
            *row = (t[i].0.to_radians(), t[i].1, slope);
        }
        Self {
            damping_rad,
            sin_l,
            cos_l,
            tan_l: s.lambda.tan(),
            lead: s.lead_per_rad(),
            law_scale,
            mu0: plant.law.mu_at_rate(0.0, s.r_m, s.lambda),
            cos_a0: g.alpha0.cos(),
            inv_length: 1.0 / g.length,
            weight: plant.load * G,
            pin_weight: 2.0 * g.mu_pin * plant.load * G,
            plant,
        }
    }

    /// Nut travel per screw radian, m/rad.
    pub fn lead(&self) -> f64 {
        self.lead
    }

    /// Loads at screw angle θ (as [`ScrewNut::loads`]).
    #[inline]
    pub fn loads(&self, theta: f64) -> Loads {
        let x = self.lead * theta;
        let c = (self.cos_a0 - x * self.inv_length).clamp(-1.0, 1.0);
        // α ∈ [0, π]: sin α ≥ 0.
        let s = (1.0 - c * c).sqrt();
        let alpha = c.acos();
        let c_x = match self.plant.damping {
            StructureDamping::Table1 => self.table1(alpha),
            StructureDamping::Constant(k) => k,
        };
        Loads {
            x,
            alpha,
            height: self.plant.geometry.h0 + self.plant.geometry.length * s,
            r: self.weight * c / s,
            f0: self.pin_weight / s,
            c_x,
        }
    }

    /// Table 1's c_x(α) (as [`crate::twin::physics::geometry::structure_damping`]: linear between
    /// the rows, flat outside), interpolated in radians.
    #[inline]
    fn table1(&self, alpha: f64) -> f64 {
        let t = &self.damping_rad;
        if alpha <= t[0].0 {
            t[0].1
        } else if alpha <= t[1].0 {
            t[0].1 + t[0].2 * (alpha - t[0].0)
        } else if alpha <= t[2].0 {
            t[1].1 + t[1].2 * (alpha - t[1].0)
        } else {
            t[2].1
        }
    }

    /// μ at screw rate θ̇.
    #[inline]
    fn mu(&self, theta_dot: f64) -> f64 {
        self.plant.law.mu_of(self.law_scale * theta_dot)
    }

    /// The contact for coefficient `mu`, direction `d` (±1) and axial demand `w`
    /// (as [`crate::twin::physics::Screw::contact`]).
    #[inline]
    fn contact(&self, mu: f64, d: f64, w: f64) -> Contact {
        let (s, c, t) = (self.sin_l, self.cos_l, self.tan_l);
        let mu_s = mu * d;
        let (n, xi) = if w >= 0.0 {
            (w / (c - mu_s * s), (t + mu_s) / (1.0 - mu_s * t))
        } else {
            (w / (c + mu_s * s), (t - mu_s) / (1.0 + mu_s * t))
        };
        let r_m = self.plant.screw.r_m;
        Contact {
            mu,
            mu_s,
            xi,
            normal: n,
            friction_torque: mu_s * n.abs() * r_m * c,
            thread_torque: r_m * (n * s + mu_s * n.abs() * c),
        }
    }

    /// ξ of the flank of sign `w_sign` (as `ScrewNut::xi`).
    #[inline]
    fn xi(&self, mu: f64, d: f64, w_pos: bool) -> f64 {
        let (t, mu_s) = (self.tan_l, mu * d);
        if w_pos {
            (t + mu_s) / (1.0 - mu_s * t)
        } else {
            (t - mu_s) / (1.0 + mu_s * t)
        }
    }

    /// θ̈ and W sliding in direction `d` (as `ScrewNut::accel`).
    #[inline]
    fn accel(&self, l: &Loads, theta_dot: f64, t_c: f64, d: f64, mu: f64) -> (f64, f64) {
        let s = &self.plant.screw;
        let lead = self.lead;
        let a = t_c - s.damping * theta_dot - s.support_torque * d;
        let w0 = l.r + l.f0 * d + l.c_x * lead * theta_dot;
        let xi = self.xi(mu, d, s.nut_mass * lead * a + s.inertia * w0 >= 0.0);
        let theta_ddot = (a - s.r_m * xi * w0) / (s.inertia + s.r_m * xi * s.nut_mass * lead);
        let w = s.nut_mass * lead * theta_ddot + w0;
        (theta_ddot, w)
    }

    /// Mechanics while slipping (as [`ScrewNut::slipping`]).
    #[inline]
    pub fn slipping(&self, l: &Loads, theta_dot: f64, t_c: f64, dir: Dir) -> Mechanics {
        let d = dir.sign();
        let mu = self.mu(theta_dot);
        let (theta_ddot, w) = self.accel(l, theta_dot, t_c, d, mu);
        Mechanics {
            theta_ddot,
            w,
            contact: self.contact(mu, d, w),
            flank: if w >= 0.0 {
                Flank::Loaded
            } else {
                Flank::Reversed
            },
            pin_force: l.f0 * d,
            support_torque: self.plant.screw.support_torque * d,
            mobilisation: d,
        }
    }

    /// Dissipated powers while slipping (as [`ScrewNut::powers`]).
    #[inline]
    pub fn powers(&self, l: &Loads, theta_dot: f64, m: &Mechanics) -> Powers {
        let s = &self.plant.screw;
        let xd = self.lead * theta_dot;
        Powers {
            thread: m.contact.mu * m.contact.normal.abs() * (s.r_m * theta_dot / self.cos_l).abs(),
            support: s.support_torque * theta_dot.abs() + s.damping * theta_dot * theta_dot,
            pins: l.f0 * xd.abs(),
            structure: l.c_x * xd * xd,
        }
    }

    /// Breakaway acceleration (as [`ScrewNut::breakaway_accel`]).
    #[inline]
    pub fn breakaway_accel(&self, l: &Loads, t_c: f64, dir: Dir) -> f64 {
        self.accel(l, 0.0, t_c, dir.sign(), self.mu0).0
    }

    /// Breakaway direction (as [`ScrewNut::breakaway`]).
    pub fn breakaway(&self, l: &Loads, t_c: f64) -> Option<Dir> {
        if self.breakaway_accel(l, t_c, Dir::Up) > 0.0 {
            Some(Dir::Up)
        } else if self.breakaway_accel(l, t_c, Dir::Down) < 0.0 {
            Some(Dir::Down)
        } else {
            None
        }
    }

    /// Breakaway margin (as [`ScrewNut::breakaway_margin`]).
    #[inline]
    pub fn breakaway_margin(&self, l: &Loads, t_c: f64) -> f64 {
        let up = self.breakaway_accel(l, t_c, Dir::Up);
        let down = -self.breakaway_accel(l, t_c, Dir::Down);
        up.max(down)
    }

    /// Static torque residual at mobilisation ρ (as `ScrewNut::static_residual`).
    fn static_residual(&self, l: &Loads, t_c: f64, rho: f64) -> f64 {
        let w = l.r + rho * l.f0;
        rho * self.plant.screw.support_torque
            + self.plant.screw.r_m * self.xi(self.mu0, rho, w >= 0.0) * w
            - t_c
    }

    /// The mobilisation ρ ∈ [−1, 1] at which the static torques balance `t_c`.
    ///
    /// On each flank the residual times the (positive) denominator of ξ is a quadratic in ρ:
    /// with `σ = +1` on the loaded flank (W = R + ρF₀ ≥ 0) and `−1` on the other,
    /// `ρT₀(1 − σμ₀tρ) + r_m(t + σμ₀ρ)(R + ρF₀) − T_c(1 − σμ₀tρ) = 0`. The residual rises with
    /// ρ, so the flank is the one on the root's side of W = 0; the root is the quadratic's
    /// root on that interval (the reference solves the same equation by regula falsi to 10⁻¹²).
    fn stuck_share(&self, l: &Loads, t_c: f64) -> f64 {
        let lo = self.static_residual(l, t_c, -1.0);
        let hi = self.static_residual(l, t_c, 1.0);
        if lo >= 0.0 {
            return -1.0;
        }
        if hi <= 0.0 {
            return 1.0;
        }
        let (t0, r_m, mu0, t) = (
            self.plant.screw.support_torque,
            self.plant.screw.r_m,
            self.mu0,
            self.tan_l,
        );
        // W changes sign at ρ_w = −R/F₀; the loaded flank holds for ρ ≥ ρ_w.
        let rho_w = if l.f0 > 0.0 {
            -l.r / l.f0
        } else {
            f64::NEG_INFINITY
        };
        let (sigma, a, b) =
            if rho_w > -1.0 && rho_w < 1.0 && self.static_residual(l, t_c, rho_w) > 0.0 {
                (-1.0, -1.0, rho_w)
            } else {
                (1.0, rho_w.max(-1.0), 1.0)
            };
        let qa = sigma * mu0 * (r_m * l.f0 - t0 * t);
        let qb = t0 + r_m * (t * l.f0 + sigma * mu0 * l.r) + sigma * t_c * mu0 * t;
        let qc = r_m * t * l.r - t_c;
        let disc = qb * qb - 4.0 * qa * qc;
        let mut best = None;
        if disc >= 0.0 {
            // The cancellation-free pair of roots.
            let q = -0.5 * (qb + qb.signum() * disc.sqrt());
            for root in [q / qa, qc / q] {
                if root.is_finite() && root >= a - 1e-12 && root <= b + 1e-12 {
                    best = Some(root.clamp(-1.0, 1.0));
                    break;
                }
            }
        }
        match best {
            Some(r) => r,
            // Not reached for physical parameters; the reference's bracketing as a safety net.
            None => {
                let (x, y) = crate::twin::solver::bracket_root(
                    &mut |r| self.static_residual(l, t_c, r),
                    -1.0,
                    1.0,
                    lo,
                    hi,
                    1e-12,
                    60,
                );
                0.5 * (x + y)
            }
        }
    }

    /// Mechanics while stuck (as [`ScrewNut::stuck`]).
    #[inline]
    pub fn stuck(&self, l: &Loads, t_c: f64) -> Mechanics {
        let rho = self.stuck_share(l, t_c);
        let d = if rho >= 0.0 { 1.0 } else { -1.0 };
        let w = l.r + rho * l.f0;
        let mut contact = self.contact(self.mu0 * rho.abs(), d, w);
        contact.mu = self.mu0 * rho.abs();
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
            support_torque: rho * self.plant.screw.support_torque,
            mobilisation: rho,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::twin::physics::Lubricant;

    fn close(a: f64, b: f64, what: &str) {
        let tol = 1e-10 * a.abs().max(b.abs()).max(1.0);
        assert!((a - b).abs() <= tol, "{what}: {a} vs {b}");
    }

    fn same(k: &Mechanics, r: &Mechanics, what: &str) {
        close(k.theta_ddot, r.theta_ddot, what);
        close(k.w, r.w, what);
        close(k.contact.normal, r.contact.normal, what);
        close(k.contact.friction_torque, r.contact.friction_torque, what);
        close(k.contact.thread_torque, r.contact.thread_torque, what);
        close(k.contact.mu, r.contact.mu, what);
        // ρ: the reference stops its regula falsi at a 10⁻¹² bracket.
        assert!((k.mobilisation - r.mobilisation).abs() < 1e-9, "{what}: ρ");
        assert_eq!(k.flank, r.flank, "{what}");
    }

    #[test]
    fn kernel_matches_the_reference_mechanics() {
        for lube in Lubricant::ALL {
            for mu_pin in [0.0, 0.3] {
                for damping in [StructureDamping::Table1, StructureDamping::Constant(1e6)] {
                    let mut p = ScrewNut::paper(lube.law(), 1000.0);
                    p.geometry.mu_pin = mu_pin;
                    p.damping = damping;
                    let k = Kernel::new(p);
                    for deg in [15.0f64, 22.5, 45.0, 60.0, 65.0, 74.0] {
                        let theta = p.theta_at_alpha(deg.to_radians());
                        let (lk, lr) = (k.loads(theta), p.loads(theta));
                        for (a, b) in [(lk.r, lr.r), (lk.f0, lr.f0), (lk.c_x, lr.c_x)] {
                            close(a, b, "loads");
                        }
                        close(lk.height, lr.height, "height");
                        close(lk.alpha, lr.alpha, "alpha");
                        for t_c in [-90.0, -12.0, -3.0, -0.5, 0.0, 0.7, 5.0, 30.0, 76.0, 120.0] {
                            let what = format!("{lube:?} μ_b {mu_pin} {deg}° T_c {t_c}");
                            close(
                                k.breakaway_margin(&lk, t_c),
                                p.breakaway_margin(&lr, t_c),
                                &what,
                            );
                            assert_eq!(k.breakaway(&lk, t_c), p.breakaway(&lr, t_c), "{what}");
                            same(&k.stuck(&lk, t_c), &p.stuck(&lr, t_c), &what);
                            for (td, dir) in [(15.0, Dir::Up), (-15.0, Dir::Down), (800.0, Dir::Up)]
                            {
                                let (mk, mr) =
                                    (k.slipping(&lk, td, t_c, dir), p.slipping(&lr, td, t_c, dir));
                                same(&mk, &mr, &what);
                                let (pk, pr) = (k.powers(&lk, td, &mk), p.powers(&lr, td, &mr));
                                for (a, b) in [
                                    (pk.thread, pr.thread),
                                    (pk.support, pr.support),
                                    (pk.pins, pr.pins),
                                    (pk.structure, pr.structure),
                                ] {
                                    close(a, b, &what);
                                }
                            }
                        }
                    }
                }
            }
        }
    }
}
