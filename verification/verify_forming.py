#!/usr/bin/env python3
"""The forming foundation on problems with known answers, at fine meshes.

ncform runs the shipped verification cases of `cases/verification/` (the
same files `cargo test` runs coarse) through `ncform run`, refined here,
and each result is compared with a reference that shares no code with
ncform:

* capstan (`capstan.toml`): a strip pre-wrapped over a fixed cylinder
  (R = 50 mm, wrap angle pi, mu = 0.336), one end held, the other pulled:
  at full slip the ratio of the end reactions is exp(mu pi) (Euler-Eytelwein,
  closed form), within 0.5 %; the explicit run agrees with the quasi-static
  one within 1 %.
* friction patch (`friction-patch.toml`): a patch pulled up a slope
  (tan alpha = 0.1, mu = 0.3) under a dead weight G: the pull at full slip is
  G (sin alpha + mu cos alpha), to 1e-6; without the pull the patch sticks.
* cantilevers (`cantilever-rovings.toml`, `cantilever-transverse.toml`):
  strips clamped horizontally, bent by their own weight (B11 = 4.06 N mm,
  L = 150 mm; B22 = 0.018 N mm, L = 30 mm; 0.30 kg/m^2): the tip deflection
  within 1 % of the large-deflection elastica, solved here with scipy
  (`reference_elastica.py`).
* indentation (`indentation.toml`): a clamped circular SVK membrane
  (R = 100, t = 0.3, E = 10, nu = 0.3) pushed 40 mm by a frictionless
  sphere (R = 40): the force within 1 % of the axisymmetric solution of
  `reference_indentation.py` at 10, 20, 30 and 40 mm (quasi-static), and
  the explicit force within 1 % of the quasi-static one at 30 and 40 mm
  (where the indentation is quasi-static: at small depths the force of the
  slack membrane, ~d^3, is below the inertia and damping forces of any
  practical explicit run).
* blankholder at rest (`blankholder.toml`): the contact force on a floating
  1.7 kg blankholder equals its weight to 1e-6 and it stays there, quasi-
  statically and explicitly (damped).

Usage: verify_forming.py --ncform PATH [--keep DIR]
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
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
CASES = os.path.join(REPO, "cases", "verification")
sys.path.insert(0, HERE)

import reference_elastica  # noqa: E402
import reference_indentation  # noqa: E402

results = []


def check(name, ok, detail):
    results.append(bool(ok))
    print(f"{'PASS' if ok else 'FAIL'} [{name}] {detail}")


def read_history(out):
    with open(os.path.join(out, "history.csv")) as f:
        rows = [r for r in csv.reader(line for line in f if not line.startswith("#"))]
    header = rows[0]
    data = np.array([[float(x) for x in r] for r in rows[1:]])
    return {h: data[:, i] for i, h in enumerate(header)}


def case_text(name, edits=(), prepend=""):
    with open(os.path.join(CASES, name)) as f:
        text = f.read()
    for old, new in edits:
        if old not in text:
            raise ValueError(f"{name}: `{old}` not in the case")
        text = text.replace(old, new, 1)
    return prepend + text


def run(ncform, work, name, text):
    """Writes `text` as `name` in `work` (with the shipped parameter file
    beside it) and runs it; returns (exit code, output folder)."""
    path = os.path.join(work, name)
    with open(path, "w") as f:
        f.write(text)
    out = os.path.join(work, "out-" + os.path.splitext(name)[0])
    start = time.time()
    proc = subprocess.run([ncform, "run", path, "--out", out, "--quiet"],
                          capture_output=True, text=True)
    print(f"# {name}: exit {proc.returncode}, {time.time() - start:.1f} s; "
          f"{proc.stdout.strip().splitlines()[0] if proc.stdout.strip() else ''}")
    if proc.stderr.strip():
        print("# stderr: " + proc.stderr.strip().replace("\n", "\n# stderr: "))
    return proc.returncode, out


def explicit(text, settings):
    """The case with the explicit solver: drop the [solver] table of Newton
    knobs, add the [explicit] table."""
    text = re.sub(r"\n\[solver\]\n(?:[^\n\[]+\n)*", "\n", text)
    return 'solver = "explicit"\n' + text + "\n[explicit]\n" + settings + "\n"


def capstan(ncform, work):
    # At h = 1.25 mm, without bending stiffness, the stick penalty of the
    # automatic setting (the rovings' E t per node) leaves a stick zone of
    # mu t_N / eps_T ~ 1e-4 mm per node, and Newton stalls on the
    # stick/slip switches at zero tension; a tenth of it converges
    # (docs/contact.md, "Limits"). The ratio at full slip, mu t_N exactly,
    # does not depend on the penalty.
    fine = case_text("capstan.toml", [
        ("element_size = 2.5", "element_size = 1.25"),
        ("[output]", "[contact]\ntangential_penalty_scale = 0.1\n\n[output]"),
    ])
    code, out = run(ncform, work, "capstan.toml", fine)
    check("capstan-run", code == 0, f"quasi-static run exit {code}")
    if code != 0:
        return
    h = read_history(out)
    held = h["boundary 1 (end_a) reaction z [N]"]
    pulled = h["boundary 2 (end_b) reaction z [N]"]
    slipping = h["slipping contacts [-]"]
    closed = h["closed contacts [-]"]
    exact = math.exp(0.336 * math.pi)
    ratio = pulled / held
    full = slipping == closed
    worst = float(np.max(np.abs(ratio[full] / exact - 1))) if full.any() else 1.0
    check("capstan-ratio", full.any() and worst <= 5e-3,
          f"T_pull/T_hold at full slip ({int(full.sum())} of {len(full)} steps): "
          f"{ratio[-1]:.5f} at the end, worst {worst:.2e} from exp(mu pi) = {exact:.5f} (limit 5e-3)")
    # The explicit copy without the quasi-static stick penalty, a key the
    # explicit solver does not take (docs/cases.md, "Keys that do not apply").
    xtext = explicit(fine.replace("[contact]\ntangential_penalty_scale = 0.1\n\n", ""),
                     "duration = 0.02")
    code, xout = run(ncform, work, "capstan-explicit.toml", xtext)
    check("capstan-explicit-run", code == 0, f"explicit run exit {code}")
    if code != 0:
        return
    x = read_history(xout)
    xratio = x["boundary 2 (end_b) reaction z [N]"] / x["boundary 1 (end_a) reaction z [N]"]
    lam = x["programme fraction [-]"]
    # Full slip once the pull has built up (from 10 % of the programme on).
    sel = lam >= 0.1
    qs = np.interp(lam[sel], h["programme fraction [-]"], ratio)
    worst = float(np.max(np.abs(xratio[sel] / qs - 1)))
    check("capstan-explicit-vs-quasi-static", worst <= 1e-2,
          f"explicit/quasi-static ratio of the end-force ratios, worst {worst:.2e} over "
          f"{int(sel.sum())} outputs from 10 % of the pull (limit 1e-2)")
    with open(os.path.join(xout, "summary.json")) as f:
        figures = json.load(f)["explicit"]
    check("capstan-explicit-energy", figures["max_relative_balance_error"] <= 1e-2,
          f"energy balance error {figures['max_relative_balance_error']:.2e} of the work (limit 1e-2)")


def friction_patch(ncform, work):
    code, out = run(ncform, work, "friction-patch.toml", case_text("friction-patch.toml"))
    check("friction-patch-run", code == 0, f"exit {code}")
    if code != 0:
        return
    h = read_history(out)
    alpha = math.atan(0.1)
    expected = 10.0 * (math.sin(alpha) + 0.3 * math.cos(alpha))
    pull = h["boundary 1 (right) reaction x [N]"][-1]
    err = abs(pull / expected - 1)
    check("friction-patch-slip", err <= 1e-6,
          f"pull at full slip {pull:.9f} N vs G (sin a + mu cos a) = {expected:.9f} N: {err:.1e} (limit 1e-6)")
    text = case_text("friction-patch.toml")
    start, end = text.index("# The uphill edge"), text.index("[contact]")
    text = text[:start] + '[[probe]]\nnodes = "all"\n\n' + text[end:]
    code, out = run(ncform, work, "friction-stick.toml", text)
    check("friction-patch-stick-run", code == 0, f"exit {code}")
    if code != 0:
        return
    h = read_history(out)
    slipping = int(np.max(h["slipping contacts [-]"]))
    moved = float(np.max(np.abs(h["probe 1 (all) displacement x [mm]"])))
    check("friction-patch-stick", slipping == 0 and moved <= 1e-6,
          f"without the pull: {slipping} slipping nodes, largest mean slide {moved:.1e} mm (limit 1e-6)")


def cantilevers(ncform, work):
    q = 0.30e-9 * 9810.0  # N/mm^2
    for name, stiffness, length, cells in (
            ("cantilever-rovings.toml", 4.06, 150.0, ("cells = [120, 4]", "cells = [480, 8]")),
            ("cantilever-transverse.toml", 0.018, 30.0, ("cells = [48, 4]", "cells = [192, 8]"))):
        code, out = run(ncform, work, name, case_text(name, [cells]))
        check(f"{name}-run", code == 0, f"exit {code}")
        if code != 0:
            continue
        h = read_history(out)
        tip = -h["probe 1 (right) displacement z [mm]"][-1]
        exact = reference_elastica.tip_deflection(stiffness, q, length)
        err = abs(tip / exact - 1)
        check(f"{name}-elastica", err <= 1e-2,
              f"tip deflection {tip:.4f} mm vs elastica {exact:.4f} mm: {err:.2e} (limit 1e-2)")


def indentation(ncform, work):
    shutil.copy(os.path.join(CASES, "svk-e10.toml"), work)
    fine = case_text("indentation.toml", [("element_size = 4.0", "element_size = 2.0")])
    code, out = run(ncform, work, "indentation.toml", fine)
    check("indentation-run", code == 0, f"exit {code}")
    if code != 0:
        return
    h = read_history(out)
    depth, force = h["sphere displacement [mm]"], h["sphere force [N]"]
    depths = [10.0, 20.0, 30.0, 40.0]
    reference, _ = reference_indentation.indentation_force(depths, 10.0, 0.3, 0.3, 100.0, 40.0)
    errors = [abs(np.interp(d, depth, force) / f - 1) for d, f in zip(depths, reference)]
    check("indentation-force", max(errors) <= 1e-2,
          "force vs the axisymmetric reference at "
          + ", ".join(f"{d:g} mm: {e:.2e}" for d, e in zip(depths, errors)) + " (limit 1e-2)")
    xtext = explicit(fine.replace("offset = 0.0", "offset = 0.0\nexplicit_stiffness = 1.0"),
                     "duration = 0.2\ndamping = 200.0")
    code, xout = run(ncform, work, "indentation-explicit.toml", xtext)
    check("indentation-explicit-run", code == 0, f"exit {code}")
    if code != 0:
        return
    x = read_history(xout)
    errors = [abs(np.interp(d, x["sphere displacement [mm]"], x["sphere force [N]"])
                  / np.interp(d, depth, force) - 1) for d in (30.0, 40.0)]
    check("indentation-explicit-vs-quasi-static", max(errors) <= 1e-2,
          f"explicit/quasi-static force at 30 mm: {errors[0]:.2e}, 40 mm: {errors[1]:.2e} (limit 1e-2)")


def blankholder(ncform, work):
    weight = 1.7e-3 * 9810.0
    fine = case_text("blankholder.toml", [("element_size = 10.0", "element_size = 2.5")])
    code, out = run(ncform, work, "blankholder.toml", fine)
    check("blankholder-run", code == 0, f"exit {code}")
    if code == 0:
        h = read_history(out)
        err = float(np.max(np.abs(h["blankholder force [N]"] / weight - 1)))
        moved = float(np.max(np.abs(h["blankholder displacement [mm]"])))
        check("blankholder-weight", err <= 1e-6 and moved <= 3e-3,
              f"contact force / weight - 1 = {err:.1e} (limit 1e-6); displacement {moved:.1e} mm "
              "(limit: the gap tolerance 3e-3 mm)")
    xtext = explicit(fine, "duration = 0.02\ndamping = 2000.0")
    code, xout = run(ncform, work, "blankholder-explicit.toml", xtext)
    check("blankholder-explicit-run", code == 0, f"exit {code}")
    if code == 0:
        x = read_history(xout)
        force = x["blankholder force [N]"]
        err = abs(force[-1] / weight - 1)
        drift = abs(x["blankholder displacement [mm]"][-1] - x["blankholder displacement [mm]"][-2])
        check("blankholder-explicit-weight", err <= 1e-6,
              f"settled contact force / weight - 1 = {err:.1e} (limit 1e-6; the damped "
              f"start-up transient decays as exp(-alpha T / 2) = 2e-9); last drift {drift:.1e} mm")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--ncform", required=True)
    parser.add_argument("--keep", help="keep the outputs in this folder")
    args = parser.parse_args()
    if not args.ncform or not os.path.exists(args.ncform):
        check("binary", False, f"no ncform binary at {args.ncform!r}")
        print(f"CHECK-SUMMARY passed={sum(results)} failed={len(results) - sum(results)}")
        return 1
    work = args.keep or tempfile.mkdtemp(prefix="ncform-forming-")
    os.makedirs(work, exist_ok=True)
    for part in (capstan, friction_patch, cantilevers, indentation, blankholder):
        try:
            part(args.ncform, work)
        except Exception as e:  # a crash counts as a failed check, not a missing summary
            check(part.__name__, False, f"raised {type(e).__name__}: {e}")
    print(f"CHECK-SUMMARY passed={sum(results)} failed={len(results) - sum(results)}")
    return 0 if all(results) else 1


if __name__ == "__main__":
    sys.exit(main())
