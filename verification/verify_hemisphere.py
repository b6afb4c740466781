#!/usr/bin/env python3
"""The hemisphere bench's outputs recomputed independently (docs/forming.md).

ncform runs the shipped `cases/hemisphere-0.toml` with a coarse blank
(CELLS x CELLS cells; the paper-size runs are `full_hemisphere.py`, run by
`bash verification/run.sh --full`). Its VTU files are read back with meshio
and everything the run reads on the blank is recomputed here with numpy
from the deformed positions alone, sharing no code with ncform:

* `fields`: gamma = I10, E22 = I8 - 1, E_perp = I11 - 1 of every element from
  the deformed triangle and the reference rovings (paper Section 4:
  I4 = a.C.a, I8 = b.C.b, I6 = a.C.b, I10 = asin(I6 / sqrt(I4 I8)),
  I11 = sqrt(det C / I4)), against the VTU cell fields, to 1e-9 (round-off
  of the two computations of the same formulas);
* `dic`: the same on the mesh projected on the blank plane (z dropped),
  against the `dic_*` fields and `vtu/ply-dic_*.vtu`, to 1e-9; turned-over
  projected triangles flagged by dic_valid = 0 exactly where the projected
  signed area is not positive;
* `contour`: the boundary loop of the triangle mesh found here (edges of one
  triangle), its final positions against `outer_contour.csv`, to 1e-9 mm;
* `draw-in`: the in-plane displacement towards the blank's centre at the
  edge midpoints (linear interpolation between the two boundary nodes) and
  corners, against `forming.csv`'s last row, to 1e-9 mm;
* `zones`: the area-weighted mean and standard deviation of gamma over the
  elements whose reference centroid lies in each zone window, against
  `forming.csv`, to 1e-9 deg;
* `modes`: every element's deformation mode from the signs of the
  recomputed I8 - 1 and I11 - 1 (beyond 1e-3), against the VTU field, and
  the zones' shares of mixed-modes 1 and 2 against `forming.csv`;
* `symmetry`: the final contour mirror-symmetric about both blank axes
  within 1 mm (the required limit);
* `energy`: KE/IE below 5 % from 10 % of the stroke on and the energy
  balance error below 1 % (energy.csv).

Usage: verify_hemisphere.py --ncform PATH [--keep DIR]
"""

import argparse
import csv
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
CASE = os.path.join(REPO, "cases", "hemisphere-0.toml")
CELLS = 24

results = []


def check(name, ok, detail):
    results.append(bool(ok))
    print(f"{'PASS' if ok else 'FAIL'} [{name}] {detail}")


def read_csv(path):
    with open(path) as f:
        rows = [r for r in csv.reader(line for line in f if not line.startswith("#"))]
    header = rows[0]
    data = np.array([[float(x) for x in r] for r in rows[1:]])
    return header, data


def measures(points, triangles, rovings_angle_deg):
    """gamma [deg], E22, E_perp and the signed area ratio of every triangle
    mapped from the flat reference `points[0]` to `points[1]` (both n x 3)."""
    ref, cur = points
    a = np.array([math.cos(math.radians(rovings_angle_deg)),
                  math.sin(math.radians(rovings_angle_deg)), 0.0])
    b = np.array([-a[1], a[0], 0.0])
    out = []
    for t in triangles:
        x0 = ref[t]
        x = cur[t]
        # Reference edge vectors in the (a, b) frame and the current ones.
        e0 = np.array([[np.dot(x0[1] - x0[0], a), np.dot(x0[2] - x0[0], a)],
                       [np.dot(x0[1] - x0[0], b), np.dot(x0[2] - x0[0], b)]])
        e = np.column_stack([x[1] - x[0], x[2] - x[0]])
        F = e @ np.linalg.inv(e0)          # 3 x 2: columns F a, F b
        C = F.T @ F
        i4, i8, i6 = C[0, 0], C[1, 1], C[0, 1]
        gamma = math.degrees(math.asin(i6 / math.sqrt(i4 * i8)))
        i11 = math.sqrt(np.linalg.det(C) / i4)
        n0 = np.cross(x0[1] - x0[0], x0[2] - x0[0])
        n = np.cross(x[1] - x[0], x[2] - x[0])
        orientation = np.dot(n, n0) / np.dot(n0, n0)
        out.append((gamma, i8 - 1.0, i11 - 1.0, orientation))
    return np.array(out)


def boundary_loop(triangles):
    count = {}
    for t in triangles:
        for k in range(3):
            a, b = int(t[k]), int(t[(k + 1) % 3])
            key = (min(a, b), max(a, b))
            count.setdefault(key, [0, (a, b)])[0] += 1
    nxt = {ab[0]: ab[1] for c, ab in count.values() if c == 1}
    start = min(nxt)
    loop = [start]
    while nxt[loop[-1]] != start:
        loop.append(nxt[loop[-1]])
    return loop


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ncform", required=True)
    ap.add_argument("--keep")
    args = ap.parse_args()
    import meshio

    work = args.keep or tempfile.mkdtemp(prefix="ncform-hemisphere-")
    os.makedirs(work, exist_ok=True)
    with open(CASE) as f:
        text = f.read()
    text = text.replace("cells = [84, 84]", f"cells = [{CELLS}, {CELLS}]")
    case = os.path.join(work, "hemisphere-0.toml")
    with open(case, "w") as f:
        f.write(text)
    out = os.path.join(work, "out")
    shutil.rmtree(out, ignore_errors=True)
    run = subprocess.run([args.ncform, "run", case, "--out", out, "--quiet"],
                         capture_output=True, text=True)
    check("run", run.returncode == 0,
          f"ncform run {CELLS}x{CELLS}-cell hemisphere-0 exits {run.returncode}"
          + (f": {run.stderr.strip()[-300:]}" if run.returncode else ""))
    if run.returncode != 0:
        return
    summary = json.load(open(os.path.join(out, "summary.json")))
    states = sorted(f for f in os.listdir(os.path.join(out, "vtu"))
                    if re.fullmatch(r"ply_\d{4}\.vtu", f))
    final = meshio.read(os.path.join(out, "vtu", states[-1]))
    dic_mesh = meshio.read(os.path.join(out, "vtu", states[-1].replace("ply_", "ply-dic_")))
    tri = final.cells_dict["triangle"]
    disp = final.point_data["displacement"]
    cur = final.points
    ref = cur - disp

    m = measures((ref, cur), tri, 0.0)
    cell = {k: v[0] for k, v in final.cell_data.items()}
    worst = max(np.max(np.abs(m[:, 0] - cell["shear_angle_deg"])),
                np.max(np.abs(m[:, 1] - cell["E22"])),
                np.max(np.abs(m[:, 2] - cell["E_perp"])))
    check("fields", worst < 1e-9,
          f"gamma, E22, E_perp of {len(tri)} elements recomputed: largest difference {worst:.2e}")

    projected = cur.copy()
    projected[:, 2] = ref[:, 2]
    mp = measures((ref, projected), tri, 0.0)
    valid = mp[:, 3] > 0.0
    same_valid = np.array_equal(valid.astype(int), cell["dic_valid"].astype(int))
    dic = {k: v[0] for k, v in dic_mesh.cell_data.items()}
    worst_dic = max(np.max(np.abs(mp[valid, 0] - cell["dic_shear_angle_deg"][valid])),
                    np.max(np.abs(mp[valid, 1] - cell["dic_E22"][valid])),
                    np.max(np.abs(mp[valid, 2] - cell["dic_E_perp"][valid])),
                    np.max(np.abs(mp[valid, 0] - dic["dic_shear_angle_deg"][valid])),
                    np.max(np.abs(dic_mesh.points - projected)))
    check("dic", same_valid and worst_dic < 1e-9,
          f"projection: {int(valid.sum())} of {len(tri)} elements valid (flags agree: {same_valid}); "
          f"largest difference {worst_dic:.2e}")

    loop = boundary_loop(tri)
    _, contour = read_csv(os.path.join(out, "outer_contour.csv"))
    csv_final = contour[:, -2:]
    csv_ref = contour[:, 2:4]
    # Match the loops by reference position (the start node may differ).
    index = {tuple(np.round(ref[n, :2], 9)): n for n in loop}
    order = [index.get(tuple(np.round(r, 9))) for r in csv_ref]
    ok = None not in order and len(order) == len(loop)
    worst_c = (np.max(np.abs(cur[order, :2] - csv_final)) if ok else float("inf"))
    check("contour", ok and worst_c < 1e-9,
          f"{len(loop)} boundary nodes found here, {len(csv_ref)} in outer_contour.csv; "
          f"largest difference {worst_c:.2e} mm")

    header, hist = read_csv(os.path.join(out, "forming.csv"))
    last = hist[-1]
    col = {h: i for i, h in enumerate(header)}
    r = ref[loop, :2]
    lo, hi = r.min(axis=0), r.max(axis=0)
    centre = 0.5 * (lo + hi)
    targets = {"+x edge": (hi[0], centre[1]), "+y edge": (centre[0], hi[1]),
               "-x edge": (lo[0], centre[1]), "-y edge": (centre[0], lo[1]),
               "+x+y corner": (hi[0], hi[1]), "-x+y corner": (lo[0], hi[1]),
               "-x-y corner": (lo[0], lo[1]), "+x-y corner": (hi[0], lo[1])}
    worst_d = 0.0
    for name, target in targets.items():
        target = np.array(target)
        best = None
        for k in range(len(loop)):
            p, q = ref[loop[k], :2], ref[loop[(k + 1) % len(loop)], :2]
            d = q - p
            s = np.clip(np.dot(target - p, d) / np.dot(d, d), 0.0, 1.0)
            dist = np.linalg.norm(p + s * d - target)
            if best is None or dist < best[0] - 1e-12:
                best = (dist, k, s, p + s * d)
        _, k, s, x = best
        u = (1 - s) * disp[loop[k], :2] + s * disp[loop[(k + 1) % len(loop)], :2]
        inward = (centre - x) / np.linalg.norm(centre - x)
        value = float(np.dot(u, inward))
        worst_d = max(worst_d, abs(value - last[col[f"ply draw-in {name} [mm]"]]))
    check("draw-in", worst_d < 1e-9,
          f"draw-in at 4 edge midpoints and 4 corners recomputed: largest difference {worst_d:.2e} mm")

    worst_z = 0.0
    centroids = ref[tri].mean(axis=1)
    area = 0.5 * np.linalg.norm(np.cross(ref[tri[:, 1]] - ref[tri[:, 0]],
                                         ref[tri[:, 2]] - ref[tri[:, 0]]), axis=1)
    zones = summary["forming"]["zones"]
    for name, _ply, centre_z, size in zones:
        inside = ((np.abs(centroids[:, 0] - centre_z[0]) <= 0.5 * size[0])
                  & (np.abs(centroids[:, 1] - centre_z[1]) <= 0.5 * size[1]) & (m[:, 3] > 0))
        w = area[inside]
        g = m[inside, 0]
        mean = float(np.sum(w * g) / np.sum(w))
        std = float(math.sqrt(max(np.sum(w * g * g) / np.sum(w) - mean * mean, 0.0)))
        worst_z = max(worst_z,
                      abs(mean - last[col[f"zone {name} shear angle mean [deg]"]]),
                      abs(std - last[col[f"zone {name} shear angle std [deg]"]]))
    check("zones", len(zones) == 3 and worst_z < 1e-9,
          f"{len(zones)} zones: mean and std of gamma recomputed, largest difference {worst_z:.2e} deg")

    # Deformation modes from the recomputed E22 = I8 - 1 and E_perp = I11 - 1
    # (signs beyond 1e-3), against the VTU field and the zones' shares.
    tol = 1e-3
    e22, ep = m[:, 1], m[:, 2]
    near = (np.abs(e22) <= tol) & (np.abs(ep) <= tol)
    stretched, compacted = e22 > tol, ep < -tol
    modes = np.where(near, 0, np.where(compacted, np.where(stretched, 2, 1),
                                       np.where(stretched, 3, 4)))
    # Elements within 1e-12 of a threshold could fall either way by
    # round-off: leave them out of the comparison.
    clear = ((np.abs(np.abs(e22) - tol) > 1e-12) & (np.abs(np.abs(ep) - tol) > 1e-12))
    mismatched = int(np.sum((modes != cell["deformation_mode"]) & clear))
    worst_m = 0.0
    for name, _ply, centre_z, size in zones:
        inside = ((np.abs(centroids[:, 0] - centre_z[0]) <= 0.5 * size[0])
                  & (np.abs(centroids[:, 1] - centre_z[1]) <= 0.5 * size[1]) & (m[:, 3] > 0))
        w = area[inside]
        for k in (1, 2):
            share = float(np.sum(w[modes[inside] == k]) / np.sum(w))
            worst_m = max(worst_m, abs(share - last[col[f"zone {name} mixed-mode {k} share [-]"]]))
    check("modes", mismatched == 0 and worst_m < 1e-9,
          f"deformation modes of {len(tri)} elements from the signs of I8 - 1 and I11 - 1: "
          f"{mismatched} differ from the VTU field; zone shares of mixed-modes 1 and 2 "
          f"recomputed, largest difference {worst_m:.2e}")

    final_pos = {tuple(np.round(ref[n, :2], 6)): cur[n, :2] for n in loop}
    dev = 0.0
    for key, x in final_pos.items():
        for mirror in ((1, -1), (-1, 1)):
            other = final_pos.get((round(key[0] * mirror[0], 6), round(key[1] * mirror[1], 6)))
            if other is not None:
                dev = max(dev, float(np.linalg.norm(other * np.array(mirror) - x)))
    check("symmetry", dev < 1.0,
          f"final contour mirrored about both blank axes: largest deviation {dev:.3f} mm (limit 1 mm)")

    e = summary["explicit"]
    check("energy", e["max_kinetic_ratio"] < 0.05 and e["max_relative_balance_error"] < 0.01,
          f"max KE/IE from 10 % of the stroke {100 * e['max_kinetic_ratio']:.2f} % (< 5 %), "
          f"balance error {100 * e['max_relative_balance_error']:.3f} % (< 1 %)")
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    try:
        main()
    finally:
        passed = sum(results)
        print(f"CHECK-SUMMARY passed={passed} failed={len(results) - passed}")
        sys.exit(0 if results and all(results) else 1)
