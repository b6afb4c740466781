#!/usr/bin/env python3
"""The 30° OAT's force slope against the paper's sentence (Schäfer et al.
2024, Section 4, Fig. 6a: "the slope of the forces in the simulation is too
high at a displacement of 25 mm and flattens out again from 30 mm because
at this point the coupling strongly reduces W8"): runs copies of
cases/oat30.toml with `[solver] max_increment = 1.0` (a row every mm) and
one change each — the free length, the coupling off (k_min = 1), the W11
lock's onset or stiffness, the printed Table D.1 — and prints the table of
docs/validation.md, "The 30° OAT's shape": the slope at 20/25/30/35 mm
(central differences over ±1 mm), the knee (the steepest slope past 15 mm)
and the slope 10 mm after it, the coupling factor k11 in the MDZ at 30 mm
(from the MDZ's E⊥ and the law's coupling), and the force at 20/40/80 mm.

A study, not a check: it prints and asserts nothing (about 21 runs, two at
a time; a few minutes on two cores).

Usage: oat30_shape.py --ncform PATH [--keep DIR]
"""

import argparse
import math
import os
import shutil
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import findings as F  # noqa: E402
from verify_findings import MATERIAL, case_copy  # noqa: E402

# (name, label, free length L [mm], {section: {key: value}} of the law, or "printed")
VARIANTS = [
    ("L300", "100 × 300, shipped law", 300.0, {}),
    ("L280", "100 × 280", 280.0, {}),
    ("L260", "100 × 260", 260.0, {}),
    ("L250", "100 × 250", 250.0, {}),
    ("L240", "100 × 240", 240.0, {}),
    ("L200", "100 × 200", 200.0, {}),
    ("nc300", "100 × 300, coupling off (k_min = 1)", 300.0, {"coupling": {"k_min": 1.0}}),
    ("nc250", "100 × 250, coupling off", 250.0, {"coupling": {"k_min": 1.0}}),
    ("nc200", "100 × 200, coupling off", 200.0, {"coupling": {"k_min": 1.0}}),
    ("pr300", "100 × 300, printed set (no acting W11 lock)", 300.0, "printed"),
    ("pr250", "100 × 250, printed set", 250.0, "printed"),
    ("pr200", "100 × 200, printed set", 200.0, "printed"),
    ("il010", "W11 lock i_lock 0.1", 300.0, {"w11": {"i_lock": 0.1}}),
    ("il015", "i_lock 0.15", 300.0, {"w11": {"i_lock": 0.15}}),
    ("il020", "i_lock 0.2", 300.0, {"w11": {"i_lock": 0.2}}),
    ("il030", "i_lock 0.3", 300.0, {"w11": {"i_lock": 0.3}}),
    ("il050", "i_lock 0.5", 300.0, {"w11": {"i_lock": 0.5}}),
    ("cl1", "c_lock 1 MPa", 300.0, {"w11": {"c_lock": 1.0}}),
    ("cl100", "c_lock 100 MPa", 300.0, {"w11": {"c_lock": 100.0}}),
    ("il015nc", "i_lock 0.15, coupling off", 300.0,
     {"w11": {"i_lock": 0.15}, "coupling": {"k_min": 1.0}}),
    ("L250il030", "100 × 250, i_lock 0.3", 250.0, {"w11": {"i_lock": 0.3}}),
]


def law_file(path, edits):
    """The default parameter file with `edits` ({section: {key: value}})."""
    out, section = [], None
    for line in open(MATERIAL):
        s = line.strip()
        if s.startswith("["):
            section = s.strip("[]")
        key = s.split("=")[0].strip() if "=" in s and not s.startswith("#") else None
        if key is not None and key in edits.get(section, {}):
            line = f"{key} = {edits[section][key]!r}\n"
        out.append(line)
    open(path, "w").write("".join(out))
    return path


def coupling(edits):
    c = {"k_min": 0.4, "s11": 10.0, "e11": 2.0}
    c.update(edits.get("coupling", {}) if isinstance(edits, dict) else {})
    return c


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ncform", required=True)
    ap.add_argument("--keep")
    args = ap.parse_args()
    work = args.keep or tempfile.mkdtemp(prefix="ncform-oat30-shape-")
    os.makedirs(work, exist_ok=True)

    def one(v):
        name, _, length, edits = v
        out = os.path.join(work, name)
        if os.path.exists(os.path.join(out, "summary.json")):
            return out
        params = "schaefer2024-printed" if edits == "printed" else \
            law_file(os.path.join(work, f"{name}-law.toml"), edits)
        case = case_copy(30, os.path.join(work, f"{name}.toml"), params=params, fine=True)
        text = open(case).read().replace("length = 300.0", f"length = {length}")
        open(case, "w").write(text)
        subprocess.run([args.ncform, "run", case, "--out", out, "--quiet"],
                       capture_output=True, text=True,
                       env=dict(os.environ, RAYON_NUM_THREADS="1"))
        return out

    with ThreadPoolExecutor(max_workers=2) as pool:
        outs = list(pool.map(one, VARIANTS))
    print("| variant | slope at 20 / 25 / 30 / 35 mm [N/mm] | knee [mm] | slope there / "
          "10 mm later [N/mm] | MDZ k11 at 30 mm | force at 20 / 40 / 80 mm [N] |")
    print("| --- | --- | --- | --- | --- | --- |")
    for (name, label, _, edits), out in zip(VARIANTS, outs):
        if not os.path.exists(os.path.join(out, "summary.json")):
            print(f"| {label} | (no result) | | | | |")
            continue
        s = F.force_slopes(out)
        k = F.force_knee(out, start=15.0)
        d, f = F.oat_force(out)
        _, t = F.read_table(os.path.join(out, "mdz_strains.csv"))
        x = max(-float(np.interp(30.0, t[:, 0], t[:, 3])), 0.0)
        c = coupling(edits)
        k11 = (1 - c["k_min"]) * math.exp(-c["s11"] * x ** c["e11"]) + c["k_min"]
        rising = k["d"] >= d[-1] - 1.0
        knee = "none (rising to the end)" if rising else f"{k['d']:.1f}"
        at = "—" if rising else f"{k['slope']:.3f} / {k['slope_after']:.3f}"
        status = "" if F.oat_summary(out)["complete"] else f" (stopped at {d[-1]:.1f} mm)"
        print(f"| {label} | " + " / ".join(f"{v:.3f}" for v in s.values())
              + f" | {knee} | {at} | {k11:.2f} | {np.interp(20, d, f):.2f} / "
              f"{np.interp(40, d, f):.2f} / {f[-1]:.2f}{status} |")
    if not args.keep:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
