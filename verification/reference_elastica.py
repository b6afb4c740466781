#!/usr/bin/env python3
"""Heavy elastica: a clamped strip bending under its own weight (large deflection).

Independent Python reference for the cantilever bending test (Peirce 1930).
It shares no code with ncform's Rust solver (src/analytic/elastica.rs) and
uses a different method: shooting from the *clamp* on the clamp curvature
with scipy's adaptive DOP853 integrator and Brent's root finder, started from
a scipy.integrate.solve_bvp solution (the Rust solver shoots from the tip on
the tip angle with a fixed-step RK4 and bisection).

Problem (docs/references.md §1). A strip of bending stiffness B [N mm per mm
width], areal weight q [N/mm^2] and length L [mm], clamped at s = 0 with the
slope theta0 below the horizontal, free at s = L, gravity along -z. theta(s)
is the slope below the horizontal, x' = cos theta, z' = -sin theta, and the
bending moment at s is the moment of the weight beyond s:

    B theta'(s) = q * integral_s^L (x(sigma) - x(s)) dsigma
    B theta''   = -q (L - s) cos theta,   theta(0) = theta0,   theta'(L) = 0.

In s_hat = s/L the only parameter is lam = q L^3 / B = (L/c)^3 with
c = (B/q)^(1/3) Peirce's bending length. The tip deflection (positive down)
is delta = L * integral_0^1 sin theta ds_hat.

Method: y = [theta, k, X, Z] with k = dtheta/ds_hat,
    theta' = k, k' = -lam (1 - s) cos theta, X' = cos theta, Z' = sin theta,
theta(0) = theta0, k(0) = m unknown; residual k(1; m) = 0.
1. solve_bvp (tol 1e-8) from the small-deflection shape gives m approximately
   (continuation in lam for large lam);
2. Brent's method polishes m in a bracket of +-2 % around it (widened until
   the residual changes sign), each shot with DOP853 at rtol = atol = 1e-13.
Accuracy: the polish leaves |k(1)| ~ 1e-12, so delta is accurate to ~1e-11
relative (measured by halving the integrator tolerances; see
verify_references.py).

Usage: reference_elastica.py  (prints the two paper cases and a small table)
"""

import math
import sys

import numpy as np
from scipy.integrate import solve_bvp, solve_ivp
from scipy.optimize import brentq

RTOL = 1e-13  # DOP853 relative tolerance of the polishing shots
ATOL = 1e-13  # absolute tolerance (the state is O(1) to O(lam))


def _rhs(lam):
    def f(s, y):
        th, k = y[0], y[1]
        c, sn = np.cos(th), np.sin(th)
        return np.array([k, -lam * (1.0 - s) * c, c, sn])
    return f


def shoot(lam, theta0, m, rtol=RTOL, atol=ATOL):
    """State [theta, k, X, Z] at the tip for the clamp curvature m (unit length)."""
    sol = solve_ivp(_rhs(lam), (0.0, 1.0), [theta0, m, 0.0, 0.0], method="DOP853",
                    rtol=rtol, atol=atol)
    if not sol.success:
        raise RuntimeError(f"solve_ivp failed: {sol.message}")
    return sol.y[:, -1]


def _bvp_guess(lam, theta0):
    """Clamp curvature m from solve_bvp, by continuation in lam from the linear solution."""
    s = np.linspace(0.0, 1.0, 201)
    # linear (small deflection) solution for the first load: theta = theta0 + lam th1(s)
    steps = max(1, int(math.ceil(math.log2(max(lam, 1.0)) * 2)))
    lams = np.geomspace(min(lam, 1.0), lam, steps + 1) if lam > 1.0 else [lam]
    th = theta0 + lams[0] * s * (s * s - 3.0 * s + 3.0) / 6.0
    k = lams[0] * (1.0 - s) ** 2 / 2.0
    y = np.vstack([th, k])
    for lm in lams:
        def f(x, yy, lm=lm):
            return np.vstack([yy[1], -lm * (1.0 - x) * np.cos(yy[0])])

        def bc(ya, yb):
            return np.array([ya[0] - theta0, yb[1]])
        res = solve_bvp(f, bc, s, y, tol=1e-8, max_nodes=100000)
        if not res.success:
            raise RuntimeError(f"solve_bvp failed at lam = {lm}: {res.message}")
        s, y = res.x, res.y
    return float(y[1, 0])


def clamp_curvature(lam, theta0=0.0, rtol=RTOL, atol=ATOL):
    """Unit-length clamp curvature m = L theta'(0) of the physical solution."""
    m0 = _bvp_guess(lam, theta0)
    g = lambda m: shoot(lam, theta0, m, rtol, atol)[1]  # noqa: E731
    width = 0.02 * abs(m0) + 1e-12
    lo, hi = m0 - width, m0 + width
    for _ in range(60):
        if g(lo) < 0.0 < g(hi):
            break
        width *= 2.0
        lo, hi = m0 - width, m0 + width
    else:
        raise RuntimeError("no sign change around the solve_bvp clamp curvature")
    return brentq(g, lo, hi, xtol=1e-15, rtol=4 * np.finfo(float).eps, maxiter=200)


def solve(B, q, L, theta0=0.0, rtol=RTOL, atol=ATOL):
    """Dict with tip_deflection, tip_x, tip_angle, clamp_moment (N mm/mm), lam, c."""
    for name, v in (("B", B), ("q", q), ("L", L)):
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} = {v} is invalid; expected a finite value > 0")
    if not (math.isfinite(theta0) and 0.0 <= theta0 < math.pi / 2):
        raise ValueError(f"theta0 = {theta0} is invalid; expected [0, pi/2) rad")
    lam = q * L ** 3 / B
    m = clamp_curvature(lam, theta0, rtol, atol)
    th, k, X, Z = shoot(lam, theta0, m, rtol, atol)
    return {"tip_deflection": L * Z, "tip_x": L * X, "tip_angle": th,
            "clamp_moment": B * m / L, "tip_curvature_residual": k, "lam": lam,
            "c": (B / q) ** (1.0 / 3.0)}


def tip_deflection(B, q, L, theta0=0.0):
    """Tip deflection delta [mm] (positive down) of the heavy elastica."""
    return solve(B, q, L, theta0)["tip_deflection"]


# The paper's fabric: areal mass 0.30 kg/m^2 -> q = 0.30 * 9.81 N/m^2 = 2.943e-6 N/mm^2.
Q_FABRIC = 0.30 * 9.81 * 1e-6
CASES = (("B11 = 4.06 N mm, L = 150 mm", 4.06, Q_FABRIC, 150.0),
         ("B22 = 0.018 N mm, L = 30 mm", 0.018, Q_FABRIC, 30.0))


def main():
    print(f"q = {Q_FABRIC:.6e} N/mm^2")
    for name, B, q, L in CASES:
        r = solve(B, q, L)
        print(f"{name}: c = {r['c']:.6f} mm, L/c = {L / r['c']:.6f}, lam = {r['lam']:.9f}")
        print(f"  delta = {r['tip_deflection']:.12f} mm  (linear qL^4/8B = {q * L**4 / (8 * B):.6f})")
        print(f"  x_tip = {r['tip_x']:.12f} mm, tip angle = {r['tip_angle']:.12f} rad, "
              f"M(0) = {r['clamp_moment']:.12e} N mm/mm")
    print("\n  L/c      lam        delta/L          x_tip/L        chord angle [deg]")
    for lc in (0.5, 1.0, 1.5, 2.0, 3.0, 4.0):
        lam = lc ** 3
        r = solve(1.0, 1.0, lc)  # B = q = 1 -> c = 1, L = L/c
        print(f"  {lc:4.1f} {lam:9.3f}  {r['tip_deflection'] / lc:.12f}  {r['tip_x'] / lc:.12f}  "
              f"{math.degrees(math.atan2(r['tip_deflection'], r['tip_x'])):.6f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
