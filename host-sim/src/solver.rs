//! Explicit fixed-step Bogacki–Shampine RK23 (the formula behind Simulink's `ode3`, which seed
//! 000 used) and the root finder that locates stick/slip events inside a step.
//!
//! The integrator is generic over the state: anything that can form `y + h·k` is a state.

/// A state vector the integrator can advance: it only needs `self += a·other`.
pub trait OdeState: Clone {
    /// `self += a·other`.
    fn add_scaled(&mut self, a: f64, other: &Self);
}

impl<const N: usize> OdeState for [f64; N] {
    #[inline(always)]
    fn add_scaled(&mut self, a: f64, other: &Self) {
        for (y, k) in self.iter_mut().zip(other) {
            *y += a * k;
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
    let mut y2 = y.clone();
    y2.add_scaled(0.5 * h, &k1);
    let k2 = f(t + 0.5 * h, &y2);
    let mut y3 = y.clone();
    y3.add_scaled(0.75 * h, &k2);
    let k3 = f(t + 0.75 * h, &y3);
    let mut out = y.clone();
    out.add_scaled(2.0 / 9.0 * h, &k1);
    out.add_scaled(1.0 / 3.0 * h, &k2);
    out.add_scaled(4.0 / 9.0 * h, &k3);
    out
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
    fn illinois_brackets_a_root_tightly() {
        let (lo, hi) = bracket_root(&mut |x| x * x - 2.0, 0.0, 2.0, -2.0, 2.0, 1e-14, 100);
        assert!(lo * lo - 2.0 <= 0.0 && hi * hi - 2.0 > 0.0);
        assert!((hi - lo).abs() <= 1e-14 && (lo - 2f64.sqrt()).abs() < 1e-13);
    }
}
