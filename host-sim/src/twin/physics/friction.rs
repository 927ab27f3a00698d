//! Friction-coefficient laws of seeds 000 and 002, as one parameterised shape.
//!
//! Every law the papers use is an instance of
//! `μ(s) = base + amp·e^(−rate·s) + slope·min(s, s_max)`, floored at 0,
//! where `s ≥ 0` is the law's own speed variable: the screw rate |θ̇| (Eq 13), the sliding speed
//! |v_s| = r_m·|θ̇|/cos λ (Eqs 11, 12, 14), or the lubrication parameter τ = η₀·V/P (seed 002, Eq 3).

/// The variable a law is written in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Variable {
    /// |θ̇| in rad/s (seed 000, Eq 13).
    ScrewRate,
    /// |v_s| = r_m·|θ̇|/cos λ in m/s (seed 000, Eqs 11, 12, 14).
    SlidingSpeed,
    /// τ = η₀·V/P, dimensionless (seed 002, Eq 3).
    Lubrication,
}

/// A friction law `μ(s) = base + amp·e^(−rate·s) + slope·min(s, s_max)`, μ ≥ 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrictionLaw {
    /// Constant term.
    pub base: f64,
    /// Amplitude of the exponential (Stribeck) term; negative for laws that rise with speed.
    pub amp: f64,
    /// Decay rate of the exponential term, 1/unit of `s`.
    pub rate: f64,
    /// Viscous slope, 1/unit of `s`.
    pub slope: f64,
    /// The viscous term is held flat beyond this value of `s` (`f64::INFINITY`: never).
    pub s_max: f64,
    /// Unit of `s`.
    pub variable: Variable,
}

/// The lubrication cases of seed 000.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Lubricant {
    /// Dry/boundary friction, Eq 13.
    Dry,
    /// PTFE dry spray, Eq 14.
    Ptfe,
    /// Lithium grease, Eq 11 in our reading (see [`FrictionLaw::lithium`]).
    Lithium,
}

impl Lubricant {
    /// All three, in the paper's order.
    pub const ALL: [Lubricant; 3] = [Lubricant::Dry, Lubricant::Ptfe, Lubricant::Lithium];

    /// The preset law.
    pub fn law(self) -> FrictionLaw {
        match self {
            Lubricant::Dry => FrictionLaw::dry(),
            Lubricant::Ptfe => FrictionLaw::ptfe(),
            Lubricant::Lithium => FrictionLaw::lithium(),
        }
    }

    /// Lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Lubricant::Dry => "dry",
            Lubricant::Ptfe => "ptfe",
            Lubricant::Lithium => "lithium",
        }
    }
}

impl FrictionLaw {
    /// Dry/boundary, Eq 13: μ₁ = 0.218, μ₂ = 0.02, r₀ = 0.38 s/rad, μ₃ = −4.47·10⁻⁴ s/rad.
    pub fn dry() -> Self {
        Self {
            base: 0.218,
            amp: 0.02,
            rate: 0.38,
            slope: -4.47e-4,
            s_max: f64::INFINITY,
            variable: Variable::ScrewRate,
        }
    }

    /// PTFE, Eq 14: μ = μ_max − (μ_max − μ_min)·e^(−ϑ·v_s), μ_min = 0.0843, μ_max = 0.1961,
    /// ϑ = 0.02 s/m (v_s in m/s).
    pub fn ptfe() -> Self {
        Self {
            base: 0.1961,
            amp: -(0.1961 - 0.0843),
            rate: 0.02,
            slope: 0.0,
            s_max: f64::INFINITY,
            variable: Variable::SlidingSpeed,
        }
    }

    /// Lithium grease, Eq 11, as we read it (docs/model.md): the Ghezzi data (μ_st = 0.193 at
    /// rest, μ₀ = 0.177 at v₀ = 0.1 mm/s, μ_k = 0.19 at 2 mm/s) in Tustin form with the Stribeck
    /// drop μ̃₂ = μ_st − μ₀ = 0.016 (the printed 0.177 is μ₀ itself), viscous slope
    /// μ̃₃ = (0.19 − 0.177)/(2 − 0.1) mm/s, held flat beyond 2 mm/s where the data end.
    pub fn lithium() -> Self {
        Self {
            base: 0.177,
            amp: 0.193 - 0.177,
            rate: 1.0 / 0.1e-3,
            slope: (0.19 - 0.177) / (2.0 - 0.1) * 1e3,
            s_max: 2e-3,
            variable: Variable::SlidingSpeed,
        }
    }

    /// Lithium grease, Eq 11 exactly as printed (μ̃₁ = 0.193, μ̃₂ = 0.177, no saturation):
    /// kept only to show why we do not use it (μ ≈ 1.5 at 50 rad/s).
    pub fn lithium_as_printed() -> Self {
        Self {
            base: 0.193 - 0.177,
            amp: 0.177,
            rate: 1.0 / 0.1e-3,
            slope: (0.19 - 0.177) / (2.0 - 0.1) * 1e3,
            s_max: f64::INFINITY,
            variable: Variable::SlidingSpeed,
        }
    }

    /// Ball screw, seed 002 Eq 3: f = 0.0026 + 0.9117·τ + 0.0028·e^(−8863·τ).
    pub fn ball_screw() -> Self {
        Self {
            base: 0.0026,
            amp: 0.0028,
            rate: 0.08863e5,
            slope: 0.9117,
            s_max: f64::INFINITY,
            variable: Variable::Lubrication,
        }
    }

    /// μ at the law's own variable `s` (its magnitude is used).
    pub fn mu_of(&self, s: f64) -> f64 {
        let s = s.abs();
        let mu = self.base + self.amp * (-self.rate * s).exp() + self.slope * s.min(self.s_max);
        mu.max(0.0)
    }

    /// μ at screw rate θ̇ (rad/s) for a lead screw of pitch radius `r_m` and lead angle `lambda`.
    /// Laws in τ are not speed laws: use [`FrictionLaw::mu_of`] with τ for them.
    pub fn mu_at_rate(&self, theta_dot: f64, r_m: f64, lambda: f64) -> f64 {
        match self.variable {
            Variable::ScrewRate => self.mu_of(theta_dot),
            Variable::SlidingSpeed => self.mu_of(r_m * theta_dot / lambda.cos()),
            Variable::Lubrication => self.mu_of(0.0),
        }
    }

    /// Where the law has its minimum for s ≥ 0 (the mixed-to-hydrodynamic turning point of
    /// seed 002), from d μ/ds = 0: s* = ln(amp·rate/slope)/rate; 0 when the law has no interior
    /// minimum.
    pub fn turning_point(&self) -> f64 {
        let q = self.amp * self.rate / self.slope;
        if self.slope > 0.0 && q > 1.0 {
            (q.ln() / self.rate).min(self.s_max)
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    const RM: f64 = 4.265e-3;

    fn lambda() -> f64 {
        3.47f64.to_radians()
    }

    #[test]
    fn lithium_reading_reproduces_the_cited_data_points() {
        let l = FrictionLaw::lithium();
        assert!((l.mu_of(0.0) - 0.193).abs() < 1e-12);
        assert!((l.mu_of(2e-3) - 0.19).abs() < 1e-3);
        assert!(
            (l.mu_of(0.1) - l.mu_of(2e-3)).abs() < 1e-9,
            "flat beyond the data"
        );
    }

    #[test]
    fn printed_lithium_law_explodes_at_lift_speeds() {
        let mu = FrictionLaw::lithium_as_printed().mu_at_rate(50.0, RM, lambda());
        assert!(mu > 1.4, "{mu}");
    }

    #[test]
    fn ptfe_is_less_than_half_of_dry_at_lift_speed() {
        for w in [5.0, 15.0, 50.0, 100.0] {
            let d = FrictionLaw::dry().mu_at_rate(w, RM, lambda());
            let p = FrictionLaw::ptfe().mu_at_rate(w, RM, lambda());
            assert!(p < 0.5 * d, "{w}: {p} vs {d}");
        }
    }

    #[test]
    fn dry_law_is_floored_at_zero() {
        assert_eq!(FrictionLaw::dry().mu_of(1000.0), 0.0);
    }

    #[test]
    fn ball_screw_turning_point_is_the_minimum() {
        let l = FrictionLaw::ball_screw();
        let t = l.turning_point();
        // Closed form: τ* = ln(0.0028·8863/0.9117)/8863.
        assert!((t - (0.0028f64 * 8863.0 / 0.9117).ln() / 8863.0).abs() < 1e-15);
        assert!(l.mu_of(t) < l.mu_of(t * 0.9) && l.mu_of(t) < l.mu_of(t * 1.1));
    }
}
