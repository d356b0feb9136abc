"""Each axis's measured output response (noise.output_response: a minimum-phase FIR) applied
to a stream, with the FIR's memory carried from one request to the next, and on a second
core beside the generator when the process has one.

Why direct convolution: output k is one dot product of the taps with inputs k - K .. k
whatever the record's cut (numpy's ``correlate``, one BLAS dot per sample: 5-25 ns a sample
for 2-65 taps; lfilter took 8-55 ns, an FFT overlap-add 21-112 ns at these lengths, and a
matrix product sums in another order, so other bits).

Why a second thread: the FIR of 65 taps costs a third of drawing the normals the generator
consumes (issue 37's 1.5x target), and a faster kernel with the same bits does not exist
(the bits are BLAS's dot's). numpy releases the GIL inside ``correlate``, so the FIR of one
piece runs on a worker thread while the calling thread draws the next piece: one worker,
only when ``os.sched_getaffinity`` gives the process two CPUs or more, and only for a request
of two pieces or more. Every output is the same dot product on either thread: the bits do not
depend on the thread count (tested).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # (concurrent.futures is imported at the first large request: not on a
    from concurrent.futures import Future, ThreadPoolExecutor  # chip's import path)

PIECE = 1 << 15  # samples drawn, then filtered, as one step (3 columns: 768 kB)
BLOCK = 1 << 14  # samples per correlate call (a column's block and its result in cache)


def usable_cpus() -> int:
    """CPUs this process may run on (its affinity mask), at most ``os.cpu_count()``."""
    count = os.cpu_count() or 1
    affinity = getattr(os, "sched_getaffinity", None)
    return min(len(affinity(0)), count) if affinity is not None else count


class ResponseFIR:
    """The axes' FIRs (``taps[i]`` None or one tap: that axis passes as it is), each with its
    memory, the last len(taps) - 1 inputs; ``start`` fills the memories with the stream's
    first samples (the FIRs start settled). ``threads``: 1 or 2 (None: 2 when
    ``usable_cpus()`` is 2 or more)."""

    def __init__(self, taps: list[np.ndarray | None], threads: int | None = None) -> None:
        if threads is None:
            threads = 2 if usable_cpus() >= 2 else 1
        if threads not in (1, 2):
            raise ValueError(f"FIR threads must be 1 or 2, got {threads!r}")
        self.threads = threads
        # correlate with the taps reversed is numpy's convolve, with no reversed copy a call
        self.reversed = [None if h is None or h.size < 2 else np.ascontiguousarray(h[::-1])
                         for h in taps]
        self.memory: list[np.ndarray | None] = [None for _ in taps]
        self._pool: ThreadPoolExecutor | None = None

    @property
    def settle_samples(self) -> int:
        """Samples the memories take before the first output: the longest FIR's, less one."""
        return max((r.size - 1 for r in self.reversed if r is not None), default=0)

    def start(self, first: np.ndarray) -> None:
        """The memories filled from ``first`` (settle_samples rows, one column per axis)."""
        for i, r in enumerate(self.reversed):
            if r is not None:
                self.memory[i] = np.array(first[first.shape[0] - (r.size - 1):, i])

    def run(self, n: int, take: Callable[[int], np.ndarray]) -> np.ndarray:
        """The next n outputs (n, 3): ``take(m)`` hands the next m input rows, piece by
        piece; each piece's FIR runs on the worker while ``take`` draws the next one."""
        out = np.empty((n, len(self.reversed)))
        pool = self._worker() if n >= 2 * PIECE else None
        pending: list[Future[None]] = []
        try:
            for at in range(0, n, PIECE):
                m = min(PIECE, n - at)
                joined = self._join(take(m))
                if pool is None:
                    self._convolve(joined, out[at:at + m])
                else:
                    pending.append(pool.submit(self._convolve, joined, out[at:at + m]))
        finally:
            for job in pending:  # (an error in take: the pieces already sent finish first)
                job.result()
        return out

    def _join(self, source: np.ndarray) -> list[np.ndarray]:
        """Per axis: its memory then this piece's column (the FIR's input, contiguous), or
        the column alone for an axis without a FIR; the memories move on to the piece's end."""
        joined = []
        for i, r in enumerate(self.reversed):
            memory = self.memory[i]
            if r is None or memory is None:
                joined.append(source[:, i])
                continue
            column = np.empty(memory.size + source.shape[0])
            column[:memory.size] = memory
            column[memory.size:] = source[:, i]
            self.memory[i] = column[source.shape[0]:]
            joined.append(column)
        return joined

    def _convolve(self, joined: list[np.ndarray], out: np.ndarray) -> None:
        """out[:, i]: axis i's FIR over its joined input, in blocks that stay in cache."""
        n = out.shape[0]
        for i, (column, r) in enumerate(zip(joined, self.reversed)):
            if r is None:
                out[:, i] = column
                continue
            for at in range(0, n, BLOCK):
                stop = min(at + BLOCK, n)
                out[at:stop, i] = np.correlate(column[at:stop + r.size - 1], r, "valid")

    @property
    def worker_started(self) -> bool:
        """Whether the worker thread exists (a large request was made with 2 threads)."""
        return self._pool is not None

    def _worker(self) -> ThreadPoolExecutor | None:
        """The one worker thread (made at the first large request), or None with 1 thread."""
        if self.threads < 2:
            return None
        if self._pool is None:
            from concurrent.futures import ThreadPoolExecutor

            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="response-fir")
        return self._pool
