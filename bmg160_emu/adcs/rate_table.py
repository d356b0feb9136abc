"""A scenario's rate table: the body rates of the user's own dynamics simulation, ``t_s, x,
y, z`` per row, inline (``samples``) or in a file (``file``: CSV, or an .npy array).

Every value is checked where it is read, and a bad one names the table file and its line
(CSV) or row (.npy): a ``nan`` used to pass loading and fail later in the interpolation
without naming either, and a table path that was a folder was reported as the scenario file
(issue 35). The CSV reading stays in this one function (:func:`read_csv_rows`), so that it
can move onto the project's common format registry (issue 36) as a whole.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from bmg160_emu.adcs.scenario_values import ScenarioError
from bmg160_emu.io.errors import read_text

COLUMNS = "t_s, x, y, z"


def load_rate_table(entry: dict[str, Any], where: str, base: Path | None) -> np.ndarray:
    """The (n, 4) table of a ``kind = "table"`` motion: ``samples``, or ``file`` relative to
    ``base`` (the scenario file's folder). Errors start with ``where`` (``motion 2``)."""
    if "samples" in entry:
        try:
            data = np.asarray(entry["samples"], dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise ScenarioError(f"{where}: a rate table needs rows of 4 numbers: {COLUMNS}") \
                from None
        if data.ndim == 2 and data.shape[1] == 4:
            bad = np.flatnonzero(~np.isfinite(data).all(axis=1))
            if bad.size:
                raise ScenarioError(f"{where}: samples row {bad[0] + 1}: the times and rates "
                                    "must be finite numbers")
    elif "file" in entry:
        name = entry["file"]
        if not isinstance(name, str) or not name:
            raise ScenarioError(f"{where}: file must be the path of a table (a string), "
                                f"not {name!r}"[:200])
        path = Path(name)
        if not path.is_absolute() and base is not None:
            path = base / path
        data = read_table_file(path, where)
    else:
        raise ScenarioError(f"{where}: a table needs 'samples' or 'file'")
    if data.ndim != 2 or data.shape[1] != 4:
        raise ScenarioError(f"{where}: a rate table needs rows of 4 numbers: {COLUMNS}")
    return data


def read_table_file(path: Path, where: str) -> np.ndarray:
    """A table file, as (n, k) float64: ``.npy`` or CSV (any other suffix)."""
    try:
        if path.is_dir():
            raise ScenarioError(f"{where}: rate table {path} is a folder, not a file")
        if not path.exists():
            raise ScenarioError(f"{where}: rate table file not found: {path}")
        if path.suffix.lower() == ".npy":
            return _read_npy(path, where)
        return read_csv_rows(path, where)
    except OSError as exc:  # unreadable, a name too long, ...: the table, not the scenario
        raise ScenarioError(f"{where}: cannot read rate table {path}: "
                            f"{exc.strerror or type(exc).__name__}") from None


def read_csv_rows(path: Path, where: str) -> np.ndarray:
    """Rows of numbers; '#' comments, blank lines and one header line of names are skipped.
    Every number is finite and every row as long as the first: else the file and line."""
    rows: list[list[float]] = []
    header_skipped = False
    for number, line in enumerate(read_text(path, ScenarioError).splitlines(), 1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        try:
            row = [float(cell) for cell in text.split(",")]
        except ValueError:
            if rows or header_skipped:
                raise ScenarioError(f"{where}: {path}:{number}: not numbers: "
                                    f"{text[:80]!r}") from None
            header_skipped = True
            continue
        if not all(math.isfinite(v) for v in row):
            raise ScenarioError(f"{where}: {path}:{number}: the times and rates must be finite "
                                f"numbers, not {text[:80]!r}")
        if rows and len(row) != len(rows[0]):
            raise ScenarioError(f"{where}: {path}:{number}: {len(row)} values where the rows "
                                f"before have {len(rows[0])}")
        rows.append(row)
    if not rows:
        raise ScenarioError(f"{where}: {path} holds no rows of numbers")
    return np.array(rows)


def _read_npy(path: Path, where: str) -> np.ndarray:
    """An .npy table, its header checked against the bytes that follow before anything is
    allocated (io.array_header), no pickles, numbers only, each row finite."""
    from bmg160_emu.io.array_header import check_declared_size

    try:
        with path.open("rb") as handle:
            check_declared_size(handle, path.stat().st_size, path, ScenarioError)
        data = np.load(path, allow_pickle=False)
    except ScenarioError as exc:
        raise ScenarioError(f"{where}: {exc}") from None
    except (ValueError, EOFError) as exc:
        raise ScenarioError(f"{where}: {path}: not a readable .npy array ({exc})"[:300]) \
            from None
    if data.dtype.kind not in "iuf":
        raise ScenarioError(f"{where}: {path}: a table of numbers, not {data.dtype}")
    data = data.astype(float)
    if data.ndim == 2:
        bad = np.flatnonzero(~np.isfinite(data).all(axis=1))
        if bad.size:
            raise ScenarioError(f"{where}: {path}: row {bad[0] + 1}: the times and rates "
                                "must be finite numbers")
    return data
