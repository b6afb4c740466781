#!/usr/bin/env python3
"""A small parameter study with Dask: the coarse 45° OAT over a few values of
the law's shear parameter `material.w6.s_ini`, one run per task, on a local
cluster of two worker processes.

What crosses the process boundaries is small: the case file's path and the
key edits go to the workers (an `ncform.Case` pickles as its path plus its
edits, replayed where it is unpickled, so the case file must be readable
there), and each task returns a dict of a few numbers, not the Result (whose
run folder is a temporary folder of the worker).

    python examples/dask_sweep.py              # 4 values
    python examples/dask_sweep.py --count 2

On a Slurm cluster, replace the LocalCluster line by (pip install dask-jobqueue):

    from dask_jobqueue import SLURMCluster; cluster = SLURMCluster(cores=1, memory="2GB", processes=1, walltime="00:30:00"); cluster.scale(jobs=4)

and keep the rest: the case path must then be on a file system the nodes share.
"""

import argparse
from pathlib import Path

import numpy as np
from dask.distributed import Client, LocalCluster

CASE = Path(__file__).resolve().parents[1] / "cases" / "oat45.toml"


def run_one(case_path: str, edits: dict) -> dict:
    """Runs the case with `edits` ({key: value}) applied, one thread; returns
    the force at the end and at 40 mm, the status and the edits."""
    import ncform

    case = ncform.load_case(case_path)
    for key, value in edits.items():
        case.set(key, value)
    result = ncform.run(case, threads=1)
    d = result.history["displacement [mm]"]
    f = result.history["force [N]"]
    return {
        **edits,
        "force at 40 mm [N]": float(np.interp(40.0, d, f)),
        "final force [N]": float(f[-1]),
        "shear at the end [deg]": float(result.history["shear_angle [deg]"][-1]),
        "status": result.status,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=4, help="values of material.w6.s_ini (default 4)")
    parser.add_argument("--case", default=str(CASE), help="the OAT case file (default cases/oat45.toml)")
    args = parser.parse_args()

    import ncform

    base = ncform.load_case(args.case).get("material.w6.s_ini")
    values = [float(v) for v in base * np.linspace(0.5, 1.5, args.count)]
    edits = [{"mesh.element_size": 10.0, "material.w6.s_ini": v} for v in values]

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with Client(cluster) as client:
            futures = client.map(run_one, [args.case] * len(edits), edits, pure=False)
            rows = client.gather(futures)

    columns = ["material.w6.s_ini", "force at 40 mm [N]", "final force [N]", "shear at the end [deg]", "status"]
    print("| " + " | ".join(columns) + " |")
    print("|" + "|".join("---" for _ in columns) + "|")
    for row in rows:
        cells = [f"{row[c]:.6g}" if isinstance(row[c], float) else str(row[c]) for c in columns]
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
