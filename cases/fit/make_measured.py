#!/usr/bin/env python3
"""Makes the measured data of the worked fit example (cases/fit/): three
off-axis tension tests (30°, 45°, 60°) simulated by ncform with a perturbed
parameter set (every one of the ten fitted parameters moved by 8 to 20 %,
up or down, seeded), sampled at 400 displacements like a load cell and DIC, with seeded
Gaussian noise at the levels the fit file states:

    force:        σ = 2 % · |F| + 0.01 N
    E22, E_perp:  σ = 0.003
    shear angle:  σ = 0.5°

Writes cases/fit/truth.toml (the perturbed set: what a perfect fit finds up
to the noise) and cases/fit/oat30.csv, oat45.csv, oat60.csv.

Usage (from the repository root, after `cargo build --release`):

    python3 cases/fit/make_measured.py [--bin target/release/ncform] [--seed 2024]

Standard library only. The simulations use the shipped OAT cases with
`solver.max_increment = 0.5` (160+ states per test), then linear
interpolation to the 400 sampling displacements (its error, below 1e-4 N
and 1e-5 in strain, is far below the noise).
"""

import argparse
import csv
import math
import os
import random
import re
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
FREE = [
    "w6.c_ini", "w6.s_ini", "w6.c_mid", "w6.delta_s_mid",
    "w8.c_ini", "w8.s_ini", "w8.c_mid", "w8.delta_s_mid",
    "coupling.k_min", "coupling.s11",
]
ANGLES = [30, 45, 60]
ROWS = 400
NOISE = {"force": (0.02, 0.01), "E22": 0.003, "shear_angle": 0.5, "E_perp": 0.003}


def perturbed_set(seed):
    """The schaefer2024 set with every free parameter scaled by a seeded
    factor 1 ± [0.08, 0.2]; returns (toml text, {key: (start, truth)})."""
    with open(os.path.join(ROOT, "cases", "materials", "schaefer2024.toml")) as f:
        text = f.read()
    rng = random.Random(seed)
    table = None
    out, moved = [], {}
    for line in text.splitlines():
        m = re.match(r"^\[(\w+)\]", line)
        if m:
            table = m.group(1)
        m = re.match(r"^(\w+)\s*=\s*([-0-9.eE+]+)(.*)$", line)
        if m and table and f"{table}.{m.group(1)}" in FREE:
            key = f"{table}.{m.group(1)}"
            start = float(m.group(2))
            truth = start * (1.0 + rng.choice([-1.0, 1.0]) * rng.uniform(0.08, 0.2))
            moved[key] = (start, truth)
            line = f"{m.group(1)} = {truth!r}{m.group(3)}"
        if line.startswith("name ="):
            line = 'name = "fit-example-truth"'
        if line.startswith("description ="):
            line = f'description = "schaefer2024 with the ten OAT parameters moved by seeded factors 1 ± [0.08, 0.2] (seed {seed})"'
        out.append(line)
    header = [
        "# The truth of the worked fit example: made by cases/fit/make_measured.py.",
        "# " + ", ".join(f"{k}: {s} -> {t:.6g}" for k, (s, t) in moved.items()),
    ]
    return "\n".join(header + out) + "\n", moved


def read_csv(path):
    with open(path) as f:
        rows = [r for r in csv.reader(line for line in f if not line.startswith("#"))]
    header = rows[0]
    return {h: [float(r[i]) for r in rows[1:]] for i, h in enumerate(header)}


def interp(x, xs, ys):
    if x <= xs[0]:
        return ys[0] * x / xs[0] if xs[0] > 0 else ys[0]
    for i in range(1, len(xs)):
        if x <= xs[i]:
            t = (x - xs[i - 1]) / (xs[i] - xs[i - 1])
            return ys[i - 1] + t * (ys[i] - ys[i - 1])
    return ys[-1]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "ncform"))
    parser.add_argument("--seed", type=int, default=2024)
    args = parser.parse_args()
    truth_text, moved = perturbed_set(args.seed)
    truth_path = os.path.join(HERE, "truth.toml")
    with open(truth_path, "w") as f:
        f.write(truth_text)
    rng = random.Random(args.seed + 1)
    with tempfile.TemporaryDirectory() as tmp:
        for angle in ANGLES:
            with open(os.path.join(ROOT, "cases", f"oat{angle}.toml")) as f:
                case = f.read()
            case = case.replace('params = "schaefer2024"', f'params = "{truth_path}"')
            case += "\n[solver]\nmax_increment = 0.5\nresidual_tolerance = 1e-9\n"
            case_path = os.path.join(tmp, f"oat{angle}.toml")
            with open(case_path, "w") as f:
                f.write(case)
            out = os.path.join(tmp, f"out{angle}")
            subprocess.run([args.bin, "run", case_path, "--out", out, "--quiet"], check=True,
                           stdout=subprocess.DEVNULL)
            force = read_csv(os.path.join(out, "force_displacement.csv"))
            strains = read_csv(os.path.join(out, "mdz_strains.csv"))
            d_force = force["displacement [mm]"]
            d_strain = strains["displacement [mm]"]
            final = d_force[-1]
            path = os.path.join(HERE, f"oat{angle}.csv")
            with open(path, "w") as f:
                f.write(f"# ncform fit example: {angle}° off-axis tension test, made by make_measured.py (seed {args.seed})\n")
                f.write("# simulated by ncform with truth.toml, sampled at 400 displacements, seeded Gaussian noise:\n")
                f.write("# force 2 % + 0.01 N, E22 and E_perp 0.003, shear angle 0.5 deg\n")
                f.write("# units: mm, N; strains dimensionless; shear angle in degrees\n")
                f.write("displacement [mm],force [N],E22 [-],shear_angle [deg],E_perp [-]\n")
                for k in range(1, ROWS + 1):
                    d = final * k / ROWS
                    F = interp(d, d_force, force["force [N]"])
                    F += rng.gauss(0.0, NOISE["force"][0] * abs(F) + NOISE["force"][1])
                    e22 = interp(d, d_strain, strains["E22 [-]"]) + rng.gauss(0.0, NOISE["E22"])
                    g = interp(d, d_strain, strains["shear_angle [deg]"]) + rng.gauss(0.0, NOISE["shear_angle"])
                    ep = interp(d, d_strain, strains["E_perp [-]"]) + rng.gauss(0.0, NOISE["E_perp"])
                    f.write(f"{d:.4f},{F:.6f},{e22:.6f},{g:.5f},{ep:.6f}\n")
            print(f"wrote {path}", file=sys.stderr)
    for key, (start, truth) in moved.items():
        print(f"{key:22s} start {start:<10g} truth {truth:.6g} ({100 * (truth / start - 1):+.1f} %)")


if __name__ == "__main__":
    main()
