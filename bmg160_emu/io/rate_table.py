"""The table a rate file is read into, and the one error of rate files.

Apart from :mod:`bmg160_emu.io.rates` so that the readers it dispatches to (RESD, the
firmware's UART stream) can build tables without importing it back.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bmg160_emu.io.errors import FormatError

__all__ = ["ColumnChoice", "RateFileError", "RateTable"]


class RateFileError(FormatError):
    """A rate file that cannot be used: unreadable, wrong shape, bad time column, no rate."""


# A choice of columns: given the header (None when the file has none), the number of
# columns and where the header (or first row) is, the index of the time column (or None)
# and the indices of the value columns, in the order wanted.
ColumnChoice = Callable[[list[str] | None, int, str], tuple[int | None, list[int]]]


@dataclass
class RateTable:
    """Columns read from a rate file, and where each row came from (for messages)."""

    path: Path
    header: list[str] | None
    t_s: np.ndarray | None
    values: np.ndarray  # (n, k) float64
    comments: list[tuple[int, str]] = field(default_factory=list)  # leading '#' lines
    # where rows came from: row_starts[i] is the first row of a chunk whose rows are file
    # lines row_lines[i] (an int: consecutive lines from it; an array: line of each row)
    row_starts: list[int] = field(default_factory=list)
    row_lines: list[int | np.ndarray] = field(default_factory=list)
    rate_hz: float | None = None  # the sample rate the file itself states (an NPZ's rate_hz)
    # the unit the file states for its rates, already converted to deg/s (a CSV column's
    # name, io/rate_units.py; "deg/s" for formats defined in it); None: the file says none
    stated_unit: str | None = None

    def where(self, row: int) -> str:
        """``path:LINE`` of CSV data row ``row`` (0-based), or ``path: row N`` for arrays."""
        if not self.row_starts:
            return f"{self.path}: row {row}"
        k = bisect_right(self.row_starts, row) - 1
        lines = self.row_lines[k]
        start = self.row_starts[k]
        line = lines + (row - start) if isinstance(lines, int) else int(lines[row - start])
        return f"{self.path}:{line}"

    def line_text(self, row: int) -> str:
        """The text of CSV data row ``row`` as the file holds it (read again: for messages)."""
        line = int(self.where(row).rsplit(":", 1)[1])
        with open(self.path, encoding="utf-8", errors="replace") as handle:
            for number, text in enumerate(handle, 1):
                if number == line:
                    return text.strip()
        return ""
