#!/usr/bin/env python3
"""The module graph of ncform's library has no import circles.

Requirement (docs/architecture.md, "Checks on the structure"): no module of
`src/` imports a module that imports it back, directly or through others.
An edge A -> B is a path `crate::…`, `super::…` or `self::…` in A's code
(outside comments and `#[cfg(test)] mod tests`) that names module B or an
item in it; a path resolves to the deepest module it names. Edges from a
module to its own descendants (`mod` declarations, the façade's `pub use`
of its children's items) are not dependencies and are left out. The
floors are checked too: a kernel module (material, element, contact, mesh)
imports none of model, solver, case, report, cli; model imports none of
solver (except its parameters' types), case, report, cli; solver none of
case, report, cli; case none of report, cli; report none of cli.

Prints PASS/FAIL lines and `CHECK-SUMMARY passed=N failed=M` (the suite
protocol of verification/run.sh); `--ncform` is accepted and unused.
"""
import argparse
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent / "src"

# Floors, bottom up; a module may import its own floor and those below.
FLOORS = {
    "analytic": 0, "config": 0, "material": 0, "element": 1, "contact": 1,
    "mesh": 0, "model": 2, "solver": 3, "post": 3, "case": 4, "report": 5,
    "cli": 6,
}


def modules(root):
    mods = {}
    for f in sorted(root.rglob("*.rs")):
        parts = list(f.relative_to(root).with_suffix("").parts)
        if parts[0] == "bin":
            continue
        if parts[-1] in ("mod", "lib"):
            parts = parts[:-1]
        mods[tuple(parts)] = f
    return mods


def resolve(mods, current, path):
    segs = path.split("::")
    if segs[0] == "crate":
        base, segs = [], segs[1:]
    else:
        base = list(current)
        while segs and segs[0] in ("super", "self"):
            if segs[0] == "super":
                base = base[:-1]
            segs = segs[1:]
    full = base + segs
    for i in range(len(full), 0, -1):
        if tuple(full[:i]) in mods:
            return tuple(full[:i])
    return None


def edges(mods):
    out = {m: set() for m in mods}
    for m, f in mods.items():
        text = f.read_text()
        cut = re.search(r"#\[cfg\(test\)\]\s*mod tests", text)
        if cut:
            text = text[: cut.start()]
        text = re.sub(r"//[^\n]*", "", text)
        for mt in re.finditer(
            r"\b((?:crate|super|self)(?:::[A-Za-z_][A-Za-z0-9_]*)+)(::\{([^;]*?)\})?", text
        ):
            targets = [mt.group(1)]
            if mt.group(3):
                for item in mt.group(3).split(","):
                    item = item.strip().strip("{}").strip()
                    if item:
                        targets.append(mt.group(1) + "::" + item.split("::")[0])
            for t in targets:
                r = resolve(mods, m, t)
                if r and r != m and r[: len(m)] != m:
                    out[m].add(r)
    return out


def cycles(graph):
    index, low, stack, on, found = {}, {}, [], set(), []
    counter = [0]
    sys.setrecursionlimit(10000)

    def strong(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(comp)

    for v in graph:
        if v not in index:
            strong(v)
    return found


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--ncform", default="")
    parser.add_argument("--src", type=Path, default=ROOT, help="the source tree (default: src/)")
    args = parser.parse_args()
    mods = modules(args.src)
    graph = edges(mods)
    name = lambda m: "::".join(m) or "crate"
    passed = failed = 0
    found = cycles(graph)
    if found:
        failed += 1
        print(f"FAIL [modules] no import circles among the {len(mods)} modules of src/")
        for comp in found:
            print("    circle: " + " <-> ".join(name(m) for m in sorted(comp)))
    else:
        passed += 1
        print(f"PASS [modules] no import circles among the {len(mods)} modules of src/")
    upward = []
    for m, targets in graph.items():
        for t in targets:
            if m and t and m[0] in FLOORS and t[0] in FLOORS and FLOORS[t[0]] > FLOORS[m[0]]:
                # The Newton parameters live in solver/ and the model's
                # terms take none of them: no exception is needed today.
                upward.append(f"{name(m)} -> {name(t)}")
    if upward:
        failed += 1
        print("FAIL [floors] no module imports a floor above its own")
        for u in sorted(upward):
            print("    " + u)
    else:
        passed += 1
        print("PASS [floors] no module imports a floor above its own")
    print(f"CHECK-SUMMARY passed={passed} failed={failed}")
    return 0 if failed == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
