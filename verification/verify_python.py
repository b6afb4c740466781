#!/usr/bin/env python3
"""The Python module `ncform` (python/, pyproject.toml): built, installed and
tested against the command line.

1. The verification suite's pinned environment (verification/.venv, when
   run from it as verification/run.sh does; standalone, a venv of its own,
   verification/.venv-python, made once, git-ignored) with the pinned
   packages of verification/requirements.txt that the module and its tests
   need (PYTHON_PACKAGES below: numpy, meshio, maturin, pytest,
   dask[distributed] and their dependencies).
2. `pip install --no-build-isolation <repo>` builds the abi3 wheel with the
   pinned maturin and installs it, with CARGO_TARGET_DIR=<repo>/target so
   that the dependencies compiled for the release binary are reused where
   their features agree (the build time is printed).
3. pytest runs python/tests (the CLI binary given by --ncform, through
   $NCFORM_BIN): history to the CSV's digits, states as meshio meshes, the
   CLI's error messages, pickling, Ctrl-C, the interpreter lock released,
   the Dask example. One PASS/FAIL line per test.

Prints `CHECK-SUMMARY passed=N failed=M` (the protocol of verification/run.sh).

Usage: verify_python.py --ncform PATH [--venv DIR]
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ElementTree
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent

# The packages of requirements.txt installed into the module's environment.
PYTHON_PACKAGES = {
    "numpy", "meshio", "rich", "markdown-it-py", "mdurl", "Pygments",
    "maturin", "pytest", "iniconfig", "pluggy", "packaging",
    "dask", "distributed", "click", "cloudpickle", "fsspec", "importlib_metadata",
    "zipp", "locket", "partd", "toolz", "PyYAML", "Jinja2", "MarkupSafe",
    "msgpack", "psutil", "sortedcontainers", "tblib", "tornado", "zict",
    "lazy-importer",
}


def pinned_lines():
    """The lines of requirements.txt for PYTHON_PACKAGES (`name==version`,
    extras kept)."""
    lines = []
    for line in (HERE / "requirements.txt").read_text().splitlines():
        line = line.split("#")[0].strip()
        name = re.split(r"[\[=<>]", line)[0] if line else ""
        if name in PYTHON_PACKAGES:
            lines.append(line)
    return lines


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--ncform", default="", help="the ncform binary the tests compare with")
    parser.add_argument("--venv", type=Path, default=None,
                        help="the environment to install into (default: the suite's own, "
                             "verification/.venv, when run from it as run.sh does; else "
                             "verification/.venv-python)")
    args = parser.parse_args()
    if args.venv is None:
        in_venv = sys.prefix != getattr(sys, "base_prefix", sys.prefix)
        args.venv = Path(sys.prefix) if in_venv else HERE / ".venv-python"
    passed = failed = 0

    def check(ok, what, detail=""):
        nonlocal passed, failed
        print(f"{'PASS' if ok else 'FAIL'} [python] {what}" + (f": {detail}" if detail and not ok else ""))
        if ok:
            passed += 1
        else:
            failed += 1
        return ok

    py = args.venv / "bin" / "python"
    env = dict(os.environ, PIP_DISABLE_PIP_VERSION_CHECK="1")
    env.pop("PYTHONPATH", None)
    env.pop("VIRTUAL_ENV", None)

    # --- 1. the environment -------------------------------------------------
    pins = pinned_lines()
    stamp = args.venv / ".requirements.installed"
    try:
        if not py.exists():
            print(f"# creating {args.venv}")
            subprocess.run([sys.executable, "-m", "venv", str(args.venv)], check=True)
        if not stamp.exists() or stamp.read_text() != "\n".join(pins):
            print("# installing " + " ".join(pins))
            subprocess.run([str(py), "-m", "pip", "install", "--quiet", *pins], check=True, env=env)
            stamp.write_text("\n".join(pins))
        env_ok = True
    except (subprocess.CalledProcessError, OSError) as e:
        env_ok = False
        check(False, "the module's environment installs", str(e))
    if not env_ok:
        print(f"CHECK-SUMMARY passed={passed} failed={failed}")
        return 1

    # --- 2. the wheel -------------------------------------------------------
    build_env = dict(
        env,
        CARGO_TARGET_DIR=str(REPO / "target"),
        PATH=str(args.venv / "bin") + os.pathsep + env.get("PATH", ""),
    )
    start = time.monotonic()
    built = subprocess.run(
        [str(py), "-m", "pip", "install", "--quiet", "--no-build-isolation", "--no-deps", "--force-reinstall", str(REPO)],
        env=build_env, capture_output=True, text=True,
    )
    seconds = time.monotonic() - start
    print(f"# pip install --no-build-isolation {REPO}: {seconds:.1f} s")
    if not check(built.returncode == 0, "the abi3 wheel builds (maturin) and installs", built.stderr[-3000:]):
        print(f"CHECK-SUMMARY passed={passed} failed={failed}")
        return 1

    # --- 3. the tests ---------------------------------------------------------
    with tempfile.TemporaryDirectory(prefix="ncform-pytest-") as tmp:
        report = Path(tmp) / "junit.xml"
        test_env = dict(env, NCFORM_BIN=os.path.abspath(args.ncform) if args.ncform else "/nonexistent/ncform")
        done = subprocess.run(
            [str(py), "-m", "pytest", "-p", "no:cacheprovider", "-q", f"--junitxml={report}",
             f"--basetemp={Path(tmp) / 'pytest'}", str(REPO / "python" / "tests")],
            env=test_env, cwd=tmp, capture_output=True, text=True,
        )
        if not report.exists():
            check(False, "pytest python/tests runs", (done.stdout + done.stderr)[-3000:])
        else:
            cases = list(ElementTree.parse(report).getroot().iter("testcase"))
            check(len(cases) > 0, "pytest python/tests collects tests", (done.stdout + done.stderr)[-3000:])
            for case in cases:
                name = case.get("name")
                doc = f"{name} ({float(case.get('time', 0)):.1f} s)"
                problem = case.find("failure")
                if problem is None:
                    problem = case.find("error")
                skipped = case.find("skipped")
                if problem is not None:
                    check(False, doc, (problem.get("message") or "")[:500])
                elif skipped is not None:
                    check(False, doc, "skipped: " + (skipped.get("message") or ""))
                else:
                    check(True, doc)
    print(f"CHECK-SUMMARY passed={passed} failed={failed}")
    return 0 if failed == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
