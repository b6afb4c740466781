"""ncform from Python: read a case, edit it by key, run it, read the results.

    import ncform
    case = ncform.load_case("cases/oat45.toml")   # CaseError: the CLI's message
    case.set("mesh.element_size", 10.0)            # the sweep's keys
    result = ncform.run(case, threads=2)           # the library's one runner
    result.history["force [N]"]                    # numpy arrays, the CSV's digits
    result.summary, result.states, result.status   # summary.json, meshio meshes
    result.write("out/oat45")                      # the run folder

A run writes its run folder (as `ncform run CASE --out DIR`) into a
temporary folder that lives as long as the Result; `history` holds the
numbers read back from its CSV files, so they are the CLI's to the last
digit. The solve releases the interpreter lock; Ctrl-C stops it at the
solver's next safe point and raises KeyboardInterrupt.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
import warnings
import xml.etree.ElementTree as ElementTree
from pathlib import Path
from typing import Any, Dict, List, Optional, Union

from ._ncform import Case, CaseError, RunError, __version__, load_case, read_csv, run_into

__all__ = [
    "Case",
    "CaseError",
    "CaseWarning",
    "Result",
    "RunError",
    "__version__",
    "load_case",
    "read_csv",
    "run",
]

PathLike = Union[str, "os.PathLike[str]"]


class CaseWarning(UserWarning):
    """A case's warning (an unusual value, a key read but not used), as
    `ncform run` prints it after `warning: `."""


# The CSV files whose columns make a run's history: an OAT's force curve and
# MDZ strains (one row per recorded state, sharing the displacement column),
# a forming run's readout on the blank.
_HISTORY_FILES = {
    "oat": ("force_displacement.csv", "mdz_strains.csv"),
    "forming": ("forming.csv",),
}


def run(case: Case, threads: Optional[int] = None, quiet: bool = True) -> "Result":
    """Runs `case` (a `Case` from `load_case`) with the library's one runner,
    as `ncform run` does, and returns its `Result`.

    threads: worker threads (a rayon pool of the run's own, and the explicit
    solver's threads); None takes all cores, as the CLI. quiet: no estimate
    and progress on stderr. The case's warnings are issued as `CaseWarning`.

    Raises `RunError` (the CLI's message) when the run cannot be set up, and
    `KeyboardInterrupt` after stopping the solve on Ctrl-C. A solve that
    stops early is not an error: `Result.status` says `incomplete`.
    """
    if not isinstance(case, Case):
        raise TypeError(f"run() takes an ncform.Case (from ncform.load_case), not {type(case).__name__}")
    for warning in case.warnings:
        warnings.warn(warning, CaseWarning, stacklevel=2)
    scratch = tempfile.TemporaryDirectory(prefix="ncform-run-")
    folder = Path(scratch.name) / "run"
    try:
        run_into(case, str(folder), threads=threads, quiet=quiet)
    except BaseException:
        scratch.cleanup()
        raise
    return Result(folder, case.kind, scratch)


class Result:
    """A run's results, read from its run folder.

    history: {CSV column name: numpy float64 array} — an OAT's
        force_displacement.csv and mdz_strains.csv columns
        ("displacement [mm]", "force [N]", "E22 [-]", …), a forming run's
        forming.csv columns; the numbers parsed from the files' digits.
    tables: {CSV file name: {column: array}} for every CSV of the folder.
    summary: summary.json as a dict.  status_file: status.json as a dict.
    status: "complete", "incomplete" or "interrupted".  exit_code: the exit
        code `ncform run` would have given (0, 3, 4 or 5).
    states: one meshio.Mesh per output state (the VTU files, in the order
        of the .pvd collection), with their point and cell data.
    times: the .pvd's timestep of each state (clamp displacement [mm] or
        programme fraction).
    folder: the run folder (temporary: it lives as long as this object;
        `write` copies it).
    """

    def __init__(self, folder: Path, kind: str, scratch: Optional[tempfile.TemporaryDirectory] = None):
        self.folder = Path(folder)
        self.kind = kind
        self._scratch = scratch
        self.status_file: Dict[str, Any] = json.loads((self.folder / "status.json").read_text())
        summary = self.folder / "summary.json"
        self.summary: Dict[str, Any] = json.loads(summary.read_text()) if summary.exists() else {}
        self.status: str = self.status_file["status"]
        self.exit_code: int = int(self.status_file["exit_code"])
        self.tables: Dict[str, Dict[str, Any]] = {
            p.name: read_csv(str(p)) for p in sorted(self.folder.glob("*.csv"))
        }
        self.history: Dict[str, Any] = {}
        for name in _HISTORY_FILES.get(kind, ()):
            for column, values in self.tables.get(name, {}).items():
                if column in self.history:
                    if not (self.history[column] == values).all():
                        raise RuntimeError(f"{name}: column {column!r} differs from the other history file's")
                    continue
                self.history[column] = values
        self._states: Optional[List[Any]] = None
        self._times: Optional[List[float]] = None

    def _collection(self) -> List[tuple]:
        """(timestep, VTU path) of every state, from the run's .pvd files."""
        entries = []
        for pvd in sorted(self.folder.glob("*.pvd")):
            for node in ElementTree.parse(pvd).getroot().iter("DataSet"):
                entries.append((float(node.get("timestep", "nan")), self.folder / node.get("file")))
        return entries

    @property
    def states(self) -> List[Any]:
        """The output states as meshio.Mesh (read once, on first use)."""
        if self._states is None:
            import meshio

            entries = self._collection()
            self._times = [t for t, _ in entries]
            self._states = [meshio.read(str(path)) for _, path in entries]
        return self._states

    @property
    def times(self) -> List[float]:
        """The timestep of each state in `states`."""
        if self._times is None:
            self._times = [t for t, _ in self._collection()]
        return self._times

    def write(self, folder: PathLike, overwrite: bool = False) -> Path:
        """Copies the run folder to `folder`; a non-empty `folder` is refused
        unless `overwrite` (then it is replaced). Returns the path."""
        target = Path(folder)
        if target.exists():
            if not target.is_dir():
                raise FileExistsError(f"{target}: exists and is not a folder")
            if any(target.iterdir()):
                if not overwrite:
                    raise FileExistsError(f"{target}: not empty (pass overwrite=True to replace it)")
                shutil.rmtree(target)
            else:
                target.rmdir()
        shutil.copytree(self.folder, target)
        return target

    def __repr__(self) -> str:
        rows = len(next(iter(self.history.values()))) if self.history else 0
        return f"ncform.Result({self.summary.get('title', '')!r}, status={self.status!r}, rows={rows})"
