"""Rate records streamed block by block (``generate``'s outputs): a day of samples is never
in memory at once, and an interrupted record is made honest (``end_short``).

One :class:`~bmg160_emu.io.formats.BlockWriter` per format, registered as the kind
``rate stream``: .npy (an (n, 3) float64 array, n given up front) and .csv (``#`` comment
lines, the header ``t_s,x_dps,y_dps,z_dps``, then sample k at t = (k + 1) / rate_hz, time
with ``%.12g``, exact to 1 us over days, and rates with ``%.10g``, 1e-10 of a deg/s); .resd
(Renode, channel 0) is io/resd.py's ``ResdRateStream``. ``load_rate_record`` reads them all.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import IO

import numpy as np

from bmg160_emu.io.formats import BlockWriter, FileFormat, register_format
from bmg160_emu.io.partial import npy_trailer

CSV_HEADER = "t_s,x_dps,y_dps,z_dps"


class NpyRateStream(BlockWriter):
    """An (total, 3) float64 .npy array, its header written first."""

    def __init__(self, handle: IO[bytes], total: int, rate_hz: float,
                 comments: Sequence[str] = ()) -> None:
        super().__init__(handle, total, rate_hz, comments)
        header = {"descr": "<f8", "fortran_order": False, "shape": (total, 3)}
        np.lib.format.write_array_header_1_0(handle, header)
        self._data_start = self._end = handle.tell()

    def write(self, start: int, block: np.ndarray) -> None:
        self.handle.write(block.astype("<f8", copy=False).tobytes())
        self.samples = start + block.shape[0]
        self._end = self.handle.tell()

    @staticmethod
    def size_bytes(total: int) -> int:
        return 128 + 24 * total  # exact: the header pads to 128 bytes

    def end_short(self, note: str) -> None:
        """Cut after the last complete sample, the header's shape rewritten for it, and
        ``note`` as a trailer after the array (np.load reads past it; io.partial reads it)."""
        handle = self.handle
        handle.flush()
        handle.truncate(self._end)
        old_length = self._data_start
        text = repr({"descr": "<f8", "fortran_order": False, "shape": (self.samples, 3)})
        head = b"\x93NUMPY\x01\x00"
        body = text.encode("latin1")
        pad = old_length - len(head) - 2 - len(body) - 1
        handle.seek(0)
        handle.write(head + (old_length - len(head) - 2).to_bytes(2, "little")
                     + body + b" " * pad + b"\n")
        handle.seek(0, 2)
        handle.write(npy_trailer(note))
        handle.flush()


class CsvRateStream(BlockWriter):
    """A CSV rate record: ``# comment`` lines, the header, one line per sample."""

    def __init__(self, handle: IO[bytes], total: int, rate_hz: float,
                 comments: Sequence[str] = ()) -> None:
        super().__init__(handle, total, rate_hz, comments)
        self.period_s = 1.0 / rate_hz
        handle.write(("".join(f"# {c}\n" for c in comments) + CSV_HEADER + "\n").encode())
        self._end = handle.tell()

    def write(self, start: int, block: np.ndarray) -> None:
        t = (np.arange(start, start + block.shape[0]) + 1) * self.period_s
        np.savetxt(self.handle, np.column_stack([t, block]), fmt=["%.12g"] + ["%.10g"] * 3,
                   delimiter=",")
        self.samples = start + block.shape[0]
        self._end = self.handle.tell()

    @staticmethod
    def size_bytes(total: int) -> int:
        return 100 + 40 * total  # a low estimate: about 40 characters a line

    def end_short(self, note: str) -> None:
        """Cut after the last complete line; the first line's ``samples=`` (a ``generate``
        header) says how many there are, and ``note`` is the last comment line."""
        handle = self.handle
        handle.flush()
        handle.truncate(self._end)
        handle.seek(0)
        first = handle.readline()
        marker = f"samples={self.total}".encode()
        if marker in first:
            fixed = first.replace(marker, f"samples={self.samples}".encode().ljust(len(marker)))
            handle.seek(0)
            handle.write(fixed)
        handle.seek(0, 2)
        handle.write(f"# {note}\n".encode())
        handle.flush()


def _register() -> None:
    from bmg160_emu.io.resd import ResdRateStream

    for suffix, writer, description in (
            (".npy", NpyRateStream, "(n, 3) float64 array"),
            (".csv", CsvRateStream, "# lines, t_s,x_dps,y_dps,z_dps"),
            (".resd", ResdRateStream, "Renode, angular rate channel 0")):
        register_format(FileFormat("rate stream", suffix, None, writer, description))


_register()
