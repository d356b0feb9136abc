"""Reader of the firmware's UART sample stream (line format in docs/firmware.md).

A stream is a banner line starting with ``#`` and then one line per output sample:
``INDEX X Y Z`` with the sample index (output periods of the data path since power-on) and the
three rates in millidegrees per second. A gap in the index is a lost line or a missed period.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

MDPS_PER_DPS = 1000.0


class UartStreamError(ValueError):
    """A stream line that does not follow the documented format."""


@dataclass(frozen=True)
class UartStream:
    index: np.ndarray  # (n,) int64, sample index
    rate_dps: np.ndarray  # (n, 3) float64, deg/s
    banner: str

    @property
    def gaps(self) -> int:
        """Samples missing between the first and the last index."""
        if len(self.index) < 2:
            return 0
        return int(self.index[-1] - self.index[0] + 1 - len(self.index))


def parse_uart_stream(data: str | bytes, *, allow_partial_last_line: bool = True) -> UartStream:
    """Parse the stream; a line cut by the end of a capture is dropped when allowed."""
    text = data.decode("ascii", errors="strict") if isinstance(data, bytes) else data
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    elif lines and allow_partial_last_line:
        lines.pop()  # the capture stopped inside this line
    banner = ""
    indices: list[int] = []
    values: list[tuple[int, int, int]] = []
    for number, line in enumerate(lines, start=1):
        if line.startswith("#"):
            banner = banner or line
            continue
        parts = line.split(" ")
        if len(parts) != 4:
            raise UartStreamError(f"line {number}: expected 'INDEX X Y Z', got {line!r}")
        try:
            index, x, y, z = (int(p) for p in parts)
        except ValueError:
            raise UartStreamError(f"line {number}: non-integer field in {line!r}") from None
        if indices and index <= indices[-1]:
            raise UartStreamError(f"line {number}: index {index} does not increase")
        indices.append(index)
        values.append((x, y, z))
    rate = np.asarray(values, dtype=float).reshape(-1, 3) / MDPS_PER_DPS
    return UartStream(np.asarray(indices, dtype=np.int64), rate, banner)


def read_uart_stream(path: str | Path) -> UartStream:
    return parse_uart_stream(Path(path).read_bytes())
