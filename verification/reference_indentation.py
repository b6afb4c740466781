#!/usr/bin/env python3
"""Indentation of a clamped circular St Venant-Kirchhoff membrane by a rigid sphere.

Independent reference for ncform's contact verification; it shares no code
with the Rust sources. See docs/references.md §3.

Problem
=======
A flat circular membrane of radius a and thickness t, isotropic St Venant-
Kirchhoff in plane stress (S = D E, W = 1/2 E:D:E per reference volume,
D = E/(1 - nu^2) [[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu)/2]]), clamped on its
rim (r = a, z = 0), is pushed down by a frictionless rigid sphere of radius R
that initially touches the centre from above: the sphere's centre is at
z_c = R - d for the depth d. The membrane's MID-SURFACE touches the sphere
(no thickness offset: a shell code must use a contact offset of zero, or
indent with a sphere of radius R - t/2 if it offsets by half the thickness).

Axisymmetric kinematics: a material circle of reference radius s goes to
(r(s), z(s)); the principal stretches are lam1 = sqrt(r'^2 + z'^2)
(meridional) and lam2 = r/s (hoop), Ei = (lami^2 - 1)/2, with k = E/(1-nu^2)

    S1 = k (E1 + nu E2),  S2 = k (E2 + nu E1),  Pi_i = dW/dlam_i = Si lam_i,
    W  = k/2 (E1^2 + E2^2 + 2 nu E1 E2),   Pi = 2 pi t  int_0^a W s ds.

Method 1 (the reference, `indentation_force`): shooting on the equilibrium
equations of the two regions,
* contact, s in [0, s_c]: the membrane lies on the sphere,
  (r, z) = (R sin b, z_c - R cos b); lam1 = R b', lam2 = R sin b / s; the
  meridional (tangential, frictionless) equilibrium is the Euler-Lagrange
  equation of Pi for b(s):  G = s P1,  G' = P2 cos b,  b' = lam1 / R;
* free, s in [s_c, a]: with H = s P1 cos psi, V = s P1 sin psi (psi the
  slope), the Euler-Lagrange equations of Pi for r(s), z(s) are
  H' = P2, V' = 0, r' = lam1 cos psi, z' = lam1 sin psi (V = F / (2 pi t)).
lam1 follows from P1 (given lam2) by Newton on (1 + e)(e + e^2/2 + nu E2) = P1/k.
At s -> 0 the state is equibiaxial, lam1 = lam2 = lam0; at s_c the position,
slope (psi = b) and meridional force (sP1) are continuous. The two unknowns
(lam0, s_c) are found by Powell's hybrid method (scipy.optimize.root) from the
two rim conditions r(a) = a, z(a) = 0, by continuation in d from
d0 = min(0.1 a, R/4) up and down through the requested depths (geometric
steps of at most 1.25, the guess extrapolated in log-log from the two previous
depths; shooting from the centre is ill-conditioned at small depths, so it
does not start there). The ODEs are integrated with DOP853 (rtol 1e-11).
Force: F = 2 pi t V (the vertical force carried by the free membrane); it is
checked against the integral of the contact pressure over the sphere
(p = (T1 + T2)/R, T1 = t P1/lam2, T2 = t P2/lam1 the Cauchy membrane forces)
and against dPi/dd by finite differences of the energy. Contact radius: the
deformed one, r_c = R sin b(s_c) (also returned: the reference s_c).

Method 2 (the cross-check, `indentation_force(..., n_elements=N)`): 1-D
finite elements in s: N linear two-node elements (uniform in s), nodal
unknowns (r_i, z_i) for free nodes and the polar angle b_i on the sphere for
contact nodes (the nodes 0..m, a contiguous set from the centre); the energy
is integrated with 3 Gauss points per element and minimised by Newton's
method with an exact gradient and Hessian (sparse), an energy line search and
an active-set loop on m (add penetrating nodes, release a node whose contact
reaction d Pi / d(normal offset) is negative). F is the vertical reaction of
the rim node. It discretises Pi directly, so it checks the ODEs of method 1,
not only their integration.

Accuracy (verify_references.py): the shooting F is converged to ~1e-11
(rtol 1e-9 vs 1e-11, integration start, rim residual, F = dPi/dd); the FE
converges onto it (1.6e-6 at N = 1600). Depths below ~5e-4 a are out of reach
(the rim residual floor exceeds RESIDUAL_TOL).

Usage: reference_indentation.py [--fe] (prints the table of F(d), r_c(d),
the convergence study and the checks).
"""

import argparse
import math
import sys
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.integrate import solve_ivp
from scipy.optimize import root

RTOL = 1e-11         # DOP853 tolerance of the reference (convergence study in main())
ATOL = 1e-14         # absolute tolerance of the normalised states (strain-sized, >= ~1e-8 at d >= 0.1 mm)
MAX_RATIO = 1.25     # largest ratio of consecutive continuation depths
CENTRE_FRACTION = 1e-6  # integration starts at s0 = 1e-6 s_c (series error ~ (s0/s_c)^2)
RESIDUAL_TOL = 1e-7   # accepted scaled rim residual (u(a)/(a eps0), z(a)/d): F error <~ 3e-7;
#                       reached ~1e-13 at d >= 1 mm, ~1e-8 at d ~ 0.1 mm (ill-conditioned)
START_DEPTH = 0.1     # continuation starts at d0 = min(0.1 a, 0.25 R), runs up and down

# the paper case of this reference
PAPER = dict(E=10.0, nu=0.3, t=0.3, a=100.0, R=40.0)


def _check_inputs(E, nu, t, a, R):
    for name, v in (("E", E), ("t", t), ("a", a), ("R", R)):
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} = {v} is invalid; expected a finite value > 0")
    if not (math.isfinite(nu) and -1.0 < nu < 0.5):
        raise ValueError(f"nu = {nu} is invalid; expected -1 < nu < 0.5")


def _meridional_strain(p, E2, nu):
    """e = lam1 - 1 with (1 + e)(e + e^2/2 + nu E2) = p (p = P1/k), tension branch."""
    e = p - nu * E2
    for _ in range(60):
        E1 = e + 0.5 * e * e
        f = (1.0 + e) * (E1 + nu * E2) - p
        fp = E1 + nu * E2 + (1.0 + e) ** 2
        de = f / fp
        e -= de
        if abs(de) <= 1e-16 * (1.0 + abs(e)):
            break
    return e


# --------------------------------------------------------------------------
# Method 1: shooting
# --------------------------------------------------------------------------


class _Shooting:
    """The two-region shooting problem for one depth (all forces / k)."""

    def __init__(self, d, nu, a, R, rtol):
        self.d, self.nu, self.a, self.R, self.rtol = d, nu, a, R, rtol
        self.zc = R - d

    def contact_rhs(self, s, y):
        nu, R = self.nu, self.R
        beta, G = y[0], y[1]
        lam2 = R * math.sin(beta) / s
        E2 = 0.5 * (lam2 * lam2 - 1.0)
        e1 = _meridional_strain(G / s, E2, nu)
        lam1 = 1.0 + e1
        E1 = e1 + 0.5 * e1 * e1
        P1 = (E1 + nu * E2) * lam1
        P2 = (E2 + nu * E1) * lam2
        W = 0.5 * (E1 * E1 + E2 * E2 + 2.0 * nu * E1 * E2)
        # pressure p/k = (t/R)(P1/lam2 + P2/lam1); vertical force density
        # d(F/(2 pi t k))/ds = (p/(t k)) cos b * r * lam1 with r = R sin b
        dF = (P1 / lam2 + P2 / lam1) / R * math.cos(beta) * R * math.sin(beta) * lam1
        return [lam1 / R, P2 * math.cos(beta), W * s, dF]

    def free_rhs(self, s, y):
        nu = self.nu
        u, _z, H, V = y[0], y[1], y[2], y[3]
        T = math.hypot(H, V)
        q = u / s
        lam2 = 1.0 + q
        E2 = q + 0.5 * q * q
        e1 = _meridional_strain(T / s, E2, nu)
        lam1 = 1.0 + e1
        E1 = e1 + 0.5 * e1 * e1
        P2 = (E2 + nu * E1) * lam2
        W = 0.5 * (E1 * E1 + E2 * E2 + 2.0 * nu * E1 * E2)
        return [lam1 * H / T - 1.0, lam1 * V / T, P2, 0.0, W * s]

    def run(self, x, dense=False):
        """Integrate both regions for x = (log eps0, log s_c)."""
        nu, R = self.nu, self.R
        eps0, sc = math.exp(x[0]), math.exp(x[1])
        if not (sc < self.a):
            raise ValueError("contact radius beyond the rim")
        lam0 = 1.0 + eps0
        E0 = eps0 + 0.5 * eps0 * eps0
        s0 = CENTRE_FRACTION * sc
        P0 = (1.0 + nu) * E0 * lam0
        W0 = (1.0 + nu) * E0 * E0
        # series start: b = lam0 s / R, G = s P0, energy W0 s^2/2, force ~ s^2
        y0 = [lam0 * s0 / R, s0 * P0, 0.5 * W0 * s0 * s0, P0 * lam0 * s0 * s0 / R]
        c = solve_ivp(self.contact_rhs, (s0, sc), y0, method="DOP853", rtol=self.rtol,
                      atol=ATOL, dense_output=dense)
        if c.status != 0:
            raise ValueError(c.message)
        beta, G = c.y[0, -1], c.y[1, -1]
        rc = R * math.sin(beta)
        yf0 = [rc - sc, self.zc - R * math.cos(beta), G * math.cos(beta), G * math.sin(beta), 0.0]
        f = solve_ivp(self.free_rhs, (sc, self.a), yf0, method="DOP853", rtol=self.rtol,
                      atol=ATOL, dense_output=dense)
        if f.status != 0:
            raise ValueError(f.message)
        return c, f

    def solve(self, x0):
        a, d = self.a, self.d
        eps_scale = math.exp(x0[0])

        def residual(x):
            try:
                _c, f = self.run(x)
            except (ValueError, OverflowError, ZeroDivisionError):
                return [1e6, 1e6]
            # rim conditions, scaled to O(1) changes per unit change of x
            return [f.y[0, -1] / (a * eps_scale), f.y[1, -1] / d]

        sol = root(residual, x0, method="hybr", options={"xtol": 1e-14})
        # hybr may stop with "no good progress" once the residual is at round-off;
        # accept on the residual itself (scaled by the strain level and by d)
        if max(abs(v) for v in sol.fun) > RESIDUAL_TOL:
            raise RuntimeError(f"shooting did not converge at d = {d}: {sol.message} "
                               f"(scaled rim residual {sol.fun})")
        self.residual = max(abs(v) for v in sol.fun)
        return sol.x


def _first_guess(d, nu, a, R):
    """(log eps0, log s_c) from the small-depth scaling s_c ~ a (dR/a^2)^(3/4),
    eps0 ~ d^(3/2) / (a sqrt(R)) (constants measured at nu = 0.3, R/a = 0.4).

    Shooting from the centre is ill-conditioned at small depths (the rim
    residual jumps where the free membrane's tension collapses; at d = 0.01 a
    the guess must be within ~0.3 %), so the continuation starts at a moderate
    depth, where hybr converges from this guess even when it is a factor 2
    off, and walks up and down from there."""
    sc = 0.84 * a * (d * R / a ** 2) ** 0.75
    eps0 = 0.21 * d ** 1.5 / (a * math.sqrt(R))
    return np.array([math.log(eps0), math.log(sc)])


def _branches(depths, a, R):
    """Continuation paths (lists of depths) from d0 up and down through the targets."""
    d0 = min(START_DEPTH * a, 0.25 * R)
    targets = sorted(set(float(d) for d in depths if d > 0))
    up = [d for d in targets if d >= d0]
    down = sorted((d for d in targets if d < d0), reverse=True)
    paths = []
    for tg, sign in ((up, 1), (down, -1)):
        if not tg:
            continue
        path = [d0]
        cur = d0
        for target in tg:
            while (target / cur if sign > 0 else cur / target) > MAX_RATIO:
                cur = cur * MAX_RATIO if sign > 0 else cur / MAX_RATIO
                path.append(cur)
            if target != cur:
                cur = target
                path.append(cur)
        paths.append(path)
    return paths


def _shoot_depth(d, x0, E, nu, t, a, R, rtol):
    """Solve one depth; dict of results (N, mm)."""
    k = E / (1.0 - nu * nu)
    prob = _Shooting(d, nu, a, R, rtol)
    x = prob.solve(x0)
    c, f = prob.run(x)
    beta_c = c.y[0, -1]
    force = 2.0 * math.pi * t * k * f.y[3, -1]
    force_pressure = 2.0 * math.pi * t * k * c.y[3, -1]
    energy = 2.0 * math.pi * t * k * (c.y[2, -1] + f.y[4, -1])
    return dict(x=x, force=force, force_pressure=force_pressure, energy=energy,
                contact_radius=R * math.sin(beta_c), contact_radius_ref=math.exp(x[1]),
                centre_strain=math.exp(x[0]), beta_c=beta_c, residual=prob.residual,
                problem=prob)


def solve_path(depths, E, nu, t, a, R, rtol=RTOL):
    """Shooting solutions at the requested depths (dict by depth, None at d = 0)."""
    _check_inputs(E, nu, t, a, R)
    depths = [float(d) for d in depths]
    for d in depths:
        if not (math.isfinite(d) and 0.0 <= d <= R and a * a > d * (2.0 * R - d)):
            raise ValueError(f"depth {d} is invalid; expected 0 <= d <= R with the rim "
                             f"outside the sphere (a^2 > d (2R - d))")
    out = {}
    wanted = set(d for d in depths if d > 0)
    for path in _branches(wanted, a, R):
        hist = []
        for d in path:
            if len(hist) >= 2:
                (d1, x1), (d2, x2) = hist[-2], hist[-1]
                w = math.log(d / d2) / math.log(d2 / d1)
                x0 = x2 + w * (x2 - x1)
            elif len(hist) == 1:
                x0 = hist[-1][1] + np.array([1.5, 0.75]) * math.log(d / hist[-1][0])
            else:
                x0 = _first_guess(d, nu, a, R)
            res = _shoot_depth(d, x0, E, nu, t, a, R, rtol)
            hist.append((d, res["x"]))
            if d in wanted:
                out[d] = res
    for d in depths:
        out.setdefault(d, None)
    return out


def indentation_force(depths, E, nu, t, a, R, n_elements=None, rtol=RTOL):
    """Indentation force F(d) [N] and deformed contact radius r_c(d) [mm].

    depths: iterable of depths d [mm], 0 <= d < min(R, a).
    n_elements=None: the shooting reference (method 1, rtol of DOP853);
    n_elements=N: the 1-D finite-element cross-check with N elements (method 2).
    Returns (forces, contact_radii) as numpy arrays in the order of `depths`.
    """
    depths = [float(d) for d in depths]
    if n_elements is not None:
        res = fe_path(depths, E, nu, t, a, R, int(n_elements))
    else:
        res = solve_path(depths, E, nu, t, a, R, rtol)
    forces = np.array([0.0 if res.get(d) is None else res[d]["force"] for d in depths])
    radii = np.array([0.0 if res.get(d) is None else res[d]["contact_radius"] for d in depths])
    return forces, radii


def energy_derivative(d, res, E, nu, t, a, R, rtol=RTOL, rel_step=1e-3):
    """dPi/dd by the 4th-order central difference of the shooting energy."""
    h = rel_step * d
    x = res["x"]
    vals = {}
    for m in (-2, -1, 1, 2):
        dm = d + m * h
        x0 = x + np.array([1.5, 0.75]) * math.log(dm / d)
        vals[m] = _shoot_depth(dm, x0, E, nu, t, a, R, rtol)["energy"]
    return (vals[-2] - 8.0 * vals[-1] + 8.0 * vals[1] - vals[2]) / (12.0 * h)


def profile_checks(res, E, nu, n=400):
    """Min contact pressure, min gap of the free part to the sphere, min hoop S2 (free)."""
    prob = res["problem"]
    c, f = prob.run(res["x"], dense=True)
    R, zc = prob.R, prob.zc
    k = E / (1.0 - nu * nu)
    sc = math.exp(res["x"][1])
    s_c = np.linspace(CENTRE_FRACTION * sc, sc, n)
    pmin = math.inf
    s2min = math.inf
    for s in s_c:
        beta, G = c.sol(s)[0], c.sol(s)[1]
        lam2 = R * math.sin(beta) / s
        E2 = 0.5 * (lam2 * lam2 - 1.0)
        e1 = _meridional_strain(G / s, E2, nu)
        lam1 = 1.0 + e1
        E1 = e1 + 0.5 * e1 * e1
        p = ((E1 + nu * E2) * lam1 / lam2 + (E2 + nu * E1) * lam2 / lam1) / R
        pmin = min(pmin, p * k)
        s2min = min(s2min, k * (E2 + nu * E1))
    gap = math.inf
    s2free = math.inf
    for s in np.linspace(sc, prob.a, n)[1:]:
        u, z, H, V, _ = f.sol(s)
        r = s + u
        gap = min(gap, math.hypot(r, z - zc) - R)
        q = u / s
        E2 = q + 0.5 * q * q
        e1 = _meridional_strain(math.hypot(H, V) / s, E2, nu)
        E1 = e1 + 0.5 * e1 * e1
        s2free = min(s2free, k * (E2 + nu * E1))
    return dict(min_pressure_over_t=pmin, min_gap=gap, min_hoop_stress_contact=s2min,
                min_hoop_stress_free=s2free)


# --------------------------------------------------------------------------
# Method 2: 1-D finite elements
# --------------------------------------------------------------------------

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(3)
_GAUSS_X = 0.5 * (_GAUSS_X + 1.0)
_GAUSS_W = 0.5 * _GAUSS_W


class _FE:
    def __init__(self, n, E, nu, t, a, R):
        self.n, self.nu, self.t, self.a, self.R = n, nu, t, a, R
        self.k = E / (1.0 - nu * nu)
        self.s = a * np.arange(n + 1) / n
        self.h = a / n

    def element_terms(self, X):
        """Energy, element gradients (n,4) and Hessians (n,4,4) in (r_a, z_a, r_b, z_b)."""
        nu, k, h = self.nu, self.k, self.h
        ra, za, rb, zb = X[:-1, 0], X[:-1, 1], X[1:, 0], X[1:, 1]
        dr, dz = rb - ra, zb - za
        E1 = 0.5 * ((dr * dr + dz * dz) / (h * h) - 1.0)
        g1 = np.stack([-dr, -dz, dr, dz], axis=1) / (h * h)
        H1 = np.array([[1, 0, -1, 0], [0, 1, 0, -1], [-1, 0, 1, 0], [0, -1, 0, 1]], float) / (h * h)
        sa = self.s[:-1]
        energy = 0.0
        grad = np.zeros((self.n, 4))
        hess = np.zeros((self.n, 4, 4))
        scale = 2.0 * math.pi * self.t * h
        for xg, wg in zip(_GAUSS_X, _GAUSS_W):
            Na, Nb = 1.0 - xg, xg
            sg = sa + xg * h
            rg = Na * ra + Nb * rb
            lam2 = rg / sg
            E2 = 0.5 * (lam2 * lam2 - 1.0)
            nvec = np.zeros((self.n, 4))
            nvec[:, 0], nvec[:, 2] = Na, Nb
            g2 = nvec * (rg / sg ** 2)[:, None]
            S1 = k * (E1 + nu * E2)
            S2 = k * (E2 + nu * E1)
            W = 0.5 * k * (E1 * E1 + E2 * E2 + 2.0 * nu * E1 * E2)
            wfac = scale * wg * sg
            energy += float(np.sum(wfac * W))
            grad += wfac[:, None] * (S1[:, None] * g1 + S2[:, None] * g2)
            outer = (np.einsum("ei,ej->eij", g1, g1) + np.einsum("ei,ej->eij", g2, g2)
                     + nu * (np.einsum("ei,ej->eij", g1, g2) + np.einsum("ei,ej->eij", g2, g1)))
            H2 = np.einsum("ei,ej->eij", nvec, nvec) / (sg ** 2)[:, None, None]
            hess += wfac[:, None, None] * (k * outer + S1[:, None, None] * H1
                                           + S2[:, None, None] * H2)
        return energy, grad, hess

    def positions(self, q, m, zc):
        """Node positions (n+1, 2) and the maps from generalised coordinates q.

        Nodes 0..m on the sphere (node 0 at b = 0 fixed), m+1..n-1 free, n fixed.
        q = [b_1..b_m, r_{m+1}, z_{m+1}, ..., r_{n-1}, z_{n-1}].
        """
        R, n = self.R, self.n
        X = np.zeros((n + 1, 2))
        beta = np.concatenate([[0.0], q[:m]])
        X[: m + 1, 0] = R * np.sin(beta)
        X[: m + 1, 1] = zc - R * np.cos(beta)
        X[m + 1: n, :] = q[m:].reshape(-1, 2)
        X[n] = (self.a, 0.0)
        return X, beta

    def assemble(self, q, m, zc, need_hessian=True):
        n, R = self.n, self.R
        X, beta = self.positions(q, m, zc)
        energy, ge, he = self.element_terms(X)
        # Node gradient / Hessian in Cartesian dofs (2 per node)
        nd = 2 * (n + 1)
        gx = np.zeros(nd)
        np.add.at(gx, np.arange(0, 2 * n, 2), ge[:, 0])
        np.add.at(gx, np.arange(1, 2 * n, 2), ge[:, 1])
        np.add.at(gx, np.arange(2, 2 * n + 2, 2), ge[:, 2])
        np.add.at(gx, np.arange(3, 2 * n + 2, 2), ge[:, 3])
        # generalised dof index of each Cartesian dof, with the chain-rule factor
        # contact node i (1..m): r = R sin b, z = zc - R cos b -> one dof b
        nq = m + 2 * (n - 1 - m)
        idx = -np.ones(nd, dtype=int)
        fac = np.zeros(nd)
        fac2 = np.zeros(nd)  # second derivative of the Cartesian dof w.r.t. its b
        for i in range(1, m + 1):
            idx[2 * i] = idx[2 * i + 1] = i - 1
            fac[2 * i], fac[2 * i + 1] = R * math.cos(beta[i]), R * math.sin(beta[i])
            fac2[2 * i], fac2[2 * i + 1] = -R * math.sin(beta[i]), R * math.cos(beta[i])
        free = np.arange(m + 1, n)
        idx[2 * free] = m + 2 * (free - m - 1)
        idx[2 * free + 1] = m + 2 * (free - m - 1) + 1
        fac[2 * free] = fac[2 * free + 1] = 1.0
        mask = idx >= 0
        g = np.zeros(nq)
        np.add.at(g, idx[mask], gx[mask] * fac[mask])
        if not need_hessian:
            return energy, g, None, X, gx
        rows, cols, vals = [], [], []
        loc = np.stack([2 * np.arange(n), 2 * np.arange(n) + 1,
                        2 * np.arange(n) + 2, 2 * np.arange(n) + 3], axis=1)
        for i in range(4):
            for j in range(4):
                ci, cj = loc[:, i], loc[:, j]
                ok = mask[ci] & mask[cj]
                rows.append(idx[ci[ok]])
                cols.append(idx[cj[ok]])
                vals.append(he[ok, i, j] * fac[ci[ok]] * fac[cj[ok]])
        # curvature of the map: sum over the two Cartesian dofs of a contact node
        cn = np.arange(1, m + 1)
        for comp in (0, 1):
            c = 2 * cn + comp
            rows.append(idx[c])
            cols.append(idx[c])
            vals.append(gx[c] * fac2[c])
        H = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(nq, nq))
        return energy, g, H, X, gx

    def newton(self, q, m, zc, tol=1e-12, max_iter=100):
        energy, g, H, X, gx = self.assemble(q, m, zc)
        g0 = max(np.max(np.abs(g)), 1e-300)
        for _ in range(max_iter):
            try:
                dq = spla.spsolve(H.tocsc(), -g)
            except RuntimeError:
                dq = -g
            if not np.all(np.isfinite(dq)) or g @ dq >= 0:
                dq = -g / max(np.max(np.abs(H.diagonal())), 1e-300)
            step = 1.0
            while True:
                qn = q + step * dq
                en, gn, _, _, _ = self.assemble(qn, m, zc, need_hessian=False)
                if en <= energy + 1e-4 * step * (g @ dq) or step < 1e-10:
                    break
                step *= 0.5
            q = qn
            energy, g, H, X, gx = self.assemble(q, m, zc)
            if np.max(np.abs(g)) <= tol * g0 or np.max(np.abs(step * dq)) <= 1e-15 * self.a:
                break
        return q, energy, g, X, gx

    def convert(self, X, m_new, zc):
        """Generalised coordinates for the contact set m_new from positions X."""
        R, n = self.R, self.n
        Xc = X[1: m_new + 1]
        beta = np.arctan2(Xc[:, 0], zc - Xc[:, 1])
        return np.concatenate([beta, X[m_new + 1: n].reshape(-1)])

    def reaction(self, X, gx, i, zc):
        """d Pi / d(normal offset) of contact node i (>= 0 when the sphere pushes)."""
        r, z = X[i]
        nr, nz = r, z - zc
        norm = math.hypot(nr, nz)
        return gx[2 * i] * nr / norm + gx[2 * i + 1] * nz / norm

    def solve_depth(self, d, X_guess, m_guess):
        R, n = self.R, self.n
        zc = R - d
        m = max(1, min(m_guess, n - 2))
        X = X_guess.copy()
        seen = set()
        for _ in range(200):
            q = self.convert(X, m, zc)
            q, energy, g, X, gx = self.newton(q, m, zc)
            dist = np.hypot(X[:, 0], X[:, 1] - zc) - R
            pen = np.nonzero(dist[m + 1: n] < -1e-12 * R)[0]
            key = m
            if len(pen) > 0:
                m_new = m + 1 + int(pen[-1])
            elif self.reaction(X, gx, m, zc) < 0.0 and m > 1:
                m_new = m - 1
            else:
                m_new = m
            if m_new == m or (m_new, key) in seen:
                break
            seen.add((key, m_new))
            m = m_new
        force = gx[2 * n + 1]  # vertical reaction of the rim node (= load on the sphere)
        return dict(force=force, energy=energy, X=X, m=m,
                    contact_radius=X[m, 0], contact_radius_ref=self.s[m])


def fe_path(depths, E, nu, t, a, R, n_elements, step=1.0):
    """FE solutions at the requested depths, by continuation in steps <= `step` mm."""
    _check_inputs(E, nu, t, a, R)
    fe = _FE(n_elements, E, nu, t, a, R)
    targets = sorted(set(d for d in depths if d > 0))
    out = {}
    if not targets:
        return out
    d = 0.0
    X = np.stack([fe.s, np.zeros_like(fe.s)], axis=1)
    m = 1
    path = []
    for tgt in targets:
        while tgt - d > step:
            d += step
            path.append(d)
        d = tgt
        path.append(d)
    d_prev = 0.0
    for d in path:
        # guess: previous shape pushed down by the depth increment, tapering to the rim
        Xg = X.copy()
        Xg[:, 1] -= (d - d_prev) * (1.0 - fe.s / a)
        if d_prev == 0.0:
            Xg[:, 1] = -d * (1.0 - fe.s / a) ** 1.5
            Xg[:, 0] = fe.s * (1.0 + 0.5 * (d / a) ** 2)
            m = max(1, int(0.5 * math.sqrt(2 * R * d) / fe.h))
        res = fe.solve_depth(d, Xg, m)
        X, m = res["X"], res["m"]
        d_prev = d
        if d in targets:
            out[d] = res
    return out


# --------------------------------------------------------------------------
# main: the table, the convergence study, the checks
# --------------------------------------------------------------------------


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--fe", action="store_true", help="also run the FE cross-check")
    args = ap.parse_args(argv)
    p = PAPER
    depths = [5.0, 10.0, 20.0, 30.0, 40.0]
    print(f"# E = {p['E']} MPa, nu = {p['nu']}, t = {p['t']} mm, a = {p['a']} mm, R = {p['R']} mm")
    t0 = time.time()
    ref = solve_path(depths, **p, rtol=RTOL)
    print(f"# shooting, rtol = {RTOL:g}: {time.time() - t0:.1f} s")
    coarse = solve_path(depths, **p, rtol=1e-9)
    print("  d [mm]        F [N]            r_c [mm]      s_c [mm]     F_pressure/F-1   "
          "|F(rtol 1e-9)/F - 1|")
    for d in depths:
        r = ref[d]
        print(f"  {d:5.1f}  {r['force']:.12e}  {r['contact_radius']:.9f}  "
              f"{r['contact_radius_ref']:.9f}  {r['force_pressure'] / r['force'] - 1:+.2e}  "
              f"{abs(coarse[d]['force'] / r['force'] - 1):.2e}")
    for d in (10.0, 40.0):
        dpi = energy_derivative(d, ref[d], **p)
        print(f"# d = {d}: dPi/dd = {dpi:.12e} N, dPi/dd / F - 1 = {dpi / ref[d]['force'] - 1:+.2e}")
    for d in depths:
        c = profile_checks(ref[d], p["E"], p["nu"])
        print(f"# d = {d}: min p/t = {c['min_pressure_over_t']:.4e} MPa/mm, min gap = "
              f"{c['min_gap']:.4e} mm, min S2 contact {c['min_hoop_stress_contact']:.4e}, "
              f"free {c['min_hoop_stress_free']:.4e} MPa")
    if args.fe:
        for n in (400, 800, 1600):
            t0 = time.time()
            fe = fe_path(depths, **p, n_elements=n)
            print(f"# FE n = {n} ({time.time() - t0:.1f} s): "
                  + ", ".join(f"{d:g}: {fe[d]['force'] / ref[d]['force'] - 1:+.2e}" for d in depths))
    return 0


if __name__ == "__main__":
    sys.exit(main())
