#!/usr/bin/env python3
"""Straightforward SciPy reference of host-sim's paper-mode ODE, for the throughput benchmark.

The same model as host-sim (docs/plant.md): seed 000's screw-nut equation in one form for both
directions, Table 1 structure damping, pin friction, the Fig. 2 input profile, and the
Karnopp-exact stick/slip switch (slip until theta_dot = 0, stuck until the breakaway test fires;
while stuck the static share is solved by the equal-mobilisation rule). Integrated with
scipy.integrate.solve_ivp(method="RK23") with terminal events for the phase switches and a
restart at each event. The mean friction torque comes from integrating T_r as a state, like
host-sim does.

Not part of the tests. Run through bench/run (it runs host-sim side by side and prints the ratio).

    python3 bench/scipy_reference.py --lubricant ptfe --duration 1 --rtol 1e-6
"""

import argparse
import json
import math
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

G = 9.80665
# Screw S12x2 and supports (seed 000).
R_M, LAM = 4.265e-3, math.radians(3.47)
I_S, C_S, T0, M_NUT, K = 3e-6, 4e-4, 0.01, 1.0, 160.0
SIN_L, COS_L, TAN_L = math.sin(LAM), math.cos(LAM), math.tan(LAM)
LEAD = R_M * TAN_L
# Geometry (host-sim Geometry::paper): L = 0.4 m diagonal, alpha0 = 15 deg.
LENGTH, ALPHA0 = 0.4, math.radians(15.0)
TABLE1 = [(15.0, 58544.0), (45.0, 28878.0), (65.0, 23175.0)]

# mu(s) = base + amp*exp(-rate*s) + slope*min(s, s_max), floored at 0; s = |theta_dot| or |v_s|.
LAWS = {
    "dry": dict(base=0.218, amp=0.02, rate=0.38, slope=-4.47e-4, s_max=math.inf, sliding=False),
    "ptfe": dict(base=0.1961, amp=-(0.1961 - 0.0843), rate=0.02, slope=0.0, s_max=math.inf, sliding=True),
    "lithium": dict(base=0.177, amp=0.193 - 0.177, rate=1.0 / 0.1e-3,
                    slope=(0.19 - 0.177) / (2.0 - 0.1) * 1e3, s_max=2e-3, sliding=True),
}


class Lift:
    def __init__(self, lubricant, mu_pin, start_deg, cruise, mass=1000.0):
        self.law = LAWS[lubricant]
        self.mu_pin, self.mass, self.cruise = mu_pin, mass, cruise
        self.theta_start = LENGTH * (math.cos(ALPHA0) - math.cos(math.radians(start_deg))) / LEAD
        self.mu0 = self.mu(0.0)

    def mu(self, theta_dot):
        l = self.law
        s = abs(theta_dot) * (R_M / COS_L if l["sliding"] else 1.0)
        return max(l["base"] + l["amp"] * math.exp(-l["rate"] * s) + l["slope"] * min(s, l["s_max"]), 0.0)

    def theta_i(self, t):
        """Fig. 2: ramp 0-0.06 s, hold to 4.94 s, brake to 5 s (exact integral)."""
        w, t1, t2, t3 = self.cruise, 0.06, 4.94, 5.0
        if t <= 0:
            a = 0.0
        elif t < t1:
            a = 0.5 * w * t * t / t1
        elif t <= t2:
            a = 0.5 * w * t1 + w * (t - t1)
        else:
            tt = min(t, t3)
            a = 0.5 * w * t1 + w * (t2 - t1) + 0.5 * w * (t3 - t2) - 0.5 * w * (t3 - tt) ** 2 / (t3 - t2)
        return self.theta_start + a

    def loads(self, theta):
        x = LEAD * theta
        alpha = math.acos(max(-1.0, min(1.0, math.cos(ALPHA0) - x / LENGTH)))
        deg = math.degrees(alpha)
        if deg <= TABLE1[0][0]:
            cx = TABLE1[0][1]
        elif deg >= TABLE1[-1][0]:
            cx = TABLE1[-1][1]
        else:
            for (a0, c0), (a1, c1) in zip(TABLE1, TABLE1[1:]):
                if deg <= a1:
                    cx = c0 + (c1 - c0) * (deg - a0) / (a1 - a0)
                    break
        r = self.mass * G / math.tan(alpha)
        f0 = 2.0 * self.mu_pin * self.mass * G / math.sin(alpha)
        return r, f0, cx

    @staticmethod
    def xi(mu_s, w_pos):
        return (TAN_L + mu_s) / (1 - mu_s * TAN_L) if w_pos else (TAN_L - mu_s) / (1 + mu_s * TAN_L)

    def accel(self, theta, theta_dot, tc, d, mu):
        r, f0, cx = self.loads(theta)
        a = tc - C_S * theta_dot - T0 * d
        w0 = r + f0 * d + cx * LEAD * theta_dot
        xi = self.xi(mu * d, M_NUT * LEAD * a + I_S * w0 >= 0)
        thdd = (a - R_M * xi * w0) / (I_S + R_M * xi * M_NUT * LEAD)
        return thdd, M_NUT * LEAD * thdd + w0

    @staticmethod
    def friction_torque(mu_s, w):
        n = w / (COS_L - mu_s * SIN_L) if w >= 0 else w / (COS_L + mu_s * SIN_L)
        return mu_s * abs(n) * R_M * COS_L

    def slip_rhs(self, d):
        def f(t, y):
            theta, theta_dot, _ = y
            tc = K * (self.theta_i(t) - theta)
            mu = self.mu(theta_dot)
            thdd, w = self.accel(theta, theta_dot, tc, d, mu)
            return [theta_dot, thdd, self.friction_torque(mu * d, w)]
        return f

    def stuck_torque(self, theta, tc):
        r, f0, _ = self.loads(theta)

        def res(rho):
            w = r + rho * f0
            return rho * T0 + R_M * self.xi(self.mu0 * rho, w >= 0) * w - tc

        lo, hi = res(-1.0), res(1.0)
        rho = -1.0 if lo >= 0 else 1.0 if hi <= 0 else brentq(res, -1.0, 1.0, xtol=1e-12)
        return self.friction_torque(self.mu0 * rho, r + rho * f0)

    def stick_rhs(self, t, y):
        tc = K * (self.theta_i(t) - y[0])
        return [0.0, 0.0, self.stuck_torque(y[0], tc)]

    def margin(self, theta, tc):
        up = self.accel(theta, 0.0, tc, 1.0, self.mu0)[0]
        down = -self.accel(theta, 0.0, tc, -1.0, self.mu0)[0]
        return max(up, down)

    def breakaway(self, theta, tc):
        if self.accel(theta, 0.0, tc, 1.0, self.mu0)[0] > 0:
            return 1.0
        if self.accel(theta, 0.0, tc, -1.0, self.mu0)[0] < 0:
            return -1.0
        return 0.0


def simulate(lift, duration, rtol, atol, window):
    """Returns (mean T_r over window, mean T_r over 0.06..duration, events, rhs evaluations)."""
    t, y, phase = 0.0, np.array([lift.theta_start, 0.0, 0.0]), 0.0  # 0 = stuck, +-1 = slipping
    events, nfev = 0, 0
    samples = []  # (t, q) at the ends of the pieces plus dense output at the window edges

    def q_at(ts, sol):
        return float(sol.sol(ts)[2])

    marks = {}
    while t < duration - 1e-12:
        if phase == 0.0:
            fun = lift.stick_rhs

            def ev(tt, yy):
                return lift.margin(yy[0], K * (lift.theta_i(tt) - yy[0]))
        else:
            fun = lift.slip_rhs(phase)
            d = phase

            def ev(tt, yy, d=d):
                return -d * yy[1]
        ev.terminal, ev.direction = True, 1.0
        sol = solve_ivp(fun, (t, duration), y, method="RK23", rtol=rtol, atol=atol,
                        events=ev, dense_output=True)
        nfev += sol.nfev
        t_end = sol.t[-1]
        for name, tm in (("w0", window[0]), ("w1", window[1]), ("c0", 0.06), ("c1", duration)):
            if name not in marks and t <= tm <= t_end:
                marks[name] = q_at(tm, sol)
        y = sol.y[:, -1].copy()
        if sol.status == 1 and t_end < duration - 1e-12:
            events += 1
            if phase != 0.0:
                y[1] = 0.0
            tc = K * (lift.theta_i(t_end) - y[0])
            if phase == 0.0:
                # The breakaway margin crossed zero: slip in the direction that broke away
                # (the located root may sit a rounding error before the crossing).
                up = lift.accel(y[0], 0.0, tc, 1.0, lift.mu0)[0]
                down = -lift.accel(y[0], 0.0, tc, -1.0, lift.mu0)[0]
                phase = 1.0 if up >= down else -1.0
            else:
                phase = lift.breakaway(y[0], tc)
            t = t_end
        else:
            t = t_end
    window_mean = (marks["w1"] - marks["w0"]) / (window[1] - window[0])
    cruise_mean = (marks["c1"] - marks["c0"]) / (duration - 0.06)
    return window_mean, cruise_mean, events, nfev


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--lubricant", default="ptfe", choices=sorted(LAWS))
    ap.add_argument("--pin-friction", type=float, default=0.3)
    ap.add_argument("--start-deg", type=float, default=15.0)
    ap.add_argument("--cruise", type=float, default=15.0, help="signed: negative lowers")
    ap.add_argument("--duration", type=float, default=1.0)
    ap.add_argument("--rtol", type=float, default=1e-6)
    ap.add_argument("--atol", type=float, default=1e-9)
    a = ap.parse_args()
    lift = Lift(a.lubricant, a.pin_friction, a.start_deg, a.cruise)
    window = (a.duration - 1e-3, a.duration)
    t0 = time.perf_counter()
    wm, cm, ev, nfev = simulate(lift, a.duration, a.rtol, a.atol, window)
    wall = time.perf_counter() - t0
    print(json.dumps(dict(window_mean=wm, cruise_mean=cm, events=ev, nfev=nfev, wall=wall,
                          duration=a.duration, rtol=a.rtol, atol=a.atol)))


if __name__ == "__main__":
    main()
