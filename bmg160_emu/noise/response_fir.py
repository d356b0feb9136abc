"""Each axis's measured output response (noise.output_response: a minimum-phase FIR) applied
to a stream, with the FIR's memory carried from one request to the next, and on a second
core beside the generator when the process has one.

Why direct convolution: output k is one dot product of the taps with inputs k - K .. k
whatever the record's cut (numpy's ``correlate``, one BLAS dot per sample: 5-25 ns a sample
for 2-65 taps; lfilter took 8-55 ns, an FFT overlap-add 21-112 ns at these lengths, and a
matrix product sums in another order, so other bits).

Why pieces: the FIR of 65 taps costs a third of drawing the normals the generator consumes
(issue 37's 1.5x target), and no faster kernel gives the same bits (they are BLAS's dot's);
so each piece's FIR runs on a worker thread while the caller draws the next piece
(noise.worker_thread: numpy releases the GIL in ``correlate``). Every output is the same dot
product on either thread: the bits do not depend on the thread count (tested).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from bmg160_emu.noise.worker_thread import WorkerThread

PIECE = 1 << 14  # samples drawn, then filtered, as one step (3 columns: 384 kB; 1.28-1.30x
# of the normals through 65 taps against 1.33x for 2^15 and 1.35-1.37x for 2^16, in one run)
BLOCK = 1 << 14  # samples per correlate call (a column's block and its result in cache)


class ResponseFIR:
    """The axes' FIRs (``taps[i]`` None or one tap: that axis passes as it is), each with its
    memory, the last len(taps) - 1 inputs; ``start`` fills the memories with the stream's
    first samples (the FIRs start settled). ``worker``: the WorkerThread to run on (else
    one of ``threads``, noise.worker_thread.filter_threads)."""

    def __init__(self, taps: list[np.ndarray | None], threads: int | None = None,
                 worker: WorkerThread | None = None) -> None:
        self.worker = worker if worker is not None else WorkerThread(threads)
        # correlate with the taps reversed is numpy's convolve, with no reversed copy a call
        self.reversed = [None if h is None or h.size < 2 else np.ascontiguousarray(h[::-1])
                         for h in taps]
        self.memory: list[np.ndarray | None] = [None for _ in taps]

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
        """The next n outputs (n, 3): ``take(m)`` hands the next m input rows (arrays it
        never writes again), piece by piece; each piece's FIR runs on the worker while
        ``take`` draws the next one."""
        out = np.empty((n, len(self.reversed)))

        def work(start: int, source: np.ndarray) -> None:  # (in order: memory, then piece)
            self._convolve(self._join(source), out[start:start + PIECE])

        self.worker.run_pieces(n, PIECE, lambda start, m: take(m), work)
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
