"""The true body rate a chip measures, in deg/s: a constant, a function of time, or samples.

A source answers "the true rate at output samples k0 .. k0 + n - 1" for the data path
(``datapath.py``); the sample times come from the chip's schedule, asked for only by the
sources that need them.
"""

from __future__ import annotations

import bisect
from collections.abc import Callable
from typing import Any

import numpy as np

from bmg160_emu.clock import NS_PER_S

Times = Callable[[int, int], np.ndarray]  # (k0, n) -> sample times in ns
# Largest true rate taken, deg/s: 5e5 times the widest full scale (2000 deg/s, spec 4.8), far
# beyond anything a sensing element survives, and small enough that every product of the
# data path (filter, sensitivity up to 262.4 LSB/(deg/s)) stays finite: no overflow, only
# saturated counts (issue 24: 1e308 deg/s raised numpy overflow warnings).
MAX_RATE_DPS = 1e9
_RANGE_TEXT = f"finite and within +-{MAX_RATE_DPS:g} deg/s"


def _in_range(values: np.ndarray) -> bool:
    """Every value finite and within MAX_RATE_DPS (NaN fails the comparison)."""
    return bool(np.all(np.abs(values) <= MAX_RATE_DPS))


class ConstantRate:
    """One rate for every sample; the filter may re-reference at it (``LowPass``)."""

    constant = True
    failed = False
    ahead = True  # samples may be computed before they are due

    def __init__(self, rate_dps: np.ndarray) -> None:
        self.rate_dps = rate_dps

    def block(self, k0: int, n: int, times_ns: Times) -> np.ndarray:
        if n == 1:  # a closed loop's one-sample piece: a view, cheaper than broadcasting
            return self.rate_dps[None, :]
        return np.broadcast_to(self.rate_dps, (n, 3))


class FunctionRate:
    """``func(t_s) -> 3 numbers``, called once per output sample in order."""

    constant = False
    ahead = True

    def __init__(self, func: Callable[[float], Any]) -> None:
        self.func = func
        # True while the function has not served a whole block: set_true_rate may then
        # replace it although catching up with it raised
        self.failed = False

    def block(self, k0: int, n: int, times_ns: Times) -> np.ndarray:
        out = np.empty((n, 3))
        self.failed = True
        for i, t in enumerate(times_ns(k0, n) / NS_PER_S):
            value = self.func(float(t))
            try:
                row = np.asarray(value, dtype=float)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"the true-rate function must return 3 numbers in deg/s: "
                                 f"at t = {float(t):g} s {exc}") from None
            if row.size != 3:
                raise ValueError(f"the true-rate function must return 3 numbers in deg/s, "
                                 f"got {row.size} at t = {float(t):g} s")
            out[i] = row.reshape(3)
        if not _in_range(out):
            raise ValueError("the true-rate function returned a non-finite value or one beyond "
                             f"+-{MAX_RATE_DPS:g} deg/s")
        self.failed = False
        return out


class SampledRate:
    """(n, 3) rows: one per output sample from sample ``first_k`` on, or at ``rate_hz``
    from ``first_ns`` on (held between rows); the last row then holds."""

    constant = False
    failed = False
    ahead = True

    def __init__(self, samples: np.ndarray, first_k: int, first_ns: int,
                 rate_hz: float | None) -> None:
        self.samples, self.first_k, self.first_ns, self.rate_hz = samples, first_k, first_ns, rate_hz

    def block(self, k0: int, n: int, times_ns: Times) -> np.ndarray:
        if self.rate_hz is None:
            rows = np.arange(k0, k0 + n) - self.first_k
        else:
            rows = np.floor((times_ns(k0, n) - self.first_ns) / NS_PER_S
                            * self.rate_hz).astype(np.int64)
        return self.samples[np.clip(rows, 0, len(self.samples) - 1)]


class QueuedRates:
    """Rates handed in one at a time (``BMG160.queue_true_rate``), each from a given sample
    on and held until the next one's; ``ahead = False``: a sample is computed only once it
    is due, when its rate is known."""

    constant = False
    failed = False
    ahead = False

    def __init__(self, first_k: int, rate_dps: Any) -> None:  # rows: streamed_row's
        self.starts, self.rows = [first_k], [rate_dps]

    def add(self, first_k: int, rate_dps: Any) -> None:
        if first_k <= self.starts[-1]:  # a second rate before the first's sample: it wins
            self.rows[-1] = rate_dps
        else:
            self.starts.append(first_k)
            self.rows.append(rate_dps)

    def block(self, k0: int, n: int, times_ns: Times) -> np.ndarray:
        starts = self.starts
        used = bisect.bisect_right(starts, k0) - 1  # the rate of sample k0; earlier ones go
        if used > 0:
            del starts[:used], self.rows[:used]
        if len(starts) == 1 or k0 + n <= starts[1]:
            return np.broadcast_to(self.rows[0], (n, 3))
        if n <= _SHORT:  # a loop's few due samples: the rows picked in Python (the same rows)
            picked = []
            j, last = 0, len(starts) - 1
            for k in range(k0, k0 + n):
                while j < last and starts[j + 1] <= k:
                    j += 1
                picked.append(self.rows[j])
            return np.array(picked, dtype=float)
        index = np.searchsorted(starts, np.arange(k0, k0 + n), side="right") - 1
        return np.array(self.rows)[index]


_SHORT = 64  # QueuedRates.block: up to this many samples, rows picked without numpy


TrueRate = ConstantRate | FunctionRate | SampledRate | QueuedRates


def streamed_rate(rate_dps: Any) -> ConstantRate:
    """The source for ``BMG160.stream_true_rate``: 3 finite numbers in deg/s, checked with
    less work than ``true_rate_source`` (it is called every step of a loop)."""
    row = streamed_row(rate_dps)
    return ConstantRate(row if row.__class__ is np.ndarray else np.array(row))


def streamed_row(rate_dps: Any) -> tuple[float, float, float] | np.ndarray:
    """``rate_dps`` checked as ``streamed_rate`` checks it, as a row of its own: a tuple of
    the floats of a list or tuple of 3 floats (a loop's rate, no numpy call: 2 us a step
    less), else a float array (``BMG160.queue_true_rate`` keeps it as it is)."""
    if rate_dps.__class__ in _PLAIN and len(rate_dps) == 3:
        x, y, z = rate_dps
        if x.__class__ is float and y.__class__ is float and z.__class__ is float:
            if not (abs(x) <= MAX_RATE_DPS and abs(y) <= MAX_RATE_DPS and abs(z) <= MAX_RATE_DPS):
                raise ValueError(f"true rate must be {_RANGE_TEXT}")
            return x, y, z
    if rate_dps.__class__ is np.ndarray and rate_dps.shape == (3,) and rate_dps.dtype == _F8:
        arr = rate_dps.copy()  # (np.array's result for a float array's row)
    else:
        try:
            arr = np.array(rate_dps, dtype=float)
        except (TypeError, ValueError):
            arr = np.empty(0)
    if arr.shape != (3,):
        raise ValueError(f"a streamed true rate must be 3 numbers in deg/s, not {rate_dps!r}")
    x, y, z = arr.tolist()
    if not (abs(x) <= MAX_RATE_DPS and abs(y) <= MAX_RATE_DPS and abs(z) <= MAX_RATE_DPS):
        raise ValueError(f"true rate must be {_RANGE_TEXT}")
    return arr


_PLAIN = (list, tuple)  # streamed_row's fast path: exactly these, holding exactly floats
_F8 = np.dtype(np.float64)


def true_rate_source(rate: Any, sample_rate_hz: float | None, *, first_k: int,
                     first_ns: int) -> TrueRate:
    """The source for ``BMG160.set_true_rate``'s argument; samples start at ``first_k``."""
    if callable(rate):
        return FunctionRate(rate)
    try:
        arr = np.asarray(rate, dtype=float)
    except (TypeError, ValueError):
        raise ValueError("true rate must be 3 numbers in deg/s, a callable of t or (n, 3) "
                         f"samples, not {rate!r}") from None
    if arr.shape == (3,):
        if not _in_range(arr):
            raise ValueError(f"true rate must be {_RANGE_TEXT}")
        return ConstantRate(arr.copy())
    if arr.ndim == 2 and arr.shape[1] == 3 and arr.shape[0] >= 1:
        if not _in_range(arr):
            raise ValueError(f"true rate samples must be {_RANGE_TEXT}")
        if sample_rate_hz is not None and not sample_rate_hz > 0:
            raise ValueError("sample_rate_hz must be positive")
        return SampledRate(arr.copy(), first_k, first_ns, sample_rate_hz)
    raise ValueError("true rate must be 3 numbers, a callable of t or (n, 3) samples")
