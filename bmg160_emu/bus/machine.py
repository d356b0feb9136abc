"""MicroPython's ``machine`` module (``I2C``, ``SoftI2C``, ``SPI``, ``SoftSPI``, ``Pin``,
``freq``, ``unique_id``, ``idle``) over the emulated buses, for driver code written for a
microcontroller and run on a PC.

Why a module and not a fake class: a MicroPython driver does ``import machine`` (some check
``type(i2c) == machine.I2C``), so :class:`micropython_machine` puts this very module in
``sys.modules["machine"]``, with the buses it wires, and removes it after; the pytest
fixture ``bmg160_machine`` and the command ``bmg160-emu micropython main.py`` both use it.
The board is the ESP32 port (:mod:`.micropython_board`); the I2C classes are
:mod:`.machine_i2c`, the argument rules :mod:`.micropython_rules`:

- ``machine.freq()`` is 160 MHz; ``freq(hz)`` takes 20, 40, 80, 160 or 240 MHz
  (``ValueError: frequency must be 20MHz, 40MHz, 80Mhz, 160MHz or 240MHz`` otherwise), and
  ``time.ticks_cpu()`` counts cycles at it; ``unique_id()`` is the 6-byte MAC;
  ``idle()`` yields and returns (the port's taskYIELD).
- ``SPI`` has no chip select of its own: a ``Pin`` wired as a chip's CS selects it while it is
  low, and every transfer in between is one frame for the chip (bmg160_emu.bus.spi). A chip
  takes part in SPI modes 0 and 3 only; a byte nobody drives reads as ``UNDRIVEN_BYTE``.

``micropython_machine`` also gives ``time`` MicroPython's ``sleep_ms``, ``sleep_us``,
``ticks_ms``, ``ticks_us``, ``ticks_cpu``, ``ticks_diff`` and ``ticks_add``
(:mod:`.micropython_time`, over ``time.sleep`` and ``time.monotonic``, so virtual time moves
them too), ``utime`` and ``ustruct`` (MicroPython's names of ``time`` and ``struct``) and a
``micropython`` module (``const``) when none is installed.
"""

from __future__ import annotations

import struct
import sys
import time
import types
from collections.abc import Mapping
from contextlib import ContextDecorator
from typing import Any

from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.bus.machine_i2c import I2C, SoftI2C
from bmg160_emu.bus.micropython_board import CPU_MHZ_CHOICES, UNIQUE_ID, board
from bmg160_emu.bus.micropython_rules import allocate, get_int, read_buffer, write_buffer
from bmg160_emu.bus.micropython_time import time_functions
from bmg160_emu.bus.registry import register_bus, unregister_bus
from bmg160_emu.bus.spi import UNDRIVEN_BYTE, SpiFrame

__all__ = ["I2C", "SPI", "Pin", "SoftI2C", "SoftSPI", "freq", "idle", "micropython_machine",
           "unique_id"]

class Pin:
    """``machine.Pin(id, mode=-1, pull=-1, *, value=None)``: a GPIO; a pin wired as a chip
    select frames SPI transfers while it is low."""

    IN, OUT, OPEN_DRAIN, ALT, ALT_OPEN_DRAIN, ANALOG = 0, 1, 2, 3, 4, 5
    PULL_UP, PULL_DOWN, PULL_HOLD = 1, 2, 4
    IRQ_FALLING, IRQ_RISING = 1, 2

    def __init__(self, id: Any, mode: int = -1, pull: int = -1, *, value: Any = None,
                 **_: Any) -> None:
        self.id = id
        self.mode = mode
        self.pull = pull
        if value is not None:
            self.value(value)

    def init(self, mode: int = -1, pull: int = -1, *, value: Any = None, **_: Any) -> None:
        self.mode, self.pull = mode, pull
        if value is not None:
            self.value(value)

    def value(self, x: Any = None) -> int | None:
        if x is None:
            return board.levels.get(self.id, 1 if self.pull == self.PULL_UP else 0)
        level = 1 if x else 0
        board.levels[self.id] = level
        wired = board.chip_selects.get(self.id)
        if wired is not None:
            if level == 0 and self.id not in board.frames:
                board.frames[self.id] = SpiFrame(wired[1])  # CS falls: a new frame
            elif level == 1:
                board.frames.pop(self.id, None)  # CS rises: the frame ends
        return None

    __call__ = value

    def on(self) -> None:
        self.value(1)

    def off(self) -> None:
        self.value(0)

    high, low = on, off

    def __repr__(self) -> str:
        return f"Pin({self.id!r})"


class SPI:
    """``machine.SPI(id, baudrate=1000000, *, polarity=0, phase=0, bits=8, firstbit=MSB, ...)``:
    transfers reach the chips whose chip-select pin is low."""

    MSB, LSB = 0, 1

    def __init__(self, id: Any = -1, baudrate: int = 1000000, *, polarity: int = 0,
                 phase: int = 0, bits: int = 8, firstbit: int = 0, **pins: Any) -> None:
        self.id = id
        self.init(baudrate, polarity=polarity, phase=phase, bits=bits, firstbit=firstbit)

    def init(self, baudrate: int = 1000000, *, polarity: int = 0, phase: int = 0, bits: int = 8,
             firstbit: int = 0, **_: Any) -> None:
        self.baudrate, self.polarity, self.phase = baudrate, polarity, phase
        self.bits, self.firstbit = bits, firstbit

    def deinit(self) -> None:
        """Nothing to release on the emulated bus."""

    def _clock(self, mosi: bytes) -> bytes:
        frames = [f for pin, f in board.frames.items() if board.chip_selects[pin][0] == self.id]
        if not frames or self.polarity != self.phase:  # modes 1 and 2: the chip stays out
            return bytes([UNDRIVEN_BYTE]) * len(mosi)
        with frames[0].chip.lock:
            return frames[0].clock(mosi)

    def read(self, nbytes: Any, write: Any = 0x00) -> bytes:
        length = allocate(get_int(nbytes), board.heap_bytes, "SPI.read")
        return self._clock(bytes([get_int(write) & 0xFF]) * length)

    def readinto(self, buf: Any, write: Any = 0x00) -> None:
        view = write_buffer(buf)
        view[:] = self._clock(bytes([get_int(write) & 0xFF]) * len(view))

    def write(self, buf: Any) -> None:
        self._clock(read_buffer(buf))

    def write_readinto(self, write_buf: Any, read_buf: Any) -> None:
        out, into = read_buffer(write_buf), write_buffer(read_buf)
        if len(out) != len(into):
            raise ValueError("buffers must be the same length")
        into[:] = self._clock(out)


class SoftSPI(SPI):
    """``machine.SoftSPI(baudrate=500000, *, polarity=0, phase=0, bits=8, firstbit=MSB, sck,
    mosi, miso)``: the emulated SPI bus -1."""

    def __init__(self, baudrate: int = 500000, *, polarity: int = 0, phase: int = 0,
                 bits: int = 8, firstbit: int = 0, **pins: Any) -> None:
        super().__init__(-1, baudrate, polarity=polarity, phase=phase, bits=bits,
                         firstbit=firstbit)


# ----------------------------------------------------------------------- time, micropython

def freq(*hz: Any) -> int | None:
    """``machine.freq()``: the CPU frequency in Hz; ``freq(hz)`` sets it to one the ESP32
    takes (20, 40, 80, 160 or 240 MHz)."""
    if not hz:
        return board.cpu_hz
    if len(hz) > 1:
        raise TypeError(f"function expected at most 1 arguments, got {len(hz)}")
    mhz = int(get_int(hz[0]) / 1_000_000)  # C division: towards zero
    if mhz not in CPU_MHZ_CHOICES:
        raise ValueError("frequency must be 20MHz, 40MHz, 80Mhz, 160MHz or 240MHz")
    board.cpu_hz = mhz * 1_000_000
    return None


def unique_id() -> bytes:
    """``machine.unique_id()``: the board's 6-byte MAC, the same on every run."""
    return UNIQUE_ID


def idle() -> None:
    """``machine.idle()``: the port yields to other tasks and returns (no time passes)."""
    time.sleep(0)


class micropython_machine(ContextDecorator):
    """Context manager (and decorator): ``import machine`` gives this module, with the
    hardware I2C buses ``i2c`` ({id: I2CBus or {address: chip}}), the bus ``soft_i2c`` for
    every ``SoftI2C``, and ``spi`` ({SPI id: {CS pin id: chip}}); yields the module.
    ``heap_bytes``: the board's heap (None: no limit; a buffer past it is a MemoryError);
    ``where``: a sentence saying where the chips are, for the error of an I2C id not wired,
    ``{id}`` standing for the id asked for (the pytest plugin says which marker option moves
    them)."""

    def __init__(self, i2c: Mapping[int, I2CBus | Mapping[int, Any]] | None = None, *,
                 soft_i2c: int | None = None,
                 spi: Mapping[Any, Mapping[Any, Any]] | None = None,
                 heap_bytes: int | None = None, where: str | None = None) -> None:
        self.buses = {n: b if isinstance(b, I2CBus) else I2CBus(n, b) for n, b in (i2c or {}).items()}
        self.soft_i2c = soft_i2c if soft_i2c is not None else next(iter(self.buses), None)
        self.spi = {sid: dict(cs) for sid, cs in (spi or {}).items()}
        self.heap_bytes = heap_bytes
        if where is None and self.buses:
            where = "the emulated I2C buses are " + ", ".join(
                f"I2C({n})" for n in sorted(self.buses))
        self.where = where or ""
        self._saved: dict[str, Any] = {}
        self._time_saved: dict[str, Any] = {}

    def __enter__(self) -> types.ModuleType:
        for bus in self.buses.values():
            register_bus(bus)
        board.reset()
        board.soft_i2c = self.soft_i2c
        board.heap_bytes = self.heap_bytes
        board.where = self.where
        for spi_id, selects in self.spi.items():
            for pin, chip in selects.items():
                board.chip_selects[pin] = (spi_id, chip)
                board.levels[pin] = 1  # chip selects idle high
        module = sys.modules[__name__]
        injected = {"machine": module}
        if "micropython" not in sys.modules:
            try:
                __import__("micropython")
            except ImportError:
                injected["micropython"] = _micropython_module()
        injected["utime"], injected["ustruct"] = time, struct  # MicroPython's u-names
        for name, value in injected.items():
            self._saved[name] = sys.modules.get(name)
            sys.modules[name] = value
        for name, function in time_functions(lambda: board.cpu_hz).items():
            self._time_saved[name] = getattr(time, name, None)
            setattr(time, name, function)
        return module

    def __exit__(self, *exc: object) -> None:
        for name, old in self._time_saved.items():
            if old is None:
                delattr(time, name)
            else:
                setattr(time, name, old)
        for name, old in self._saved.items():
            if old is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = old
        self._saved, self._time_saved = {}, {}
        for selects in self.spi.values():
            for pin in selects:
                board.chip_selects.pop(pin, None)
                board.frames.pop(pin, None)
        board.reset()  # no pin level, frequency or heap outlives the test
        for bus in self.buses.values():
            unregister_bus(bus)


def _micropython_module() -> types.ModuleType:
    module = types.ModuleType("micropython", "micropython's const(), for drivers run on a PC")
    module.const = lambda value: value  # type: ignore[attr-defined]
    return module
