#!/usr/bin/env python3
"""How a large sweep folder's bookkeeping scales: prepare, --status and
collect of a 1,000-point sweep (docs/benchmarks.md, "Sweeps").

A 40 x 25 grid on the coarse 45 deg OAT is prepared with --prepare-only
(every point's case checked and written, the manifest); one point is run
for real, and its run folder and status are copied into the other 999
folders with each point's own input hash, so that --status and collect
read 1,000 complete points. Prints the wall time of each command, median
of --repeat runs.

    python3 benches/sweep_scale.py --ncform target/release/ncform
"""
import argparse, json, shutil, statistics, subprocess, tempfile, time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def timed(cmd):
    t = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ncform", default=str(REPO / "target/release/ncform"))
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    nc = a.ncform
    tmp = Path(tempfile.mkdtemp(prefix="ncform-sweep-scale-"))
    try:
        sweep = tmp / "big.toml"
        sweep.write_text(f'''title = "1,000-point bookkeeping"
case = "{REPO / 'cases/oat45.toml'}"
design = "grid"
[[set]]
key = "mesh.element_size"
value = 10.0
[[set]]
key = "loading.output_displacements"
value = []
[[vary]]
key = "material.w6.s_ini"
range = [0.012, 0.024, 40]
[[vary]]
key = "loading.displacement"
range = [30.0, 60.0, 25]
''')
        prep = []
        for k in range(a.repeat):
            d = tmp / f"prep{k}"
            prep.append(timed([nc, "sweep", str(sweep), "--out", str(d), "--prepare-only"]))
        d = tmp / "prep0"
        subprocess.run([nc, "sweep", str(d), "--points", "0"], check=True, stdout=subprocess.DEVNULL)
        manifest = json.loads((d / "sweep.json").read_text())
        p0 = d / manifest["points"][0]["folder"]
        status0 = json.loads((p0 / "status.json").read_text())
        for p in manifest["points"][1:]:
            pd = d / p["folder"]
            shutil.copytree(p0 / "run", pd / "run")
            st = dict(status0, inputs_sha256=p["inputs_sha256"])
            (pd / "status.json").write_text(json.dumps(st))
        status = [timed([nc, "sweep", str(d), "--status"]) for _ in range(a.repeat)]
        collect = [timed([nc, "collect", str(d)]) for _ in range(a.repeat)]
        rows = sum(1 for l in (d / "results.csv").read_text().splitlines() if l and not l.startswith("#")) - 1
        print(f"points: {len(manifest['points'])}, results.csv rows: {rows}")
        for name, t in [("prepare (--prepare-only)", prep), ("--status", status), ("collect", collect)]:
            print(f"{name}: median {statistics.median(t):.2f} s of {[round(x, 2) for x in t]}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
