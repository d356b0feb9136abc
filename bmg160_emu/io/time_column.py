"""The time column of a rate file: finite, strictly increasing and without gaps, and its
median step; the names a time column goes by.

Allan deviation, the PSD and resampling all need evenly spaced samples, so every reader of
a rate file with time stamps (identify, replay) checks its column here, in chunks: no (n,)
temporaries beside the column.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from bmg160_emu.io.rate_table import RateFileError

TIME_COLUMN_NAMES = ("t", "t_s", "time", "time_s", "timestamp")
CHUNK_ROWS = 1 << 20  # rows of a time column checked at a time
MEDIAN_STEPS = 1 << 21  # steps the median step is taken from (evenly spread over the record)


def check_time_column(t: np.ndarray, where: Callable[[int], str], gap_factor: float,
                      gap_hint: str = "split the record at the gap") -> float:
    """Refuse a time column that is not finite, not increasing or has a gap; its median step.

    A step over ``gap_factor`` median steps is a gap (missing samples), not jitter: Allan
    deviation, PSD and resampling all need evenly spaced samples.
    """
    n = len(t)
    for start in range(0, n, CHUNK_ROWS):  # in chunks: no (n,) temporaries beside t
        part = t[start:start + CHUNK_ROWS + 1]
        bad = np.flatnonzero(~np.isfinite(part))
        if bad.size:
            raise RateFileError(f"{where(start + int(bad[0]))}: the time column has NaN or "
                                "infinite values")
        back = np.flatnonzero(~(np.diff(part) > 0))
        if back.size:
            i = start + int(back[0]) + 1
            raise RateFileError(
                f"{where(i)}: time {float(t[i])!r} s is not after {float(t[i - 1])!r} s "
                f"(the time column is not strictly increasing at sample {i})"
            )
    if n < 2:
        return math.inf
    typical = median_step(t)
    for start in range(0, n - 1, CHUNK_ROWS):
        steps = np.diff(t[start:start + CHUNK_ROWS + 1])
        wide = np.flatnonzero(steps > gap_factor * typical)
        if wide.size:
            i = start + int(wide[0])
            step = float(steps[wide[0]])
            raise RateFileError(
                f"{where(i + 1)}: gap of {step:.6g} s after sample {i} ({step / typical:.1f} "
                f"sample periods of {typical:.6g} s): evenly spaced samples are needed; {gap_hint}"
            )
    return typical


def median_step(t: np.ndarray) -> float:
    """The median time step; of evenly spread steps when there are over MEDIAN_STEPS.

    Exact up to MEDIAN_STEPS + 1 samples (2.9 h at 200 Hz); beyond, the median of every
    k-th step, which is within a small fraction of the jitter of the exact one (a sample
    median of 2**21 values has a standard error of 1.25 sd / 1450) and needs no (n,) copy.
    """
    n_steps = len(t) - 1
    if n_steps <= MEDIAN_STEPS:
        return float(np.median(np.diff(t)))
    k = -(-n_steps // MEDIAN_STEPS)
    return float(np.median(t[k::k][: n_steps // k] - t[0:-1:k][: n_steps // k]))
