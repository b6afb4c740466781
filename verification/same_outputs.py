#!/usr/bin/env python3
"""Proves that a change leaves every number ncform writes as it was.

Builds the `ncform` binary of a base revision (in a git worktree of its own,
with its own target folder) and the working tree's binary, runs a set of
cases with both, and compares the two run folders of each case file by
file:

- every file name must be in both folders;
- JSON files (`summary.json`, `status.json`) are compared value by value,
  with the wall-clock figures masked (`MASKED_KEYS`: wall and output times,
  the solvers' time splits, element cycles per second, the process id and
  the start and finish times; in `status.json` the byte count of the
  `summary.json` it lists, whose times vary in length);
- every other file (CSV, VTU, PVD, PNG) byte for byte;
- the exit codes, and stdout and stderr with times in seconds masked;
- a JSON member that is `null` in the base run and left out in the head
  run is the same (the run folder's files no longer write `null`: a figure
  that does not apply is left out; `docs/cases.md`, "summary.json");
- the files that only a newer head writes (`HEAD_ONLY`, listed by name:
  `case.resolved.json`) are ignored when only the head has them, and left
  out of the head's `status.json` manifest.

Both binaries run each case into the same folder name (moved aside after
the run), so that paths written into the outputs are the same.

Usage (from the repository root; Python 3 standard library only):

    python3 verification/same_outputs.py --base REV [--set quick|shipped|all]
    python3 verification/same_outputs.py --base-bin PATH ...   # a built base

`--set quick` (default, about 2 minutes per binary): the three OATs, the
verification cases, and coarse, short-stroke copies of the explicit OAT and
of every shipped forming case (24 x 24 cells, 30 mm, a shortened programme),
plus a coarse quasi-static hemisphere. `--set shipped`: every shipped case
as it is (paper size: about 15 minutes per binary on 2 cores for the
paper's cases; the stacks of four and eight plies add more: see
docs/benchmarks.md). `--set all`: both. A case the base refuses as a case
file (an error exit, no run folder: a key new with the head, such as the stacks'
`[[tool]] plies`) is reported as NEW and neither passes nor fails.
`git_commit` (case.resolved.json's provenance) is masked: it differs
between any two revisions by design. What only a newer head writes is
left out of the comparison, each item named below (`HEAD_ONLY`,
`HEAD_ONLY_KEYS`, `HEAD_ONLY_PATHS`, `HEAD_ONLY_ARRAYS`): a file, summary
keys, a resolved-case key, VTU arrays; the rest of those files must still
be the same. Exit 0 when every case gives the same
outputs; the last line reads
`same-outputs: N passed, N failed`.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

# Keys whose values are wall-clock figures or process facts, at any depth.
MASKED_KEYS = {
    "wall_seconds",
    "output_seconds",
    "timings",
    "term_seconds",
    "element_cycles_per_second",
    "pid",
    "started",
    "finished",
    # The commit a binary was built from (case.resolved.json's provenance):
    # it differs between any two revisions by design.
    "git_commit",
}

# Files whose content holds masked values, so that their size varies too.
VARIABLE_SIZE = {"summary.json", "status.json", "case.resolved.json"}

# Files that only a newer head writes, listed one by one: ignored when they
# are only in the head run, and dropped from the head's status.json
# manifest. `case.resolved.json`: the resolved case and its provenance
# (ncform version, git commit, hashes of the files read), new with the run
# folder's provenance record; it names the commit, so it differs by design.
HEAD_ONLY = {"case.resolved.json"}

# Files that only a newer head writes, by pattern: the defect maps of the
# forming plies (`maps/<ply>-defects_NNNN.png`,
# `maps/<ply>-wrinkle-indicators_NNNN.png`), new with the defect
# indicators.
HEAD_ONLY_FILES = re.compile(r"^maps/.*-(defects|wrinkle-indicators)_\d{4}\.png$")

# Summary keys that only a newer head writes, dropped wherever they occur:
# `term_steps`, the step each term alone would allow (new with the
# explicit summary's account of what sets the step); `defects`, the defect
# areas per ply (new with the defect indicators).
HEAD_ONLY_KEYS = {"term_steps", "defects"}

# Keys of the resolved case that only a newer head writes, by path:
# `[[tool]] plies` (the plies a tool touches), new with the key; its
# default, every ply, is the model of the base; `[rosette]` and
# `[defects]`, new with the orientation fields and defect indicators.
HEAD_ONLY_PATHS = re.compile(r"^/case/(tools\[\d+\]/plies|rosette|defects)$")

# VTU arrays that only a newer head writes, by name: the per-interface
# ply-ply contact fields (`ply_contact_<quantity>[<other ply>]`), new
# beside the merged ones, and the orientation and defect fields. The two
# VTUs are compared with these arrays taken out of both (a base that has
# some of them writes them as the head does); everything else must be the
# same bytes.
HEAD_ONLY_ARRAYS = re.compile(
    r'\n *<DataArray [^>]*Name="(ply_contact_[a-z_]+\[[^"]*\]|' + "|".join((
        "a0", "b0", "fibre_direction", "transverse_direction", "fibre_angle_deg",
        "fibre_angle_deviation_deg", "area_ratio", "thickness", "areal_mass", "tool_gap",
        "curvature_1", "curvature_2", "max_curvature", "membrane_force_1", "membrane_force_2",
        "fibre_line_force", "gap_width", "element_label", "orientation_valid", "rosette_use",
        "tension_field", "wrinkled", "gapping", "waviness_risk", "defect_class")) +
    r')"[^>]*>.*?</DataArray>'
    # ... and the comment lines that describe them (orientation fields,
    # defect fields and thresholds).
    r'|\n<!-- (a0, b0: |tool_gap \[mm\]: |defect thresholds: )[^\n]*-->', re.S)

# Times in seconds and speeds on stdout/stderr ("2.85 s", "31.9 M
# element-cycles/s").
TIME_PATTERN = re.compile(r"[0-9][0-9.eE+-]* (s|M element-cycles/s)\b")

# Cases that are not case files (a parameter file for the indentation case).
NOT_CASES = {"svk-e10.toml"}


def coarse(text: str, *, explicit_duration: str | None = "0.15") -> str:
    """A coarse, short-stroke copy of a shipped forming case: 24 x 24 cells,
    a 30 mm stroke and a shortened explicit programme."""
    text = re.sub(r"cells = \[\d+, \d+\]", "cells = [24, 24]", text)
    text = re.sub(r"^displacement = [0-9.]+", "displacement = 30.0", text, flags=re.M)
    if explicit_duration is not None:
        text = re.sub(r"^duration = [0-9.]+", f"duration = {explicit_duration}", text, flags=re.M)
    return text


def quasi_static(text: str) -> str:
    """The coarse case on the quasi-static path: the solver line, the
    `[explicit]` table and the explicit history count removed (the
    quasi-static solver reads neither and warns about them)."""
    text = re.sub(r'^solver = "explicit".*$', "", coarse(text, explicit_duration=None), flags=re.M)
    text = re.sub(r"^\[explicit\]\n(?:(?!\[).*\n?)*", "", text, flags=re.M)
    return re.sub(r"^history = \d+.*$", "", text, flags=re.M)


def with_inertia(text: str) -> str:
    """The coarse quasi-static case with the viscous stabilisation and the
    free dofs' inertia (`docs/solver.md`, "Inertia")."""
    return quasi_static(text) + (
        '\n[solver]\ninitial_increment = 0.0125\nmax_increment = 0.025\n'
        'stabilisation = "automatic"\ninertia_duration = 2.0\n'
    )


def coarse_oat(text: str) -> str:
    """The explicit OAT on a coarse mesh (8 mm elements)."""
    return re.sub(r"element_size = [0-9.]+", "element_size = 8.0", text)


def case_set(name: str, work: Path) -> list[tuple[str, Path]]:
    """(label, case file) pairs of a set; derived cases are written to
    `work/cases/` (the shipped forming cases name no file of their own, so
    they run from any folder)."""
    cases = REPO / "cases"
    derived_dir = work / "cases"
    chosen: list[tuple[str, Path]] = []
    if name in ("quick", "all"):
        for stem in ("oat30", "oat45", "oat60"):
            chosen.append((stem, cases / f"{stem}.toml"))
        for path in sorted((cases / "verification").glob("*.toml")):
            if path.name not in NOT_CASES:
                chosen.append((f"verification-{path.stem}", path))
        derived_dir.mkdir(exist_ok=True)
        derived = [("oat45-explicit", coarse_oat, "oat45-explicit-coarse")]
        for path in sorted(cases.glob("*.toml")):
            if "[[ply]]" in path.read_text():
                derived.append((path.stem, coarse, f"{path.stem}-coarse"))
        derived.append(("hemisphere-0", quasi_static, "hemisphere-0-quasi-static-coarse"))
        derived.append(("hemisphere-0", with_inertia, "hemisphere-0-inertia-coarse"))
        for stem, transform, label in derived:
            text = transform((cases / f"{stem}.toml").read_text())
            target = derived_dir / f"{label}.toml"
            target.write_text(text)
            chosen.append((label, target))
    if name in ("shipped", "all"):
        for path in sorted(cases.glob("*.toml")):
            chosen.append((path.stem, path))
    return chosen


def build_base(rev: str, work: Path) -> Path:
    """The base revision's binary, built in a worktree of its own."""
    src = work / "base-src"
    target = work / "base-target"
    commit = subprocess.run(
        ["git", "rev-parse", "--verify", f"{rev}^{{commit}}"],
        cwd=REPO, check=True, capture_output=True, text=True,
    ).stdout.strip()
    if src.exists():
        subprocess.run(["git", "checkout", "--quiet", "--detach", commit], cwd=src, check=True)
    else:
        subprocess.run(["git", "worktree", "add", "--quiet", "--detach", str(src), commit],
                       cwd=REPO, check=True)
    print(f"# building the base {rev} ({commit[:12]}) in {src}", flush=True)
    env = dict(os.environ, CARGO_TARGET_DIR=str(target))
    subprocess.run(["cargo", "build", "--release", "--bin", "ncform"], cwd=src, env=env, check=True)
    return target / "release" / "ncform"


def build_head() -> Path:
    print("# building the working tree", flush=True)
    subprocess.run(["cargo", "build", "--release", "--bin", "ncform"], cwd=REPO, check=True)
    return REPO / "target" / "release" / "ncform"


def run_case(binary: Path, case: Path, run_dir: Path, keep: Path) -> dict:
    """Runs `case` into `run_dir` and moves the folder to `keep`."""
    for folder in (run_dir, keep, run_dir.with_name(run_dir.name + ".previous")):
        if folder.exists():
            shutil.rmtree(folder)
    done = subprocess.run(
        [str(binary), "run", str(case), "--out", str(run_dir), "--quiet"],
        cwd=REPO, capture_output=True, text=True,
    )
    if run_dir.exists():
        keep.parent.mkdir(parents=True, exist_ok=True)
        run_dir.rename(keep)
    return {
        "code": done.returncode,
        "stdout": TIME_PATTERN.sub(r"<t> \1", done.stdout),
        "stderr": TIME_PATTERN.sub(r"<t> \1", done.stderr),
    }


def masked(value, parent_file: str = "", where: str = ""):
    """`value` with the masked keys replaced by a placeholder and the
    head-only keys dropped."""
    if isinstance(value, dict):
        out = {}
        for k, v in value.items():
            if k in HEAD_ONLY_KEYS or HEAD_ONLY_PATHS.match(f"{where}/{k}"):
                continue
            if k in MASKED_KEYS:
                out[k] = "<masked>"
            else:
                out[k] = masked(v, parent_file, f"{where}/{k}")
        # A manifest entry of a file whose size varies with its times, or
        # of a VTU (which may hold head-only arrays; its content is
        # compared on its own).
        path = value.get("path")
        if isinstance(path, str) and "bytes" in value and (
                path in VARIABLE_SIZE or path.endswith(".vtu")):
            out["bytes"] = "<masked>"
        return out
    if isinstance(value, list):
        return [masked(v, parent_file, f"{where}[{i}]") for i, v in enumerate(value)]
    return value


def first_json_difference(a, b, where: str = "") -> str | None:
    if type(a) is not type(b):
        return f"{where or '/'}: {a!r} against {b!r}"
    if isinstance(a, dict):
        for k in sorted(set(a) | set(b)):
            if k not in b and a[k] is None:
                continue  # a null of the base, left out by the head
            if k not in a or k not in b:
                return f"{where}/{k}: only in {'head' if k in b else 'base'}"
            d = first_json_difference(a[k], b[k], f"{where}/{k}")
            if d:
                return d
        return None
    if isinstance(a, list):
        if len(a) != len(b):
            return f"{where}: {len(a)} items against {len(b)}"
        for i, (x, y) in enumerate(zip(a, b)):
            d = first_json_difference(x, y, f"{where}[{i}]")
            if d:
                return d
        return None
    if a != b:
        return f"{where}: {a!r} against {b!r}"
    return None


def first_text_difference(a: bytes, b: bytes) -> str:
    la, lb = a.splitlines(), b.splitlines()
    for i, (x, y) in enumerate(zip(la, lb)):
        if x != y:
            return f"line {i + 1}: {x[:160]!r} against {y[:160]!r}"
    return f"{len(la)} lines against {len(lb)}"


def compare_folders(base: Path, head: Path) -> list[str]:
    """The differences between two run folders (empty when the same)."""
    files = lambda root: {p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file()}
    fa = files(base) if base.exists() else set()
    fb = files(head) if head.exists() else set()
    problems = [f"{f}: only in the base run" for f in sorted(fa - fb)]
    problems += [f"{f}: only in the head run" for f in sorted(fb - fa)
                 if f not in HEAD_ONLY and not HEAD_ONLY_FILES.match(f)]
    for rel in sorted(fa & fb):
        a, b = (base / rel).read_bytes(), (head / rel).read_bytes()
        if rel.endswith(".json"):
            try:
                ja, jb = masked(json.loads(a)), masked(json.loads(b))
                if rel == "status.json" and isinstance(jb, dict) and isinstance(jb.get("files"), list):
                    jb["files"] = [f for f in jb["files"]
                                   if not (isinstance(f, dict)
                                           and (f.get("path") in HEAD_ONLY
                                                or HEAD_ONLY_FILES.match(str(f.get("path"))))
                                           and f.get("path") not in fa)]
            except json.JSONDecodeError as e:
                if a != b:
                    problems.append(f"{rel}: not JSON ({e}) and different")
                continue
            d = first_json_difference(ja, jb)
            if d:
                problems.append(f"{rel}: {d}")
        elif a != b and not (rel.endswith(".vtu")
                             and HEAD_ONLY_ARRAYS.sub("", b.decode())
                             == HEAD_ONLY_ARRAYS.sub("", a.decode())):
            if rel.endswith(".png"):
                problems.append(f"{rel}: the pictures differ ({len(a)} against {len(b)} bytes)")
            else:
                problems.append(f"{rel}: {first_text_difference(a, b)}")
    return problems


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    base = parser.add_mutually_exclusive_group(required=True)
    base.add_argument("--base", help="the base revision (commit, tag, branch)")
    base.add_argument("--base-bin", type=Path, help="an ncform binary built from the base")
    parser.add_argument("--head-bin", type=Path, help="the head binary (default: build the working tree)")
    parser.add_argument("--set", default="quick", choices=("quick", "shipped", "all"))
    parser.add_argument("--work", type=Path, default=REPO / "target" / "same-outputs",
                        help="scratch folder (worktree, builds, run folders)")
    parser.add_argument("--only", default="", help="run only the cases whose label contains this")
    args = parser.parse_args()

    work = args.work.resolve()
    work.mkdir(parents=True, exist_ok=True)
    base_bin = args.base_bin.resolve() if args.base_bin else build_base(args.base, work)
    head_bin = args.head_bin.resolve() if args.head_bin else build_head()
    cases = [c for c in case_set(args.set, work) if args.only in c[0]]
    passed = failed = 0
    run_dir = work / "run"
    new_cases = 0
    for label, case in cases:
        outcome = {}
        for side, binary in (("base", base_bin), ("head", head_bin)):
            outcome[side] = run_case(binary, case, run_dir, work / side / label)
        # A case the base refuses as a case file (an error exit before any
        # run folder) while the head runs it is new with the head (a key
        # the base does not know): nothing to compare; reported, neither
        # passed nor failed.
        if (outcome["base"]["code"] != 0 and not (work / "base" / label).exists()
                and outcome["head"]["code"] == 0):
            new_cases += 1
            print(f"NEW  [{label}] the base refuses the case: "
                  f"{outcome['base']['stderr'].strip()[:200]!r}", flush=True)
            continue
        problems = compare_folders(work / "base" / label, work / "head" / label)
        for stream in ("code", "stdout", "stderr"):
            if outcome["base"][stream] != outcome["head"][stream]:
                problems.append(
                    f"{stream}: {str(outcome['base'][stream])[:300]!r} against "
                    f"{str(outcome['head'][stream])[:300]!r}"
                )
        if problems:
            failed += 1
            print(f"FAIL [{label}] the same outputs as the base")
            for p in problems[:20]:
                print(f"    {p}")
            if len(problems) > 20:
                print(f"    ... and {len(problems) - 20} more")
        else:
            passed += 1
            count = sum(1 for p in (work / "head" / label).rglob("*") if p.is_file())
            print(f"PASS [{label}] the same outputs as the base ({count} files, exit {outcome['head']['code']})",
                  flush=True)
    print(f"same-outputs: {passed} passed, {failed} failed"
          + (f", {new_cases} new (refused by the base)" if new_cases else ""))
    return 0 if failed == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
