#!/usr/bin/env python3
"""The explicit path against the quasi-static path on the 45 deg OAT.

What this checks
================
ncform runs the same off-axis tension test twice: `cases/oat45.toml`
(quasi-static: Newton with load stepping, 0 to 80 mm) and
`cases/oat45-explicit.toml` (central differences, lumped masses from the
areal mass 0.30 kg/m^2, the clamp moved along a smooth step at a mean
100 mm/s; the same paper-size mesh of ~8,200 triangles). For a
rate-independent law, a slow enough explicit run must reproduce the
quasi-static curves. The criteria:

* `force-rms`: the explicit clamp force, linearly interpolated to the
  quasi-static displacements in (0, 80] mm, within 2 % RMS of the
  quasi-static force, relative to the peak quasi-static force.
* `mdz-rms`: likewise for the MDZ means of E22, the shear angle and E_perp,
  each relative to the peak magnitude of its quasi-static curve (2 %).
* `kinetic`: the kinetic energy stays below 1 % of the internal energy from
  10 % of the stroke on (summary.json `explicit.max_kinetic_ratio`, and
  recomputed here from energy.csv).
* `energy-balance`: |IE + KE + damping - W_ext - E0| below 1 % of the
  largest energy at every output (energy.csv); central differences conserve
  energy to O((omega dt)^2) per unit energy, far below that.
* `roving-mass/...`: the same checks for the explicit run with
  `roving_mass_length = 6.5` (mm) (docs/explicit.md, "Roving mass scaling"):
  the coupling masses along the rovings lengthen the step about 4.5 times
  and must leave the quasi-static curves within the same limits.
* `outputs`: the explicit run writes the same files as the quasi-static one,
  plus energy.csv/png, and the units in every CSV header.

The explicit run's interpolation error is bounded by its 0.5 mm history
interval: the force curve's curvature over 0.5 mm changes it by < 0.1 %.
Usage: verify_explicit.py --ncform PATH [--keep DIR]
"""

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
results = []


def check(name, ok, detail):
    results.append(ok)
    print(f"{'PASS' if ok else 'FAIL'} [{name}] {detail}")


def read_csv(path):
    with open(path) as f:
        rows = [r for r in csv.reader(line for line in f if not line.startswith("#"))]
    header, data = rows[0], np.array([[float(x) for x in r] for r in rows[1:]])
    return header, data


def run(ncform, case, out):
    start = time.time()
    proc = subprocess.run([ncform, "run", case, "--out", out, "--quiet"],
                          capture_output=True, text=True)
    wall = time.time() - start
    print(f"# {case}: exit {proc.returncode}, {wall:.1f} s; {proc.stdout.strip()}")
    if proc.stderr.strip():
        print("# stderr: " + proc.stderr.strip().replace("\n", "\n# stderr: "))
    return proc.returncode


def rms_relative(x_ref, y_ref, x, y):
    """RMS of y (interpolated to x_ref) - y_ref over the peak |y_ref|."""
    interp = np.interp(x_ref, x, y)
    peak = np.max(np.abs(y_ref))
    return float(np.sqrt(np.mean((interp - y_ref) ** 2)) / peak)


def compare(label, qs_out, ex_out):
    """The checks of one explicit run against the quasi-static one."""
    _, qs_force = read_csv(os.path.join(qs_out, "force_displacement.csv"))
    ex_header, ex_force = read_csv(os.path.join(ex_out, "force_displacement.csv"))
    d_ref, f_ref = qs_force[:, 0], qs_force[:, 1]
    window = (d_ref > 0) & (d_ref <= 80.0 + 1e-9)
    err = rms_relative(d_ref[window], f_ref[window], ex_force[:, 0], ex_force[:, 1])
    check(f"{label}force-rms", err <= 0.02,
          f"clamp force RMS difference {100 * err:.3f} % of the peak "
          f"{np.max(f_ref):.4f} N over {window.sum()} quasi-static points (limit 2 %)")
    for d in (20.0, 40.0, 60.0, 80.0):
        fq = np.interp(d, d_ref, f_ref)
        fe = np.interp(d, ex_force[:, 0], ex_force[:, 1])
        print(f"#   F({d:.0f} mm): quasi-static {fq:.4f} N, explicit {fe:.4f} N "
              f"({100 * (fe - fq) / fq:+.2f} %)")

    _, qs_mdz = read_csv(os.path.join(qs_out, "mdz_strains.csv"))
    _, ex_mdz = read_csv(os.path.join(ex_out, "mdz_strains.csv"))
    for col, name in ((1, "E22"), (2, "shear angle"), (3, "E_perp")):
        err = rms_relative(qs_mdz[window, 0], qs_mdz[window, col], ex_mdz[:, 0], ex_mdz[:, col])
        check(f"{label}mdz-rms", err <= 0.02,
              f"MDZ {name}: RMS difference {100 * err:.3f} % of the peak "
              f"{np.max(np.abs(qs_mdz[:, col])):.4g} (limit 2 %)")

    with open(os.path.join(ex_out, "summary.json")) as f:
        summary = json.load(f)
    explicit = summary["explicit"]
    e_header, energy = read_csv(os.path.join(ex_out, "energy.csv"))
    col = {h: i for i, h in enumerate(e_header)}
    disp = energy[:, col["displacement [mm]"]]
    ie = energy[:, col["internal [N*mm]"]]
    ke = energy[:, col["kinetic [N*mm]"]]
    late = disp >= 0.1 * 80.0
    ratio = float(np.max(ke[late] / ie[late]))
    check(f"{label}kinetic", ratio < 0.01 and explicit["max_kinetic_ratio"] < 0.01,
          f"max KE/IE from 8 mm on: {100 * ratio:.3f} % (energy.csv), "
          f"{100 * explicit['max_kinetic_ratio']:.3f} % (summary.json); limit 1 %")
    balance = float(np.max(np.abs(energy[:, col["relative balance error [-]"]])))
    check(f"{label}energy-balance", balance < 0.01,
          f"largest relative energy-balance error {balance:.2e} (limit 1e-2)")
    w_end = energy[-1, col["external work [N*mm]"]]
    print(f"# explicit: {explicit['increments']} increments, "
          f"{explicit['element_cycles_per_second'] / 1e6:.1f} M element-cycles/s on "
          f"{explicit['threads']} threads, critical step "
          f"{explicit['initial_critical_time_step']:.3e} s, W_ext(80 mm) = {w_end:.3f} N*mm, "
          f"wall {summary['wall_seconds']:.1f} s")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--ncform", required=True)
    parser.add_argument("--keep")
    args = parser.parse_args()
    if not args.ncform or not os.path.exists(args.ncform):
        check("build", False, "no ncform binary")
        print(f"CHECK-SUMMARY passed={sum(results)} failed={len(results) - sum(results)}")
        return 1
    work = args.keep or tempfile.mkdtemp(prefix="ncform-explicit-")
    qs_out, ex_out = os.path.join(work, "qs"), os.path.join(work, "explicit")
    rc_qs = run(args.ncform, os.path.join(REPO, "cases", "oat45.toml"), qs_out)
    rc_ex = run(args.ncform, os.path.join(REPO, "cases", "oat45-explicit.toml"), ex_out)
    check("runs", rc_qs == 0 and rc_ex == 0,
          f"both runs complete (exit codes {rc_qs}, {rc_ex})")
    if rc_qs != 0 or rc_ex != 0:
        print(f"CHECK-SUMMARY passed={sum(results)} failed={len(results) - sum(results)}")
        return 1

    compare("", qs_out, ex_out)

    # The same run with roving mass scaling (docs/explicit.md): the same
    # limits must hold with about 4.5 times fewer increments.
    with open(os.path.join(REPO, "cases", "oat45-explicit.toml")) as f:
        text = f.read()
    roving_case = os.path.join(work, "oat45-explicit-roving.toml")
    with open(roving_case, "w") as f:
        f.write(text.replace("[explicit]\n", "[explicit]\nroving_mass_length = 6.5\n", 1))
    roving_out = os.path.join(work, "explicit-roving")
    rc_rm = run(args.ncform, roving_case, roving_out)
    check("roving-mass/runs", rc_rm == 0, f"the run with roving_mass_length = 6.5 mm completes (exit {rc_rm})")
    if rc_rm == 0:
        compare("roving-mass/", qs_out, roving_out)

    expected = {"force_displacement.csv", "force_displacement.png", "mdz_strains.csv",
                "mdz_strains.png", "contours.png", "oat.pvd", "summary.json", "vtu"}
    have_qs, have_ex = set(os.listdir(qs_out)), set(os.listdir(ex_out))
    units_ok = all("units:" in open(os.path.join(ex_out, n)).read()
                   for n in ("force_displacement.csv", "mdz_strains.csv", "energy.csv"))
    check("outputs", expected <= have_qs and expected | {"energy.csv", "energy.png"} <= have_ex
          and sorted(os.listdir(os.path.join(qs_out, "vtu"))) ==
          sorted(os.listdir(os.path.join(ex_out, "vtu"))) and units_ok,
          f"explicit outputs {sorted(have_ex)}; same VTU states as quasi-static; units in headers")
    print(f"CHECK-SUMMARY passed={sum(results)} failed={len(results) - sum(results)}")
    return 0 if all(results) else 1


if __name__ == "__main__":
    sys.exit(main())
