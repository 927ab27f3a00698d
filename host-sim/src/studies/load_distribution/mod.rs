//! Ball-screw load distribution with geometric errors (seed 001, Liu et al., *Lubricants* 2025).
//!
//! A single-nut ball screw under an axial load `F_a`: 78 balls in 3 turns, each with an
//! equivalent geometric error `E_g(j)` (Eq 3), a contact angle that grows with its contact
//! deformation (Eq 10), a Hertz contact computed from the elliptic integrals (Eqs 15–16, see
//! [`hertz`]), and nut/screw segments that compress/stretch between balls (Eqs 11–13). The
//! self-adjusting Newton–Raphson solve of [`newton`] finds the normal contact deformation of every
//! ball, detects the non-loaded ones and drops them from the equation set (and adds a ball back
//! if the new solution would press it). [`study`] sweeps the load and the error bands and writes
//! the reproduction report; `host-sim ballscrew` runs it.
//!
//! Balls are numbered from the end where the load enters the nut (ball 1 carries the most when
//! there are no errors). Length in metres, force in newtons, angles in radians.

pub mod hertz;
pub mod newton;
pub mod plots;
pub mod study;

pub use newton::{LoadCase, SolveError, Solver};

/// How the contact angle behaves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AngleModel {
    /// Seed 001: α_j from the curvature-centre geometry (Eq 10), changing with δ_j and E_g(j).
    Variable,
    /// Mei et al. (seed 001's ref. 11, its Fig. 14 comparison): α_j = α₀ = 45° for every ball.
    Fixed,
}

/// The ball screw's geometry and material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BallScrew {
    /// Nominal radius: the ball-centre circle, m.
    pub r_m: f64,
    /// Ball radius r_b, m.
    pub r_b: f64,
    /// Curvature radius of the screw raceway r_s, m.
    pub r_s: f64,
    /// Curvature radius of the nut raceway r_n, m.
    pub r_n: f64,
    /// Helix angle λ (seed 001 calls it α), rad.
    pub helix: f64,
    /// Lead (helical pitch) P_h, m.
    pub lead: f64,
    /// Initial contact angle α₀, rad.
    pub alpha0: f64,
    /// Number of balls M.
    pub balls: usize,
    /// Balls per turn Z.
    pub per_turn: usize,
    /// Young's modulus of balls, screw and nut, Pa.
    pub young: f64,
    /// Poisson's ratio.
    pub poisson: f64,
    /// Cross-section area of the screw A_s, m².
    pub area_screw: f64,
    /// Cross-section area of the nut A_n, m².
    pub area_nut: f64,
    /// Contact-angle model.
    pub angle: AngleModel,
}

impl BallScrew {
    /// Seed 001's Table 2 (type 4008-3) in our reading (docs/ballscrew-reproduction.md):
    ///
    /// - "Ball radius 4.763 mm" is the ball *diameter* (3/16 in, a standard ball): a 4.763 mm
    ///   radius could not sit in a "raceway radius" of 2.477 mm. So r_b = 2.3815 mm and
    ///   r_s = r_n = 2.477 mm, a conformity of 0.52 (typical: 0.51–0.56).
    /// - 78 balls in "-3" = 3 turns: Z = 26 per turn (26 balls of 4.763 mm fill 123.8 mm of the
    ///   125.9 mm helix turn at r_m = 20 mm).
    /// - Helix angle 3.64° = atan(8 mm / (2π·20 mm)) (consistent), α₀ = 45°.
    /// - GCr15: E = 205 GPa, ν = 0.3 (the text of §3.2.1).
    /// - The cross-section areas are missing. Screw: the root circle under the Gothic-arch
    ///   groove, d_r = 35.18 mm → A_s = 972 mm². Nut: a catalogue 4008 flange-nut body,
    ///   Ø63 mm outside, Ø41 mm bore → A_n = 1797 mm².
    pub fn paper() -> Self {
        let r_m = 20e-3;
        let lead = 8e-3;
        let r_b = 4.763e-3 / 2.0;
        let r_s = 2.477e-3;
        let alpha0 = 45f64.to_radians();
        let mut s = Self {
            r_m,
            r_b,
            r_s,
            r_n: r_s,
            helix: 3.64f64.to_radians(),
            lead,
            alpha0,
            balls: 78,
            per_turn: 26,
            young: 205e9,
            poisson: 0.3,
            area_screw: 0.0,
            area_nut: std::f64::consts::FRAC_PI_4 * (63e-3f64.powi(2) - 41e-3f64.powi(2)),
            angle: AngleModel::Variable,
        };
        s.area_screw = std::f64::consts::FRAC_PI_4 * s.screw_root_diameter().powi(2);
        s
    }

    /// Root diameter of the screw: where the two arcs of the Gothic-arch groove (radius r_s,
    /// centres r_s − r_b from the ball centre along the ±α₀ contact lines) meet.
    pub fn screw_root_diameter(&self) -> f64 {
        let off = self.r_s - self.r_b;
        let (cx, cy) = (off * self.alpha0.sin(), off * self.alpha0.cos());
        let depth = (self.r_s * self.r_s - cx * cx).sqrt() - cy;
        2.0 * (self.r_m - depth)
    }

    /// Free distance between the raceways' curvature centres, A₀ = r_s + r_n − 2·r_b (Eq 7
    /// without error).
    pub fn centre_distance(&self) -> f64 {
        self.r_s + self.r_n - 2.0 * self.r_b
    }

    /// Axial distance between neighbouring balls, P_h/Z (Eq 11).
    pub fn ball_spacing(&self) -> f64 {
        self.lead / self.per_turn as f64
    }

    /// Axial compliance of the nut and screw segments per unit length, 1/(E·A_n) + 1/(E·A_s),
    /// 1/N (Eqs 12–13: nut in compression, screw in tension, both carrying F(k)).
    pub fn segment_compliance(&self) -> f64 {
        1.0 / (self.young * self.area_nut) + 1.0 / (self.young * self.area_screw)
    }

    /// Effective modulus E' = E/(1 − ν²) (ball and raceways of the same steel).
    pub fn e_prime(&self) -> f64 {
        self.young / (1.0 - self.poisson * self.poisson)
    }

    /// Hertz coefficient of one ball (screw and nut contacts in series) at contact angle α,
    /// N/m^1.5 (Eq 14). The raceways' curvatures along the helix depend on α:
    /// screw `cos α·cos λ/(r_m − r_b cos α)` (convex), nut `−cos α·cos λ/(r_m + r_b cos α)`
    /// (concave); across the groove `−1/r_s`, `−1/r_n`; the ball `1/r_b` both ways.
    pub fn hertz_k(&self, alpha: f64) -> f64 {
        let (ca, cl) = (alpha.cos(), self.helix.cos());
        let ball = 1.0 / self.r_b;
        let screw = hertz::contact(
            ball + ca * cl / (self.r_m - self.r_b * ca),
            ball - 1.0 / self.r_s,
            self.e_prime(),
        );
        let nut = hertz::contact(
            ball - ca * cl / (self.r_m + self.r_b * ca),
            ball - 1.0 / self.r_n,
            self.e_prime(),
        );
        hertz::series(screw.k, nut.k)
    }

    /// The state of ball `j` with geometric error `eg` at normal contact deformation `delta`,
    /// with the Hertz coefficient solved afresh (slow; the reference for [`KTable`]).
    pub fn ball(&self, eg: f64, delta: f64) -> BallState {
        self.ball_with(eg, delta, |a| {
            let h = 1e-6;
            (
                self.hertz_k(a),
                (self.hertz_k(a + h) - self.hertz_k(a - h)) / (2.0 * h),
            )
        })
    }

    /// The state of a ball with `k_of(α) = (K, dK/dα)`.
    ///
    /// δ < 0 (the ball would be in tension) is evaluated with the odd extension Q = −K|δ|^1.5 so
    /// that the Newton iteration stays smooth; [`newton`] removes such balls.
    pub fn ball_with(&self, eg: f64, delta: f64, k_of: impl Fn(f64) -> (f64, f64)) -> BallState {
        let cl = self.helix.cos();
        let (alpha, dalpha) = match self.angle {
            AngleModel::Fixed => (self.alpha0, 0.0),
            AngleModel::Variable => {
                // Eq 10: cos α_j = cos α₀·(A₀ − E_g)/(A₀ − E_g + δ_j).
                let a = self.centre_distance() - eg;
                let c = (self.alpha0.cos() * a / (a + delta)).clamp(-1.0, 1.0);
                let alpha = c.acos();
                let s = alpha.sin().max(1e-12);
                (alpha, c / ((a + delta) * s))
            }
        };
        let (sa, ca) = alpha.sin_cos();
        let (k, dk_da) = k_of(alpha);
        let dk = dk_da * dalpha;
        let mag = delta.abs();
        let pow = mag * mag.sqrt();
        let q = k * pow * delta.signum();
        let dq = dk * pow * delta.signum() + 1.5 * k * mag.sqrt();
        // Axial component (Eq 4) and the axial approach at the ball (A(j) − B(j), Eq 13, along
        // the screw axis).
        let p = q * sa * cl;
        let dp = (dq * sa + q * ca * dalpha) * cl;
        let u = (delta - eg) / (sa * cl);
        let du = (1.0 - (delta - eg) * ca * dalpha / sa) / (sa * cl);
        BallState {
            alpha,
            k,
            q,
            p,
            u,
            dp,
            du,
        }
    }
}

/// K(α) of one ball screw tabulated once from the exact elliptic-integral solve
/// ([`BallScrew::hertz_k`]) on a 0.1° grid over 20°…85°, read back with a cubic Hermite
/// interpolant (node slopes from 4th-order differences): within 10⁻¹⁰ relative of the direct
/// solve (test), and ~100× cheaper, which is what makes a 100-load sweep take milliseconds.
/// Outside the grid it solves directly.
#[derive(Clone, Debug)]
pub struct KTable {
    lo: f64,
    step: f64,
    k: Vec<f64>,
    dk: Vec<f64>,
    screw: BallScrew,
}

impl KTable {
    const LO_DEG: f64 = 20.0;
    const HI_DEG: f64 = 85.0;
    const STEP_DEG: f64 = 0.1;

    /// Tabulate K(α) for `screw`.
    pub fn new(screw: &BallScrew) -> Self {
        let lo = Self::LO_DEG.to_radians();
        let step = Self::STEP_DEG.to_radians();
        let n = ((Self::HI_DEG - Self::LO_DEG) / Self::STEP_DEG).round() as usize + 1;
        // Two extra nodes each side for the slopes.
        let raw: Vec<f64> = (0..n + 4)
            .map(|i| screw.hertz_k(lo + (i as f64 - 2.0) * step))
            .collect();
        let k = raw[2..n + 2].to_vec();
        let dk = (2..n + 2)
            .map(|i| {
                (-raw[i + 2] + 8.0 * raw[i + 1] - 8.0 * raw[i - 1] + raw[i - 2]) / (12.0 * step)
            })
            .collect();
        Self {
            lo,
            step,
            k,
            dk,
            screw: *screw,
        }
    }

    /// (K, dK/dα) at α.
    pub fn at(&self, alpha: f64) -> (f64, f64) {
        let x = (alpha - self.lo) / self.step;
        let i = x.floor();
        if !(i >= 0.0 && (i as usize) + 1 < self.k.len()) {
            let h = 1e-6;
            return (
                self.screw.hertz_k(alpha),
                (self.screw.hertz_k(alpha + h) - self.screw.hertz_k(alpha - h)) / (2.0 * h),
            );
        }
        let i = i as usize;
        let t = x - i as f64;
        let (p0, p1) = (self.k[i], self.k[i + 1]);
        let (m0, m1) = (self.dk[i] * self.step, self.dk[i + 1] * self.step);
        let (t2, t3) = (t * t, t * t * t);
        let v = (2.0 * t3 - 3.0 * t2 + 1.0) * p0
            + (t3 - 2.0 * t2 + t) * m0
            + (-2.0 * t3 + 3.0 * t2) * p1
            + (t3 - t2) * m1;
        let d = (6.0 * t2 - 6.0 * t) * p0
            + (3.0 * t2 - 4.0 * t + 1.0) * m0
            + (-6.0 * t2 + 6.0 * t) * p1
            + (3.0 * t2 - 2.0 * t) * m1;
        (v, d / self.step)
    }
}

/// One ball's contact at a given deformation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BallState {
    /// Contact angle α_j, rad.
    pub alpha: f64,
    /// Hertz coefficient K_j, N/m^1.5.
    pub k: f64,
    /// Normal contact load Q_j, N.
    pub q: f64,
    /// Axial component Q_j·sin α_j·cos λ, N.
    pub p: f64,
    /// Axial approach of nut and screw at the ball, (δ_j − E_g(j))/(sin α_j·cos λ), m.
    pub u: f64,
    /// dP/dδ.
    pub dp: f64,
    /// dU/dδ.
    pub du: f64,
}

/// Seeded uniform random equivalent errors in ±`band` (m) for `n` balls: seed 001's
/// `E_g = −b + 2b·rand(1, 78)`. The same seed gives the same unit draw for every band, so the
/// ±1/±2/±3 µm sets are scaled copies of one pattern.
pub fn random_errors(seed: u64, band: f64, n: usize) -> Vec<f64> {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    (0..n)
        .map(|_| band * (2.0 * rng.random::<f64>() - 1.0))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table2_reading_is_self_consistent() {
        let b = BallScrew::paper();
        // Helix angle from lead and radius.
        let lam = (b.lead / (2.0 * std::f64::consts::PI * b.r_m)).atan();
        assert!((lam.to_degrees() - 3.64).abs() < 0.01);
        // 26 balls fit one helix turn.
        let turn = 2.0 * std::f64::consts::PI * b.r_m / b.helix.cos();
        assert!(26.0 * 2.0 * b.r_b < turn);
        assert!(b.centre_distance() > 0.0);
        let d = b.screw_root_diameter();
        assert!(d > 35e-3 && d < 35.5e-3, "{d}");
    }

    #[test]
    fn k_table_matches_the_direct_elliptic_solve() {
        let b = BallScrew::paper();
        let t = KTable::new(&b);
        for i in 0..500 {
            let a = (30.0 + 0.0537 * f64::from(i)).to_radians();
            let (k, _) = t.at(a);
            let want = b.hertz_k(a);
            assert!(
                (k - want).abs() < 1e-10 * want,
                "{}: {k} {want}",
                a.to_degrees()
            );
        }
    }

    #[test]
    fn ball_derivatives_match_finite_differences() {
        let b = BallScrew::paper();
        for (eg, d) in [(0.0, 3e-6), (1.5e-6, 0.4e-6), (-2e-6, 6e-6)] {
            let s = b.ball(eg, d);
            let h = 1e-12;
            let (hi, lo) = (b.ball(eg, d + h), b.ball(eg, d - h));
            let dp = (hi.p - lo.p) / (2.0 * h);
            let du = (hi.u - lo.u) / (2.0 * h);
            assert!((dp - s.dp).abs() < 1e-5 * s.dp.abs(), "{dp} {}", s.dp);
            assert!((du - s.du).abs() < 1e-5 * s.du.abs(), "{du} {}", s.du);
        }
    }
}
