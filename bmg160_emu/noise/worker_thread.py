"""One worker thread beside the caller, for generate's output filters: the filter of one piece
of noise runs there while the caller draws the next piece (issue 37's 1.5x target).

Why a thread is enough: numpy's ``correlate`` and scipy's ``lfilter`` release the GIL while
they run, and so does drawing normals, so the two threads run on two cores. Why one: the
generator's pieces come in order and each filter carries its state from the previous piece,
so the worker takes them one after another; a request shorter than two pieces does not
use it. The thread count is 1 or 2, and 2 only when the process may run on two CPUs or more.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # (concurrent.futures is imported at the first large request: not on a
    from concurrent.futures import Future, ThreadPoolExecutor  # chip's import path)


def usable_cpus() -> int:
    """CPUs this process may run on (its affinity mask), at most ``os.cpu_count()``."""
    count = os.cpu_count() or 1
    affinity = getattr(os, "sched_getaffinity", None)
    return min(len(affinity(0)), count) if affinity is not None else count


def filter_threads(threads: int | None) -> int:
    """``threads`` checked (1 or 2), or None: 2 when ``usable_cpus()`` is 2 or more, else 1."""
    if threads is None:
        return 2 if usable_cpus() >= 2 else 1
    if threads not in (1, 2):
        raise ValueError(f"filter threads must be 1 or 2, got {threads!r}")
    return int(threads)


class WorkerThread:
    """The worker (made at the first ``submit``), or the caller itself with ``threads`` 1."""

    def __init__(self, threads: int | None = None) -> None:
        self.threads = filter_threads(threads)
        self._pool: ThreadPoolExecutor | None = None
        self._pid = 0  # the process the worker was started in: a forked child starts its own

    @property
    def started(self) -> bool:
        """Whether the worker thread exists in this process (a large request was made with
        2 threads)."""
        return self._pool is not None and self._pid == os.getpid()

    def splits(self, total: int, piece: int) -> bool:
        """Whether ``total`` rows in pieces of ``piece`` go to the worker: 2 threads, and 2
        pieces or more."""
        return self.threads > 1 and total >= 2 * piece

    def run_pieces(self, total: int, piece: int, draw: Callable[[int, int], Any],
                   work: Callable[[int, Any], None]) -> None:
        """For the pieces of ``total`` rows, ``piece`` rows each (the last one shorter), in
        order: ``work(start, draw(start, rows))``; each piece's work on the worker while the
        caller draws the next, when there are 2 threads and ``total`` is 2 pieces or more.
        Returns when every piece's work is done (an error in ``draw``: after the pieces sent
        finish)."""
        starts = range(0, total, piece)
        if not self.splits(total, piece):
            for start in starts:
                work(start, draw(start, min(piece, total - start)))
            return
        if not self.started:  # (after a fork the parent's worker is not in the child: the
            from concurrent.futures import ThreadPoolExecutor  # pool would wait on it forever)

            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="output-filter")
            self._pid = os.getpid()
        pool = self._pool
        assert pool is not None
        pending: list[Future[None]] = []
        try:
            for start in starts:
                pending.append(pool.submit(work, start, draw(start, min(piece, total - start))))
        finally:
            for job in pending:
                job.result()
