#!/usr/bin/env python3
"""Mesh study and run-to-run spread of a forming bench (docs/forming.md,
"Mesh study, κ held"; method and results: docs/validation.md, "Mesh studies").

Writes copies of a shipped case (cases/<bench>.toml) with every ply's
`cells` changed, `[explicit] roving_mass_length` scaled with the cell size
(ℓ = ℓ_case × cells_case / cells: the same coupling mass ratio
κ = 3 (ℓ/L)² on every mesh, as docs/forming.md's study holds it, so that
the coupling masses vanish with the mesh) and any `--set` overrides, runs
them with `ncform run` (under `nice`), and tabulates per mesh:

* increments and wall time (summary.json);
* the punch force averaged over the last 10 mm of the stroke (the history
  rows of forming.csv, every 0.5 mm on the shipped cases), beside it the
  late-stroke oscillation: RMS and peak-to-peak of the force minus a
  quadratic fit over the same 10 mm;
* the external work at full depth (summary.json, explicit runs);
* the draw-in at full depth of every edge midpoint (±x, ±y) and every
  corner, per ply (summary.json);
* every zone's mean shear at each output depth: the case's `[[zone]]`
  windows and the flange windows (verification/flange_windows_<bench>.json,
  picked by verification/dic_zones.py's rule on the shipped single-ply
  paper-size run; the [0°/90°] stack takes the [0°] ply's; `--windows FILE`
  for others, `--pick-windows` to pick them on this study's run), each as
  the 3D mean over the window and the 2D-DIC mean over its DIC-visible
  elements (with their area share);
* the blankholder lift at full depth and its largest value (forming.csv).

With three or more meshes, for each quantity at full depth (and for the
zones at every output depth) the three finest meshes give the observed
order p of the non-uniform Richardson equation (Celik et al. 2008, "Procedure
for estimation and reporting of uncertainty due to discretization in CFD
applications", J. Fluids Eng. 130: 078001), solved by fixed-point
iteration, the Richardson estimate and GCI_fine = 1.25 |e21| / (r21^p − 1)
where 0.5 <= p <= 4 (otherwise "no order"; an oscillatory sign of the
differences is flagged), and whether the targets are met between the
coarsest and the finest mesh: window-averaged force within 5 %, draw-ins
within 1 mm, zone means within 2°.

`--nudged K` (the step re-estimated every K increments,
`time_step_update_interval`), `--friction-scale f` (every tool's and
ply–ply contact's `friction` times f) and `--mass-length-scale s`
(`roving_mass_length` times s) run the middle mesh once per value; the
table gives the spread (min / max over these runs and the middle mesh)
beside the mesh columns.

`--set KEY=VALUE` overrides a key of the case by its dotted path
(`explicit.duration=0.3`, `ply.compaction.pressure=1e-4`, `tool.punch.friction=0.2`,
`contact.explicit_pressure_stiffness=1.5`); a path through `[[ply]]` applies
to every ply, `tool.NAME.` / `zone.NAME.` select one entry of an array by
its name; VALUE is parsed as TOML (`1e-4`, `"text"`, `[1, 2]`, `true`).
Missing tables and keys are added; every written case then goes through
`ncform check` before anything runs, which refuses a key or table ncform
does not know (the study stops with ncform's message and the `--set`s).

A run folder DIR/<tag>/ is reused when its summary.json says the run is
complete and DIR/<tag>/study-case.toml equals the case file it would run.
`--only-table` runs nothing and tabulates the folders that exist;
`--use CELLS=RUN_DIR` takes an existing run folder (read only) as the run
of that mesh, e.g. a paper-size run of the shipped case.

Usage:
  mesh_study.py --ncform PATH --keep DIR --bench hemisphere-0|hemisphere-0-90|tetrahedron-0
                [--cells 60 84 120] [--set KEY=VALUE ...] [--nudged K ...]
                [--friction-scale f ...] [--mass-length-scale s ...]
                [--windows windows.json | --pick-windows] [--use CELLS=RUN_DIR ...] [--only-table]

Outputs DIR/study.json and DIR/study.md; units mm, N, N·mm, s, degrees.
"""

import argparse
import copy
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import time
import tomllib

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import bands
import dic_zones  # noqa: E402

BENCHES = ("hemisphere-0", "hemisphere-0-90", "tetrahedron-0")
LATE = 10.0          # the late-stroke window [mm]
TARGETS = {"force": 0.05, "draw-in": 1.0, "zone": 2.0}   # relative, mm, degrees
SAFETY = 1.25
# Run figures, not results: no order is sought for them.
NOT_ANALYSED = {"depth [mm]", "increments", "wall [s]", "KE/IE max"}
# The flange windows of a bench are those picked on its single-ply run.
SINGLE_PLY = {"hemisphere-0-90": "hemisphere-0"}


class StudyError(Exception):
    pass


# ---------------------------------------------------------------- the case

def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise StudyError(f"cannot write {v!r} as TOML")


def _key(k):
    return k if k.replace("_", "").replace("-", "").isalnum() else json.dumps(k)


def _is_table_array(v):
    return isinstance(v, list) and v and all(isinstance(x, dict) for x in v)


def dump_toml(data):
    """A TOML text of a parsed case (comments are not kept)."""
    out = []

    def table(d, prefix, header):
        scalars = [(k, v) for k, v in d.items() if not isinstance(v, dict) and not _is_table_array(v)]
        subs = [(k, v) for k, v in d.items() if isinstance(v, dict) or _is_table_array(v)]
        if header:
            out.append(header)
        for k, v in scalars:
            out.append(f"{_key(k)} = {toml_value(v)}")
        if header or scalars:
            out.append("")
        for k, v in subs:
            path = f"{prefix}.{_key(k)}" if prefix else _key(k)
            if isinstance(v, dict):
                table(v, path, f"[{path}]")
            else:
                for item in v:
                    table(item, path, f"[[{path}]]")
    table(data, "", None)
    return "\n".join(out).rstrip() + "\n"


def parse_value(text, where):
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        # a bare word: a string
        if text and all(c.isalnum() or c in "-_." for c in text):
            return text
        raise StudyError(f"{where}: `{text}` is not a TOML value (quote strings: '\"text\"')")


def apply_set(case, assignment, case_path):
    """Applies `a.b.c=VALUE` to the parsed case (module docstring)."""
    if "=" not in assignment:
        raise StudyError(f"--set {assignment}: expected KEY=VALUE")
    path, text = assignment.split("=", 1)
    keys = path.strip().split(".")
    value = parse_value(text.strip(), f"--set {assignment}")
    where = f"--set {path}: {case_path}"
    targets = [case]
    walked = []
    i = 0
    while i < len(keys) - 1:
        k = keys[i]
        nxt = []
        for t in targets:
            if k not in t:
                t[k] = {}     # a new table: ncform check judges it
            v = t[k]
            if isinstance(v, dict):
                nxt.append(v)
            elif _is_table_array(v):
                names = [x.get("name") for x in v]
                if i + 1 < len(keys) - 1 and keys[i + 1] in names:
                    nxt.append(v[names.index(keys[i + 1])])
                    i += 1
                else:
                    nxt.extend(v)
            else:
                raise StudyError(f"{where}: `{'.'.join(walked + [k])}` is a value, not a table")
        walked.append(k)
        targets = nxt
        i += 1
    last = keys[-1]
    if len(keys) >= 2:
        parent = case
        for k in keys[:-2]:
            parent = parent.get(k, {}) if isinstance(parent, dict) else {}
        arr = parent.get(keys[-2]) if isinstance(parent, dict) else None
        if _is_table_array(arr) and last in [x.get("name") for x in arr]:
            raise StudyError(f"{where}: `{path}` is a table ([[{keys[-2]}]] \"{last}\"), not a key")
    for t in targets:
        if isinstance(t.get(last), dict) or _is_table_array(t.get(last)):
            raise StudyError(f"{where}: `{path}` is a table, not a key")
        t[last] = value
    return case


def _all_plies(case):
    return case.get("ply", [])


def make_case(base, base_path, cells=None, sets=(), nudged=None, friction_scale=None, mass_length_scale=None):
    case = copy.deepcopy(base)
    cells0 = None
    for ply in _all_plies(case):
        mesh = ply.get("mesh")
        if mesh is None or "cells" not in mesh:
            raise StudyError(f"{base_path}: [[ply]] \"{ply.get('name')}\" has no mesh.cells")
        c = mesh["cells"]
        cells0 = c[0] if cells0 is None else cells0
        if cells is not None:
            # square cells on a rectangular blank: scale both counts
            mesh["cells"] = [int(cells), int(round(c[1] * cells / c[0]))]
    ex = case.setdefault("explicit", {})
    if cells is not None and ex.get("roving_mass_length"):
        ex["roving_mass_length"] = float(ex["roving_mass_length"]) * cells0 / cells
    for s in sets:
        apply_set(case, s, base_path)
    if nudged is not None:
        ex["time_step_update_interval"] = int(nudged)
    if friction_scale is not None:
        for t in case.get("tool", []) + case.get("ply_contact", []):
            if "friction" in t:
                t["friction"] = float(t["friction"]) * friction_scale
    if mass_length_scale is not None:
        if not ex.get("roving_mass_length"):
            raise StudyError(f"{base_path}: --mass-length-scale needs [explicit] roving_mass_length")
        ex["roving_mass_length"] = float(ex["roving_mass_length"]) * mass_length_scale
    return case


# ---------------------------------------------------------------- runs

def summary_of(out):
    p = os.path.join(out, "summary.json")
    try:
        return json.load(open(p))
    except (OSError, ValueError):
        return None


def run(ncform, work, tag, case, only_table):
    text = dump_toml(case)
    out = os.path.join(work, tag)
    stamp = os.path.join(out, "study-case.toml")
    s = summary_of(out)
    same = os.path.exists(stamp) and open(stamp).read() == text
    if s is not None and s.get("complete") and same:
        print(f"# reusing {out}", flush=True)
        return out, s
    if only_table:
        if s is not None:
            print(f"# {out}: {'incomplete' if not s.get('complete') else 'a different case file'}; "
                  "tabulated as it is (--only-table)", flush=True)
            return out, s
        print(f"# {out}: no run (--only-table)", flush=True)
        return None, None
    path = os.path.join(work, f"{tag}.toml")
    with open(path, "w") as f:
        f.write(text)
    shutil.rmtree(out, ignore_errors=True)
    print(f"# nice ncform run {path} --out {out}", flush=True)
    t0 = time.time()
    r = subprocess.run(["nice", ncform, "run", path, "--out", out, "--quiet"], capture_output=True, text=True)
    if r.returncode != 0:
        print(f"# {tag}: ncform exited with {r.returncode}: {r.stderr.strip()[-1500:]}", flush=True)
    s = summary_of(out)
    if s is None:
        print(f"# {tag}: no summary.json", flush=True)
        return None, None
    with open(stamp, "w") as f:
        f.write(text)
    print(f"# {tag}: {'complete' if s.get('complete') else 'INCOMPLETE'}, "
          f"{s.get('explicit', {}).get('increments', s.get('steps'))} increments, {time.time() - t0:.1f} s", flush=True)
    return out, s


# ---------------------------------------------------------------- figures

def read_forming(out):
    p = os.path.join(out, "forming.csv")
    try:
        with open(p) as f:
            rows = list(csv.reader(line for line in f if not line.startswith("#")))
    except OSError as e:
        raise StudyError(f"{p}: {e}")
    head = rows[0]
    data = np.array([[float(x) for x in r] for r in rows[1:] if r], float)
    return {h: data[:, i] for i, h in enumerate(head)}


def figures(out, summary, case, case_path, windows):
    """The study's quantities of one run: {name: value} (None when not
    defined) and the zone tables."""
    f = {}
    fm = read_forming(out)
    d = fm.get("punch displacement [mm]")
    force = fm.get("punch force [N]")
    if d is None or force is None:
        raise StudyError(f"{out}/forming.csv: no `punch displacement [mm]` / `punch force [N]` columns")
    dmax = float(d.max())
    late = d >= dmax - LATE - 1e-9
    f["depth [mm]"] = dmax
    f["force, mean over the last 10 mm [N]"] = float(force[late].mean())
    if late.sum() >= 4:
        c = np.polyfit(d[late], force[late], 2)
        res = force[late] - np.polyval(c, d[late])
        f["force oscillation RMS, last 10 mm [N]"] = float(np.sqrt(np.mean(res ** 2)))
        f["force oscillation peak-to-peak, last 10 mm [N]"] = float(res.max() - res.min())
    f["force at full depth [N]"] = float(force[-1])
    ex = summary.get("explicit") or {}
    f["increments"] = ex.get("increments", summary.get("steps"))
    f["wall [s]"] = summary.get("wall_seconds")
    f["external work at full depth [N·mm]"] = (ex.get("final_energies") or {}).get("external_work")
    f["KE/IE max"] = ex.get("max_kinetic_ratio")
    lifts = [k for k in fm if k.endswith("lift [mm]")]
    for k in lifts:
        f[f"{k.replace(' [mm]', '')} at full depth [mm]"] = float(fm[k][-1])
        f[f"{k.replace(' [mm]', '')}, largest [mm]"] = float(fm[k].max())
    fo = summary.get("forming", {})
    states = fo.get("states", [])
    plies = [p.get("name") for p in case.get("ply", [])]
    if states:
        for pi, points in enumerate(fo.get("draw_in_points", [])):
            for (name, _), v in zip(points, states[-1]["draw_in"][pi]):
                f[f"draw-in {plies[pi] if pi < len(plies) else pi} {name} [mm]"] = float(v)
    # The fine-scale measures (verification/bands.py) of the camera ply
    # at full depth: the shear bands and the flange's heights.
    last = len(states)
    camera = dic_zones.camera_ply(case, case_path).get("name", "ply") if states else None
    vtu = os.path.join(out, "vtu", f"{camera}_{last:04d}.vtu") if camera else None
    if vtu and os.path.exists(vtu):
        f["shear-band index at full depth [deg]"] = bands.band_index(vtu)
        f["flange heights RMS at full depth [mm]"] = bands.flange_waves(vtu)[0]
    zones = {}
    try:
        ps = dic_zones.PlyStates(out, case, path=case_path)
    except dic_zones.InputError as e:
        print(f"# {out}: zones not evaluated: {e}", flush=True)
        ps = None
    if ps is not None:
        # the case's zones on the ply each names (visibility: that ply's own centroids)
        for z in dic_zones.case_zones(case):
            ply = z["ply"] or ps.name
            src = ps if ply == ps.name else dic_zones.PlyStates(out, case, ply, case_path)
            zones[f"{z['name']} ({ply})"] = {"kind": "case zone", "centre": z["centre"], "ply": ply,
                                            "states": src.stats(z["centre"], z["size"])}
        for w in windows:
            zones[f"{w['name']} ({ps.name})"] = {"kind": "flange window", "centre": w["centre"], "ply": ps.name,
                                                 "states": ps.stats(w["centre"], w["size"])}
        for zn, z in zones.items():
            for s in z["states"]:
                tag = f"{s['stroke']:.0f} mm"
                f[f"zone {zn} 3D at {tag} [deg]"] = s["shear_3d_mean"]
                f[f"zone {zn} 2D-DIC at {tag} [deg]"] = s["shear_dic_mean"]
                f[f"zone {zn} visible share at {tag}"] = s["visible_area_share"]
    return f, zones


def kind(name):
    if name.startswith("force, mean"):
        return "force"
    if name.startswith("draw-in"):
        return "draw-in"
    if name.startswith("zone") and "visible share" not in name:
        return "zone"
    return None


# ---------------------------------------------------------------- Richardson

def observed_order(h, phi):
    """Celik et al. (2008): h = (h1, h2, h3) fine to coarse, phi the
    solutions. Returns (p, phi_ext, gci_fine, note)."""
    h1, h2, h3 = h
    f1, f2, f3 = phi
    r21, r32 = h2 / h1, h3 / h2
    e21, e32 = f2 - f1, f3 - f2
    if e21 == 0 or e32 == 0:
        return None, None, None, "a difference is zero"
    s = math.copysign(1.0, e32 / e21)
    p = abs(math.log(abs(e32 / e21))) / math.log(r21)
    ok = True
    for _ in range(200):
        try:
            q = math.log((r21 ** p - s) / (r32 ** p - s))
        except (ValueError, ZeroDivisionError, OverflowError):
            ok = False
            break
        pn = abs(math.log(abs(e32 / e21)) + q) / math.log(r21)
        if abs(pn - p) < 1e-10:
            p = pn
            break
        p = pn
    note = "oscillatory" if s < 0 else ""
    if not ok or not math.isfinite(p):
        return None, None, None, (note + " " if note else "") + "no order (iteration failed)"
    if not 0.5 <= p <= 4.0:
        return p, None, None, (note + ", " if note else "") + "no order"
    ext = (r21 ** p * f1 - f2) / (r21 ** p - 1)
    ea = abs((f1 - f2) / f1) if f1 != 0 else None
    gci = SAFETY * ea / (r21 ** p - 1) if ea is not None else None
    return p, ext, gci, note


# ---------------------------------------------------------------- table

def fmt(v, nd=3):
    if v is None:
        return "—"
    if isinstance(v, int):
        return f"{v:,}"
    if isinstance(v, float):
        if not math.isfinite(v):
            return "—"
        if abs(v) >= 1000:
            return f"{v:,.0f}"
        return f"{v:.{nd}f}"
    return str(v)


def main(argv=None):
    ap = argparse.ArgumentParser(description="mesh study of a forming bench (see the module docstring)")
    ap.add_argument("--ncform", default="ncform")
    ap.add_argument("--keep", required=True, help="the study's folder")
    ap.add_argument("--bench", required=True, choices=BENCHES)
    ap.add_argument("--cells", nargs="+", type=int, default=[60, 84, 120])
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--nudged", nargs="*", type=int, default=[])
    ap.add_argument("--friction-scale", nargs="*", type=float, default=[])
    ap.add_argument("--mass-length-scale", nargs="*", type=float, default=[])
    ap.add_argument("--windows", help="flange windows (JSON of verification/dic_zones.py); default: "
                    "verification/flange_windows_<bench>.json (the stack: hemisphere-0's)")
    ap.add_argument("--pick-windows", action="store_true",
                    help="pick the flange windows on this study's run (the case's cells, else the finest) "
                         "instead of verification/flange_windows_<single-ply bench>.json")
    ap.add_argument("--use", action="append", default=[], metavar="CELLS=RUN_DIR",
                    help="an existing run folder (read only) as the run of that mesh; "
                         "LABEL=RUN_DIR (LABEL not a number): a spread run of the middle mesh")
    ap.add_argument("--case", help="the case file the bench's runs are copies of "
                    "(default cases/<bench>.toml; e.g. cases/regularised/<bench>.toml)")
    ap.add_argument("--only-table", action="store_true", help="run nothing; tabulate the folders present")
    ap.add_argument("--plot", help="also draw the punch force and the corner draw-in of every run "
                    "against the stroke into this PNG (needs matplotlib)")
    args = ap.parse_args(argv)

    case_path = args.case or os.path.join(REPO, "cases", f"{args.bench}.toml")
    if not os.path.exists(case_path):
        raise StudyError(f"--case {case_path}: no such file")
    base = dic_zones.load_case(case_path)
    if not args.only_table and not args.use and shutil.which(args.ncform) is None and not os.path.exists(args.ncform):
        raise StudyError(f"--ncform {args.ncform}: not found")
    work = args.keep
    os.makedirs(work, exist_ok=True)
    used = {}
    used_spread = {}
    for u in args.use:
        if "=" not in u:
            raise StudyError(f"--use {u}: expected CELLS=RUN_DIR or LABEL=RUN_DIR")
        c, d = u.split("=", 1)
        if summary_of(d) is None:
            raise StudyError(f"--use {u}: {d}/summary.json missing or unreadable")
        try:
            used[int(c)] = d
        except ValueError:
            used_spread[c] = d
    if used and (args.set or args.nudged or args.friction_scale or args.mass_length_scale):
        print("# note: --use folders are tabulated as they are: --set does not apply to them", flush=True)
    cells = sorted(set(args.cells) | set(used))
    for s in args.set:            # refuse bad paths before any run
        apply_set(copy.deepcopy(base), s, case_path)
    case_cells = base["ply"][0]["mesh"]["cells"][0]
    blank = float(base["ply"][0]["mesh"]["size"][0])

    if args.set and not args.only_table:
        checked = os.path.join(work, "set-check.toml")
        with open(checked, "w") as f:
            f.write(dump_toml(make_case(base, case_path, cells[0], args.set)))
        r = subprocess.run([args.ncform, "check", checked], capture_output=True, text=True)
        if r.returncode != 0:
            raise StudyError(f"--set {' '.join(args.set)}: ncform check refuses the case {checked}:\n"
                             + (r.stderr or r.stdout).strip())
    runs = {}    # label -> (cells, out, summary, case)
    for c in cells:
        case = make_case(base, case_path, c, args.set)
        if c in used:
            runs[f"{c}"] = (c, used[c], summary_of(used[c]), case)
            print(f"# {c} cells: {used[c]} (--use, read only)", flush=True)
            continue
        out, s = run(args.ncform, work, f"{args.bench}-c{c}", case, args.only_table)
        if out:
            runs[f"{c}"] = (c, out, s, case)
    if not runs:
        raise StudyError(f"{work}: no run folder to tabulate (--only-table runs nothing)")
    middle = cells[len(cells) // 2]
    variants = []
    for k in args.nudged:
        variants.append((f"nudged {k}", dict(nudged=k), f"k{k}"))
    for fs in args.friction_scale:
        variants.append((f"friction ×{fs:g}", dict(friction_scale=fs), f"mu{fs:g}"))
    for ms in args.mass_length_scale:
        variants.append((f"ℓ ×{ms:g}", dict(mass_length_scale=ms), f"l{ms:g}"))
    spread_labels = []
    for label, d in used_spread.items():
        runs[label] = (middle, d, summary_of(d), make_case(base, case_path, middle, args.set))
        spread_labels.append(label)
        print(f"# {label}: {d} (--use, read only)", flush=True)
    for label, kw, tag in variants:
        case = make_case(base, case_path, middle, args.set, **kw)
        out, s = run(args.ncform, work, f"{args.bench}-c{middle}-{tag}", case, args.only_table)
        if out:
            runs[label] = (middle, out, s, case)
            spread_labels.append(label)

    # flange windows
    shipped = os.path.join(HERE, f"flange_windows_{SINGLE_PLY.get(args.bench, args.bench)}.json")
    if args.windows:
        windows = dic_zones.load_windows(args.windows)
        placement = {"rule": f"from {args.windows}"}
    elif os.path.exists(shipped) and not args.pick_windows:
        windows = dic_zones.load_windows(shipped)
        placement = {"rule": f"{os.path.relpath(shipped, REPO)}: the rule of verification/dic_zones.py "
                             "on the shipped single-ply paper-size run"}
    else:
        pick = next((runs[str(c)] for c in (case_cells,) if str(c) in runs), None) or \
            (runs[str(max(c for c in cells if str(c) in runs))] if any(str(c) in runs for c in cells) else None)
        if pick is None:
            raise StudyError(f"{work}: no run to tabulate")
        ps = dic_zones.PlyStates(pick[1], pick[3], path=case_path)
        windows, placement = dic_zones.pick_windows(ps, pick[3])
        placement["cells"] = pick[0]
    with open(os.path.join(work, "flange_windows.json"), "w") as f:
        f.write(dic_zones.windows_json(windows))

    table, zones, meta = {}, {}, {}
    for label, (c, out, s, case) in runs.items():
        table[label], zones[label] = figures(out, s, case, case_path, windows)
        meta[label] = {"cells": c, "h [mm]": blank / c, "run": os.path.abspath(out),
                       "complete": bool(s.get("complete")),
                       "roving_mass_length [mm]": case.get("explicit", {}).get("roving_mass_length")}
    mesh_labels = [str(c) for c in cells if str(c) in runs]
    names = []
    for label in table:
        for n in table[label]:
            if n not in names:
                names.append(n)

    # Richardson on the three finest meshes; targets coarsest vs finest
    analysis = {}
    for n in names:
        vals = [table[l].get(n) for l in mesh_labels]
        a = {}
        if len(mesh_labels) >= 3 and n not in NOT_ANALYSED and all(isinstance(v, (int, float)) and v is not None for v in vals[-3:]):
            fine = mesh_labels[-3:][::-1]
            h = [blank / runs[l][0] for l in fine]
            p, ext, gci, note = observed_order(h, [float(table[l][n]) for l in fine])
            a.update({"p": p, "richardson": ext, "gci_fine": gci, "note": note})
        k = kind(n)
        if k and len(mesh_labels) >= 2:
            v0, v1 = table[mesh_labels[0]].get(n), table[mesh_labels[-1]].get(n)
            if v0 is not None and v1 is not None:
                diff = abs(v1 - v0) / abs(v1) if k == "force" else abs(v1 - v0)
                a["coarse_fine_difference"] = diff
                a["target"] = TARGETS[k]
                a["target_met"] = bool(diff <= TARGETS[k])
        sv = [table[l].get(n) for l in [str(middle)] + spread_labels if l in table]
        sv = [v for v in sv if isinstance(v, (int, float))]
        if spread_labels and sv:
            a["spread_min"], a["spread_max"] = min(sv), max(sv)
        analysis[n] = a

    result = {"bench": args.bench, "case": os.path.relpath(case_path, REPO), "set": args.set,
              "cells": cells, "middle": middle, "runs": meta, "figures": table, "analysis": analysis,
              "flange_windows": windows, "placement": placement, "zones": zones,
              "targets": {"force (relative)": TARGETS["force"], "draw-in [mm]": TARGETS["draw-in"],
                          "zone mean [deg]": TARGETS["zone"]},
              "units": "mm, N, N·mm, s, degrees"}
    with open(os.path.join(work, "study.json"), "w") as f:
        json.dump(result, f, indent=1, ensure_ascii=False)
    md = markdown(result, mesh_labels, spread_labels, names)
    with open(os.path.join(work, "study.md"), "w") as f:
        f.write(md)
    with open(os.path.join(work, "summary.md"), "w") as f:
        f.write(compact(result, mesh_labels, spread_labels, names))
    if args.plot:
        plot(args.plot, runs, mesh_labels, spread_labels, result["case"])
    print(md)
    return result


def plot(path, runs, mesh_labels, spread_labels, case_name):
    """The punch force and the mean corner draw-in against the stroke, one
    line per mesh (darker: finer) and dashed per spread run: how the late
    stroke parts with the mesh, beside the spread of one mesh."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax_f, ax_d) = plt.subplots(1, 2, figsize=(11, 4.2))
    shades = plt.cm.viridis(np.linspace(0.8, 0.1, max(len(mesh_labels), 1)))
    styles = [(l, dict(color=c, lw=1.4)) for l, c in zip(mesh_labels, shades)]
    styles += [(l, dict(color="0.45", lw=1.0, ls="--")) for l in spread_labels]
    for label, style in styles:
        cells, out, summary, _ = runs[label]
        fm = read_forming(out)
        d, force = fm["punch displacement [mm]"], fm["punch force [N]"]
        name = f"{cells} cells" if label in mesh_labels else f"{cells} cells, {label}"
        ax_f.plot(d, force, label=name, **style)
        fo = summary.get("forming", {})
        states = fo.get("states", [])
        points = fo.get("draw_in_points", [[]])[0]
        corners = [k for k, (n, _) in enumerate(points) if "corner" in n]
        if states and corners:
            ax_d.plot([s["stroke"] for s in states],
                      [np.mean([s["draw_in"][0][k] for k in corners]) for s in states],
                      marker="o", ms=3, label=name, **style)
    ax_f.set_xlabel("punch displacement [mm]")
    ax_f.set_ylabel("punch force [N]")
    ax_d.set_xlabel("punch displacement [mm]")
    ax_d.set_ylabel("mean corner draw-in, first ply [mm]")
    for ax in (ax_f, ax_d):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"mesh study of {case_name}: the late stroke against the mesh and the spread runs")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# The rows of the short table (DIR/summary.md): the quantities the targets
# name and the fine-scale measures, at full depth; zones at 60 mm too,
# where the case zones still have visible elements.
COMPACT = ("force, mean over the last 10 mm", "force oscillation RMS", "external work",
           "blankholder lift, largest", "draw-in", "shear-band index", "flange heights RMS")


def compact(r, mesh_labels, spread_labels, names):
    """The short table of a study: the COMPACT rows and every zone's 3D mean
    at 60 mm and at full depth and 2D-DIC mean at 60 mm, per mesh, with
    the observed order, the coarse–fine difference against its target and
    the spread of the middle mesh's variant runs."""
    depth = max((r["figures"][l].get("depth [mm]") or 0.0) for l in mesh_labels)
    full = f"{depth:.0f} mm"
    picked = [n for n in names if n.startswith(COMPACT)]
    picked += [n for n in names if n.startswith("zone") and (
        n.endswith(f"3D at {full} [deg]") or n.endswith("3D at 60 mm [deg]")
        or n.endswith("2D-DIC at 60 mm [deg]"))]
    head = ["quantity"] + [f"{l} cells" for l in mesh_labels] + ["p", "coarse–fine", "target"]
    if spread_labels:
        head.append(f"spread at {r['middle']} cells ({', '.join(spread_labels)})")
    L = [f"Short table of the mesh study of `{r['case']}` (all rows: `study.md`).", "",
         "| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    for n in picked:
        a = r["analysis"].get(n, {})
        row = [n] + [fmt(r["figures"][l].get(n)) for l in mesh_labels]
        row.append(fmt(a.get("p"), 2) if a.get("p") is not None else "—")
        if "coarse_fine_difference" in a:
            diff = a["coarse_fine_difference"]
            shown = f"{100 * diff:.1f} %" if n.startswith("force, mean") else fmt(diff, 2)
            row += [shown, "met" if a["target_met"] else "**not met**"]
        else:
            row += ["—", "—"]
        if spread_labels:
            row.append(f"{fmt(a['spread_min'])} … {fmt(a['spread_max'])}" if "spread_min" in a else "—")
        L.append("| " + " | ".join(row) + " |")
    return "\n".join(L) + "\n"


def markdown(r, mesh_labels, spread_labels, names):
    L = [f"# Mesh study: {r['case']}", ""]
    L.append(f"Cells {', '.join(str(c) for c in r['cells'])}; `--set` {', '.join(r['set']) or 'none'}; "
             f"spread runs at {r['middle']} cells: {', '.join(spread_labels) or 'none'}. Units mm, N, N·mm, s, "
             "degrees. Force: forming.csv's punch force averaged over the history rows of the last 10 mm of "
             "the stroke; oscillation: the force minus a quadratic fit over the same rows. Draw-in, "
             "external work: summary.json at full depth. Zones: 3D mean over the window / 2D-DIC mean over "
             "its DIC-visible elements (verification/dic_zones.py).")
    L.append("")
    L.append("| run | cells | h [mm] | ℓ [mm] | complete | run folder |")
    L.append("| --- | --- | --- | --- | --- | --- |")
    for l, m in r["runs"].items():
        L.append(f"| {l} | {m['cells']} | {m['h [mm]']:.3f} | {fmt(m['roving_mass_length [mm]'], 2)} | "
                 f"{'yes' if m['complete'] else '**no**'} | `{m['run']}` |")
    L.append("")
    w = r["flange_windows"]
    L.append("Flange windows (" + r["placement"]["rule"] + (f", on the {r['placement']['cells']}-cell run"
                                                           if "cells" in r["placement"] else "") + "): "
             + ", ".join(f"{x['name']} ({x['centre'][0]:g}, {x['centre'][1]:g})" for x in w) + ".")
    L.append("")
    head = ["quantity"] + [f"{l} cells" for l in mesh_labels]
    if spread_labels:
        head += [f"spread at {r['middle']} (min / max)"]
    head += ["p", "Richardson", "GCI fine", "coarse–fine", "target"]
    L.append("| " + " | ".join(head) + " |")
    L.append("|" + " --- |" * len(head))
    for n in names:
        a = r["analysis"].get(n, {})
        row = [n] + [fmt(r["figures"][l].get(n)) for l in mesh_labels]
        if spread_labels:
            row.append(f"{fmt(a.get('spread_min'))} / {fmt(a.get('spread_max'))}" if "spread_min" in a else "—")
        p = a.get("p")
        row.append("—" if "note" not in a else (f"{p:.2f}" if p is not None and a.get("richardson") is not None
                                                else (a["note"] + (f" ({p:.2f})" if p is not None else ""))))
        if a.get("note") == "oscillatory" and a.get("richardson") is not None:
            row[-1] += " (oscillatory)"
        row.append(fmt(a.get("richardson")))
        row.append(f"{100 * a['gci_fine']:.1f} %" if a.get("gci_fine") is not None else "—")
        if "coarse_fine_difference" in a:
            k = kind(n)
            d = a["coarse_fine_difference"]
            row.append(f"{100 * d:.1f} %" if k == "force" else f"{d:.2f}")
            t = a["target"]
            row.append(("met" if a["target_met"] else "**not met**")
                       + (f" (≤ {100 * t:.0f} %)" if k == "force" else f" (≤ {t:g})"))
        else:
            row += ["—", "—"]
        L.append("| " + " | ".join(row) + " |")
    L.append("")
    return "\n".join(L)


if __name__ == "__main__":
    try:
        main()
    except (StudyError, dic_zones.InputError) as e:
        sys.exit(f"error: {e}")
