//! The screw-nut contact (seed 000, Eqs 7–10) in one equation for lifting and lowering.
//!
//! With `W` the axial force the thread must deliver to the nut
//! (`W = m·ẍ + R + F₀·sgn θ̇ + c_x·ẋ`, `ẋ = r_m·tan λ·θ̇`) and μ_s = μ·sgn θ̇:
//! - loaded flank (W ≥ 0): `N = W/(cos λ − μ_s sin λ)`, thread torque `r_m·W·ξ`,
//!   `ξ = (tan λ + μ_s)/(1 − μ_s tan λ)`;
//! - the other flank carries it when the net axial force reverses (W < 0, e.g. lowering near
//!   65° with pin friction): `N = W/(cos λ + μ_s sin λ)` (negative), `ξ = (tan λ − μ_s)/(1 + μ_s tan λ)`.
//!
//! In both, friction acts on |N|: thread torque `r_m·(N sin λ + μ_s·|N|·cos λ)`, friction
//! torque about the screw axis `T_r = μ_s·|N|·r_m·cos λ` (the strict moment arm; Eq 10 prints
//! `r_m`, 0.18 % more) and friction power `μ·|N|·|v_s|`.

/// Lead-screw and drive-train parameters (SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Screw {
    /// Pitch radius r_m, m (S12x2: 4.265 mm).
    pub r_m: f64,
    /// Lead angle λ, rad (S12x2: 3.47°).
    pub lambda: f64,
    /// Screw inertia I, kg·m² (3·10⁻⁶).
    pub inertia: f64,
    /// Screw support damping c, N·m·s/rad (4·10⁻⁴).
    pub damping: f64,
    /// Support friction torque T₀, N·m (0.01).
    pub support_torque: f64,
    /// Translating mass m, kg (≈ 1).
    pub nut_mass: f64,
    /// Coupling stiffness k, N·m/rad (160).
    pub coupling: f64,
}

impl Screw {
    /// The S12x2 screw of seed 000.
    pub fn paper() -> Self {
        Self {
            r_m: 4.265e-3,
            lambda: 3.47f64.to_radians(),
            inertia: 3e-6,
            damping: 4e-4,
            support_torque: 0.01,
            nut_mass: 1.0,
            coupling: 160.0,
        }
    }

    /// Nut travel per screw radian, m/rad: x = r_m·tan λ·θ.
    pub fn lead_per_rad(&self) -> f64 {
        self.r_m * self.lambda.tan()
    }

    /// Sliding speed along the thread, m/s (Eq 12).
    pub fn sliding_speed(&self, theta_dot: f64) -> f64 {
        self.r_m * theta_dot / self.lambda.cos()
    }

    /// Self-locking margin μ − tan λ: the screw holds its load when stopped while it is > 0.
    pub fn self_locking_margin(&self, mu: f64) -> f64 {
        mu - self.lambda.tan()
    }

    /// Drive efficiency when lifting, tan λ / tan(λ + φ), tan φ = μ.
    pub fn efficiency_lifting(&self, mu: f64) -> f64 {
        let t = self.lambda.tan();
        t * (1.0 - mu * t) / (t + mu)
    }

    /// Back-drive efficiency, tan(λ − φ)/tan λ: negative when self-locking.
    pub fn efficiency_backdrive(&self, mu: f64) -> f64 {
        let t = self.lambda.tan();
        (t - mu) / (1.0 + mu * t) / t
    }

    /// The contact state for friction coefficient magnitude `mu`, motion direction `dir`
    /// (sgn θ̇: −1, 0 or +1) and axial demand `w` (N).
    pub fn contact(&self, mu: f64, dir: f64, w: f64) -> Contact {
        let (s, c) = self.lambda.sin_cos();
        let t = self.lambda.tan();
        let mu_s = mu * dir;
        let (n, xi) = if w >= 0.0 {
            (w / (c - mu_s * s), (t + mu_s) / (1.0 - mu_s * t))
        } else {
            (w / (c + mu_s * s), (t - mu_s) / (1.0 + mu_s * t))
        };
        Contact {
            mu,
            mu_s,
            xi,
            normal: n,
            friction_torque: mu_s * n.abs() * self.r_m * c,
            thread_torque: self.r_m * (n * s + mu_s * n.abs() * c),
        }
    }

    /// Axial demand W = m·ẍ + R + F₀·sgn θ̇ + c_x·ẋ, N.
    pub fn axial_demand(
        &self,
        theta_dot: f64,
        theta_ddot: f64,
        dir: f64,
        r: f64,
        f0: f64,
        c_x: f64,
    ) -> f64 {
        let lead = self.lead_per_rad();
        self.nut_mass * lead * theta_ddot + r + f0 * dir + c_x * lead * theta_dot
    }

    /// Torque the coupling must deliver to the screw, N·m: I·θ̈ + c·θ̇ + T₀·sgn θ̇ + thread torque.
    pub fn required_torque(
        &self,
        theta_dot: f64,
        theta_ddot: f64,
        dir: f64,
        contact: &Contact,
    ) -> f64 {
        self.inertia * theta_ddot
            + self.damping * theta_dot
            + self.support_torque * dir
            + contact.thread_torque
    }
}

/// The screw-nut contact at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    /// Friction coefficient magnitude μ.
    pub mu: f64,
    /// Signed friction coefficient μ_s = μ·sgn θ̇ (Eq 7).
    pub mu_s: f64,
    /// ξ of the loaded flank.
    pub xi: f64,
    /// Thread normal force N, N (negative: the other flank carries the load).
    pub normal: f64,
    /// Friction torque about the screw axis T_r = μ_s·|N|·r_m·cos λ, N·m.
    pub friction_torque: f64,
    /// Torque of the thread contact on the screw, N·m.
    pub thread_torque: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_speed_reduces_to_power_screw_formulas() {
        let s = Screw::paper();
        let (r, mu) = (20_000.0, 0.2f64);
        let phi = mu.atan();
        let lift = s.contact(mu, 1.0, r);
        assert!((lift.thread_torque - s.r_m * r * (s.lambda + phi).tan()).abs() < 1e-9);
        let lower = s.contact(mu, -1.0, r);
        assert!((-lower.thread_torque - s.r_m * r * (phi - s.lambda).tan()).abs() < 1e-9);
    }

    #[test]
    fn thread_torque_is_ramp_work_plus_friction_work() {
        // Power balance: T·θ̇ = W·ẋ + μ|N|·|v_s| for both flanks and directions.
        let s = Screw::paper();
        for (dir, w) in [(1.0, 5e3), (-1.0, 5e3), (1.0, -3e3), (-1.0, -3e3)] {
            let c = s.contact(0.15, dir, w);
            let theta_dot = 10.0 * dir;
            let p_in = c.thread_torque * theta_dot;
            let p_out = w * s.lead_per_rad() * theta_dot
                + c.mu * c.normal.abs() * s.sliding_speed(theta_dot).abs();
            assert!(
                (p_in - p_out).abs() < 1e-9 * p_in.abs().max(1.0),
                "{dir} {w}: {p_in} {p_out}"
            );
        }
    }
}
