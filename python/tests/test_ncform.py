"""Tests of the Python module `ncform` against the command line.

The CLI binary is $NCFORM_BIN (verification/verify_python.py sets it from
--ncform), else target/release/ncform of this repository.
"""

import csv
import json
import os
import pickle
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import meshio
import numpy as np
import pytest

import ncform

REPO = Path(__file__).resolve().parents[2]
CLI = os.environ.get("NCFORM_BIN") or str(REPO / "target" / "release" / "ncform")
OAT45 = REPO / "cases" / "oat45.toml"


def cli_run(case, out):
    """`ncform run CASE --out OUT --quiet`: (exit code, stderr)."""
    done = subprocess.run([CLI, "run", str(case), "--out", str(out), "--quiet"], capture_output=True, text=True)
    return done.returncode, done.stderr


def csv_columns(path):
    """The CSV's columns as {name: [float]} parsed by Python from its text."""
    with open(path, newline="") as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    header, data = rows[0], rows[1:]
    return {name: [float(r[i]) if r[i] else float("nan") for r in data] for i, name in enumerate(header)}


def coarse_case(tmp_path):
    """cases/oat45.toml with 10 mm elements, edited by key and written out."""
    case = ncform.load_case(str(OAT45))
    case.set("mesh.element_size", 10.0)
    return case, Path(case.write(str(tmp_path / "case")))


def test_history_equals_cli(tmp_path):
    case, written = coarse_case(tmp_path)
    code, err = cli_run(written, tmp_path / "cli")
    assert code == 0, err
    result = ncform.run(case)
    assert result.status == "complete" and result.exit_code == 0
    force = csv_columns(tmp_path / "cli" / "force_displacement.csv")
    mdz = csv_columns(tmp_path / "cli" / "mdz_strains.csv")
    assert list(result.history) == list(force) + [c for c in mdz if c not in force]
    assert "force [N]" in result.history and "displacement [mm]" in result.history
    for name, values in {**force, **mdz}.items():
        got = result.history[name]
        assert got.dtype == np.float64
        assert got.tolist() == values, name  # exact: the CSV's digits
    # Every CSV of the run folder, and the summary's forces and history.
    for path in sorted((tmp_path / "cli").glob("*.csv")):
        ref = csv_columns(path)
        assert {k: v.tolist() for k, v in result.tables[path.name].items()} == ref, path.name
    summary = json.loads((tmp_path / "cli" / "summary.json").read_text())
    assert result.summary["forces"] == summary["forces"]
    assert result.summary["history"] == summary["history"]


def test_loaded_case_equals_cli(tmp_path):
    """The shipped cases/oat45.toml (paper size, unedited) runs as `ncform run`
    runs it: the force curve to the last digit."""
    path = OAT45
    code, err = cli_run(path, tmp_path / "cli")
    assert code == 0, err
    result = ncform.run(ncform.load_case(str(path)), threads=None)
    force = csv_columns(tmp_path / "cli" / "force_displacement.csv")
    assert result.history["force [N]"].tolist() == force["force [N]"]


def test_states_are_meshio_meshes(tmp_path):
    case, written = coarse_case(tmp_path)
    code, err = cli_run(written, tmp_path / "cli")
    assert code == 0, err
    result = ncform.run(case)
    assert result.times == [20.0, 40.0, 60.0, 80.0]
    assert len(result.states) == 4
    vtus = sorted((tmp_path / "cli" / "vtu").glob("*.vtu"))
    assert len(vtus) == 4
    for state, vtu in zip(result.states, vtus):
        assert isinstance(state, meshio.Mesh)
        ref = meshio.read(vtu)
        assert np.array_equal(state.points, ref.points)
        assert set(state.point_data) == set(ref.point_data) >= {"displacement"}
        assert set(state.cell_data) == set(ref.cell_data) >= {"E22", "shear_angle_deg", "mdz"}
        for name in ref.point_data:
            assert np.array_equal(state.point_data[name], ref.point_data[name])
        for name in ref.cell_data:
            for a, b in zip(state.cell_data[name], ref.cell_data[name]):
                assert np.array_equal(a, b)


def test_write_refuses_non_empty(tmp_path):
    case, _ = coarse_case(tmp_path)
    case.set("loading.output_displacements", [10.0])
    case.set("loading.displacement", 20.0)
    result = ncform.run(case, threads=1)
    out = result.write(tmp_path / "out")
    assert (out / "status.json").exists() and (out / "force_displacement.csv").exists()
    with pytest.raises(FileExistsError):
        result.write(tmp_path / "out")
    result.write(tmp_path / "out", overwrite=True)
    assert (tmp_path / "out" / "summary.json").exists()


def test_bad_case_message(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(OAT45.read_text().replace("element_size = 2.7", "element_size = -1.0"))
    code, err = cli_run(bad, tmp_path / "cli")
    assert code == 1
    line = [l for l in err.splitlines() if l.startswith("error: ")][0]
    with pytest.raises(ncform.CaseError) as caught:
        ncform.load_case(str(bad))
    assert isinstance(caught.value, ValueError)
    assert str(caught.value) == line[len("error: "):]
    missing = tmp_path / "missing.toml"
    code, err = cli_run(missing, tmp_path / "cli2")
    with pytest.raises(ncform.CaseError, match="missing.toml") as caught:
        ncform.load_case(str(missing))
    assert "error: " + str(caught.value) in err


def test_run_error_message(tmp_path):
    """A case that loads but cannot be set up: the explicit OAT allowed
    fewer increments than its first stable step asks for."""
    text = (REPO / "cases" / "oat45-explicit.toml").read_text()
    path = tmp_path / "few.toml"
    path.write_text(text.replace("[explicit]\n", "[explicit]\nmax_increments = 10\n"))
    code, err = cli_run(path, tmp_path / "cli")
    assert code == 1, err
    line = [l for l in err.splitlines() if l.startswith("error: ")][0]
    case = ncform.load_case(str(path))
    with pytest.raises(ncform.RunError) as caught:
        ncform.run(case)
    assert str(caught.value) == line[len("error: "):]
    assert "explicit.max_increments" in str(caught.value)


def test_keys_get_set(tmp_path):
    case = ncform.load_case(str(OAT45))
    assert case.get("loading.displacement") == 80.0
    assert case.get("loading.output_displacements") == [20.0, 40.0, 60.0]
    s_ini = case.get("material.w6.s_ini")
    case.set("material.w6.s_ini", s_ini * 1.5)
    assert case.get("material.w6.s_ini") == s_ini * 1.5
    with pytest.raises(ncform.CaseError, match="loading.nothing"):
        case.set("loading.nothing", 1.0)
    with pytest.raises(ncform.CaseError):
        case.set("loading.displacement", "far")
    assert case.get("loading.displacement") == 80.0  # unchanged by the refusals
    assert "element_size" in case.text


def test_pickle_round_trip(tmp_path):
    case = ncform.load_case(str(OAT45))
    case.set("mesh.element_size", 10.0)
    case.set("material.w6.s_ini", 0.5)
    back = pickle.loads(pickle.dumps(case))
    assert isinstance(back, ncform.Case)
    assert back.sets == case.sets == [("mesh.element_size", 10.0), ("material.w6.s_ini", 0.5)]
    assert back.text == case.text
    assert back.get("material.w6.s_ini") == 0.5
    a = ncform.run(case).history["force [N]"]
    b = ncform.run(back).history["force [N]"]
    assert a.tolist() == b.tolist()


CTRL_C_SCRIPT = textwrap.dedent(
    """
    import sys, ncform
    case = ncform.load_case(sys.argv[1])
    print("started", flush=True)
    try:
        ncform.run(case, threads=1)
    except KeyboardInterrupt:
        print("KeyboardInterrupt", flush=True)
        sys.exit(42)
    print("finished", flush=True)
    """
)


def test_ctrl_c_cancels(tmp_path):
    """SIGINT during a long run (the explicit OAT, about a minute): the solve
    stops at its next safe point and KeyboardInterrupt is raised."""
    proc = subprocess.Popen(
        [sys.executable, "-c", CTRL_C_SCRIPT, str(REPO / "cases" / "oat45-explicit.toml")],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout.readline().strip() == "started"
        time.sleep(2.0)
        assert proc.poll() is None, "the run ended before the signal"
        sent = time.monotonic()
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=20)
        elapsed = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 42, (out, err)
    assert "KeyboardInterrupt" in out
    assert elapsed < 5.0, elapsed


def test_gil_released(tmp_path):
    """A Python thread keeps counting while a run is going."""
    case = ncform.load_case(str(OAT45))
    case.set("mesh.element_size", 3.5)
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(time.monotonic())
            time.sleep(0.005)

    counter = threading.Thread(target=count)
    counter.start()
    start = time.monotonic()
    try:
        ncform.run(case, threads=1)
    finally:
        end = time.monotonic()
        stop.set()
        counter.join()
    during = [t for t in ticks if start <= t <= end]
    assert end - start > 0.3, "the run was too short to tell"
    gaps = np.diff([start] + during + [end])
    assert gaps.max() < 0.25, f"the counter stalled for {gaps.max():.3f} s during a {end - start:.2f} s run"
    assert len(during) > (end - start) / 0.05


def test_threads_argument(tmp_path):
    case, _ = coarse_case(tmp_path)
    with pytest.raises(ValueError):
        ncform.run(case, threads=0)
    one = ncform.run(case, threads=1)
    assert one.status == "complete" and len(one.history["force [N]"]) > 0


def test_dask_example_runs():
    """examples/dask_sweep.py on two values of material.w6.s_ini."""
    pytest.importorskip("distributed")
    done = subprocess.run(
        [sys.executable, str(REPO / "examples" / "dask_sweep.py"), "--count", "2"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=str(REPO),
    )
    assert done.returncode == 0, done.stdout + done.stderr
    rows = [l for l in done.stdout.splitlines() if l.startswith("|")]
    assert len(rows) == 2 + 2, done.stdout  # header, rule, two values
