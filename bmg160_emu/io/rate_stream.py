"""Writing a rate record block by block: a day of samples is never in memory at once.

Split from io/rates.py (one reader and writer of rate files) because the streaming writer
also makes an interrupted record honest (``end_short``): it is the ``generate`` command's
writer, and ``bmg160_emu.io.rates.RateStreamWriter`` names it too.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bmg160_emu.io.errors import FormatError
from bmg160_emu.io.partial import npy_trailer


class RateStreamWriter:
    """Write a rate record block by block (a day of samples never in memory at once).

    ``.npy``: an (n, 3) float64 array, n given up front; ``.csv``: ``# comment`` lines, the
    header ``t_s,x_dps,y_dps,z_dps``, then sample k at t = (k + 1) / rate_hz, time with
    ``%.12g`` (exact to 1 us over days) and rates with ``%.10g`` (1e-10 of a deg/s).
    """

    def __init__(self, handle, suffix: str, total: int, rate_hz: float,
                 comments: Sequence[str] = ()) -> None:
        self.handle, self.suffix, self.period_s = handle, suffix.lower(), 1.0 / rate_hz
        self.total = total
        self.samples = 0  # complete samples written
        self._comments = list(comments)
        if self.suffix == ".npy":
            header = {"descr": "<f8", "fortran_order": False, "shape": (total, 3)}
            np.lib.format.write_array_header_1_0(handle, header)
        elif self.suffix == ".csv":
            text = "".join(f"# {c}\n" for c in comments) + "t_s,x_dps,y_dps,z_dps\n"
            handle.write(text.encode())
        else:
            raise FormatError(f"a rate stream must end in .npy or .csv, not {suffix!r}")
        self._data_start = self._end = handle.tell()

    def write(self, start: int, block: np.ndarray) -> None:
        """Samples ``start .. start + len(block) - 1`` as a (m, 3) deg/s block."""
        if self.suffix == ".npy":
            self.handle.write(block.astype("<f8", copy=False).tobytes())
        else:
            t = (np.arange(start, start + block.shape[0]) + 1) * self.period_s
            np.savetxt(self.handle, np.column_stack([t, block]), fmt=["%.12g"] + ["%.10g"] * 3,
                       delimiter=",")
        self.samples = start + block.shape[0]
        self._end = self.handle.tell()

    @staticmethod
    def size_bytes(suffix: str, total: int) -> int:
        """What ``total`` samples take: exact for .npy and .resd (RESD v1: a 45-byte header
        and block header, 12 bytes a sample), a low estimate for .csv (about 40 characters a
        line), so a free-space check never refuses what would fit."""
        suffix = suffix.lower()
        if suffix == ".npy":
            return 128 + 24 * total
        if suffix == ".resd":
            return 45 + 12 * total
        return 100 + 40 * total

    def end_short(self, note: str) -> None:
        """Make the file an honest shorter record after an interruption: cut it after the
        last complete sample, say ``samples`` (the .npy shape; the CSV header's
        ``samples=``) and add ``note``: in a CSV as a last comment line, in a .npy as a
        trailer after the array (io.partial reads both)."""
        handle = self.handle
        handle.flush()
        handle.truncate(self._end)
        if self.suffix == ".npy":
            old_length = self._data_start
            text = repr({"descr": "<f8", "fortran_order": False, "shape": (self.samples, 3)})
            head = b"\x93NUMPY\x01\x00"
            body = text.encode("latin1")
            pad = old_length - len(head) - 2 - len(body) - 1
            handle.seek(0)
            handle.write(head + (old_length - len(head) - 2).to_bytes(2, "little")
                         + body + b" " * pad + b"\n")
            handle.seek(0, 2)
            handle.write(npy_trailer(note))  # after the array: np.load reads past it
        else:
            handle.seek(0)
            first = handle.readline()
            marker = f"samples={self.total}".encode()
            if marker in first:
                fixed = first.replace(marker, f"samples={self.samples}".encode().ljust(
                    len(marker)))
                handle.seek(0)
                handle.write(fixed)
            handle.seek(0, 2)
            handle.write(f"# {note}\n".encode())
        handle.flush()


