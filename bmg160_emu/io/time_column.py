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

# A unit on a time column's name: seconds per unit. Logs stamp in other units: ROS and the
# EuRoC/TUM-VI datasets in ns ("timestamp [ns]"), PX4's ulog CSV export in us
# ("timestamp", left to mean seconds here: a bare name is seconds, as t and time are);
# rostopic echo -p's "%time" in ns.
TIME_UNITS_S = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_TIME_BASES = ("t", "time", "timestamp")


def time_column_scale_s(name: str) -> float | None:
    """Seconds per unit of a column or array named ``name`` if it is a time column, else
    None: t, time or timestamp, bare (seconds) or with a unit as a suffix (``time_ms``,
    ``timestamp_ns``) or in brackets (``timestamp [ns]``)."""
    text = name.strip().lower().lstrip("#").strip()
    if text == "%time":  # rostopic echo -p: the receive time in ns from the epoch
        return 1e-9
    if text.endswith("]") and "[" in text:
        base, _, unit = text[:-1].partition("[")
        text = f"{base.strip()}_{unit.strip()}"
    if text in _TIME_BASES:
        return 1.0
    base, _, unit = text.rpartition("_")
    return TIME_UNITS_S.get(unit) if base in _TIME_BASES else None


def time_column_index(names: list[str]) -> tuple[int, float] | None:
    """The first time column of a header and its seconds per unit, or None."""
    for index, name in enumerate(names):
        scale = time_column_scale_s(name)
        if scale is not None:
            return index, scale
    return None


def time_column_help() -> str:
    """The accepted time column names, for an error that says which work."""
    return ("t, time or timestamp in seconds, or with a unit: _s, _ms, _us, _ns "
            "(time_ms, timestamp_ns, 'timestamp [ns]')")


CHUNK_ROWS = 1 << 20  # rows of a time column checked at a time
MEDIAN_STEPS = 1 << 21  # steps the median step is taken from (evenly spread over the record)


def in_seconds(t: np.ndarray, scale_s: float | None) -> np.ndarray:
    """A time column in seconds: as it is, or times its unit (``time_ms``, ``timestamp_ns``),
    counted from its first stamp so that a ns epoch stamp keeps its sample spacing in a
    float64 (1.6e18 ns carries steps of 256 ns; from the start, a day in ns, 0.02 ns)."""
    if scale_s is None or scale_s == 1.0 or len(t) == 0:
        return t
    if t.dtype.kind in "iu":  # int64 ns stamps: subtract exactly, then scale
        return (t - t[0]).astype(np.float64) * scale_s
    return (t - t[0]) * scale_s


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
