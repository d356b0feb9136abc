"""A scenario's rate table: the body rates of the user's own dynamics simulation, ``t_s, x,
y, z`` per row, inline (``samples``) or in a file (``file``: CSV, or an .npy array, read
through the format registry's ``rate table`` kind, io/rates.py).

A bad value names the table file and its line (CSV) or row (.npy), or the inline row: a
``nan`` used to pass loading and fail later in the interpolation without naming either, and
a table path that was a folder was reported as the scenario file (issue 35).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bmg160_emu.adcs.scenario_values import ScenarioError
from bmg160_emu.io.errors import FormatError
from bmg160_emu.io.formats import read_file

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
        try:  # the registry's rate table formats: .csv, .npy (a folder, a missing file,
            data = read_file("rate table", path)  # a bad value: named by file and place)
        except FormatError as exc:
            raise ScenarioError(f"{where}: {exc}") from None
        except OSError as exc:  # unreadable, a name too long: the table, not the scenario
            raise ScenarioError(f"{where}: cannot read rate table {path}: "
                                f"{exc.strerror or type(exc).__name__}") from None
    else:
        raise ScenarioError(f"{where}: a table needs 'samples' or 'file'")
    if data.ndim != 2 or data.shape[1] != 4:
        raise ScenarioError(f"{where}: a rate table needs rows of 4 numbers: {COLUMNS}")
    return data
