//! The self-adjusting Newton–Raphson load-distribution solve (seed 001, §2.2 and §3.1).
//!
//! Unknowns: the normal contact deformations δ_j of the balls currently taken as loaded
//! (`active`, in ball order s₀ < s₁ < … < s_{n−1}). Equations:
//!
//! - compatibility of each pair of neighbouring loaded balls (Eq 13 with Eqs 11–12, i.e. Eq 17):
//!   `g_k = U(s_k) − U(s_{k+1}) − c·(s_{k+1} − s_k)·(P_h/Z)·F_k = 0`, where
//!   `U(j) = (δ_j − E_g(j))/(sin α_j cos λ)` is the axial approach of nut and screw at ball j,
//!   `c = 1/(E A_n) + 1/(E A_s)` and `F_k = F_a − Σ_{m≤k} Q(s_m) sin α(s_m) cos λ` the force the
//!   nut and screw segments between the two balls carry (Eq 6). Non-loaded balls between two
//!   loaded ones only lengthen the segment: this is the paper's merged equation (its Step 4,
//!   `(m(k)+1)·P_h/Z`), written directly;
//! - axial equilibrium (Eq 18): `g_{n−1} = Σ_m Q(s_m) sin α(s_m) cos λ − F_a = 0`.
//!
//! The Jacobian is lower Hessenberg plus one full row; written as a forward recursion in the
//! first ball's step it solves in O(n) (no matrix is formed). Steps are damped by backtracking
//! on the scaled residual.
//!
//! Self-adjusting (Step 4): after each converged solve, balls with δ_j < 0 are non-loaded and
//! leave the set; a non-loaded ball whose position the new solution presses (the approach there,
//! interpolated along the segment, exceeds its free gap) comes back. The loop ends when the set
//! no longer changes, so the answer satisfies: loaded ⇔ pressed.

use super::{BallScrew, BallState, KTable};
use std::fmt;

/// Why a solve failed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SolveError {
    /// The load must be positive and finite.
    BadLoad,
    /// The error vector does not have one entry per ball.
    BadErrors,
    /// Newton did not reach the tolerance (iterations, scaled residual).
    NoConvergence(usize, f64),
    /// The loaded set kept changing (passes).
    Cycling(usize),
}

impl fmt::Display for SolveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SolveError::BadLoad => write!(f, "axial load must be positive and finite"),
            SolveError::BadErrors => write!(f, "need one geometric error per ball"),
            SolveError::NoConvergence(i, r) => {
                write!(
                    f,
                    "Newton did not converge in {i} iterations (residual {r:e})"
                )
            }
            SolveError::Cycling(p) => write!(f, "loaded set still changing after {p} passes"),
        }
    }
}

impl std::error::Error for SolveError {}

/// The solution for one axial load.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadCase {
    /// Axial load F_a, N.
    pub fa: f64,
    /// Normal contact deformation per ball, m (0 for non-loaded balls).
    pub delta: Vec<f64>,
    /// Normal contact load per ball Q_j, N.
    pub q: Vec<f64>,
    /// Contact angle per ball α_j, rad.
    pub alpha: Vec<f64>,
    /// Number of loaded balls.
    pub loaded: usize,
    /// First loaded ball (0-based): the one nearest the load's entry.
    pub first: usize,
    /// Axial displacement of the nut, Eq 19, m.
    pub axial_displacement: f64,
    /// Newton iterations over all passes.
    pub iterations: usize,
    /// Passes of the self-adjusting loop (1 = the first loaded set was right).
    pub passes: usize,
}

impl LoadCase {
    /// |Σ Q_j sin α_j cos λ − F_a| / F_a.
    pub fn force_balance_error(&self, screw: &BallScrew) -> f64 {
        let cl = screw.helix.cos();
        let sum: f64 = self
            .q
            .iter()
            .zip(&self.alpha)
            .map(|(q, a)| q * a.sin() * cl)
            .sum();
        (sum - self.fa).abs() / self.fa
    }

    /// Q_last / Q_first (seed 001's Q78/Q1).
    pub fn end_ratio(&self) -> f64 {
        self.q.last().copied().unwrap_or(0.0) / self.q.first().copied().unwrap_or(f64::NAN)
    }

    /// Smallest and largest normal load, N.
    pub fn load_range(&self) -> (f64, f64) {
        self.q.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &q| {
            (lo.min(q), hi.max(q))
        })
    }
}

/// Newton tolerance: scaled residual (compatibility / largest approach, equilibrium / F_a).
const TOL: f64 = 1e-12;
const MAX_NEWTON: usize = 100;

/// A ball screw with one set of geometric errors.
#[derive(Clone, Debug)]
pub struct Solver {
    /// The ball screw.
    pub screw: BallScrew,
    /// Equivalent geometric error E_g(j) per ball, m.
    pub errors: Vec<f64>,
    table: KTable,
}

impl Solver {
    /// A solver for `screw` with `errors` (one per ball, m).
    pub fn new(screw: BallScrew, errors: Vec<f64>) -> Result<Self, SolveError> {
        if errors.len() != screw.balls || errors.iter().any(|e| !e.is_finite()) {
            return Err(SolveError::BadErrors);
        }
        let table = KTable::new(&screw);
        Ok(Self {
            screw,
            errors,
            table,
        })
    }

    /// Solve for axial load `fa` (N), from scratch or warm-started from a neighbouring load's
    /// solution (a sweep passes the previous case).
    pub fn solve(&self, fa: f64, warm: Option<&LoadCase>) -> Result<LoadCase, SolveError> {
        if !(fa > 0.0 && fa.is_finite()) {
            return Err(SolveError::BadLoad);
        }
        let b = &self.screw;
        let n = b.balls;
        let (sa0, cl) = (b.alpha0.sin(), b.helix.cos());
        let mut delta = vec![0.0; n];
        let mut active = vec![true; n];
        match warm {
            Some(w) if w.delta.len() == n => {
                // Scale the previous deformations to the new load (δ ∝ F^(2/3) on the loaded part).
                let s = (fa / w.fa).powf(2.0 / 3.0);
                for j in 0..n {
                    active[j] = w.delta[j] > 0.0;
                    delta[j] = w.delta[j] * s;
                }
            }
            _ => {
                // Step 2: every ball loaded, the uniform share plus its own error.
                let k0 = b.hertz_k(b.alpha0);
                let q0 = fa / (n as f64 * sa0 * cl);
                let d0 = (q0 / k0).powf(2.0 / 3.0);
                let mean = self.errors.iter().sum::<f64>() / n as f64;
                for (d, e) in delta.iter_mut().zip(&self.errors) {
                    *d = d0 + e - mean;
                }
            }
        }
        let mut iterations = 0;
        let max_passes = 4 * n;
        for pass in 1..=max_passes {
            let mut idx: Vec<usize> = (0..n).filter(|&j| active[j]).collect();
            if idx.is_empty() {
                // The ball with the largest error touches first.
                let j = argmax(&self.errors);
                active[j] = true;
                idx.push(j);
            }
            let mut x: Vec<f64> = idx
                .iter()
                .map(|&j| if delta[j] > 0.0 { delta[j] } else { 1e-9 })
                .collect();
            iterations += self.newton(fa, &idx, &mut x)?;
            delta.fill(0.0);
            for (&j, &d) in idx.iter().zip(&x) {
                delta[j] = d;
            }
            // Step 4: drop the balls the solution puts in tension.
            let mut changed = false;
            for (&j, &d) in idx.iter().zip(&x) {
                if d < 0.0 {
                    active[j] = false;
                    delta[j] = 0.0;
                    changed = true;
                }
            }
            if changed {
                continue;
            }
            // …and bring back the non-loaded balls the solution presses.
            for (j, gap) in self.gaps(fa, &idx, &x) {
                let d = gap * sa0 * cl;
                if d > 1e-13 {
                    active[j] = true;
                    delta[j] = d;
                    changed = true;
                }
            }
            if changed {
                continue;
            }
            return Ok(self.finish(fa, delta, iterations, pass));
        }
        Err(SolveError::Cycling(max_passes))
    }

    /// Ball `j` at deformation `d` (K from the table).
    pub fn ball(&self, j: usize, d: f64) -> BallState {
        self.screw
            .ball_with(self.errors[j], d, |a| self.table.at(a))
    }

    fn states(&self, idx: &[usize], x: &[f64]) -> Vec<BallState> {
        idx.iter().zip(x).map(|(&j, &d)| self.ball(j, d)).collect()
    }

    /// Residuals (compatibility rows, then equilibrium) and the approach scale.
    fn residuals(&self, fa: f64, idx: &[usize], st: &[BallState], g: &mut [f64]) -> f64 {
        let c = self.screw.segment_compliance() * self.screw.ball_spacing();
        let mut f = fa;
        let n = idx.len();
        let mut uref: f64 = 0.0;
        for k in 0..n {
            f -= st[k].p;
            uref = uref.max(st[k].u.abs());
            if k + 1 < n {
                let gap = (idx[k + 1] - idx[k]) as f64;
                g[k] = st[k].u - st[k + 1].u - c * gap * f;
            }
        }
        g[n - 1] = -f; // Σ P − F_a
        uref.max(1e-12)
    }

    fn merit(g: &[f64], fa: f64, uref: f64) -> f64 {
        let n = g.len();
        let mut m = (g[n - 1] / fa).abs();
        for v in &g[..n - 1] {
            m = m.max((v / uref).abs());
        }
        m
    }

    /// Newton on the loaded set `idx`; returns the iterations used.
    fn newton(&self, fa: f64, idx: &[usize], x: &mut [f64]) -> Result<usize, SolveError> {
        let n = idx.len();
        let c = self.screw.segment_compliance() * self.screw.ball_spacing();
        let mut g = vec![0.0; n];
        let mut st = self.states(idx, x);
        let uref = self.residuals(fa, idx, &st, &mut g);
        let mut m = Self::merit(&g, fa, uref);
        let (mut a, mut bb) = (vec![0.0; n], vec![0.0; n]);
        let mut trial = vec![0.0; n];
        let mut gt = vec![0.0; n];
        for it in 0..MAX_NEWTON {
            if m <= TOL {
                return Ok(it);
            }
            // Solve J·dx = −g by forward recursion in dx₀ = z: dx_k = a_k + b_k·z.
            // Row k: U'_k dx_k − U'_{k+1} dx_{k+1} + c·gap_k·S_k = −g_k, S_k = Σ_{m≤k} P'_m dx_m.
            a[0] = 0.0;
            bb[0] = 1.0;
            let (mut sa, mut sb) = (0.0, 0.0);
            for k in 0..n {
                sa += st[k].dp * a[k];
                sb += st[k].dp * bb[k];
                if k + 1 < n {
                    let gap = (idx[k + 1] - idx[k]) as f64;
                    let du1 = st[k + 1].du;
                    a[k + 1] = (g[k] + st[k].du * a[k] + c * gap * sa) / du1;
                    bb[k + 1] = (st[k].du * bb[k] + c * gap * sb) / du1;
                }
            }
            // Last row: Σ P'_m dx_m = −g_{n−1}.
            let z = if sb.abs() > 0.0 {
                (-g[n - 1] - sa) / sb
            } else {
                // Every ball at δ = 0: move them all by the uniform guess.
                1e-9
            };
            // Backtracking on the scaled residual.
            let mut t = 1.0;
            loop {
                for k in 0..n {
                    trial[k] = x[k] + t * (a[k] + bb[k] * z);
                }
                let st_t = self.states(idx, &trial);
                let u_t = self.residuals(fa, idx, &st_t, &mut gt);
                let m_t = Self::merit(&gt, fa, u_t);
                if m_t < m * (1.0 - 1e-4 * t) || t < 1e-6 {
                    x.copy_from_slice(&trial);
                    st = st_t;
                    g.copy_from_slice(&gt);
                    m = m_t;
                    break;
                }
                t *= 0.5;
            }
        }
        if m <= TOL * 100.0 {
            // Rounding floor of the Hertz/elliptic evaluations: accept (still ≪ 1e-9).
            return Ok(MAX_NEWTON);
        }
        Err(SolveError::NoConvergence(MAX_NEWTON, m))
    }

    /// For every non-loaded ball: how far the solution's approach at its position exceeds its
    /// free gap (m, axial; > 0 means the ball is pressed and must be loaded).
    fn gaps(&self, fa: f64, idx: &[usize], x: &[f64]) -> Vec<(usize, f64)> {
        let b = &self.screw;
        let c = b.segment_compliance() * b.ball_spacing();
        let (sa0, cl) = (b.alpha0.sin(), b.helix.cos());
        let st = self.states(idx, x);
        // Approach and segment force after each loaded ball.
        let mut out = Vec::new();
        let mut f_after = Vec::with_capacity(idx.len());
        let mut f = fa;
        for s in &st {
            f -= s.p;
            f_after.push(f);
        }
        let mut k = 0; // the last loaded ball at or before j
        for j in 0..b.balls {
            while k + 1 < idx.len() && idx[k + 1] <= j {
                k += 1;
            }
            if idx[k] == j {
                continue;
            }
            let u = if j < idx[0] {
                // Ahead of the first loaded ball the segments carry all of F_a.
                st[0].u + c * (idx[0] - j) as f64 * fa
            } else {
                st[k].u - c * (j - idx[k]) as f64 * f_after[k]
            };
            let free = -self.errors[j] / (sa0 * cl);
            out.push((j, u - free));
        }
        out
    }

    fn finish(&self, fa: f64, delta: Vec<f64>, iterations: usize, passes: usize) -> LoadCase {
        let b = &self.screw;
        let (mut q, mut alpha) = (vec![0.0; b.balls], vec![b.alpha0; b.balls]);
        for j in 0..b.balls {
            if delta[j] > 0.0 {
                let s = self.ball(j, delta[j]);
                q[j] = s.q;
                alpha[j] = s.alpha;
            } else {
                alpha[j] = self.ball(j, 0.0).alpha;
            }
        }
        let loaded = delta.iter().filter(|&&d| d > 0.0).count();
        let first = delta.iter().position(|&d| d > 0.0).unwrap_or(0);
        // Eq 19: the first loaded ball's deformation along the axis, plus its clearance to the
        // largest ball (the one that touched first at F_a = 0).
        let cl = b.helix.cos();
        let emax = self
            .errors
            .iter()
            .cloned()
            .fold(f64::NEG_INFINITY, f64::max);
        let axial_displacement = delta[first] / (alpha[first].sin() * cl)
            + (emax - self.errors[first]) / (b.alpha0.sin() * cl);
        LoadCase {
            fa,
            delta,
            q,
            alpha,
            loaded,
            first,
            axial_displacement,
            iterations,
            passes,
        }
    }
}

fn argmax(v: &[f64]) -> usize {
    let mut best = 0;
    for (i, x) in v.iter().enumerate() {
        if *x > v[best] {
            best = i;
        }
    }
    best
}
