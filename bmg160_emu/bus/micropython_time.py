"""MicroPython's ``time`` functions (extmod/modtime.c) on this process's clocks.

They are written over ``time.sleep`` and ``time.monotonic``, looked up at each call, so the
virtual clock of ``bmg160_virtual_time`` or of ``bmg160-emu micropython`` moves them too.
The ticks wrap at 2**30 (MICROPY_PY_TIME_TICKS_PERIOD); ``ticks_cpu`` counts CPU cycles at
the emulated board's ``machine.freq()`` (the ESP32 port's cycle counter). As in the port,
``sleep_ms`` of a negative number and ``sleep_us`` of zero or less return at once, and each
takes an integer only (``TypeError: can't convert float to int``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from bmg160_emu.bus.micropython_rules import get_int

TICKS_PERIOD = 1 << 30  # MICROPY_PY_TIME_TICKS_PERIOD
TICKS_MAX = TICKS_PERIOD - 1


def sleep_ms(ms: Any) -> None:
    value = get_int(ms)
    if value >= 0:
        time.sleep(value / 1000)


def sleep_us(us: Any) -> None:
    value = get_int(us)
    if value > 0:
        time.sleep(value / 1e6)


def ticks_ms() -> int:
    return int(time.monotonic() * 1000) & TICKS_MAX


def ticks_us() -> int:
    return int(time.monotonic() * 1_000_000) & TICKS_MAX


def ticks_diff(ticks1: int, ticks2: int) -> int:
    half = TICKS_PERIOD // 2
    return ((ticks1 - ticks2 + half) & TICKS_MAX) - half


def ticks_add(ticks: int, delta: Any) -> int:
    step = get_int(delta)
    if not -TICKS_PERIOD // 2 < step < TICKS_PERIOD // 2:  # ticks_diff could not undo it
        raise OverflowError("ticks interval overflow")
    return (ticks + step) & TICKS_MAX


def time_functions(cpu_hz: Callable[[], int]) -> dict[str, Callable[..., Any]]:
    """The names ``time`` gains, ``ticks_cpu`` counting cycles at ``cpu_hz()``."""

    def ticks_cpu() -> int:
        return int(time.monotonic() * cpu_hz()) & TICKS_MAX

    return {"sleep_ms": sleep_ms, "sleep_us": sleep_us, "ticks_ms": ticks_ms,
            "ticks_us": ticks_us, "ticks_cpu": ticks_cpu, "ticks_diff": ticks_diff,
            "ticks_add": ticks_add}
