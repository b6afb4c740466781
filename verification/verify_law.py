#!/usr/bin/env python3
"""Independent verification of the UD-NCF membrane law in `ncform material eval`.

What this checks
================
The reference is built from the ENERGY ALONE, as stated in docs/theory.md
(which holds over the paper where they differ): sympy differentiates W; no
derivative of W is written by hand anywhere in this file. The reference is then
compared with the Rust implementation, `ncform material eval`, at thousands of
random states (fixed seed) that cover every branch of the law, for three
parameter sets: the named `schaefer2024` (default) and `schaefer2024-printed`,
and a "balanced" user TOML file written to a temporary directory, in which all
moduli are of order 1 and every term has a transition and a lock (so the small
shear/compaction terms are not hidden under the 1000 MPa roving modulus), with a
non-integer coupling exponent e11 = 2.5 (exercises k11'' properly).

Energy (docs/theory.md, "Energy" and "The generalized stress function")
-----------------------------------------------------------------
    a0 = (cos t, sin t), b0 = (-sin t, cos t)   (t = fibre angle)
    I4 = a0.C a0,  I6 = a0.C b0,  I8 = b0.C b0
    I11 = sqrt((I4 I8 - I6^2) / I4),  I10 = pi/2 - arccos(I6 / sqrt(I4 I8))
    W = G4(|I4-1|) + G6(|I6|) + [I8>1] k11(I11) G8(I8-1) + [I11<1] G11(1-I11)
    k11 = (1-k_min) exp(-s11 (1-I11)^e11) + k_min  for I11 < 1, else 1
    G(x) = 1/2 C_ini x^2                                             x < x_t
         = 1/2 C_ini x_t^2 + (S_ini + dS_mid) y + 1/2 C_mid y^2
           - dS_mid (1 - e^(-c y))/c - C_mid (1 - e^(-c y)(1 + c y))/c^2  x >= x_t
         (+ C_lock (x - I_lock)^3 / 3 for x >= I_lock)
    x_t = S_ini/C_ini, c = C_ini/dS_mid, y = x - x_t; a term without S_ini is
    1/2 C_ini x^2 everywhere; a term without a lock has none.

Branches: instead of one big Piecewise, W is built symbolically for each
branch of each term (sign of I4-1 and of I6, initial/middle region, lock or
not, I8 <> 1, I11 <> 1 for W8's k11 and for W11), each is differentiated by
sympy and lambdified (numpy, with common-subexpression elimination). The
numeric state picks the branch of each term; the four terms are summed
(differentiation is linear, so this is the derivative of the summed W).
States within 1e-6 (relative) of any branch boundary (I11=1, I8=1, I4=1,
I6=0, x=x_t, x=I_lock) are excluded: there the one-sided derivatives differ
and a 1-ulp difference in the invariants could legitimately pick the other
side. Away from the boundaries the comparison is exact up to round-off.

Derivative conventions (exactly as applied here)
------------------------------------------------
C is parametrised symmetrically, C = [[c11, c12], [c12, c22]], with three
independent symbols. Then

    S11 = 2 dW/dc11,   S22 = 2 dW/dc22,   S12 = S21 = dW/dc12

(c12 appears twice in C, so the tensor derivative dW/dC12 = 1/2 dW/dc12).
The same convention for the tangent, C_ijkl = 2 dS_ij/dC_kl:

    C_ij11 = 2 dS_ij/dc11,   C_ij22 = 2 dS_ij/dc22,   C_ij12 = C_ij21 = dS_ij/dc12

i.e. with D11 = 2 d/dc11, D22 = 2 d/dc22, D12 = D21 = d/dc12:
S_ij = D_ij W and C_ijkl = D_ij D_kl W = 4 d2W/dCdC.

Tolerance
---------
Per state, norm-wise: |W - W_ref| <= 1e-8 max(|W_ref|, 1e-30),
||S - S_ref||_F <= 1e-8 ||S_ref||_F, ||C - C_ref||_F <= 1e-8 ||C_ref||_F;
invariants component-wise to 1e-12 relative to max(|ref|, ||C||_F) (they are
bilinear forms of C with unit vectors, so their round-off scales with ||C||).
1e-8 is the requirement. Both sides evaluate sums of a few dozen
double-precision terms of moderate condition, so round-off is ~1e-14
(the reference itself is checked against 40-digit mpmath evaluation to 1e-10:
the law is ill-conditioned only through x = |I4 - 1| or |I6| near 0, where a
1-ulp error of the invariant is a relative error ~1e-16/x of the term, at most
~1e-10 with x >= 1e-6 as the boundary margin guarantees);
1e-8 therefore leaves room only for round-off, never for a wrong or missing
derivative term, which shows up as an O(1) relative error of that term (and the
balanced set keeps every term at O(1) of the total).

Input-handling checks: a line with det C <= 0 (or C not positive definite), a
malformed JSON line and a line without C each give `{"line": n, "error": ...}`
on stdout in place, the other lines are still answered, and the exit status is
non-zero; blank lines are skipped.

Usage: verify_law.py --ncform PATH [--states N]. Prints one PASS/FAIL line per
check, and finally `CHECK-SUMMARY passed=N failed=M`, which
verification/run.sh adds up into its closing line.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
import traceback

import mpmath
import numpy as np
import sympy as sp

SEED = 20240527
REL_TOL = 1e-8          # the requirement (see docstring)
INV_TOL = 1e-12         # invariants, relative to max(|ref|, ||C||_F)
SYM_TOL = 1e-12         # symmetry of ncform's own S and tangent, relative to norm
BOUNDARY_MARGIN = 1e-6  # relative distance from any branch boundary
REF_SELF_TOL = 1e-10    # numpy reference vs 40-digit mpmath reference (see docstring)

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)

# --------------------------------------------------------------------------
# Tiny check harness (later suites use the same PASS/FAIL + CHECK-SUMMARY
# protocol; see README.md).
# --------------------------------------------------------------------------


class Harness:
    def __init__(self):
        self.passed = 0
        self.failed = 0

    def run(self, name, requirement, fn):
        t0 = time.time()
        try:
            ok, detail = fn()
        except RuntimeError as e:  # an expected failure (e.g. ncform missing or crashing)
            ok, detail = False, f"error: {e}"
        except Exception:  # a crashing check is a failed check
            ok, detail = False, "exception:\n" + traceback.format_exc()
        dt = time.time() - t0
        tag = "PASS" if ok else "FAIL"
        print(f"{tag} [{name}] {requirement} ({dt:.1f}s)")
        if detail:
            for line in detail.rstrip().splitlines():
                print(f"    {line}")
        sys.stdout.flush()
        if ok:
            self.passed += 1
        else:
            self.failed += 1
        return ok

    def summary(self):
        print(f"CHECK-SUMMARY passed={self.passed} failed={self.failed}")


# --------------------------------------------------------------------------
# Parameter sets (values from docs/theory.md, Table D.1; the default's W11 lock is
# the reconstruction I_lock = 0.4, C_lock = 10 MPa).
# --------------------------------------------------------------------------

TERMS = ("w4", "w6", "w8", "w11")
KEYS = ("c_ini", "s_ini", "c_mid", "delta_s_mid", "c_lock", "i_lock")


def _term(c_ini, s_ini=None, c_mid=None, delta_s_mid=None, c_lock=None, i_lock=None):
    return dict(c_ini=c_ini, s_ini=s_ini, c_mid=c_mid, delta_s_mid=delta_s_mid,
                c_lock=c_lock, i_lock=i_lock)


def _printed():
    return {
        "w4": _term(1000.0),
        "w6": _term(0.14, 0.018, 0.01, 0.005),
        "w8": _term(1.1, 0.025, 0.03, 0.02),
        "w11": _term(0.01, 0.0025, 0.001, 0.4, 0.045, 10.0),
        "coupling": dict(k_min=0.4, s11=10.0, e11=2.0),
    }


def _default():
    p = _printed()
    p["w11"]["c_lock"] = 10.0
    p["w11"]["i_lock"] = 0.4
    return p


def _balanced():
    return {
        "w4": _term(2.0, 0.04, 0.5, 0.03, 50.0, 0.05),
        "w6": _term(1.0, 0.1, 0.3, 0.05, 5.0, 0.5),
        "w8": _term(1.5, 0.15, 0.4, 0.1, 3.0, 0.3),
        "w11": _term(0.8, 0.12, 0.2, 0.3, 4.0, 0.35),
        "coupling": dict(k_min=0.3, s11=4.0, e11=2.5),
    }


def write_toml(params, path, name):
    lines = ['law = "ud-ncf"', f'name = "{name}"',
             'description = "verification: all moduli O(1), every term with '
             'transition and lock, non-integer e11"', ""]
    for t in TERMS:
        lines.append(f"[{t}]")
        for k in KEYS:
            v = params[t][k]
            if v is not None:
                lines.append(f"{k} = {v!r}")
        lines.append("")
    lines.append("[coupling]")
    for k in ("k_min", "s11", "e11"):
        lines.append(f"{k} = {params['coupling'][k]!r}")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def x_t(tp):
    return tp["s_ini"] / tp["c_ini"] if tp["s_ini"] is not None else math.inf


def i_lock(tp):
    return tp["i_lock"] if tp["c_lock"] is not None else math.inf


# --------------------------------------------------------------------------
# Symbolic model: energy per branch, differentiated by sympy.
# --------------------------------------------------------------------------

c11, c12, c22 = sp.symbols("c11 c12 c22", real=True)
cs, sn = sp.symbols("cs sn", real=True)  # cos and sin of the fibre angle
CI, SI, CM, DS, CL, IL = sp.symbols("C_ini S_ini C_mid dS_mid C_lock I_lock", positive=True)
KMIN, S11, E11 = sp.symbols("k_min s11 e11", positive=True)
CVARS = (c11, c12, c22)
TERM_ARGS = (c11, c12, c22, cs, sn, CI, SI, CM, DS, CL, IL)
COUPLED_ARGS = TERM_ARGS + (KMIN, S11, E11)
# Hessian entries kept: upper triangle of d2W/dc_a dc_b, a,b in (c11,c12,c22)
HPAIRS = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]

_Cs = sp.Matrix([[c11, c12], [c12, c22]])
_a0 = sp.Matrix([cs, sn])
_b0 = sp.Matrix([-sn, cs])
SYM_I4 = (_a0.T * _Cs * _a0)[0]
SYM_I6 = (_a0.T * _Cs * _b0)[0]
SYM_I8 = (_b0.T * _Cs * _b0)[0]
SYM_I11 = sp.sqrt((SYM_I4 * SYM_I8 - SYM_I6 ** 2) / SYM_I4)


def G_sym(x, region, lock):
    """Generalized energy G(x) of docs/theory.md, in one region, with or without lock."""
    if region == "ini":
        g = CI * x ** 2 / 2
    else:
        xt = SI / CI
        c = CI / DS
        y = x - xt
        g = (CI * xt ** 2 / 2 + (SI + DS) * y + CM * y ** 2 / 2
             - DS * (1 - sp.exp(-c * y)) / c
             - CM * (1 - sp.exp(-c * y) * (1 + c * y)) / c ** 2)
    if lock:
        g = g + CL * (x - IL) ** 3 / 3
    return g


def term_energy(term, key):
    """Symbolic energy of one term in one branch. key is a tuple (see classify)."""
    if term == "w4":
        sign, region, lock = key
        x = (SYM_I4 - 1) if sign > 0 else (1 - SYM_I4)
        return G_sym(x, region, lock)
    if term == "w6":
        sign, region, lock = key
        x = SYM_I6 if sign > 0 else -SYM_I6
        return G_sym(x, region, lock)
    if term == "w8":  # only called for I8 > 1
        region, lock, kbranch = key
        k11 = 1 if kbranch == "k=1" else (1 - KMIN) * sp.exp(-S11 * (1 - SYM_I11) ** E11) + KMIN
        return k11 * G_sym(SYM_I8 - 1, region, lock)
    if term == "w11":  # only called for I11 < 1
        region, lock = key
        return G_sym(1 - SYM_I11, region, lock)
    raise ValueError(term)


class SymbolicLaw:
    """Lazily differentiates and lambdifies each branch energy."""

    def __init__(self):
        self._cache = {}
        self.compile_time = 0.0

    def exprs(self, term, key):
        W = term_energy(term, key)
        g = [sp.diff(W, v) for v in CVARS]
        H = [sp.diff(g[a], CVARS[b]) for a, b in HPAIRS]
        return [W] + g + H

    def func(self, term, key, module="numpy"):
        ck = (term, key, module)
        if ck not in self._cache:
            t0 = time.time()
            args = COUPLED_ARGS if term == "w8" else TERM_ARGS
            self._cache[ck] = sp.lambdify(args, self.exprs(term, key), modules=module, cse=True)
            self.compile_time += time.time() - t0
        return self._cache[ck]


def term_param_values(tp):
    """Numeric values of (C_ini, S_ini, C_mid, dS_mid, C_lock, I_lock); missing ones
    are unused by the selected branch, given a harmless placeholder."""
    return [tp["c_ini"],
            tp["s_ini"] if tp["s_ini"] is not None else 1.0,
            tp["c_mid"] if tp["c_mid"] is not None else 1.0,
            tp["delta_s_mid"] if tp["delta_s_mid"] is not None else 1.0,
            tp["c_lock"] if tp["c_lock"] is not None else 0.0,
            tp["i_lock"] if tp["i_lock"] is not None else 1.0]


# --------------------------------------------------------------------------
# Numeric invariants and branch classification.
# --------------------------------------------------------------------------


def invariants(C, th_deg):
    """C: (N,2,2) array, th_deg: (N,). Returns dict of arrays."""
    th = np.radians(th_deg)
    c, s = np.cos(th), np.sin(th)
    a = np.stack([c, s], axis=1)
    b = np.stack([-s, c], axis=1)
    I4 = np.einsum("ni,nij,nj->n", a, C, a)
    I6 = np.einsum("ni,nij,nj->n", a, C, b)
    I8 = np.einsum("ni,nij,nj->n", b, C, b)
    I11 = np.sqrt((I4 * I8 - I6 ** 2) / I4)
    I10 = np.pi / 2 - np.arccos(I6 / np.sqrt(I4 * I8))
    return dict(I4=I4, I6=I6, I8=I8, I10=I10, I11=I11, cos=c, sin=s)


def region_of(x, tp):
    return "mid" if x >= x_t(tp) else "ini"


def classify(inv, params):
    """Per state: the branch key of each term (None = term inactive)."""
    n = len(inv["I4"])
    keys = {t: [None] * n for t in TERMS}
    for i in range(n):
        I4, I6, I8, I11 = inv["I4"][i], inv["I6"][i], inv["I8"][i], inv["I11"][i]
        x4 = abs(I4 - 1)
        keys["w4"][i] = (1 if I4 > 1 else -1, region_of(x4, params["w4"]),
                         bool(x4 >= i_lock(params["w4"])))
        x6 = abs(I6)
        keys["w6"][i] = (1 if I6 > 0 else -1, region_of(x6, params["w6"]),
                         bool(x6 >= i_lock(params["w6"])))
        if I8 > 1:
            x8 = I8 - 1
            keys["w8"][i] = (region_of(x8, params["w8"]), bool(x8 >= i_lock(params["w8"])),
                             "k=1" if I11 >= 1 else "k<1")
        if I11 < 1:
            x11 = 1 - I11
            keys["w11"][i] = (region_of(x11, params["w11"]), bool(x11 >= i_lock(params["w11"])))
    return keys


def boundary_distance(inv, params):
    """Smallest relative distance of each state to any branch boundary."""
    d = [np.abs(inv["I4"] - 1), np.abs(inv["I6"]), np.abs(inv["I8"] - 1),
         np.abs(inv["I11"] - 1)]
    xs = {"w4": np.abs(inv["I4"] - 1), "w6": np.abs(inv["I6"]),
          "w8": inv["I8"] - 1, "w11": 1 - inv["I11"]}
    for t in TERMS:
        for thr in (x_t(params[t]), i_lock(params[t])):
            if math.isfinite(thr):
                d.append(np.abs(xs[t] - thr) / thr)
    return np.min(np.stack(d), axis=0)


def reference(law, C, th_deg, params, module="numpy"):
    """W, S (N,2,2), tangent (N,2,2,2,2), invariants, branch keys."""
    inv = invariants(C, th_deg)
    keys = classify(inv, params)
    n = C.shape[0]
    acc = np.zeros((n, 10))
    coupling = [params["coupling"][k] for k in ("k_min", "s11", "e11")]
    for t in TERMS:
        pv = term_param_values(params[t]) + (coupling if t == "w8" else [])
        for key in sorted(set(k for k in keys[t] if k is not None), key=repr):
            idx = np.array([i for i in range(n) if keys[t][i] == key])
            f = law.func(t, key, module)
            if module == "numpy":
                out = f(C[idx, 0, 0], C[idx, 0, 1], C[idx, 1, 1],
                        inv["cos"][idx], inv["sin"][idx], *pv)
                acc[idx] += np.stack([np.broadcast_to(np.asarray(o, float), idx.shape) for o in out],
                                     axis=1)
            else:  # mpmath, state by state, at the current mpmath precision
                for i in idx:
                    mp_args = [mpmath.mpf(float(v)) for v in
                               (C[i, 0, 0], C[i, 0, 1], C[i, 1, 1], inv["cos"][i], inv["sin"][i])]
                    out = f(*mp_args, *[mpmath.mpf(v) for v in pv])
                    acc[i] += np.array([float(o) for o in out])
    W, grad, hess6 = acc[:, 0], acc[:, 1:4], acc[:, 4:10]
    S, T = assemble(grad, hess6)
    return W, S, T, inv, keys


def assemble(grad, hess6):
    """Apply the convention D11 = 2 d/dc11, D22 = 2 d/dc22, D12 = D21 = d/dc12."""
    n = grad.shape[0]
    H = np.zeros((n, 3, 3))
    for m, (a, b) in enumerate(HPAIRS):
        H[:, a, b] = hess6[:, m]
        H[:, b, a] = hess6[:, m]
    comp = {(0, 0): 0, (0, 1): 1, (1, 0): 1, (1, 1): 2}
    wgt = {(0, 0): 2.0, (0, 1): 1.0, (1, 0): 1.0, (1, 1): 2.0}
    S = np.zeros((n, 2, 2))
    T = np.zeros((n, 2, 2, 2, 2))
    for ij, a in comp.items():
        S[:, ij[0], ij[1]] = wgt[ij] * grad[:, a]
        for kl, b in comp.items():
            T[:, ij[0], ij[1], kl[0], kl[1]] = wgt[ij] * wgt[kl] * H[:, a, b]
    return S, T


# --------------------------------------------------------------------------
# State generator.
# --------------------------------------------------------------------------


def term_xmax(tp, floor, cap=math.inf):
    """Generator range for a term's x: 1.5x its largest reachable threshold."""
    thr = [v for v in (x_t(tp), i_lock(tp)) if math.isfinite(v) and v < cap]
    return min(max([floor] + [1.5 * v for v in thr]), cap)


def generator_ranges(params):
    return dict(
        w4=term_xmax(params["w4"], 0.01),
        w6=term_xmax(params["w6"], 0.3, 0.9),
        w8=term_xmax(params["w8"], 0.2),
        w11=term_xmax(params["w11"], 0.35, 0.8),
    )


def generate_states(params, n, rng):
    """Random (C, theta) covering all branches; boundary states excluded."""
    R = generator_ranges(params)

    def draw(xmax, size):  # half uniform, half log-uniform (dense near 0)
        u = rng.uniform(0, xmax, size)
        lg = xmax * 10 ** rng.uniform(-3, 0, size)
        return np.where(rng.random(size) < 0.5, u, lg)

    Cs, ths = [], []
    need = n
    while need > 0:
        m = 4 * need + 200
        th = rng.uniform(0.0, 180.0, m)
        I4 = 1 + np.where(rng.random(m) < 0.5, 1, -1) * draw(R["w4"], m)
        I8 = np.where(rng.random(m) < 0.25, 1 - rng.uniform(0, 0.25, m), 1 + draw(R["w8"], m))
        mode = rng.random(m)
        sgn6 = np.where(rng.random(m) < 0.5, 1.0, -1.0)
        # mode A (40%): pick |I6| in W6's range
        I6a = sgn6 * draw(R["w6"], m)
        # mode B (40%): pick 1 - I11 in W11's range (and a little below 0)
        I11b = 1 - rng.uniform(-0.1, R["w11"], m)
        I6b = sgn6 * np.sqrt(np.clip(I4 * (I8 - I11b ** 2), 0, None))
        okb = I11b ** 2 < I8
        # mode C (20%): I11 > 1 (needs I8 > 1)
        I11c = 1 + rng.uniform(0, 1, m) * (np.sqrt(np.maximum(I8, 1)) - 1)
        I6c = sgn6 * np.sqrt(np.clip(I4 * (I8 - I11c ** 2), 0, None))
        I6 = np.where(mode < 0.4, I6a, np.where(mode < 0.8, I6b, I6c))
        ok = np.where(mode < 0.4, True, np.where(mode < 0.8, okb, I8 > 1))
        # positive definite and not too close to collapse (I11 > 0.15)
        ok &= (I4 * I8 - I6 ** 2) / I4 > 0.15 ** 2
        t = np.radians(th)
        a = np.stack([np.cos(t), np.sin(t)], 1)
        b = np.stack([-np.sin(t), np.cos(t)], 1)
        Rm = np.stack([a, b], axis=2)  # columns a0, b0
        Cf = np.stack([np.stack([I4, I6], 1), np.stack([I6, I8], 1)], 1)
        C = np.einsum("nij,njk,nlk->nil", Rm, Cf, Rm)
        C[:, 1, 0] = C[:, 0, 1]  # exactly symmetric
        C, th = C[ok], th[ok]
        inv = invariants(C, th)
        keep = boundary_distance(inv, params) > BOUNDARY_MARGIN
        Cs.append(C[keep][:need])
        ths.append(th[keep][:need])
        need -= len(ths[-1])
    return np.concatenate(Cs), np.concatenate(ths)


def branch_counts(inv, keys, th, params):
    """Counts per branch label, and the list of labels that must be hit."""
    R = generator_ranges(params)
    counts = {}

    def add(label, mask):
        counts[label] = counts.get(label, 0) + int(np.sum(mask))

    required = []
    for t, lab in (("w4", "W4"), ("w6", "W6"), ("w8", "W8"), ("w11", "W11")):
        tp = params[t]
        ks = keys[t]
        ri = {"w4": 1, "w6": 1, "w8": 0, "w11": 0}[t]  # position of region in key
        li = ri + 1                                    # position of lock flag
        add(f"{lab} initial region", [k is not None and k[ri] == "ini" for k in ks])
        add(f"{lab} middle region", [k is not None and k[ri] == "mid" for k in ks])
        add(f"{lab} lock", [k is not None and k[li] for k in ks])
        required.append(f"{lab} initial region")
        if x_t(tp) < R[t]:
            required.append(f"{lab} middle region")
        if i_lock(tp) < R[t]:
            required.append(f"{lab} lock")
    I4, I6, I8, I11 = inv["I4"], inv["I6"], inv["I8"], inv["I11"]
    for label, mask in (("I4 > 1", I4 > 1), ("I4 < 1", I4 < 1),
                        ("I6 > 0", I6 > 0), ("I6 < 0", I6 < 0),
                        ("I8 < 1 (W8 off)", I8 < 1), ("I8 > 1 (W8 on)", I8 > 1),
                        ("I11 > 1 (W11 off, k11 = 1)", I11 > 1),
                        ("I11 < 1 (W11 on)", I11 < 1),
                        ("I8 > 1 and I11 < 1 (k11 < 1 coupling)", (I8 > 1) & (I11 < 1)),
                        ("I8 > 1 and I11 > 1", (I8 > 1) & (I11 > 1))):
        add(label, mask)
        required.append(label)
    for lo in range(0, 180, 45):
        label = f"angle in [{lo}, {lo + 45}) deg"
        add(label, (th >= lo) & (th < lo + 45))
        required.append(label)
    return counts, required


# --------------------------------------------------------------------------
# Running ncform.
# --------------------------------------------------------------------------


def state_line(C, th):
    return json.dumps({"C": [[float(C[0, 0]), float(C[0, 1])], [float(C[1, 0]), float(C[1, 1])]],
                       "fiber_angle_deg": float(th)})


def run_ncform(binary, params_arg, text, timeout=120):
    if not binary or not os.access(binary, os.X_OK):
        raise RuntimeError(f"ncform binary not available: {binary!r}")
    cmd = [binary, "material", "eval"] + (["--params", params_arg] if params_arg else [])
    p = subprocess.run(cmd, input=text, capture_output=True, text=True, timeout=timeout)
    return p.returncode, p.stdout, p.stderr, cmd


def parse_outputs(stdout):
    return [json.loads(l) for l in stdout.splitlines() if l.strip()]


def ncform_arrays(objs):
    n = len(objs)
    W = np.array([o.get("W") for o in objs], dtype=float)
    S = np.array([o.get("S") for o in objs], dtype=float).reshape(n, 2, 2)
    T = np.array([o.get("tangent") for o in objs], dtype=float).reshape(n, 2, 2, 2, 2)
    inv = {k: np.array([o.get("invariants", {}).get(k) for o in objs], dtype=float)
           for k in ("I4", "I6", "I8", "I10", "I11")}
    return W, S, T, inv


def voigt(T):
    """3x3 Voigt view (11, 22, 12) of a 2x2x2x2 tangent, for messages."""
    idx = [(0, 0), (1, 1), (0, 1)]
    return [[float(T[i][j][k][l]) for (k, l) in idx] for (i, j) in idx]


def describe_state(i, C, th, inv, keys):
    br = {t: keys[t][i] for t in TERMS}
    return (f"state #{i}: C = {C[i].tolist()}, fiber_angle_deg = {th[i]!r}\n"
            f"  I4={inv['I4'][i]!r} I6={inv['I6'][i]!r} I8={inv['I8'][i]!r} "
            f"I11={inv['I11'][i]!r}\n  branches: {br}")


# --------------------------------------------------------------------------
# Checks.
# --------------------------------------------------------------------------


class SetContext:
    """One parameter set: states, reference, and ncform's answers (cached)."""

    def __init__(self, label, params, params_arg, law, binary, n_states, rng):
        self.label = label
        self.params = params
        self.params_arg = params_arg
        self.law = law
        self.binary = binary
        t0 = time.time()
        self.C, self.th = generate_states(params, n_states, rng)
        self.W, self.S, self.T, self.inv, self.keys = reference(law, self.C, self.th, params)
        self.ref_time = time.time() - t0
        self._ncform = None

    def ncform(self):
        if self._ncform is None:
            text = "\n".join(state_line(c, t) for c, t in zip(self.C, self.th)) + "\n"
            rc, out, err, cmd = run_ncform(self.binary, self.params_arg, text)
            objs = parse_outputs(out)
            bad = [o for o in objs if "error" in o]
            if rc != 0 or len(objs) != len(self.th) or bad:
                raise RuntimeError(
                    f"{' '.join(cmd)} on {len(self.th)} valid states: exit {rc}, "
                    f"{len(objs)} output lines, {len(bad)} errors "
                    f"(first: {bad[:1]}), stderr: {err[-500:]!r}")
            self._ncform = ncform_arrays(objs)
        return self._ncform

    def compare(self, what):
        W, S, T, inv = self.ncform()
        if what == "W":
            ref, got = self.W, W
            err = np.abs(got - ref) / np.maximum(np.abs(ref), 1e-30)
        elif what == "S":
            ref, got = self.S, S
            err = (np.linalg.norm((got - ref).reshape(len(ref), -1), axis=1)
                   / np.linalg.norm(ref.reshape(len(ref), -1), axis=1))
        else:
            ref, got = self.T, T
            err = (np.linalg.norm((got - ref).reshape(len(ref), -1), axis=1)
                   / np.linalg.norm(ref.reshape(len(ref), -1), axis=1))
        err = np.where(np.isnan(err), np.inf, err)
        nbad = int(np.sum(err > REL_TOL))
        detail = f"max relative error {np.max(err):.3e} over {len(err)} states"
        if nbad:
            detail += f"; {nbad} states exceed {REL_TOL:g}. Worst:"
            for i in np.argsort(-err)[:3]:
                detail += "\n" + describe_state(i, self.C, self.th, self.inv, self.keys)
                detail += f"\n  rel err {err[i]:.3e}"
                if what == "T":
                    detail += (f"\n  sympy  tangent (Voigt 11,22,12) = {voigt(ref[i])}"
                               f"\n  ncform tangent (Voigt 11,22,12) = {voigt(got[i])}")
                else:
                    detail += (f"\n  sympy  {what} = {np.asarray(ref[i]).tolist()}"
                               f"\n  ncform {what} = {np.asarray(got[i]).tolist()}")
            # which branches do the failures fall in?
            bad_br = {}
            for i in np.nonzero(err > REL_TOL)[0]:
                k = repr({t: self.keys[t][i] for t in TERMS})
                bad_br[k] = bad_br.get(k, 0) + 1
            detail += "\n  failing branch combinations (count):"
            for k, v in sorted(bad_br.items(), key=lambda kv: -kv[1])[:8]:
                detail += f"\n    {v:5d}  {k}"
        return nbad == 0, detail

    def compare_invariants(self):
        _, _, _, inv = self.ncform()
        scale = np.linalg.norm(self.C.reshape(len(self.C), -1), axis=1)
        worst, lines, ok = 0.0, [], True
        for k in ("I4", "I6", "I8", "I10", "I11"):
            ref, got = self.inv[k], inv[k]
            err = np.abs(got - ref) / np.maximum(np.abs(ref), scale)
            err = np.where(np.isnan(err), np.inf, err)
            worst = max(worst, float(np.max(err)))
            nbad = int(np.sum(err > INV_TOL))
            if nbad:
                ok = False
                i = int(np.argmax(err))
                lines.append(f"{k}: {nbad} states exceed {INV_TOL:g}; worst state #{i}: "
                             f"reference {ref[i]!r}, ncform {got[i]!r}")
        return ok, f"max relative error {worst:.3e}\n" + "\n".join(lines)

    def symmetries(self):
        _, S, T, _ = self.ncform()
        n = len(T)
        nT = np.linalg.norm(T.reshape(n, -1), axis=1)
        nS = np.linalg.norm(S.reshape(n, -1), axis=1)
        errs = {
            "S12 = S21": np.abs(S[:, 0, 1] - S[:, 1, 0]) / nS,
            "minor C_ijkl = C_jikl": np.linalg.norm((T - T.transpose(0, 2, 1, 3, 4)).reshape(n, -1), axis=1) / nT,
            "minor C_ijkl = C_ijlk": np.linalg.norm((T - T.transpose(0, 1, 2, 4, 3)).reshape(n, -1), axis=1) / nT,
            "major C_ijkl = C_klij": np.linalg.norm((T - T.transpose(0, 3, 4, 1, 2)).reshape(n, -1), axis=1) / nT,
        }
        ok, lines = True, []
        for name, e in errs.items():
            e = np.where(np.isnan(e), np.inf, e)
            lines.append(f"{name}: max relative asymmetry {np.max(e):.3e}")
            if np.max(e) > SYM_TOL:
                ok = False
                i = int(np.argmax(e))
                lines.append(f"  worst state #{i}: S = {S[i].tolist()}, tangent (Voigt) = {voigt(T[i])}, "
                             f"full = {T[i].tolist()}")
        return ok, "\n".join(lines)


def check_model_self_consistency(law, contexts):
    """Checks of the reference itself (no ncform involved)."""
    lines = []
    ok = True
    x = sp.Symbol("x", positive=True)
    xt = SI / CI
    # (1) G as written in docs/theory.md integrates f of Eq. (12): dG/dx == f.
    c = CI / DS
    y = x - xt
    f_mid = SI + (CM * y + DS) * (1 - sp.exp(-c * y))
    d1 = sp.simplify(sp.diff(G_sym(x, "mid", False), x) - f_mid)
    d2 = sp.simplify(sp.diff(G_sym(x, "ini", False), x) - CI * x)
    d3 = sp.simplify(sp.diff(G_sym(x, "mid", True) - G_sym(x, "mid", False), x) - CL * (x - IL) ** 2)
    lines.append(f"dG/dx - f (mid, ini, lock) simplify to {d1}, {d2}, {d3}")
    ok &= d1 == 0 and d2 == 0 and d3 == 0
    # (2) G, G' and G'' continuous at x_t (f is C1 there by construction).
    for order in range(3):
        jump = sp.simplify((sp.diff(G_sym(x, "mid", False), x, order)
                            - sp.diff(G_sym(x, "ini", False), x, order)).subs(x, xt))
        lines.append(f"jump of d^{order}G/dx^{order} at x_t: {jump}")
        ok &= jump == 0
    # (3) the convention D_ij on textbook energies: W = 1/2 tr(C^2) -> S = 2C, C_ijkl = 4 I_sym
    Wt = (c11 ** 2 + 2 * c12 ** 2 + c22 ** 2) / 2
    g = np.array([[float(sp.diff(Wt, v).subs({c11: 1.3, c12: 0.2, c22: 0.7})) for v in CVARS]])
    h = np.array([[float(sp.diff(Wt, CVARS[a], CVARS[b])) for a, b in HPAIRS]])
    S, T = assemble(g, h)
    Iden = np.eye(2)
    Isym = 0.5 * (np.einsum("ik,jl->ijkl", Iden, Iden) + np.einsum("il,jk->ijkl", Iden, Iden))
    conv_ok = np.allclose(S[0], 2 * np.array([[1.3, 0.2], [0.2, 0.7]])) and np.allclose(T[0], 4 * Isym)
    lines.append(f"convention on W = tr(C^2)/2 (S = 2C, tangent = 4 I_sym): {conv_ok}")
    ok &= conv_ok
    # (4) numpy reference vs 40-digit mpmath at a sample of states per set
    # (covers every branch key used), and (5) central differences W -> S -> tangent.
    mpmath.mp.dps = 40
    for ctx in contexts:
        n = len(ctx.th)
        pick = set()
        seen = set()
        for i in range(n):
            k = tuple(ctx.keys[t][i] for t in TERMS)
            if k not in seen:
                seen.add(k)
                pick.add(i)
        rng = np.random.default_rng(SEED + 1)
        pick |= set(rng.choice(n, size=min(20, n), replace=False).tolist())
        idx = np.array(sorted(pick))
        Wm, Sm, Tm, _, _ = reference(law, ctx.C[idx], ctx.th[idx], ctx.params, module="mpmath")
        eW = np.max(np.abs(ctx.W[idx] - Wm) / np.abs(Wm))
        eS = np.max(np.linalg.norm((ctx.S[idx] - Sm).reshape(len(idx), -1), axis=1)
                    / np.linalg.norm(Sm.reshape(len(idx), -1), axis=1))
        eT = np.max(np.linalg.norm((ctx.T[idx] - Tm).reshape(len(idx), -1), axis=1)
                    / np.linalg.norm(Tm.reshape(len(idx), -1), axis=1))
        good = max(eW, eS, eT) <= REF_SELF_TOL
        ok &= good
        lines.append(f"{ctx.label}: numpy vs mpmath(40 digits) at {len(idx)} states "
                     f"({len(seen)} branch combinations): W {eW:.1e}, S {eS:.1e}, "
                     f"tangent {eT:.1e} (limit {REF_SELF_TOL:g})")
        # central differences on states well away from boundaries
        dist = boundary_distance(ctx.inv, ctx.params)
        cand = np.nonzero(dist > 1e-4)[0][:40]
        h = 1e-7
        worst_s = worst_t = 0.0
        for i in cand:
            gfd = np.zeros(3)
            hfd = np.zeros((3, 2, 2))
            for a, (p, q) in enumerate([(0, 0), (0, 1), (1, 1)]):
                Cp = ctx.C[i].copy()
                Cm_ = ctx.C[i].copy()
                Cp[p, q] += h
                Cm_[p, q] -= h
                if p != q:
                    Cp[q, p] += h
                    Cm_[q, p] -= h
                Wp, Sp, _, _, _ = reference(law, Cp[None], ctx.th[i:i + 1], ctx.params)
                Wn, Sn, _, _, _ = reference(law, Cm_[None], ctx.th[i:i + 1], ctx.params)
                gfd[a] = (Wp[0] - Wn[0]) / (2 * h)
                hfd[a] = (Sp[0] - Sn[0]) / (2 * h)
            wgt = np.array([2.0, 1.0, 2.0])
            S_fd = np.array([[2 * gfd[0], gfd[1]], [gfd[1], 2 * gfd[2]]])
            worst_s = max(worst_s, np.linalg.norm(S_fd - ctx.S[i]) / np.linalg.norm(ctx.S[i]))
            T_fd = np.zeros((2, 2, 2, 2))
            for a, (p, q) in enumerate([(0, 0), (0, 1), (1, 1)]):
                T_fd[:, :, p, q] = wgt[a] * hfd[a]
                T_fd[:, :, q, p] = wgt[a] * hfd[a]
            worst_t = max(worst_t, np.linalg.norm(T_fd - ctx.T[i]) / np.linalg.norm(ctx.T[i]))
        good = len(cand) >= 20 and worst_s < 1e-5 and worst_t < 1e-5
        ok &= good
        lines.append(f"{ctx.label}: central differences (h = 1e-7) at {len(cand)} states: "
                     f"W->S {worst_s:.1e}, S->tangent {worst_t:.1e} (limit 1e-5)")
    return bool(ok), "\n".join(lines)


def check_coverage(ctx):
    counts, required = branch_counts(ctx.inv, ctx.keys, ctx.th, ctx.params)
    missing = [r for r in required if counts.get(r, 0) == 0]
    lines = [f"{len(ctx.th)} states, seed {SEED}, boundary margin {BOUNDARY_MARGIN:g}"]
    for label, v in counts.items():
        note = "" if label in required else "   (not reachable with these parameters, not required)"
        lines.append(f"{v:6d}  {label}{note}")
    if missing:
        lines.append(f"MISSING branches: {missing}")
    return not missing, "\n".join(lines)


def good_line(th=30.0):
    return json.dumps({"C": [[1.02, 0.05], [0.05, 1.1]], "fiber_angle_deg": th})


def check_rejects(binary, law, bad_lines):
    """Good lines around the bad ones: bad ones give an error object in place,
    the good ones are answered correctly, exit status non-zero."""
    lines = [good_line(10.0)] + bad_lines + [good_line(100.0)]
    rc, out, err, cmd = run_ncform(binary, "schaefer2024", "\n".join(lines) + "\n")
    objs = [json.loads(l) for l in out.splitlines() if l.strip()]
    msgs = [f"input: {lines}", f"exit {rc}; stdout lines {len(objs)}; stderr {err.strip()[:300]!r}"]
    ok = rc != 0 and len(objs) == len(lines) and bool(err.strip())
    if len(objs) == len(lines):
        for n, o in enumerate(objs[1:-1], start=2):
            if not (isinstance(o, dict) and o.get("line") == n and isinstance(o.get("error"), str)
                    and "W" not in o):
                ok = False
                msgs.append(f"line {n}: expected {{\"line\": {n}, \"error\": ...}}, got {o}")
        C = np.array([[[1.02, 0.05], [0.05, 1.1]]] * 2)
        W, _, _, _, _ = reference(law, C, np.array([10.0, 100.0]), _default())
        for pos, wref in ((0, W[0]), (-1, W[1])):
            o = objs[pos]
            if not (isinstance(o, dict) and isinstance(o.get("W"), float)
                    and abs(o["W"] - wref) <= REL_TOL * abs(wref)):
                ok = False
                msgs.append(f"good line answered wrongly: {o} (expected W = {wref!r})")
    else:
        msgs.append(f"stdout: {out[:1000]!r}")
    return ok, "\n".join(msgs)


def check_blank_lines(binary):
    text = good_line(0.0) + "\n\n   \n" + good_line(45.0) + "\n\n"
    rc, out, err, _ = run_ncform(binary, "schaefer2024", text)
    objs = [json.loads(l) for l in out.splitlines() if l.strip()]
    ok = rc == 0 and len(objs) == 2 and all("W" in o for o in objs)
    return ok, f"exit {rc}, {len(objs)} answers for 2 non-blank lines; stderr {err.strip()[:200]!r}"


def check_default_params(binary, ctx):
    text = "\n".join(state_line(c, t) for c, t in zip(ctx.C[:50], ctx.th[:50])) + "\n"
    rc0, out0, err0, _ = run_ncform(binary, None, text)
    rc1, out1, err1, _ = run_ncform(binary, "schaefer2024", text)
    o0, o1 = parse_outputs(out0), parse_outputs(out1)
    ok = (rc0 == 0 and rc1 == 0 and len(o0) == 50 and o0 == o1
          and not any("error" in o for o in o0))
    return ok, f"exit {rc0} (no --params) / {rc1} (--params schaefer2024); identical: {out0 == out1}"


def check_shipped_toml(binary, ctx, name):
    path = os.path.join(REPO, "cases", "materials", f"{name}.toml")
    if not os.path.exists(path):
        return False, f"{path} missing"
    text = "\n".join(state_line(c, t) for c, t in zip(ctx.C[:200], ctx.th[:200])) + "\n"
    rc0, out0, _, _ = run_ncform(binary, name, text)
    rc1, out1, err1, _ = run_ncform(binary, path, text)
    o0, o1 = parse_outputs(out0), parse_outputs(out1)
    ok = (rc0 == 0 and rc1 == 0 and len(o0) == 200 and o0 == o1
          and not any("error" in o for o in o0))
    return ok, f"{len(o0)}/{len(o1)} answers to 200 lines; exit {rc0} (named) / {rc1} (file); identical answers: {ok}; stderr {err1.strip()[:200]!r}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--ncform", default=os.path.join(REPO, "target", "release", "ncform"),
                    help="path of the ncform binary")
    ap.add_argument("--states", type=int, default=3000, help="states per parameter set")
    args = ap.parse_args()
    t_start = time.time()
    hx = Harness()
    law = SymbolicLaw()
    rng = np.random.default_rng(SEED)
    tmp = tempfile.mkdtemp(prefix="ncform-verify-")
    balanced_path = os.path.join(tmp, "balanced.toml")
    write_toml(_balanced(), balanced_path, "verification-balanced")

    sets = [("schaefer2024", _default(), "schaefer2024"),
            ("schaefer2024-printed", _printed(), "schaefer2024-printed"),
            ("balanced-toml", _balanced(), balanced_path)]
    contexts = []
    for label, params, arg in sets:
        ctx = SetContext(label, params, arg, law, args.ncform, args.states, rng)
        contexts.append(ctx)
        print(f"# {label}: {len(ctx.th)} states, sympy reference in {ctx.ref_time:.1f}s "
              f"(cumulative lambdify {law.compile_time:.1f}s)")
    sys.stdout.flush()

    hx.run("law/reference-self-check",
           "the sympy reference follows docs/theory.md (dG/dx = f of Eq. 12, G in C2 at x_t, "
           "derivative convention) and is accurate to 1e-10 (mpmath) and consistent (finite differences)",
           lambda: check_model_self_consistency(law, contexts))
    for ctx in contexts:
        n = len(ctx.th)
        L = ctx.label
        hx.run(f"law/coverage/{L}", f"every branch of the law is hit by the {n} states, set {L}",
               lambda ctx=ctx: check_coverage(ctx))
        hx.run(f"law/invariants/{L}", f"I4, I6, I8, I10, I11 match to {INV_TOL:g} at {n} states, set {L}",
               lambda ctx=ctx: ctx.compare_invariants())
        hx.run(f"law/W/{L}", f"W matches the energy of docs/theory.md to {REL_TOL:g} at {n} states, set {L}",
               lambda ctx=ctx: ctx.compare("W"))
        hx.run(f"law/S/{L}", f"S = 2 dW/dC matches sympy to {REL_TOL:g} at {n} states, set {L}",
               lambda ctx=ctx: ctx.compare("S"))
        hx.run(f"law/tangent/{L}", f"tangent = 4 d2W/dCdC matches sympy to {REL_TOL:g} at {n} states, set {L}",
               lambda ctx=ctx: ctx.compare("T"))
        hx.run(f"law/symmetry/{L}", f"ncform's S is symmetric and its tangent has minor and major "
               f"symmetry (to {SYM_TOL:g}) at {n} states, set {L}",
               lambda ctx=ctx: ctx.symmetries())

    b = args.ncform
    hx.run("eval/default-params", "without --params, `material eval` uses schaefer2024",
           lambda: check_default_params(b, contexts[0]))
    for name, ctx in (("schaefer2024", contexts[0]), ("schaefer2024-printed", contexts[1])):
        hx.run(f"eval/shipped-toml/{name}",
               f"--params cases/materials/{name}.toml answers exactly as the named set {name}",
               lambda name=name, ctx=ctx: check_shipped_toml(b, ctx, name))
    hx.run("eval/reject-det-negative",
           "a line with det C < 0 gives an error object in place, other lines answered, exit non-zero",
           lambda: check_rejects(b, law, [json.dumps({"C": [[1.0, 2.0], [2.0, 1.0]], "fiber_angle_deg": 0.0})]))
    hx.run("eval/reject-det-zero",
           "a line with det C = 0 gives an error object in place, other lines answered, exit non-zero",
           lambda: check_rejects(b, law, [json.dumps({"C": [[1.0, 1.0], [1.0, 1.0]], "fiber_angle_deg": 20.0})]))
    hx.run("eval/reject-not-positive-definite",
           "C = -I (det > 0 but I4 < 0: inverted) gives an error object, never NaN; exit non-zero",
           lambda: check_rejects(b, law, [json.dumps({"C": [[-1.0, 0.0], [0.0, -1.0]], "fiber_angle_deg": 0.0})]))
    hx.run("eval/reject-malformed",
           "a malformed JSON line and a line without C give error objects in place, "
           "other lines answered, exit non-zero",
           lambda: check_rejects(b, law, ['{"C": [[1.0, 0.0], [0.0, 1.0]], "fiber_angle_deg": ',
                                          '{"fiber_angle_deg": 0.0}']))
    hx.run("eval/blank-lines", "blank lines are skipped, exit status 0 when all lines are good",
           lambda: check_blank_lines(b))
    print(f"# verify_law total time {time.time() - t_start:.1f}s")
    hx.summary()
    return 0 if hx.failed == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
