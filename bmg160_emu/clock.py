"""Time for emulated chips: a virtual clock that tests advance, a real-time clock, and a
context manager that turns ``time.sleep`` into virtual time.

Time is kept in integer nanoseconds so that sample counting never drifts: every output
period of the chip (0.5, 1, 2.5, 5 and 10 ms) is a whole number of nanoseconds.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Iterator
from typing import Any, Protocol

NS_PER_S = 1_000_000_000
NEVER = 1 << 62  # a time in ns no clock reaches: "no sample due"


def seconds_to_ns(seconds: float) -> int:
    """Seconds to whole nanoseconds (rounded), refusing negative or non-finite values."""
    if isinstance(seconds, (str, bytes)):  # float("1") would take it: a caller's mistake
        raise TypeError(f"time must be a number of seconds, not {seconds!r}")
    try:
        value = float(seconds)
    except (TypeError, ValueError):
        raise TypeError(f"time must be a number of seconds, not {seconds!r}") from None
    if not value >= 0.0 or value == float("inf"):
        raise ValueError(f"time must be a finite number of seconds >= 0, not {seconds!r}")
    return round(value * NS_PER_S)


class Clock(Protocol):
    def now_ns(self) -> int: ...

    def now(self) -> float: ...

    def advance_ns(self, ns: int) -> int: ...

    def sleep(self, seconds: float) -> None: ...


class VirtualClock:
    """Time that moves only when told to; shared by chips that must stay in step.

    ``ns``, the time now in integer nanoseconds, is a public attribute: ``now_ns()`` returns
    it, and a chip on this clock that holds ``lock`` reads it, and moves it forward, directly
    (``advance_ns`` inlined on a polling driver's hot path, tools/bench_fake_smbus.py; one
    method call costs more than the attribute). Anyone else moves it with ``advance_ns``,
    ``advance`` or ``sleep``: time only goes forward."""

    realtime = False

    def __init__(self, start_s: float = 0.0) -> None:
        self.ns = seconds_to_ns(start_s)
        # Chips on this clock take this lock as theirs: one acquisition then covers a chip's
        # state and the time it advances (a polling driver's hot path, bench_fake_smbus).
        self.lock = threading.RLock()

    def now_ns(self) -> int:
        return self.ns

    def now(self) -> float:
        return self.ns / NS_PER_S

    def advance_ns(self, ns: int) -> int:
        """Move time forward by ``ns`` nanoseconds; return the new time in ns."""
        if ns < 0:
            raise ValueError("virtual time cannot go backwards")
        with self.lock:
            self.ns += ns
            return self.ns

    def advance(self, seconds: float) -> None:
        """Move time forward by ``seconds`` (>= 0)."""
        self.advance_ns(seconds_to_ns(seconds))

    sleep = advance

    def __repr__(self) -> str:
        return f"VirtualClock(t={self.now():.9f} s)"


class RealTimeClock:
    """Wall time since construction (``time.monotonic_ns``): chips catch up at each access."""

    realtime = True

    def __init__(self) -> None:
        self._origin_ns = time.monotonic_ns()

    def now_ns(self) -> int:
        return time.monotonic_ns() - self._origin_ns

    def now(self) -> float:
        return self.now_ns() / NS_PER_S

    def advance_ns(self, ns: int) -> int:
        """Real time cannot be pushed: wait instead; return the time in ns after waiting."""
        if ns < 0:
            raise ValueError("time cannot go backwards")
        time.sleep(ns / NS_PER_S)
        return self.now_ns()

    def advance(self, seconds: float) -> None:
        self.advance_ns(seconds_to_ns(seconds))

    sleep = advance

    def __repr__(self) -> str:
        return f"RealTimeClock(t={self.now():.6f} s)"


@contextlib.contextmanager
def virtual_sleep(chip_or_clock: Any, *, patch_clocks: bool = False) -> Iterator[VirtualClock]:
    """Make ``time.sleep(s)`` advance a virtual clock instead of sleeping.

    With ``patch_clocks=True``, ``time.monotonic``, ``time.time``, ``time.perf_counter``
    (and their ``_ns`` forms) also follow the virtual clock, offset so that they continue
    from their real values. Code that did ``from time import sleep`` before entering keeps
    the real function. The patch is process-wide, as any patch of ``time`` is.
    """
    clock = getattr(chip_or_clock, "clock", chip_or_clock)
    if not isinstance(clock, VirtualClock):
        raise TypeError("virtual_sleep needs a chip on a VirtualClock, or a VirtualClock")

    def fake_sleep(seconds: float) -> None:
        if seconds < 0:
            raise ValueError("sleep length must be non-negative")
        clock.advance(seconds)

    from unittest import mock  # here, not at the top: it costs every chip user ~20 ms of start-up

    with contextlib.ExitStack() as stack:
        stack.enter_context(mock.patch("time.sleep", fake_sleep))
        if patch_clocks:
            start_ns = clock.now_ns()
            for name in ("monotonic", "time", "perf_counter"):
                real_ns = getattr(time, f"{name}_ns")()

                def ns_func(base: int = real_ns) -> int:
                    return base + clock.now_ns() - start_ns

                def s_func(f: Any = ns_func) -> float:
                    return f() / NS_PER_S

                stack.enter_context(mock.patch(f"time.{name}_ns", ns_func))
                stack.enter_context(mock.patch(f"time.{name}", s_func))
        yield clock
