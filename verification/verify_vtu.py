#!/usr/bin/env python3
"""Every VTU file that `ncform run` writes, read back with meshio and recomputed.

What this checks
================
ncform's OAT writes `oat.pvd` (a ParaView collection) and one VTK XML
unstructured grid per output displacement, `vtu/oat_dXXX.XXX.vtu` (ASCII):
points = DEFORMED positions, point field `displacement` [mm], cell fields
`E22`, `shear_angle_deg`, `E_perp`, `I4`, `I6`, `I8`, `I11`, `k11`,
`energy_density`, the 2nd Piola-Kirchhoff stress `S` in global axes
(3 components xx, yy, xy; the array is named `S_xx_yy_xy` so that the order
is visible in ParaView -- a plain `S` is accepted too), `zone` (0/1/2 =
A/B/C) and `mdz` (0/1).

The suite runs ncform on the coarse cases of verify_oat.py (45 deg to 80 mm,
30 deg to 40 mm) and on a coarse 90 deg case (rovings across the load axis:
no zone A, so the MDZ falls back to the centre window), reads every VTU listed
in each `oat.pvd` with meshio, and checks per case:

* `pvd`: the collection lists exactly the requested output displacements plus
  the final one, increasing; each file exists, the displacement in its name
  (oat_dXXX.XXX) equals its timestep, its own comment "clamp displacement d mm"
  agrees, and no VTU in vtu/ is left out.
* `structure`: meshio reads each file; one block of triangles only; point and
  cell counts equal summary.json's and are the same in every file; every point
  is used; every field present with the right shape (scalars (n,) or (n,1),
  displacement (points, 3), S (cells, 3), zone/mdz integer); all values finite.
* `reference-mesh`: reference = points - displacement is the same in every
  file (to 1e-12 L: two roundings of coordinates <= 400 mm are ~1e-13), fills
  the rectangle [0, W] x [0, L] at z = 0 (bounding box to 1e-9 mm, total area
  W L to 1e-12 relative), every triangle has positive area; displacement and
  deformed z are 0 (the test is in-plane).
* `clamps`: nodes at y = 0 have zero displacement, nodes at y = L have
  (0, d, 0) with d the timestep (to 1e-12 relative: the boundary values are
  prescribed, only round-off allowed).
* `invariants`: from reference and deformed coordinates alone (this file):
  per triangle, n = unit normal (oriented to +z), a = a0 projected on the
  element plane and normalised (a0 = (sin th, cos th, 0)), b = n x a,
  F = (deformed edges) (reference edges in the (a, b) basis)^-1, C = F^T F;
  I4 = C_aa, I6 = C_ab, I8 = C_bb, I11 = sqrt(det C / I4). Tolerance
  |diff| <= 1e-9 max(|ref|, ||C||_F): the brief's 1e-9 relative, with
  ||C||_F as the scale where an invariant is ~0 (I6 in the clamp zones),
  since invariants are bilinear forms of C with unit vectors and their
  round-off scales with ||C||. Actual round-off: ~1e-13 (coordinates
  differenced over 10 mm edges).
* `strain-measures`: E22 = I8 - 1, E_perp = I11 - 1 (scale max(|ref|, ||C||_F),
  they are differences of the invariants), shear_angle_deg =
  degrees(pi/2 - arccos(I6 / sqrt(I4 I8))) (scale max(|ref|, 1 rad in deg)),
  all to 1e-9, from the recomputed invariants (docs/theory.md, "Strain measures").
* `law-fields` (beyond the brief, cheap): k11, energy_density and S equal the
  numpy law of verify_oat.py (docs/theory.md) at the recomputed C, to 1e-8
  relative -- the law requirement -- plus a round-off floor
  ||tangent|| * dC, dC = 8 eps max|x| / (shortest edge) the error of C from
  coordinates written in f64 (the roving modulus 1000 MPa amplifies it);
  energy_density >= 0.
* `zones`: zone in {0, 1, 2}, the same in every file, and equal to the
  two-family reading recomputed here from the reference centroid: the roving
  line and the stitching line through it each either end on a clamp edge
  (y = 0 or y = L) or not; A = neither does, C = both do, B = one does (this is
  the reading whose pin-jointed-net zone areas docs/verification.md (the pin-jointed net) gives;
  elements within 1e-9 mm of a zone boundary are skipped). Zone areas are
  reported next to the net's W(L - 1.5W), W^2, W^2/2 for 45 deg.
* `mdz`: mdz in {0, 1}, the same in every file, not empty; mdz elements only in
  zone 0 (A) unless zone A is empty; and equal to the recomputation (zone A
  elements whose centroid lies in the 20 x 20 mm window at the specimen centre,
  docs/cases.md; the window alone when that set is empty).
* `units`: the VTU and pvd XML comments state the units (mm, and N and MPa in
  the VTU), the CSV files carry a `# units:` comment line with mm and N, the
  force CSV header is `displacement [mm],force [N],iterations [-]`, and
  summary.json has a `units` entry.

Usage: verify_vtu.py --ncform PATH [--keep DIR]
"""

import argparse
import glob
import json
import math
import os
import re
import shutil
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, HERE)

from verify_law import Harness  # noqa: E402  (the PASS/FAIL protocol only)
from verify_oat import (CASES, LENGTH, WIDTH, law, params_schaefer2024,  # noqa: E402
                        read_force_csv, read_pvd, run_case, tangent_fd)

INV_TOL = 1e-9       # brief: invariants and strain measures to 1e-9 relative
LAW_TOL = 1e-8       # law requirement (as in verify_law.py)
REF_TOL = 1e-12      # reference coordinates / clamp values: round-off only
MDZ_SIZE = 20.0      # docs/cases.md (ncform's default; not set in the case files)
EPS = np.finfo(float).eps

VTU_CASES = dict(CASES)
VTU_CASES["oat90"] = (90.0, 4.0, [2.0])    # no zone A: the MDZ is the centre window

SCALARS = ("E22", "shear_angle_deg", "E_perp", "I4", "I6", "I8", "I11", "k11", "energy_density")
INTS = ("zone", "mdz")
S_NAMES = ("S_xx_yy_xy", "S")


def xml_comments(path):
    with open(path) as fh:
        head = fh.read(4096)
    return re.findall(r"<!--(.*?)-->", head, re.S)


class VtuCase:
    def __init__(self, name, binary, workdir):
        self.name = name
        self.binary = binary
        self.workdir = workdir
        self.theta, self.dfinal, self.outs = VTU_CASES[name]
        self.out = None
        self._data = None

    # -- reading --------------------------------------------------------------

    def run(self):
        self.out, dt, _ = run_case(self.binary, self.name, self.workdir, VTU_CASES)
        with open(os.path.join(self.out, "summary.json")) as fh:
            self.summary = json.load(fh)
        return dt

    def data(self):
        """[(timestep, file, meshio mesh)] for every DataSet of oat.pvd (read once)."""
        if self._data is not None:
            return self._data
        if self.out is None:
            raise RuntimeError("ncform did not run")
        import meshio
        self._data = [(ts, f, meshio.read(os.path.join(self.out, f)))
                      for ts, f in read_pvd(os.path.join(self.out, "oat.pvd"))]
        if not self._data:
            raise RuntimeError("oat.pvd lists no DataSet")
        return self._data

    @staticmethod
    def cell(m, name):
        v = m.cell_data_dict[name]["triangle"]
        return np.asarray(v)

    @staticmethod
    def scalar(m, name):
        return VtuCase.cell(m, name).reshape(-1)

    @staticmethod
    def stress(m):
        for n in S_NAMES:
            if n in m.cell_data_dict:
                return n, np.asarray(m.cell_data_dict[n]["triangle"])
        raise KeyError("no stress field (S_xx_yy_xy or S)")

    def reference(self, m):
        return m.points - m.point_data["displacement"]

    # -- geometry -------------------------------------------------------------

    def kinematics(self, m):
        """Per triangle: C in the (a, b) basis, the basis (a, b) in 3-D, the min edge."""
        X = self.reference(m)
        x = m.points
        tri = m.cells_dict["triangle"]
        E1, E2 = X[tri[:, 1]] - X[tri[:, 0]], X[tri[:, 2]] - X[tri[:, 0]]
        e1, e2 = x[tri[:, 1]] - x[tri[:, 0]], x[tri[:, 2]] - x[tri[:, 0]]
        n = np.cross(E1, E2)
        n /= np.linalg.norm(n, axis=1)[:, None]
        n[n[:, 2] < 0] *= -1.0                      # orient the normal to +z
        th = math.radians(self.theta)
        a0 = np.array([math.sin(th), math.cos(th), 0.0])
        a = a0 - (n @ a0)[:, None] * n              # a0 projected on the element plane
        a /= np.linalg.norm(a, axis=1)[:, None]
        b = np.cross(n, a)                          # a turned by +90 deg about n
        G = np.stack([np.stack([np.einsum("ij,ij->i", a, E1), np.einsum("ij,ij->i", a, E2)], -1),
                      np.stack([np.einsum("ij,ij->i", b, E1), np.einsum("ij,ij->i", b, E2)], -1)], 1)
        g = np.stack([e1, e2], -1)                  # (nc, 3, 2)
        F = g @ np.linalg.inv(G)                    # (nc, 3, 2): (a, b) coords -> deformed
        C = np.einsum("nki,nkj->nij", F, F)
        hmin = np.min(np.stack([np.linalg.norm(E1, axis=1), np.linalg.norm(E2, axis=1),
                                np.linalg.norm(E2 - E1, axis=1)]), axis=0)
        return C, a, b, hmin, X

    def invariants(self, m):
        C, a, b, hmin, X = self.kinematics(m)
        I4, I6, I8 = C[:, 0, 0], C[:, 0, 1], C[:, 1, 1]
        det = C[:, 0, 0] * C[:, 1, 1] - C[:, 0, 1] * C[:, 1, 0]
        I11 = np.sqrt(det / I4)
        return dict(I4=I4, I6=I6, I8=I8, I11=I11, C=C, a=a, b=b, hmin=hmin,
                    Cn=np.linalg.norm(C, axis=(1, 2)), X=X)

    def centroids(self, m):
        X = self.reference(m)
        tri = m.cells_dict["triangle"]
        return X[tri].mean(axis=1)[:, :2]

    def zones_expected(self, cen):
        """Two-family zones of the reference centroids; also the distance to a zone boundary."""
        th = math.radians(self.theta)
        dirs = (np.array([math.sin(th), math.cos(th)]), np.array([-math.cos(th), math.sin(th)]))
        clamped = []
        margin = np.full(len(cen), np.inf)
        for d in dirs:
            hit = np.zeros(len(cen), bool)
            for s in (d, -d):
                # parameter at which the line leaves through x = 0/W and through y = 0/L
                with np.errstate(divide="ignore", invalid="ignore"):
                    tx = np.where(s[0] > 1e-12, (WIDTH - cen[:, 0]) / s[0],
                                  np.where(s[0] < -1e-12, -cen[:, 0] / s[0], np.inf))
                    ty = np.where(s[1] > 1e-12, (LENGTH - cen[:, 1]) / s[1],
                                  np.where(s[1] < -1e-12, -cen[:, 1] / s[1], np.inf))
                hit |= ty <= tx
                # leaving through a corner is the boundary between the two answers
                both = np.isfinite(tx) & np.isfinite(ty)
                margin = np.minimum(margin, np.where(both, np.abs(tx - ty), np.inf))
            clamped.append(hit)
        nclamped = clamped[0].astype(int) + clamped[1].astype(int)
        zone = np.where(nclamped == 0, 0, np.where(nclamped == 2, 2, 1))
        return zone, margin

    # -- checks ---------------------------------------------------------------

    def check_pvd(self):
        pvd = os.path.join(self.out, "oat.pvd")
        sets = read_pvd(pvd)
        ts = [t for t, _ in sets]
        want = sorted(set(self.outs) | {self.dfinal})
        bad = []
        if len(ts) != len(want) or any(abs(t - w) > 1e-9 for t, w in zip(ts, want)):
            bad.append(f"timesteps {ts} != requested outputs + final {want}")
        if any(t2 <= t1 for t1, t2 in zip(ts, ts[1:])):
            bad.append(f"timesteps not increasing: {ts}")
        for t, f in sets:
            path = os.path.join(self.out, f)
            if not os.path.isfile(path):
                bad.append(f"{f}: listed but missing")
                continue
            mt = re.fullmatch(r"oat_d(\d+\.\d+)\.vtu", os.path.basename(f))
            if not mt:
                bad.append(f"{f}: name not oat_dXXX.XXX.vtu")
            elif abs(float(mt.group(1)) - t) > 5e-4:     # the name has 3 decimals
                bad.append(f"{f}: name says d = {mt.group(1)}, timestep {t}")
            cm = [re.search(r"clamp displacement ([-+0-9.eE]+) mm", c) for c in xml_comments(path)]
            cm = [c for c in cm if c]
            if len(cm) != 1 or abs(float(cm[0].group(1)) - t) > 1e-9 * max(1.0, abs(t)):
                bad.append(f"{f}: comment 'clamp displacement d mm' missing or != {t}")
        listed = {os.path.normpath(os.path.join(self.out, f)) for _, f in sets}
        on_disk = {os.path.normpath(p) for p in glob.glob(os.path.join(self.out, "vtu", "*.vtu"))}
        if on_disk - listed:
            bad.append(f"VTU files not in oat.pvd: {sorted(on_disk - listed)}")
        return not bad, "\n".join(bad) if bad else \
            f"{len(sets)} DataSets, timesteps {ts} [mm] = file names = requested + final"

    def check_structure(self):
        bad = []
        info = []
        nn = self.summary.get("mesh", {}).get("nodes")
        nt = self.summary.get("mesh", {}).get("triangles")
        for t, f, m in self.data():
            npts, ncell = len(m.points), sum(len(c.data) for c in m.cells)
            if [c.type for c in m.cells] != ["triangle"]:
                bad.append(f"{f}: cell blocks {[c.type for c in m.cells]}, expected one 'triangle'")
                continue
            if (npts, ncell) != (nn, nt):
                bad.append(f"{f}: {npts} points / {ncell} cells, summary.json {nn} / {nt}")
            tri = m.cells_dict["triangle"]
            if tri.min() < 0 or tri.max() >= npts or len(np.unique(tri)) != npts:
                bad.append(f"{f}: connectivity out of range or unused points")
            if not np.all(np.isfinite(m.points)) or m.points.shape != (npts, 3):
                bad.append(f"{f}: points not finite or not 3-D")
            u = m.point_data.get("displacement")
            if u is None or u.shape != (npts, 3) or not np.all(np.isfinite(u)):
                bad.append(f"{f}: point field displacement missing, not (points, 3) or not finite")
            for name in SCALARS + INTS:
                if name not in m.cell_data_dict:
                    bad.append(f"{f}: cell field {name} missing")
                    continue
                v = self.cell(m, name)
                if v.shape not in ((ncell,), (ncell, 1)):
                    bad.append(f"{f}: {name} has shape {v.shape}")
                if name in INTS and not np.issubdtype(v.dtype, np.integer):
                    bad.append(f"{f}: {name} has dtype {v.dtype}, expected an integer type")
                if not np.all(np.isfinite(v)):
                    bad.append(f"{f}: {name} has non-finite values")
            try:
                sname, S = self.stress(m)
                if S.shape != (ncell, 3) or not np.all(np.isfinite(S)):
                    bad.append(f"{f}: {sname} has shape {S.shape} or non-finite values")
            except KeyError as e:
                bad.append(f"{f}: {e}")
                sname = None
            extra = set(m.cell_data_dict) - set(SCALARS + INTS + S_NAMES)
            if extra:
                info.append(f"{f}: extra cell fields {sorted(extra)}")
        first = self.data()[0][2]
        shapes = {n: self.cell(first, n).shape for n in ("E22", "zone")}
        info.append(f"{len(self.data())} files, {nn} points, {nt} triangles each; stress field "
                    f"'{sname}'; meshio shapes e.g. {shapes}")
        return not bad, "\n".join(bad + info)

    def check_reference_mesh(self):
        bad = []
        X0 = self.reference(self.data()[0][2])
        for t, f, m in self.data():
            X = self.reference(m)
            dev = np.abs(X - X0).max()
            if dev > REF_TOL * LENGTH:
                bad.append(f"{f}: reference differs from the first file's by {dev:.2e} mm")
            if np.abs(m.point_data["displacement"][:, 2]).max() != 0 or np.abs(m.points[:, 2]).max() != 0:
                bad.append(f"{f}: out-of-plane displacement or deformed z != 0 (in-plane test)")
        lo, hi = X0[:, :2].min(axis=0), X0[:, :2].max(axis=0)
        if np.abs(lo).max() > 1e-9 or abs(hi[0] - WIDTH) > 1e-9 or abs(hi[1] - LENGTH) > 1e-9:
            bad.append(f"bounding box {lo} .. {hi} != [0, {WIDTH}] x [0, {LENGTH}]")
        if np.abs(X0[:, 2]).max() > 1e-12:
            bad.append("reference z != 0")
        tri = self.data()[0][2].cells_dict["triangle"]
        E1, E2 = X0[tri[:, 1], :2] - X0[tri[:, 0], :2], X0[tri[:, 2], :2] - X0[tri[:, 0], :2]
        cross = E1[:, 0] * E2[:, 1] - E1[:, 1] * E2[:, 0]
        area = 0.5 * np.abs(cross).sum()
        if abs(area - WIDTH * LENGTH) > 1e-12 * WIDTH * LENGTH * 10:
            bad.append(f"total reference area {area!r} != W L = {WIDTH * LENGTH}")
        if np.abs(cross).min() <= 0:
            bad.append("degenerate triangle in the reference mesh")
        ccw = int(np.sum(cross > 0))
        return not bad, "\n".join(bad) if bad else \
            (f"reference identical in all files; rectangle {WIDTH} x {LENGTH}, total area "
             f"{area:.9g} mm^2; {ccw}/{len(tri)} triangles counter-clockwise")

    def check_clamps(self):
        bad = []
        X0 = self.reference(self.data()[0][2])
        bottom = np.abs(X0[:, 1]) <= 1e-9 * LENGTH
        top = np.abs(X0[:, 1] - LENGTH) <= 1e-9 * LENGTH
        if bottom.sum() < 2 or top.sum() < 2:
            return False, f"clamp node sets too small: {bottom.sum()} / {top.sum()}"
        for t, f, m in self.data():
            u = m.point_data["displacement"]
            eb = np.abs(u[bottom]).max()
            et = np.abs(u[top] - np.array([0.0, t, 0.0])).max()
            if eb > REF_TOL * max(t, 1.0) or et > REF_TOL * max(t, 1.0):
                bad.append(f"{f}: fixed clamp |u| = {eb:.2e}, moving clamp |u - (0, {t}, 0)| = {et:.2e}")
        return not bad, "\n".join(bad) if bad else \
            f"{bottom.sum()} nodes at y = 0 fixed, {top.sum()} nodes at y = L at (0, d, 0) in every file"

    def _compare(self, checks):
        """checks: iterable of (file, name, vtu values, reference values, scale, tol)."""
        bad = []
        worst = {}
        for f, name, got, ref, scale, tol in checks:
            err = np.abs(got - ref) / scale
            i = int(np.argmax(err))
            worst[name] = max(worst.get(name, 0.0), float(err[i]))
            if err[i] > tol:
                bad.append(f"{f}: {name} element {i}: VTU {got[i]!r}, recomputed {ref[i]!r} "
                           f"(scaled error {err[i]:.2e} > {tol:g})")
        summ = ", ".join(f"{k} {v:.1e}" for k, v in worst.items())
        return not bad, "\n".join(bad[:20] + [f"max scaled errors: {summ}"])

    def check_invariants(self):
        def gen():
            for t, f, m in self.data():
                inv = self.invariants(m)
                for name in ("I4", "I6", "I8", "I11"):
                    ref = inv[name]
                    yield f, name, self.scalar(m, name), ref, np.maximum(np.abs(ref), inv["Cn"]), INV_TOL
        return self._compare(gen())

    def check_strain_measures(self):
        def gen():
            for t, f, m in self.data():
                inv = self.invariants(m)
                e22 = inv["I8"] - 1.0
                ep = inv["I11"] - 1.0
                gam = np.degrees(0.5 * np.pi - np.arccos(inv["I6"] / np.sqrt(inv["I4"] * inv["I8"])))
                yield f, "E22", self.scalar(m, "E22"), e22, np.maximum(np.abs(e22), inv["Cn"]), INV_TOL
                yield f, "E_perp", self.scalar(m, "E_perp"), ep, np.maximum(np.abs(ep), inv["Cn"]), INV_TOL
                yield (f, "shear_angle_deg", self.scalar(m, "shear_angle_deg"), gam,
                       np.maximum(np.abs(gam), math.degrees(1.0)), INV_TOL)
        return self._compare(gen())

    def check_law_fields(self):
        p = params_schaefer2024()
        bad = []
        worst = dict(k11=0.0, energy_density=0.0, S=0.0)
        for t, f, m in self.data():
            inv = self.invariants(m)
            C = inv["C"]
            e_ab = (np.array([1.0, 0.0]), np.array([0.0, 1.0]))   # C is in the (a, b) basis
            W, S_loc, linv = law(C, *e_ab, p)
            CC = tangent_fd(C, *e_ab, p)
            Q = np.stack([inv["a"], inv["b"]], -1)                # (nc, 3, 2)
            Sg = np.einsum("nik,nkl,njl->nij", Q, S_loc, Q)
            S_ref = np.stack([Sg[:, 0, 0], Sg[:, 1, 1], Sg[:, 0, 1]], -1)
            # round-off of C from coordinates printed in f64 (see docstring)
            xmax = np.abs(m.points).max() + np.abs(m.point_data["displacement"]).max()
            dC = 8.0 * EPS * xmax / inv["hmin"] * np.maximum(1.0, inv["Cn"])
            sname, S = self.stress(m)
            errS = np.linalg.norm(S - S_ref, axis=1)
            tolS = LAW_TOL * np.linalg.norm(S_ref, axis=1) + np.sqrt(np.sum(CC ** 2, axis=(1, 2, 3, 4))) * dC
            wd = self.scalar(m, "energy_density")
            errW = np.abs(wd - W)
            tolW = LAW_TOL * np.abs(W) + np.linalg.norm(S_loc, axis=(1, 2)) * dC
            k = self.scalar(m, "k11")
            errk = np.abs(k - linv["k11"])
            tolk = LAW_TOL * np.abs(linv["k11"])
            for name, err, tol, got, ref in (("S", errS, tolS, S, S_ref), ("energy_density", errW, tolW, wd, W),
                                             ("k11", errk, tolk, k, linv["k11"])):
                r = err / np.maximum(tol, 1e-300)
                worst[name] = max(worst[name], float(r.max()))
                if r.max() > 1.0:
                    i = int(np.argmax(r))
                    bad.append(f"{f}: {name} element {i}: VTU {got[i]!r}, law {ref[i]!r} "
                               f"(error {err[i]:.2e} > tol {tol[i]:.2e})")
            if wd.min() < 0:
                bad.append(f"{f}: negative energy_density {wd.min()!r}")
        return not bad, "\n".join(bad[:20] + ["max error / tolerance: " +
                                               ", ".join(f"{k} {v:.2e}" for k, v in worst.items())])

    def check_zones(self):
        bad = []
        m0 = self.data()[0][2]
        z0 = self.scalar(m0, "zone")
        cen = self.centroids(m0)
        zexp, margin = self.zones_expected(cen)
        for t, f, m in self.data():
            z = self.scalar(m, "zone")
            if not set(np.unique(z).tolist()) <= {0, 1, 2}:
                bad.append(f"{f}: zone values {np.unique(z).tolist()} not in {{0, 1, 2}}")
            if not np.array_equal(z, z0):
                bad.append(f"{f}: zones differ from the first file's")
        sure = margin > 1e-9
        wrong = np.nonzero(sure & (z0 != zexp))[0]
        if len(wrong):
            bad.append(f"{len(wrong)} elements with a zone other than the two-family reading, e.g. "
                       f"element {wrong[0]} centroid {cen[wrong[0]]}: VTU {z0[wrong[0]]}, expected "
                       f"{zexp[wrong[0]]}")
        tri = m0.cells_dict["triangle"]
        X = self.reference(m0)
        E1, E2 = X[tri[:, 1], :2] - X[tri[:, 0], :2], X[tri[:, 2], :2] - X[tri[:, 0], :2]
        A0 = 0.5 * np.abs(E1[:, 0] * E2[:, 1] - E1[:, 1] * E2[:, 0])
        areas = [float(A0[z0 == k].sum()) for k in range(3)]
        info = (f"zone areas A/B/C = {areas[0]:.0f}/{areas[1]:.0f}/{areas[2]:.0f} mm^2 "
                f"({int((~sure).sum())} elements on a boundary skipped)")
        if abs(self.theta - 45.0) < 1e-12:
            info += (f"; pin-jointed net (docs/verification.md (the pin-jointed net)): {WIDTH * (LENGTH - 1.5 * WIDTH):.0f}/"
                     f"{WIDTH ** 2:.0f}/{WIDTH ** 2 / 2:.0f} (element centroids, so only close)")
        return not bad, "\n".join(bad + [info])

    def check_mdz(self):
        bad = []
        m0 = self.data()[0][2]
        mdz0 = self.scalar(m0, "mdz")
        zone = self.scalar(m0, "zone")
        cen = self.centroids(m0)
        for t, f, m in self.data():
            mdz = self.scalar(m, "mdz")
            if not set(np.unique(mdz).tolist()) <= {0, 1}:
                bad.append(f"{f}: mdz values {np.unique(mdz).tolist()} not in {{0, 1}}")
            if not np.array_equal(mdz, mdz0):
                bad.append(f"{f}: mdz differs from the first file's")
        sel = mdz0 == 1
        if not sel.any():
            bad.append("no element with mdz == 1")
        if (zone == 0).any() and np.any(zone[sel] != 0):
            bad.append(f"{int(np.sum(zone[sel] != 0))} mdz elements outside zone A although zone A "
                       f"is not empty")
        off = np.abs(cen - np.array([0.5 * WIDTH, 0.5 * LENGTH]))
        window = np.all(off <= 0.5 * MDZ_SIZE, axis=1)
        near_edge = np.any(np.abs(off - 0.5 * MDZ_SIZE) <= 1e-9, axis=1)
        expected = window & (zone == 0)
        if not expected.any():
            expected = window
        wrong = np.nonzero((expected != sel) & ~near_edge)[0]
        if len(wrong):
            bad.append(f"{len(wrong)} elements differ from zone A x the {MDZ_SIZE:g} mm centre window, "
                       f"e.g. element {wrong[0]} centroid {cen[wrong[0]]}")
        return not bad, "\n".join(bad + [f"{int(sel.sum())} mdz elements, zones "
                                         f"{sorted(set(zone[sel].tolist()))}; zone A "
                                         f"{'empty' if not (zone == 0).any() else 'not empty'}"])

    def check_units(self):
        bad = []
        for t, f, m in self.data():
            text = " ".join(xml_comments(os.path.join(self.out, f)))
            if not re.search(r"units:.*\bmm\b", text) or "MPa" not in text or not re.search(r"\bN\b", text):
                bad.append(f"{f}: XML comment does not state the units (mm, N, MPa): {text[:200]!r}")
        ptext = " ".join(xml_comments(os.path.join(self.out, "oat.pvd")))
        if "mm" not in ptext or "units" not in ptext:
            bad.append(f"oat.pvd: XML comment does not state the units: {ptext[:200]!r}")
        for csv in ("force_displacement.csv", "mdz_strains.csv"):
            comments, header, _ = read_force_csv(os.path.join(self.out, csv))
            u = [c for c in comments if c.startswith("# units:")]
            if len(u) != 1 or "mm" not in u[0] or not re.search(r"\bN\b", u[0]):
                bad.append(f"{csv}: no '# units:' line with mm and N: {comments}")
            if csv == "force_displacement.csv" and header != "displacement [mm],force [N],iterations [-]":
                bad.append(f"{csv}: header {header!r}")
        if "mm" not in str(self.summary.get("units", "")):
            bad.append(f"summary.json units = {self.summary.get('units')!r}")
        return not bad, "\n".join(bad) if bad else \
            f"units stated in {len(self.data())} VTU, the pvd, both CSV files and summary.json"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--ncform", default=os.path.join(REPO, "target", "release", "ncform"))
    ap.add_argument("--keep", default=None, help="write the cases and results here (kept)")
    args = ap.parse_args()
    t_start = time.time()
    hx = Harness()
    workdir = args.keep or tempfile.mkdtemp(prefix="ncform-verify-vtu-")
    os.makedirs(workdir, exist_ok=True)
    for name in VTU_CASES:
        th, d, outs = VTU_CASES[name]
        vc = VtuCase(name, args.ncform, workdir)

        def run(vc=vc):
            dt = vc.run()
            return True, f"{vc.out}: {len(vc.data())} VTU files, ncform {dt:.2f}s"
        tag = f"vtu/{name}"
        if not hx.run(f"{tag}/ncform-run", f"ncform runs the coarse {th:g} deg OAT to {d:g} mm", run):
            vc.out = None          # every following check of this case then fails
        checks = [
            ("pvd", "oat.pvd lists every output displacement (+ final) in order; file names, "
                    "timesteps and VTU comments agree; no VTU left out"),
            ("structure", "meshio reads every VTU: counts = summary.json, triangles only, every "
                          "field present with the right shape, all finite"),
            ("reference-mesh", "reference = points - displacement is the same rectangle in every "
                               "file (1e-12 L), in-plane"),
            ("clamps", "displacement is 0 at y = 0 and (0, d, 0) at y = L (1e-12)"),
            ("invariants", f"I4, I6, I8, I11 equal C = F^T F recomputed from the coordinates "
                           f"(a0 projected on the element plane) to {INV_TOL:g}"),
            ("strain-measures", f"E22 = I8 - 1, E_perp = I11 - 1, shear_angle_deg = "
                                f"deg(pi/2 - arccos(I6/sqrt(I4 I8))) to {INV_TOL:g}"),
            ("law-fields", f"k11, energy_density and S (global xx, yy, xy) equal the docs/theory.md law "
                           f"at the recomputed C to {LAW_TOL:g} (+ coordinate round-off)"),
            ("zones", "zone in {0, 1, 2}, constant, = two-family reading of the reference centroids"),
            ("mdz", "mdz in {0, 1}, constant, non-empty, only in zone A unless zone A is empty, "
                    "= zone A x 20 mm centre window"),
            ("units", "units stated in the VTU/pvd comments, CSV '# units:' lines and headers, "
                      "summary.json"),
        ]
        for key, req in checks:
            hx.run(f"{tag}/{key}", req, getattr(vc, "check_" + key.replace("-", "_")))
    if not args.keep:
        shutil.rmtree(workdir, ignore_errors=True)
    print(f"# verify_vtu total time {time.time() - t_start:.1f}s")
    hx.summary()
    return 0 if hx.failed == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
