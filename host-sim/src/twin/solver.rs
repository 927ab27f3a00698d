//! Explicit fixed-step Bogacki–Shampine RK23 (the formula behind Simulink's `ode3`, which seed
//! 000 used) and the root finder that locates stick/slip events inside a step.
//!
//! The integrator is generic over the state: anything that can form `y + h·k` is a state.

/// A state vector the integrator can advance: it only needs `self += a·other` and `self *= a`.
pub trait OdeState: Clone {
    /// `self += a·other`.
    fn add_scaled(&mut self, a: f64, other: &Self);
    /// `self *= a`.
    fn scale(&mut self, a: f64);
}

impl<const N: usize> OdeState for [f64; N] {
    #[inline(always)]
    fn add_scaled(&mut self, a: f64, other: &Self) {
        for (y, k) in self.iter_mut().zip(other) {
            *y += a * k;
        }
    }

    #[inline(always)]
    fn scale(&mut self, a: f64) {
        for y in self.iter_mut() {
            *y *= a;
        }
    }
}

/// One explicit Bogacki–Shampine step of size `h` from `(t, y)` for `ẏ = f(t, y)`:
/// third order, three evaluations (the embedded second-order estimate is not needed at a fixed
/// step, so the FSAL fourth stage is skipped).
///
/// ```
/// use host_sim::solver::rk23_step;
/// // ẏ = −y from y = 1: e^(−0.1) to third order.
/// let y = rk23_step(&mut |_t, y: &[f64; 1]| [-y[0]], 0.0, &[1.0], 0.1);
/// assert!((y[0] - (-0.1f64).exp()).abs() < 1e-5);
/// ```
#[inline]
pub fn rk23_step<S: OdeState>(f: &mut impl FnMut(f64, &S) -> S, t: f64, y: &S, h: f64) -> S {
    let k1 = f(t, y);
    rk23_step_from(f, t, y, &k1, h)
}

/// [`rk23_step`] with the first stage `k1 = f(t, y)` already known (two evaluations).
#[inline]
pub fn rk23_step_from<S: OdeState>(
    f: &mut impl FnMut(f64, &S) -> S,
    t: f64,
    y: &S,
    k1: &S,
    h: f64,
) -> S {
    stages(f, t, y, k1, h).2
}

/// The second and third stages and the third-order solution of a step with `k1` known.
#[inline]
fn stages<S: OdeState>(
    f: &mut impl FnMut(f64, &S) -> S,
    t: f64,
    y: &S,
    k1: &S,
    h: f64,
) -> (S, S, S) {
    let mut y2 = y.clone();
    y2.add_scaled(0.5 * h, k1);
    let k2 = f(t + 0.5 * h, &y2);
    let mut y3 = y.clone();
    y3.add_scaled(0.75 * h, &k2);
    let k3 = f(t + 0.75 * h, &y3);
    let mut out = y.clone();
    out.add_scaled(2.0 / 9.0 * h, k1);
    out.add_scaled(1.0 / 3.0 * h, &k2);
    out.add_scaled(4.0 / 9.0 * h, &k3);
    (k2, k3, out)
}

/// One Bogacki–Shampine step with its embedded error estimate, for step-size control.
#[derive(Clone, Debug, PartialEq)]
pub struct EmbeddedStep<S> {
    /// The third-order solution at `t + h` (the same as [`rk23_step`]'s).
    pub y: S,
    /// `f(t + h, y)`: the fourth stage, which is the next step's first (FSAL).
    pub k_end: S,
    /// Third- minus second-order solution: the local error estimate of the second-order
    /// formula, an upper estimate of the third-order one's.
    pub err: S,
}

/// One Bogacki–Shampine step of size `h` from `(t, y)` with `k1 = f(t, y)` known: the same
/// third-order solution as [`rk23_step`] plus the embedded second-order estimate, from three
/// evaluations (the last is the next step's `k1`). The error weights are Bogacki and
/// Shampine's (1989), as in MATLAB's `ode23` and SciPy's `RK23`.
///
/// ```
/// use host_sim::solver::rk23_embedded;
/// let mut f = |_t, y: &[f64; 1]| [-y[0]];
/// let s = rk23_embedded(&mut f, 0.0, &[1.0], &[-1.0], 0.1);
/// assert!((s.y[0] - (-0.1f64).exp()).abs() < 1e-5);
/// assert!(s.err[0].abs() > (s.y[0] - (-0.1f64).exp()).abs()); // the estimate bounds the error
/// assert_eq!(s.k_end, [-s.y[0]]);
/// ```
#[inline]
pub fn rk23_embedded<S: OdeState>(
    f: &mut impl FnMut(f64, &S) -> S,
    t: f64,
    y: &S,
    k1: &S,
    h: f64,
) -> EmbeddedStep<S> {
    let (k2, k3, out) = stages(f, t, y, k1, h);
    let k4 = f(t + h, &out);
    // y₃ − y₂ with y₂ = y + h(7/24 k1 + 1/4 k2 + 1/3 k3 + 1/8 k4).
    let mut err = k1.clone();
    err.scale(-5.0 / 72.0 * h);
    err.add_scaled(1.0 / 12.0 * h, &k2);
    err.add_scaled(1.0 / 9.0 * h, &k3);
    err.add_scaled(-1.0 / 8.0 * h, &k4);
    EmbeddedStep {
        y: out,
        k_end: k4,
        err,
    }
}

/// The step-size factor after a rejected step whose error norm was `norm` (> 1), for a method
/// whose error estimate is of order 2 (local error ∝ h³): `0.9·norm^(−1/3)`, kept within
/// [0.2, 5] (the limits of SciPy's and MATLAB's RK23).
#[inline]
pub fn step_factor(norm: f64) -> f64 {
    if norm <= 0.0 || !norm.is_finite() {
        return if norm.is_finite() { 5.0 } else { 0.2 };
    }
    (0.9 * norm.powf(-1.0 / 3.0)).clamp(0.2, 5.0)
}

/// Step-size control with memory (Gustafsson's PI controller, Hairer & Wanner II §IV.2):
/// after an accepted step the factor is `0.9·norm^(−0.7/3)·prev^(0.4/3)`, `prev` the norm of
/// the previous accepted step. Where the step is bounded by stability rather than accuracy
/// (steady sliding here) the plain factor [`step_factor`] makes the step oscillate around the
/// bound with every other step rejected; the memory damps that oscillation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepControl {
    /// ln of the previous accepted step's norm.
    ln_prev: f64,
}

impl Default for StepControl {
    fn default() -> Self {
        Self {
            ln_prev: (1e-4f64).ln(),
        }
    }
}

impl StepControl {
    /// The factor for the next step after a step with error norm `norm` (≤ 1: accepted, and
    /// remembered; > 1: rejected, plain factor capped at 1).
    #[inline]
    pub fn factor(&mut self, norm: f64) -> f64 {
        if norm > 1.0 || !norm.is_finite() {
            return step_factor(norm).min(1.0);
        }
        // 0.9·n^(−0.7/3)·prev^(0.4/3), with one ln and one exp.
        let ln_n = norm.max(1e-4).ln();
        let f = 0.9 * ((0.4 * self.ln_prev - 0.7 * ln_n) / 3.0).exp();
        self.ln_prev = ln_n;
        f.clamp(0.2, 5.0)
    }
}

/// Brackets the sign change of `g` on `[a, b]` (given `g(a) ≤ 0 < g(b)` or the reverse) with the
/// Illinois variant of regula falsi, until the bracket is narrower than `tol` or `max_iter`
/// evaluations are spent. Returns `(lo, hi)`: `lo` on `a`'s side of the root, `hi` on `b`'s.
pub fn bracket_root(
    g: &mut impl FnMut(f64) -> f64,
    mut a: f64,
    mut b: f64,
    mut ga: f64,
    mut gb: f64,
    tol: f64,
    max_iter: usize,
) -> (f64, f64) {
    // `side` remembers which end moved last, to halve the stale end's weight (Illinois).
    let mut side = 0i8;
    for _ in 0..max_iter {
        if (b - a).abs() <= tol {
            break;
        }
        let mut c = (a * gb - b * ga) / (gb - ga);
        if !c.is_finite() || c <= a.min(b) || c >= a.max(b) {
            c = 0.5 * (a + b);
        }
        let gc = g(c);
        if (gc > 0.0) == (gb > 0.0) {
            b = c;
            gb = gc;
            if side == 1 {
                ga *= 0.5;
            }
            side = 1;
        } else {
            a = c;
            ga = gc;
            if side == -1 {
                gb *= 0.5;
            }
            side = -1;
        }
    }
    (a, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rk23_is_third_order() {
        // Global error on ẏ = −y over [0, 1] falls ~8× per halving of h.
        let err = |n: usize| {
            let h = 1.0 / n as f64;
            let mut y = [1.0];
            for i in 0..n {
                y = rk23_step(&mut |_t, y: &[f64; 1]| [-y[0]], i as f64 * h, &y, h);
            }
            (y[0] - (-1f64).exp()).abs()
        };
        let ratio = err(20) / err(40);
        assert!((7.0..9.5).contains(&ratio), "{ratio}");
    }

    #[test]
    fn embedded_estimate_tracks_the_local_error() {
        // ẏ = y·cos t: the estimate is within a factor of the true local error of the
        // second-order formula, which falls ∝ h³.
        fn f(t: f64, y: &[f64; 1]) -> [f64; 1] {
            [y[0] * t.cos()]
        }
        let exact = |t: f64| t.sin().exp();
        let (t, y) = (0.3, [exact(0.3)]);
        let k1 = f(t, &y);
        let est = |h: f64| rk23_embedded(&mut f, t, &y, &k1, h).err[0].abs();
        let ratio = est(0.02) / est(0.01);
        assert!((6.0..10.0).contains(&ratio), "{ratio}");
        let s = rk23_embedded(&mut f, t, &y, &k1, 0.01);
        assert_eq!(s.y, rk23_step(&mut f, t, &y, 0.01));
        assert!((s.y[0] - exact(0.31)).abs() < est(0.01));
    }

    #[test]
    fn step_control_grows_after_small_errors_and_shrinks_after_large() {
        let mut c = StepControl::default();
        assert!(c.factor(1e-3) > 1.0);
        assert!(c.factor(2.0) < 1.0);
        assert!(c.factor(0.99) < 1.0 && c.factor(0.99) > 0.5);
    }

    #[test]
    fn step_factor_is_bounded() {
        assert_eq!(step_factor(0.0), 5.0);
        assert_eq!(step_factor(f64::NAN), 0.2);
        assert_eq!(step_factor(1e9), 0.2);
        assert!((step_factor(1.0) - 0.9).abs() < 1e-12);
    }

    #[test]
    fn illinois_brackets_a_root_tightly() {
        let (lo, hi) = bracket_root(&mut |x| x * x - 2.0, 0.0, 2.0, -2.0, 2.0, 1e-14, 100);
        assert!(lo * lo - 2.0 <= 0.0 && hi * hi - 2.0 > 0.0);
        assert!((hi - lo).abs() <= 1e-14 && (lo - 2f64.sqrt()).abs() < 1e-13);
    }
}
