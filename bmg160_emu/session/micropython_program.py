"""A MicroPython program (``main.py``) run on a PC against emulated chips, as on the board.

Why: a MicroPython developer runs ``main.py`` on the board; on a PC the same file needs
``machine`` and MicroPython's ``time`` functions, and chips whose clock moves with the
program. :func:`run_program` gives it all three: the drop-in ``machine``
(bmg160_emu.bus.machine, the ESP32 port's answers) wired to the buses, ``time.sleep_ms``
and friends, and a clock that follows the program's own sleeps (virtual time: a
``sleep_ms(10)`` moves the chips 10 ms on, at once) or, with ``real_time``, the wall clock.
The program's folder and its ``lib`` folder are on the import path, as on a board.

A program that reads the rate registers again and again without sleeping sees the same
sample every time on a virtual clock (nothing moves the clock between reads; on the board
the bus takes time and the chip samples on): after ``stale_reads`` reads of one sample the
session warns, once per standstill, saying so.
"""

from __future__ import annotations

import contextlib
import runpy
import sys
import time
import traceback
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

RATE_FIRST, RATE_LAST = 0x02, 0x07  # RATE_X_LSB..RATE_Z_MSB (spec 4.2)
STALE_READS = 50  # reads of one sample, the clock standing, before the session warns


class ProgramTimeUp(BaseException):
    """The program's time (``duration_s``) is over: raised at its next sleep, and not an
    ``Exception``, so a program's own ``except Exception`` does not swallow it."""


@dataclass
class ProgramResult:
    """How the program ended: ``status`` (0, its SystemExit code, 1 after an uncaught
    exception), ``time_s`` on the chips' clock, ``stopped`` when ``duration_s`` ended it,
    and the warnings the session gave."""

    status: int
    time_s: float
    stopped: bool = False
    warnings: list[str] = field(default_factory=list)


class StaleReads:
    """A transaction-log sink that notices rate reads of one chip at one instant."""

    def __init__(self, program: str, gyros: set[int], warn: Callable[[str], None],
                 threshold: int = STALE_READS) -> None:
        self.program, self.gyros, self.warn, self.threshold = program, gyros, warn, threshold
        self.last: dict[int, tuple[float, int]] = {}  # address -> (time, reads at it)
        self.warned: set[tuple[int, float]] = set()

    def __call__(self, transaction: Any) -> None:
        register, address = transaction.register, transaction.address
        if (address not in self.gyros or register is None or not transaction.read
                or transaction.error or register > RATE_LAST
                or register + len(transaction.read) <= RATE_FIRST):
            return
        when = transaction.time
        seen, count = self.last.get(address, (None, 0))
        count = count + 1 if seen == when else 1
        self.last[address] = (when, count)
        if count >= self.threshold and (address, when) not in self.warned:
            self.warned.add((address, when))
            self.warn(f"{self.program} read the rate registers of 0x{address:02x} {count} times "
                      f"at t={when:.6f} s with the clock standing still: every read returns "
                      "the same sample. On the board each read takes bus time while the chip "
                      "samples on; sleep between reads (time.sleep_ms) to let the clock move, "
                      "or run with --realtime")


@contextlib.contextmanager
def _program_clock(clock: Any, real_time: bool, duration_s: float | None) -> Iterator[None]:
    """``time.sleep`` moves the virtual clock (and monotonic, ticks follow it), or sleeps
    for real; either way it ends the program once ``duration_s`` is over."""
    from unittest import mock

    from bmg160_emu.clock import virtual_sleep

    start = clock.now()
    with contextlib.ExitStack() as stack:
        if not real_time:
            stack.enter_context(virtual_sleep(clock, patch_clocks=True))
        moved = time.sleep

        def sleep(seconds: float) -> None:
            if duration_s is not None:
                left = start + duration_s - clock.now()
                if seconds >= left:
                    moved(max(left, 0.0))
                    raise ProgramTimeUp
            moved(seconds)

        stack.enter_context(mock.patch("time.sleep", sleep))
        yield


def run_program(path: str | Path, buses: Mapping[int, Any], clock: Any, *,
                argv: list[str] | None = None, real_time: bool = False,
                duration_s: float | None = None, heap_bytes: int | None = None,
                where: str | None = None, warn: Callable[[str], None] | None = None,
                stale_reads: int = STALE_READS) -> ProgramResult:
    """Run the MicroPython program at ``path`` with ``machine`` wired to ``buses``
    ({number: I2CBus}; the first is every SoftI2C's) on ``clock`` (the chips'): see the
    module. An uncaught exception is printed as a traceback (status 1)."""
    from bmg160_emu.bus.machine import micropython_machine
    from bmg160_emu.device.contract import RateSensor

    path = Path(path)
    messages: list[str] = []

    def note(text: str) -> None:
        messages.append(text)
        (warn or (lambda line: print(f"warning: {line}", file=sys.stderr)))(text)

    gyros = {address for bus in buses.values() for address, chip in bus.devices.items()
             if isinstance(chip, RateSensor)}  # a gyro: stand-ins sense no rate
    watcher = StaleReads(path.name, gyros, note, stale_reads)
    for bus in buses.values():
        bus.log.sinks.append(watcher)
    saved_path, saved_argv = list(sys.path), list(sys.argv)
    sys.path[:0] = [str(path.parent.resolve()), str((path.parent / "lib").resolve())]
    sys.argv = [str(path), *(argv or [])]
    status, stopped = 0, False
    try:
        with micropython_machine(dict(buses), heap_bytes=heap_bytes, where=where), \
                _program_clock(clock, real_time, duration_s):
            try:
                runpy.run_path(str(path), run_name="__main__")
            except ProgramTimeUp:
                stopped = True
            except SystemExit as exc:
                status = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
            except KeyboardInterrupt:
                status = 130
            except Exception:  # noqa: BLE001 - the program's error, shown as on the board
                traceback.print_exc()
                status = 1
    finally:
        sys.path[:], sys.argv = saved_path, saved_argv
        for bus in buses.values():
            if watcher in bus.log.sinks:
                bus.log.sinks.remove(watcher)
    return ProgramResult(status, float(clock.now()), stopped, messages)
