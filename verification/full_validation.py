#!/usr/bin/env python3
"""The paper's forming findings at paper size (docs/validation.md): runs the
six shipped forming cases as they are and prints the figures that
docs/validation.md sets beside the paper's findings. Long (some 15 to 30
minutes on two cores): run by `bash verification/run.sh --full`, not in CI.

Checks (each a rule of the benches or a sign the paper reports, never a
fitted value):

* `complete <case>`: the run reached its full depth.
* `quasi-static <case>`: kinetic energy at most 5 % of the internal energy
  from 10 % of the stroke on, and the energy balance error at most 1 % of
  the external work (the explicit path's rules, docs/explicit.md).
* `pole strains <case>` (single-ply hemispheres) and `centre strains <case>`
  (tetrahedra): E22 and E_perp positive, as area-weighted means over the
  elements whose reference centroid lies within 25 mm of the blank's
  centre, at full depth: the paper's Figs. 9 and 11 (its simulation; the
  tetrahedron's experiment does not show them).
* `mirror <case>` (tetrahedron [0°] and [90°]): the outer contour at full
  depth mirror-symmetric about the punch's mirror plane x = 0 within 1 mm
  (largest distance of a contour node from its mirror node's image); the
  [45°] ply has no mirror symmetry with this punch (docs/forming.md).

* The robust findings of the paper's Sections 5.2 and 5.3 (H1, H3, T4, T8:
  `findings_checks` below, margins from verification/findings.py).

Reported, not checked (the paper gives no number to compare with): the
draw-in and zone shear at every output depth, the deformation modes' areas,
the share of mixed-mode 2 in each zone, and the [0°/90°] plies' contours
against the single [0°] ply's (turned by 90° for the 90° ply), node by node.

With `--nudged K [K ...]` it also runs copies of the [0°] and [0°/90°]
hemispheres whose stable step is re-estimated every K increments instead
of every 100 (a perturbation of the step sequence by about 10^-4, the
same bench), and prints the zone shear of the stack's 0° ply against the
single ply's for each sequence, with the spread over the sequences: how
much of the paper's Fig. 10a comparison a single run can tell
(docs/validation.md). Reported, not checked.

Usage: full_validation.py --ncform PATH [--keep DIR] [--only CASE ...] [--nudged K ...]
  (with --keep, runs whose summary.json exists in DIR are reused)
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import traceback

import meshio
import numpy as np

import findings
import full_hemisphere

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
CASES = os.path.join(REPO, "cases")

# The shipped forming cases, in the order they are run.
CASE_NAMES = ["hemisphere-0", "hemisphere-45", "hemisphere-0-90",
              "tetrahedron-0", "tetrahedron-45", "tetrahedron-90"]

# Radius [mm] of the disc about the blank's centre (reference
# coordinates) over which the pole/centre strains are averaged.
CENTRE_RADIUS = 25.0

# The explicit path's quasi-static rules (docs/explicit.md).
KINETIC_LIMIT = 0.05
BALANCE_LIMIT = 0.01

# Mirror symmetry limit of the outer contour [mm] (the one the hemisphere
# bench's symmetry check uses, docs/forming.md).
MIRROR_LIMIT = 1.0

# Increments between two stable-step estimates in the shipped cases (the
# solver's default, `[explicit] time_step_update_interval`, docs/cases.md).
SHIPPED_STEP_INTERVAL = 100

MODE_NAMES = ["near reference", "mixed-mode 1", "mixed-mode 2", "I11 >= 1, I8 > 1",
              "I11 >= 1, I8 <= 1"]

# The PASS/FAIL protocol, the CSV reader, the run's status word and the
# node-by-node contour comparison of the hemisphere suite.
results = full_hemisphere.results
check = full_hemisphere.check
read_csv = full_hemisphere.read_csv
status = full_hemisphere.status
node_distances = full_hemisphere.node_distances


def run_case(ncform, name, work):
    """Runs the shipped case file itself (not a copy, as full_hemisphere.py
    does for its edited cases), so that the outputs name cases/<name>.toml;
    returns the output folder and its summary (None when the run wrote
    none)."""
    out = os.path.join(work, name)
    if os.path.exists(os.path.join(out, "summary.json")):
        print(f"# reusing {out}", flush=True)
    else:
        shutil.rmtree(out, ignore_errors=True)
        print(f"# ncform run cases/{name}.toml", flush=True)
        run = subprocess.run([ncform, "run", os.path.join(CASES, f"{name}.toml"),
                              "--out", out, "--quiet"], capture_output=True, text=True)
        if run.returncode != 0:
            print(run.stderr[-2000:])
    if not os.path.exists(os.path.join(out, "summary.json")):
        return out, None
    summary = json.load(open(os.path.join(out, "summary.json")))
    print(f"# {name}: {status(summary)}, wall {summary['wall_seconds']:.1f} s", flush=True)
    return out, summary


# {ply number: (reference xy, [xy at each output state])} of a run folder.
contours = findings.contours


def centre_strains(vtu):
    """Area-weighted mean E22 and E_perp over the elements whose reference
    centroid lies within CENTRE_RADIUS of the blank's centre."""
    m = meshio.read(vtu)
    ref = m.points - m.point_data["displacement"]
    tri = m.cells_dict["triangle"]
    c = ref[tri].mean(axis=1)
    area = 0.5 * np.linalg.norm(np.cross(ref[tri[:, 1]] - ref[tri[:, 0]],
                                         ref[tri[:, 2]] - ref[tri[:, 0]]), axis=1)
    inside = np.hypot(c[:, 0], c[:, 1]) < CENTRE_RADIUS
    w = area[inside]
    mean = lambda f: float((m.cell_data_dict[f]["triangle"][inside] * w).sum() / w.sum())
    return mean("E22"), mean("E_perp"), int(inside.sum())


# {ply name: its last output state's VTU} of a run folder.
last_ply_vtus = findings.ply_vtus


def report(name, out, s):
    explicit = s["explicit"]
    forming = s["forming"]
    final = forming["states"][-1]
    check(f"complete {name}", s["complete"], f"{status(s)}, {final['stroke']:.1f} mm")
    kinetic, balance = explicit["max_kinetic_ratio"], explicit["max_relative_balance_error"]
    check(f"quasi-static {name}", kinetic <= KINETIC_LIMIT and balance <= BALANCE_LIMIT,
          f"KE/IE at most {100 * kinetic:.2f} % (limit 5 %), balance error "
          f"{balance:.1e} of the external work (limit 1e-2); {explicit['increments']} increments")
    tool_names = [t.split(" (")[0] for t in s.get("tools", [])]
    zones = forming["zones"]
    for st in forming["states"]:
        forces = ", ".join(f"{n} {t['force']:.3f} N" for n, t in zip(tool_names, st["tools"]))
        lifts = ", ".join(f"{x:.3f}" for x in st["lifts"])
        print(f"# {name} at {st['stroke']:.1f} mm: {forces}; lift {lifts} mm")
        for ply, d in enumerate(st["draw_in"]):
            pts = [p[0] for p in forming["draw_in_points"][ply]]
            print(f"#   draw-in ply {ply + 1}: " + ", ".join(f"{p} {x:.1f}" for p, x in zip(pts, d)))
        print("#   zones: " + "; ".join(
            f"{z[0]} ({z[1]}) γ {v['shear_angle_mean']:.1f}° (std {v['shear_angle_std']:.1f}), "
            f"E22 {v['e22_mean']:+.3f}, mixed-mode 2 share {v['mode_fractions'][2]:.2f}"
            for z, v in zip(zones, st["zones"])))
    for m in forming.get("deformation_modes", []):
        if abs(m["stroke"] - final["stroke"]) < 1e-9:
            print(f"# {name} deformation modes of {m['ply']} at {m['stroke']:.1f} mm [mm²]: " +
                  ", ".join(f"{n} {a:.0f}" for n, a in zip(MODE_NAMES, m["areas"])))
    strains = {}
    for ply, vtu in last_ply_vtus(out).items():
        e22, e_perp, n = centre_strains(vtu)
        strains[ply] = (e22, e_perp)
        print(f"# {name} {ply}: E22 {e22:+.3f}, E_perp {e_perp:+.3f} within {CENTRE_RADIUS:.0f} mm "
              f"of the centre ({n} elements)")
    if name in ("hemisphere-0", "hemisphere-45") or name.startswith("tetrahedron"):
        e22, e_perp = next(iter(strains.values()))
        what = "pole" if name.startswith("hemisphere") else "centre"
        margin = findings.CENTRE_STRAIN_UNCERTAINTY or 0.0
        check(f"{what} strains {name}", e22 > margin and e_perp > margin,
              f"E22 {e22:+.3f}, E_perp {e_perp:+.3f} within {CENTRE_RADIUS:.0f} mm of the "
              f"{what} at {final['stroke']:.1f} mm (the paper: positive; findings "
              f"{'H11' if what == 'pole' else 'T3'}, margin {margin:g}: "
              f"findings.CENTRE_STRAIN_UNCERTAINTY)")
    if name in ("tetrahedron-0", "tetrahedron-90"):
        ref, states = contours(out)[1]
        d = node_distances(ref, states[-1], ref, states[-1],
                           lambda r: np.array([-r[0], r[1]]),
                           lambda x: np.array([-x[0], x[1]]))
        check(f"mirror {name}", d.size > 0 and d.max() <= MIRROR_LIMIT,
              f"outer contour at {final['stroke']:.1f} mm about x = 0: largest {d.max():.3f} mm, "
              f"RMS {np.sqrt(np.mean(d * d)):.3f} mm over {d.size} nodes (limit 1 mm)")


def stack_against_single(single_out, stack_out):
    single = contours(single_out)[1]
    stack = contours(stack_out)
    for ply, turned in ((1, False), (2, True)):
        ref, states = stack[ply]
        if turned:
            # The 90° ply at reference r is the [0°] ply at r turned by -90°;
            # its final positions turned back by +90°.
            d = node_distances(ref, states[-1], single[0], single[1][-1],
                               lambda r: np.array([r[1], -r[0]]),
                               lambda x: np.array([-x[1], x[0]]))
        else:
            d = node_distances(ref, states[-1], single[0], single[1][-1],
                               lambda r: r, lambda x: x)
        print(f"# hemisphere-0-90 ply {ply} against the single [0°] ply"
              f"{' turned by 90°' if turned else ''} at full depth: RMS "
              f"{np.sqrt(np.mean(d * d)):.2f} mm, largest {d.max():.2f} mm over {d.size} nodes")


def findings_checks(outs):
    """The robust forming findings of the paper (verification/findings.py,
    docs/validation.md "The paper's findings, one by one"), on the runs in
    `outs` ({case: folder}); the margins are findings.py's named
    uncertainties, each with its source there.

    * `H1 <case>` (Section 5.2, Fig. 8a: "strongly asymmetrical behavior
      unique to UD-NCF"): the [0°] and [45°] contours at 75 mm lie further
      than CONTOUR_UNCERTAINTY_MM (RMS, node by node) from themselves turned
      by 90° about the punch axis, the symmetry of a balanced biaxial
      fabric. Fails if the contour is as 90°-symmetric as a woven one's
      within the contour's uncertainty.
    * `H3 ply N` ("the simulative contours of the double-layer tests nearly
      match the results of two superposed single-layer contours"): each
      ply's contour of [0°/90°] within CONTOUR_UNCERTAINTY_MM RMS of the
      single [0°] ply's (turned by 90° for the 90° ply). Fails if the plies
      constrain each other beyond the contour's uncertainty.
    * `T4 <case>` (Section 5.3: the positive centre strains "more pronounced
      for the tetrahedron test compared to the hemisphere test"): the
      centre E22 of each tetrahedron layup exceeds the single-ply
      hemispheres' pole E22 by more than twice CENTRE_STRAIN_UNCERTAINTY (0
      while it is not measured).
    * `T8 hemisphere <case>` ("mixed-mode 1 … was the main deformation mode
      in the hemisphere-test"): mixed-mode 1 covers more than half of each
      hemisphere ply's reference area at 75 mm (the main mode: the
      majority; the share's margin MODE_AREA_UNCERTAINTY_MM2, 0 while not
      measured). `T8 tetrahedron <case>` ("mixed-mode 2 … additionally
      occurs during tetrahedron forming"): its share at 95 mm exceeds the
      largest share of any hemisphere ply. Fail if the modes' order does.

    Reported, not checked (docs/validation.md says why): H6 (the stack's
    zone shear against the single ply's: zone C is lower, where the paper
    has it higher, beyond the step sequences' spread, and A and B lie
    within it), H12 (the stack's pole strains: reduced, not prevented) and
    the mixed-mode 2 shares of the tetrahedron's zones (T8's placement)."""
    hemis = [c for c in ("hemisphere-0", "hemisphere-45") if c in outs]
    u_contour = findings.CONTOUR_UNCERTAINTY_MM
    for c in hemis:
        rms, largest = findings.contour_turn_asymmetry(outs[c])
        check(f"H1 {c}", rms > u_contour,
              f"contour at full depth against itself turned by 90°: RMS {rms:.2f} mm, "
              f"largest {largest:.2f} mm (margin {u_contour} mm: CONTOUR_UNCERTAINTY_MM)")
    if "hemisphere-0" in outs and "hemisphere-0-90" in outs:
        work = os.path.dirname(outs["hemisphere-0"])
        if os.path.dirname(outs["hemisphere-0-90"]) == work:
            for ply, (rms, largest) in findings.stack_contour_distances(work).items():
                check(f"H3 ply {ply}", rms < u_contour,
                      f"[0°/90°] ply {ply} against the single [0°] ply at full depth: RMS "
                      f"{rms:.2f} mm, largest {largest:.2f} mm (limit {u_contour} mm)")
        depths, diff = findings.stack_minus_single_zones(work)
        spread = findings.HEMI_ZONE_STEP_SPREAD_DEG
        for depth, d in zip(depths, diff):
            print(f"# H6 stack − single at {depth:.0f} mm: zone A / B / C "
                  + " / ".join(f"{x:+.1f}" for x in d) + f"° (paper: A < 0, B > 0, C > 0; "
                  f"step-sequence spread {spread}°, mesh change up to "
                  f"{findings.HEMI_ZONE_MESH_CHANGE_DEG}°)")
        for ply, (e22, ep) in findings.centre_strains(outs["hemisphere-0-90"]).items():
            print(f"# H12 [0°/90°] {ply}: pole E22 {e22:+.3f}, E_perp {ep:+.3f} "
                  f"(the paper: no positive strain in the stack)")
    pole = [findings.centre_strains(outs[c]) for c in hemis]
    pole_e22 = max((e for p in pole for e, _ in p.values()), default=None)
    u_centre = findings.CENTRE_STRAIN_UNCERTAINTY or 0.0
    tetras = [c for c in ("tetrahedron-0", "tetrahedron-45", "tetrahedron-90") if c in outs]
    for c in tetras:
        e22 = next(iter(findings.centre_strains(outs[c]).values()))[0]
        if pole_e22 is not None:
            check(f"T4 {c}", e22 - pole_e22 > 2 * u_centre,
                  f"centre E22 {e22:+.3f} against the single-ply hemispheres' pole E22 "
                  f"{pole_e22:+.3f} (margin 2 × {u_centre:g})")
    u_mode = findings.MODE_AREA_UNCERTAINTY_MM2 or 0.0
    hemi_mm2 = []
    for c in [c for c in ("hemisphere-0", "hemisphere-45", "hemisphere-0-90") if c in outs]:
        s = json.load(open(os.path.join(outs[c], "summary.json")))["forming"]
        last = max(m["stroke"] for m in s["deformation_modes"])
        for m in s["deformation_modes"]:
            if abs(m["stroke"] - last) < 1e-9:
                a = np.array(m["areas"], dtype=float)
                hemi_mm2.append(a[2] / a.sum())
                check(f"T8 hemisphere {c} {m['ply']}", a[1] - u_mode > 0.5 * a.sum(),
                      f"mixed-mode 1 covers {a[1]:.0f} of {a.sum():.0f} mm² "
                      f"({100 * a[1] / a.sum():.1f} %; the main mode: more than half)")
    for c in tetras:
        shares = findings.mode_shares(outs[c])
        s = json.load(open(os.path.join(outs[c], "summary.json")))["forming"]
        total = sum(next(m["areas"] for m in s["deformation_modes"]))
        mm2 = next(iter(shares.values()))[2]
        if hemi_mm2:
            check(f"T8 tetrahedron {c}", mm2 - u_mode / total > max(hemi_mm2),
                  f"mixed-mode 2 covers {100 * mm2:.1f} % of the ply at full depth; the "
                  f"hemisphere plies at most {100 * max(hemi_mm2):.1f} %")
        print(f"# T8 {c}: mixed-mode 2 share in zones A / B / C at full depth "
              + " / ".join(f"{x:.2f}" for x in findings.zone_mode2_shares(outs[c])))


def zone_means(summary):
    """[[zone A, B, C mean shear angle] at each output state] [deg] and the
    output depths [mm]."""
    states = summary["forming"]["states"]
    return ([[z["shear_angle_mean"] for z in st["zones"]] for st in states],
            [st["stroke"] for st in states])


def nudged_zones(ncform, work, intervals, shipped):
    """The stack's 0° ply against the single [0°] ply, zone by zone, and the
    single ply's mirror symmetry at full depth, for the shipped step
    sequence (`shipped`: the two runs' output folders, or None) and for
    copies re-estimating the step every K increments."""
    runs = {}
    if shipped is not None:
        runs[SHIPPED_STEP_INTERVAL] = shipped
    for k in intervals:
        edit = [("[explicit]\n", f"[explicit]\ntime_step_update_interval = {k}\n")]
        runs[k] = tuple(
            full_hemisphere.run_case(ncform, f"{name}.toml", work, f"{name}-k{k}", edit)[0]
            for name in ("hemisphere-0", "hemisphere-0-90"))
    differences = {}
    for k, (single_out, stack_out) in sorted(runs.items()):
        single, stack = (json.load(open(os.path.join(o, "summary.json")))
                         for o in (single_out, stack_out))
        (a, depths), (b, _) = zone_means(single), zone_means(stack)
        differences[k] = np.array(b) - np.array(a)
        ref, states = contours(single_out)[1]
        about_x, about_y = full_hemisphere.axis_mirror_deviations(ref, states[-1])
        print(f"# step re-estimated every {k} increments: "
              f"{single['explicit']['increments']} / {stack['explicit']['increments']} increments "
              f"(single / stack); the single ply's contour at {depths[-1]:.0f} mm mirror-symmetric "
              f"about the x / y axis to {about_x:.2f} / {about_y:.2f} mm (largest distance)")
        for depth, za, zb, d in zip(depths, a, b, differences[k]):
            print(f"#   {depth:.0f} mm: zone A / B / C stack 0° ply "
                  + " / ".join(f"{x:.1f}" for x in zb) + "°, single "
                  + " / ".join(f"{x:.1f}" for x in za) + "°, stack − single "
                  + " / ".join(f"{x:+.1f}" for x in d) + "°")
    if len(differences) > 1:
        stacked = np.array(list(differences.values()))
        for s, depth in enumerate(depths):
            lo, hi = stacked[:, s, :].min(axis=0), stacked[:, s, :].max(axis=0)
            print(f"# stack − single at {depth:.0f} mm over {len(differences)} step sequences: "
                  + "; ".join(f"{z} {l:+.1f} … {h:+.1f}°" for z, l, h in zip("ABC", lo, hi)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ncform", required=True)
    ap.add_argument("--keep")
    ap.add_argument("--only", nargs="*", choices=CASE_NAMES)
    ap.add_argument("--nudged", nargs="*", type=int, default=[],
                    help="also run the [0°] and [0°/90°] hemispheres with the step "
                         "re-estimated every K increments (docs/validation.md)")
    args = ap.parse_args()
    if not args.ncform:
        check("build", False, "no ncform binary")
        return
    work = args.keep or tempfile.mkdtemp(prefix="ncform-full-validation-")
    os.makedirs(work, exist_ok=True)
    outs = {}
    for name in args.only or CASE_NAMES:
        out, s = run_case(args.ncform, name, work)
        if s is None:
            check(f"complete {name}", False, "no summary.json")
            continue
        outs[name] = out
        report(name, out, s)
    if "hemisphere-0" in outs and "hemisphere-0-90" in outs:
        stack_against_single(outs["hemisphere-0"], outs["hemisphere-0-90"])
    findings_checks(outs)
    if args.nudged:
        shipped = None
        if "hemisphere-0" in outs and "hemisphere-0-90" in outs:
            shipped = (outs["hemisphere-0"], outs["hemisphere-0-90"])
        nudged_zones(args.ncform, work, args.nudged, shipped)
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    try:
        main()
    except Exception:  # a crash is a failed check, with its traceback
        traceback.print_exc()
        results.append(False)
    finally:
        passed = sum(results)
        print(f"CHECK-SUMMARY passed={passed} failed={len(results) - passed}")
        sys.exit(0 if results and all(results) else 1)
