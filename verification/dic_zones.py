#!/usr/bin/env python3
"""Zones as a 2D image correlation from below would see them
(Schäfer et al. 2024, Section 5.1 and Appendix C; docs/forming.md, "Zones"
and "The image-correlation view").

The paper measures the formed plies' strains with a 2D image correlation
(DIC) from below, through a transparent die. Only the flat flange is
measured accurately, and points that pass over the edge of the die's
opening lose their correlation (the edge shows white like the dots of the
pattern; paper Section 5.1, Fig. 9). This module reads an `ncform run`
folder and evaluates 20 x 20 mm windows the same way.

* **Window.** A square of 20 x 20 mm in reference coordinates on the blank
  (it follows the material, as a case's `[[zone]]` windows do): an element
  belongs to it when its reference centroid lies in the square (the rule of
  `src/post/forming.rs`, `Zone::elements`).
* **DIC-visible elements** at an output state: those whose current
  centroid lies on the flat flange at that state AND at every earlier
  output state (once lost, lost, as a correlation). The flat flange is the
  die's face beyond the opening's edge and its fillet: for a round opening
  (`plate-with-hole`) a horizontal distance from the opening's axis of at
  least `opening_radius + fillet_radius` (85 mm on the hemisphere); for
  the tetrahedron's `plate-with-polygon-hole` a distance of at least
  `fillet_radius` from the opening, which is computed from the case as
  docs/forming.md ("The tetrahedron bench", "Geometry and defaults")
  describes it: the punch's section by the die plane at full depth grown
  by `clearance` (straight sides 43.55 mm from the axis, corners rounded
  with 11.97 mm on the shipped case).
* **Which ply.** The camera below sees the ply nearest the die: of a
  stack, the ply whose reference mid-surface is closest to the die's face
  (`ply-0` of cases/hemisphere-0-90.toml).
* **Per window and state:** the 3D mean shear over all the window's
  elements (the VTU's `shear_angle_deg`, weighted by the reference area:
  the case zones' mean of `forming.csv`), the 3D mean over the visible
  elements, the 2D-DIC mean over the visible elements (the VTU's
  `dic_shear_angle_deg`: γ = I10 of the formed mesh projected on the blank
  plane, computed by ncform from the reference rovings exactly as for the
  formed ply; elements whose projection is turned over, `dic_valid = 0`,
  are left out), and the count and reference-area share of visible
  elements; beside them the 2D-DIC mean over all the window's elements
  whose projection is valid (what the `-dic_` maps show, visible or not).
  `projected_shear` recomputes the 2D value from the nodes (the
  in-plane deformation gradient of the projected triangle), and
  `--check` compares it with the VTU's.
* **Flange windows (placement rule).** The paper's Fig. 7c shows its zones
  without coordinates, so flange windows are placed by a stated rule on the
  shipped single-ply run: candidate centres on a reference grid with a
  5 mm step in one symmetry quadrant (x >= 0, y >= 0; the tetrahedron,
  symmetric about x = 0 only: x >= 0), the window inside the blank; keep
  the candidates whose elements are all DIC-visible at full depth (and
  therefore at every output state); rank them by the |mean 3D shear| at
  full depth; take greedily the three highest whose centres are at least
  30 mm apart; name them A′, B′, C′ in order of their distance from the
  blank's centre. The case's own `[[zone]]` windows are always reported
  beside them, with their visible share.

Usage:
  dic_zones.py RUN_DIR --case CASE.toml [--pick-out windows.json] [--windows windows.json] [--check]

Units: mm, degrees.
"""

import argparse
import json
import math
import os
import sys
import tomllib

import numpy as np

WINDOW = 20.0        # window side [mm] (the paper's windows)
GRID_STEP = 5.0      # candidate grid step [mm]
MIN_DISTANCE = 30.0  # smallest distance between two chosen windows' centres [mm]
NAMES = ["A′", "B′", "C′"]


class InputError(Exception):
    """Bad input, with the file and key it concerns."""


def load_case(path):
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except OSError as e:
        raise InputError(f"{path}: cannot read the case: {e}")
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"{path}: not valid TOML: {e}")


def _tool(case, name, path="case"):
    for t in case.get("tool", []):
        if t.get("name") == name:
            return t
    raise InputError(f"{path}: no [[tool]] named \"{name}\"")


def die_tool(case, path="case"):
    """The fixed tool below the ply: the `[[tool]]` named "die", else the
    first plate without `motion`."""
    for t in case.get("tool", []):
        if t.get("name") == "die":
            return t
    for t in case.get("tool", []):
        if t.get("shape", "").startswith("plate") and "motion" not in t:
            return t
    raise InputError(f"{path}: no [[tool]] \"die\" (a fixed plate) to define the flat flange")


def polygon_opening(case, die, path="case"):
    """The polygonal opening of a `plate-with-polygon-hole` die that follows
    a pyramid punch (docs/forming.md, "Geometry and defaults"): the punch's
    section by the die plane at full depth, grown by `clearance`. Returns
    (n sides, distance of the straight sides from the axis, corner radius,
    rotation of the first corner [rad]) in the die plane."""
    punch = _tool(case, die.get("punch", ""), path) if "punch" in die else None
    if punch is None or punch.get("shape") != "pyramid":
        raise InputError(f"{path}: tool \"{die.get('name')}\": the flange rule needs `punch` naming a pyramid")
    n = int(punch["sides"])
    alpha = math.radians(float(punch["face_angle_deg"]))
    rho = float(punch.get("rounding_radius", 0.0))
    clearance = float(die.get("clearance", 0.0))
    plane = np.array(die.get("section_at", die.get("origin", [0, 0, 0])), float)
    axis = np.array(punch.get("axis", [0, 0, 1]), float)
    axis /= np.linalg.norm(axis)
    tip = np.array(punch["origin"], float) - float(punch.get("displacement", 0.0)) * axis
    h = float(np.dot(plane - tip, axis))          # section height above the rounded tip
    hc = h - rho                                   # above the sharp core's apex
    side = hc / math.tan(alpha) + rho / math.sin(alpha)
    beta = math.atan(math.tan(alpha) * math.cos(math.pi / n))
    extreme = hc / math.tan(beta) + rho / math.sin(beta)
    c = math.cos(math.pi / n)
    corner = (side / c - extreme) / (1.0 / c - 1.0)
    side += clearance
    corner += clearance
    e = np.array(punch.get("edge_direction", [1, 0, 0]), float)
    # A base edge along edge_direction lies on the -normal side: the
    # opposite corner is at +90° from edge_direction (docs/forming.md).
    first_corner = math.atan2(e[1], e[0]) + math.pi / 2
    return n, side, corner, first_corner


def flange_rule(case, path="case"):
    """(function(xy) -> bool array, description): whether a current
    position, projected on the die plane, lies on the flat flange."""
    die = die_tool(case, path)
    fillet = float(die.get("fillet_radius", 0.0))
    origin = np.array(die.get("origin", [0, 0, 0]), float)
    if die.get("shape") == "plate-with-hole":
        if "opening_radius" not in die:
            raise InputError(f"{path}: tool \"{die.get('name')}\": `opening_radius` missing")
        r = float(die["opening_radius"]) + fillet

        def on_flange(xy):
            return np.hypot(xy[:, 0] - origin[0], xy[:, 1] - origin[1]) >= r
        return on_flange, f"horizontal distance from the opening's axis >= {r:g} mm (opening radius + fillet)"
    if die.get("shape") == "plate-with-polygon-hole":
        n, side, corner, first = polygon_opening(case, die, path)
        inner_r = (side - corner) / math.cos(math.pi / n)
        angles = first + 2 * math.pi * np.arange(n) / n
        verts = origin[:2] + inner_r * np.c_[np.cos(angles), np.sin(angles)]

        def on_flange(xy):
            return _distance_to_polygon(xy, verts) >= corner + fillet
        extreme = inner_r + corner
        return on_flange, (f"distance from the opening >= {fillet:g} mm (fillet); opening: {n} straight sides "
                           f"{side:.2f} mm from the axis, corners rounded with {corner:.2f} mm, "
                           f"corner extremes {extreme:.2f} mm from the axis")
    raise InputError(f"{path}: tool \"{die.get('name')}\": shape \"{die.get('shape')}\" has no flange rule")


def _distance_to_polygon(p, verts):
    """Distance of points p (m x 2) from a convex polygon (0 inside)."""
    d = np.full(len(p), np.inf)
    inside = np.ones(len(p), bool)
    n = len(verts)
    u, v = verts[1] - verts[0], verts[2] - verts[1]
    ccw = u[0] * v[1] - u[1] * v[0] > 0
    for i in range(n):
        a, b = verts[i], verts[(i + 1) % n]
        ab = b - a
        t = np.clip(((p - a) @ ab) / (ab @ ab), 0.0, 1.0)
        d = np.minimum(d, np.linalg.norm(p - (a + t[:, None] * ab), axis=1))
        cr = ab[0] * (p[:, 1] - a[1]) - ab[1] * (p[:, 0] - a[0])
        inside &= (cr >= 0) if ccw else (cr <= 0)
    return np.where(inside, 0.0, d)


def camera_ply(case, path="case"):
    """The ply the camera below sees: the one whose reference mid-surface is
    nearest the die's face."""
    plies = case.get("ply", [])
    if not plies:
        raise InputError(f"{path}: no [[ply]]")
    die = die_tool(case, path)
    origin = np.array(die.get("origin", [0, 0, 0]), float)
    axis = np.array(die.get("axis", [0, 0, 1]), float)

    def height(p):
        c = np.array(p.get("mesh", {}).get("centre", [0, 0, 0]), float)
        return float(np.dot(c - origin, axis))
    return min(plies, key=height)


def blank_box(ply):
    """(centre xy, half sizes) of a rectangular blank."""
    mesh = ply.get("mesh", {})
    if mesh.get("shape") != "rectangle":
        raise InputError(f"[[ply]] \"{ply.get('name')}\": mesh.shape must be \"rectangle\" for the window grid")
    c = np.array(mesh.get("centre", [0, 0, 0]), float)[:2]
    return c, 0.5 * np.array(mesh["size"], float)


def _read_vtu(path):
    import meshio
    try:
        return meshio.read(path)
    except Exception as e:
        raise InputError(f"{path}: cannot read the VTU: {e}")


class PlyStates:
    """The output states of one ply of a run folder: reference and current
    centroids, reference areas, the 3D and 2D-DIC shear angles, and the
    DIC visibility (cumulative) per state."""

    def __init__(self, run_dir, case, ply_name=None, path="case"):
        self.run_dir = run_dir
        summary_path = os.path.join(run_dir, "summary.json")
        try:
            summary = json.load(open(summary_path))
        except (OSError, ValueError) as e:
            raise InputError(f"{summary_path}: {e}")
        ply = camera_ply(case, path) if ply_name is None else next(
            (p for p in case["ply"] if p.get("name") == ply_name), None)
        if ply is None:
            raise InputError(f"{path}: no [[ply]] named \"{ply_name}\"")
        self.ply = ply
        self.name = ply.get("name", "ply")
        self.fibre_angle = math.radians(float(ply.get("fibre_angle_deg", 0.0)))
        self.on_flange, self.flange_text = flange_rule(case, path)
        states = summary.get("forming", {}).get("states", [])
        self.strokes = [float(s["stroke"]) for s in states]
        self.shear, self.dic, self.dic_valid, self.cur_xy, self.visible = [], [], [], [], []
        lost = None
        for k in range(len(states)):
            f = os.path.join(run_dir, "vtu", f"{self.name}_{k + 1:04d}.vtu")
            m = _read_vtu(f)
            tri = m.cells_dict.get("triangle")
            if tri is None:
                raise InputError(f"{f}: no triangle cells")
            u = m.point_data["displacement"]
            ref = m.points - u
            cd = m.cell_data_dict
            for key in ("shear_angle_deg", "dic_shear_angle_deg", "dic_valid"):
                if key not in cd:
                    raise InputError(f"{f}: cell field `{key}` missing (an ncform forming run's VTU has it)")
            if k == 0:
                self.tri = tri
                self.ref_nodes = ref[:, :2]
                r = ref[tri][:, :, :2]
                self.ref_centroid = r.mean(axis=1)
                e1, e2 = r[:, 1] - r[:, 0], r[:, 2] - r[:, 0]
                self.area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
            cur = m.points[tri][:, :, :2].mean(axis=1)
            self.cur_xy.append(m.points[:, :2])
            self.shear.append(np.asarray(cd["shear_angle_deg"]["triangle"], float))
            self.dic.append(np.asarray(cd["dic_shear_angle_deg"]["triangle"], float))
            self.dic_valid.append(np.asarray(cd["dic_valid"]["triangle"], float) > 0.5)
            here = self.on_flange(cur)
            lost = ~here if lost is None else (lost | ~here)
            self.visible.append(~lost)

    def window(self, centre, size=(WINDOW, WINDOW)):
        c = self.ref_centroid
        return ((np.abs(c[:, 0] - centre[0]) <= 0.5 * size[0])
                & (np.abs(c[:, 1] - centre[1]) <= 0.5 * size[1]))

    def stats(self, centre, size=(WINDOW, WINDOW)):
        """Per output state: stroke, 3D mean over the window, 3D and 2D-DIC
        means over its visible elements, visible count and area share."""
        inside = self.window(centre, size)
        a = self.area
        out = []
        for k, stroke in enumerate(self.strokes):
            g3 = self.shear[k]
            ok3 = inside & np.isfinite(g3)
            vis = inside & self.visible[k]
            vis3 = vis & np.isfinite(g3)
            vdic = vis & self.dic_valid[k] & np.isfinite(self.dic[k])
            adic = inside & self.dic_valid[k] & np.isfinite(self.dic[k])
            out.append({
                "stroke": stroke,
                "elements": int(inside.sum()),
                "shear_3d_mean": _wmean(a[ok3], g3[ok3]),
                "visible_elements": int(vis.sum()),
                "visible_area_share": float(a[vis].sum() / a[inside].sum()) if inside.any() else None,
                "shear_3d_visible_mean": _wmean(a[vis3], g3[vis3]),
                "shear_dic_mean": _wmean(a[vdic], self.dic[k][vdic]),
                "shear_dic_all_mean": _wmean(a[adic], self.dic[k][adic]),
            })
        return out

    def projected_shear(self, k):
        """γ = I10 [deg] of every element's projection on the x–y plane at
        state k, from the nodes: the 2D deformation gradient F of the
        reference triangle onto its projected current one, C = FᵀF, the
        reference rovings a0 = (cos θ, sin θ) and b0 = (−sin θ, cos θ):
        γ = π/2 − arccos(a0·C b0 / √(a0·C a0 · b0·C b0)). NaN where the
        projection is turned over."""
        X, x = self.ref_nodes[self.tri], self.cur_xy[k][self.tri]
        dX = np.stack([X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]], axis=2)   # columns: edges
        dx = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]], axis=2)
        F = dx @ np.linalg.inv(dX)
        det = np.linalg.det(F)
        C = np.transpose(F, (0, 2, 1)) @ F
        a0 = np.array([math.cos(self.fibre_angle), math.sin(self.fibre_angle)])
        b0 = np.array([-a0[1], a0[0]])
        i4, i6, i8 = (np.einsum("i,eij,j->e", p, C, q) for p, q in ((a0, a0), (a0, b0), (b0, b0)))
        g = np.degrees(np.pi / 2 - np.arccos(np.clip(i6 / np.sqrt(i4 * i8), -1, 1)))
        return np.where(det > 0, g, np.nan)


def _wmean(w, v):
    return float(np.sum(w * v) / np.sum(w)) if len(w) and np.sum(w) > 0 else None


def quadrant(case):
    """The symmetry part of the blank the candidates cover: x >= 0 and
    y >= 0 (the hemisphere's two mirror planes), x >= 0 only for a
    pyramid punch (the tetrahedron's one mirror plane x = 0)."""
    pyramid = any(t.get("shape") == "pyramid" for t in case.get("tool", []))
    return (lambda c: c[0] >= 0) if pyramid else (lambda c: c[0] >= 0 and c[1] >= 0), \
        ("x >= 0" if pyramid else "x >= 0, y >= 0")


def pick_windows(states, case, count=3):
    """The flange windows of the placement rule (module docstring): a list
    of {"name", "centre", "size", "shear_3d_full_depth", ...}."""
    centre, half = blank_box(states.ply)
    keep, qtext = quadrant(case)
    lim = half - 0.5 * WINDOW
    xs = np.arange(-np.floor(lim[0] / GRID_STEP), np.floor(lim[0] / GRID_STEP) + 1) * GRID_STEP + centre[0]
    ys = np.arange(-np.floor(lim[1] / GRID_STEP), np.floor(lim[1] / GRID_STEP) + 1) * GRID_STEP + centre[1]
    last = len(states.strokes) - 1
    a = states.area
    cands = []
    for x in xs:
        for y in ys:
            if not keep((x - centre[0], y - centre[1])):
                continue
            inside = states.window((x, y))
            if not inside.any() or not states.visible[last][inside].all():
                continue
            g = states.shear[last][inside]
            if not np.isfinite(g).all():
                continue
            cands.append((abs(_wmean(a[inside], g)), float(x), float(y)))
    cands.sort(key=lambda c: (-c[0], c[1], c[2]))
    chosen = []
    for s, x, y in cands:
        if all(math.hypot(x - cx, y - cy) >= MIN_DISTANCE for _, cx, cy in chosen):
            chosen.append((s, x, y))
        if len(chosen) == count:
            break
    chosen.sort(key=lambda c: math.hypot(c[1] - centre[0], c[2] - centre[1]))
    return [{"name": NAMES[i] if i < len(NAMES) else f"W{i + 1}", "centre": [x, y], "size": [WINDOW, WINDOW],
             "abs_shear_3d_full_depth": s}
            for i, (s, x, y) in enumerate(chosen)], {
        "rule": (f"grid {GRID_STEP:g} mm in {qtext}, {WINDOW:g} x {WINDOW:g} mm windows inside the blank, "
                 f"all elements DIC-visible at full depth, the {count} highest |mean 3D shear| at full depth "
                 f"at least {MIN_DISTANCE:g} mm apart, named by distance from the centre"),
        "candidates_visible": len(cands), "run": os.path.abspath(states.run_dir), "ply": states.name}


def case_zones(case):
    """The case's `[[zone]]` windows as {"name", "centre", "size", "ply"}."""
    return [{"name": z.get("name", f"zone {i + 1}"), "centre": list(map(float, z["centre"])),
             "size": list(map(float, z.get("size", [WINDOW, WINDOW]))), "ply": z.get("ply")}
            for i, z in enumerate(case.get("zone", []))]


def windows_json(windows):
    """The windows as JSON text: a list of {"name", "centre", "size"}."""
    return "[\n" + ",\n".join(" " + json.dumps({k: w[k] for k in ("name", "centre", "size")}, ensure_ascii=False)
                              for w in windows) + "\n]\n"


def load_windows(path):
    try:
        data = json.load(open(path))
    except (OSError, ValueError) as e:
        raise InputError(f"{path}: {e}")
    if isinstance(data, dict):
        data = data.get("windows", [])
    for i, w in enumerate(data):
        if not isinstance(w, dict) or "centre" not in w or "name" not in w:
            raise InputError(f"{path}: entry {i}: expected {{\"name\", \"centre\": [x, y], \"size\": [20, 20]}}")
        w.setdefault("size", [WINDOW, WINDOW])
    return data


def window_report(states, windows):
    """{name: stats per state} for a list of windows (on `states`' ply)."""
    return {w["name"]: {"centre": w["centre"], "size": w["size"], "ply": states.name,
                        "states": states.stats(w["centre"], w["size"])} for w in windows}


def format_report(report, strokes=None):
    lines = []
    for name, r in report.items():
        lines.append(f"{name} at ({r['centre'][0]:g}, {r['centre'][1]:g}) on {r['ply']}:")
        for s in r["states"]:
            if strokes is not None and not any(abs(s["stroke"] - t) < 0.26 for t in strokes):
                continue
            f = lambda v: "—" if v is None else f"{v:6.2f}"
            share = s["visible_area_share"]
            lines.append(f"  {s['stroke']:5.1f} mm: 3D {f(s['shear_3d_mean'])}°, visible 3D "
                         f"{f(s['shear_3d_visible_mean'])}°, 2D-DIC {f(s['shear_dic_mean'])}° (all {f(s['shear_dic_all_mean'])}°), visible "
                         f"{s['visible_elements']}/{s['elements']} elements, "
                         f"{'—' if share is None else f'{100 * share:.0f} %'} of the area")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("run_dir")
    ap.add_argument("--case", required=True, help="the case file of the run")
    ap.add_argument("--windows", help="flange windows (JSON) to evaluate instead of picking them")
    ap.add_argument("--pick-out", help="write the picked flange windows to this JSON file")
    ap.add_argument("--json", help="write the full report to this JSON file")
    ap.add_argument("--check", action="store_true",
                    help="compare the 2D-DIC shear recomputed from the nodes with the VTU's")
    args = ap.parse_args(argv)
    case = load_case(args.case)
    states = PlyStates(args.run_dir, case, path=args.case)
    print(f"# camera ply: {states.name}; flat flange: {states.flange_text}")
    if args.windows:
        windows, meta = load_windows(args.windows), {"rule": f"from {args.windows}"}
    else:
        windows, meta = pick_windows(states, case)
        print(f"# flange windows: {meta['rule']}; {meta['candidates_visible']} candidates stay visible")
        if args.pick_out:
            with open(args.pick_out, "w") as f:
                f.write(windows_json(windows))
    zones = [z for z in case_zones(case) if z["ply"] in (None, states.name)]
    report = {"flange_rule": states.flange_text, "camera_ply": states.name, "placement": meta,
              "flange_windows": window_report(states, windows), "case_zones": window_report(states, zones)}
    print("## flange windows\n" + format_report(report["flange_windows"]))
    print("## case zones\n" + format_report(report["case_zones"]))
    if args.check:
        worst = 0.0
        for k in range(len(states.strokes)):
            g = states.projected_shear(k)
            ok = states.dic_valid[k] & np.isfinite(g)
            worst = max(worst, float(np.max(np.abs(g[ok] - states.dic[k][ok]))))
        print(f"# 2D-DIC shear from the nodes against the VTU's dic_shear_angle_deg: largest difference "
              f"{worst:.2e}°")
        report["dic_check_max_difference_deg"] = worst
    if args.json:
        with open(args.json, "w") as f:
            json.dump(report, f, indent=1)
    return report


if __name__ == "__main__":
    try:
        main()
    except InputError as e:
        sys.exit(f"error: {e}")
