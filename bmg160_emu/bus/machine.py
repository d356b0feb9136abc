"""MicroPython's ``machine`` module (``I2C``, ``SoftI2C``, ``SPI``, ``SoftSPI``, ``Pin``) over
the emulated buses, for driver code written for a microcontroller and tested on a PC.

Why a module and not a fake class: a MicroPython driver does ``import machine`` (some check
``type(i2c) == machine.I2C``), so :class:`micropython_machine` puts this very module in
``sys.modules["machine"]`` for the test, with the buses it wires, and removes it after. The
methods follow MicroPython's ``extmod/machine_i2c.c`` and ``machine_spi.c``:

- ``readfrom_mem(addr, memaddr, n, *, addrsize=8)``: the memory address (``addrsize // 8``
  bytes, most significant first) written, a repeated start, ``n`` bytes read: one combined
  transfer. ``writeto_mem`` writes address and data in one message. ``writeto`` returns the
  number of data bytes acknowledged. ``scan()`` writes no data to 0x08..0x77 and lists the
  addresses that answer.
- Errors are MicroPython's: ``OSError`` whose ``errno`` (and ``args[0]``) is ENODEV (19) when
  nobody acknowledges the address, ETIMEDOUT (110) for a timed-out transfer, EIO (5) for any
  other bus failure (a stuck bus, a PEC or protocol error).
- ``SPI`` has no chip select of its own: a ``Pin`` wired as a chip's CS selects it while it is
  low, and every transfer in between is one frame for the chip (bmg160_emu.bus.spi). A chip
  takes part in SPI modes 0 and 3 only; a byte nobody drives reads as ``UNDRIVEN_BYTE``.

``micropython_machine`` also gives ``time`` MicroPython's ``sleep_ms``, ``sleep_us``,
``ticks_ms``, ``ticks_us``, ``ticks_diff`` and ``ticks_add`` (on ``time.sleep`` and
``time.monotonic``, so ``bmg160_virtual_time`` moves them too), ``utime`` and ``ustruct``
(MicroPython's names of ``time`` and ``struct``) and a ``micropython`` module (``const``)
when none is installed.
"""

from __future__ import annotations

import errno
import struct
import sys
import time
import types
from collections.abc import Iterable, Mapping
from contextlib import ContextDecorator
from typing import Any

from bmg160_emu.bus.i2c import I2CBus, I2CMessage, emulated_bus, register_bus, unregister_bus
from bmg160_emu.bus.spi import UNDRIVEN_BYTE, SpiFrame

__all__ = ["I2C", "SPI", "Pin", "SoftI2C", "SoftSPI", "micropython_error", "micropython_machine"]

_NO_ACK = (errno.EREMOTEIO, errno.ENXIO, errno.ENODEV)  # an address nobody acknowledges


def micropython_error(exc: OSError) -> OSError:
    """The OSError MicroPython raises for a failed transfer (``OSError: [Errno 19] ENODEV``)."""
    code = errno.ENODEV if exc.errno in _NO_ACK else (
        errno.ETIMEDOUT if exc.errno == errno.ETIMEDOUT else errno.EIO)
    return OSError(code, errno.errorcode[code])


def _buffer(obj: Any, writable: bool = False) -> memoryview:
    """mp_get_buffer_raise: an object with the buffer protocol (TypeError otherwise)."""
    try:
        view = memoryview(obj).cast("B")
    except TypeError:
        raise TypeError(f"object with buffer protocol required, not {type(obj).__name__}") from None
    if writable and view.readonly:
        raise TypeError("object with buffer protocol required (writable)")
    return view


class _State:
    """What the test wired: the bus every SoftI2C reaches, chip selects, pin levels."""

    def __init__(self) -> None:
        self.soft_i2c: int | None = None
        self.chip_selects: dict[Any, tuple[int, Any]] = {}  # pin id -> (SPI id, chip)
        self.frames: dict[Any, SpiFrame] = {}  # pin id -> the frame while CS is low
        self.levels: dict[Any, int] = {}


_state = _State()


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
            return _state.levels.get(self.id, 1 if self.pull == self.PULL_UP else 0)
        level = 1 if x else 0
        _state.levels[self.id] = level
        wired = _state.chip_selects.get(self.id)
        if wired is not None:
            if level == 0 and self.id not in _state.frames:
                _state.frames[self.id] = SpiFrame(wired[1])  # CS falls: a new frame
            elif level == 1:
                _state.frames.pop(self.id, None)  # CS rises: the frame ends
        return None

    __call__ = value

    def on(self) -> None:
        self.value(1)

    def off(self) -> None:
        self.value(0)

    high, low = on, off

    def __repr__(self) -> str:
        return f"Pin({self.id!r})"


class I2C:
    """``machine.I2C(id, *, scl, sda, freq=400000, timeout=...)``: hardware I2C ``id`` is the
    emulated bus of that number; ``I2C(-1, scl=..., sda=...)`` is a software I2C."""

    def __init__(self, id: int = -1, *, scl: Any = None, sda: Any = None, freq: int = 400000,
                 timeout: int = 50000) -> None:
        if not isinstance(id, int) or isinstance(id, bool):
            raise TypeError(f"can't convert {type(id).__name__} to int")
        if id == -1:
            if scl is None or sda is None:
                raise TypeError("'scl' argument required" if scl is None else "'sda' argument required")
            number = _state.soft_i2c
        else:
            number = id
        bus = emulated_bus(number) if number is not None else None
        if bus is None:
            raise ValueError(f"I2C({id}) doesn't exist")
        self._bus: I2CBus = bus
        self.freq, self.scl, self.sda = freq, scl, sda

    def init(self, *, scl: Any = None, sda: Any = None, freq: int = 400000, **_: Any) -> None:
        self.freq = freq

    def deinit(self) -> None:
        """Nothing to release on the emulated bus."""

    def _transfer(self, messages: list[I2CMessage]) -> list[I2CMessage]:
        try:
            return self._bus.i2c_transfer(messages)
        except OSError as exc:
            raise micropython_error(exc) from None

    def scan(self) -> list[int]:
        return self._bus.scan()

    def readfrom(self, addr: int, nbytes: int, stop: bool = True) -> bytes:
        return self._transfer([I2CMessage.read_message(addr, int(nbytes))])[0].data

    def readfrom_into(self, addr: int, buf: Any, stop: bool = True) -> None:
        view = _buffer(buf, writable=True)
        view[:] = self.readfrom(addr, len(view), stop)

    def writeto(self, addr: int, buf: Any, stop: bool = True) -> int:
        data = _buffer(buf).tobytes()
        self._transfer([I2CMessage.write(addr, data)])
        return len(data)  # every data byte acknowledged

    def writevto(self, addr: int, vector: Iterable[Any], stop: bool = True) -> int:
        data = b"".join(_buffer(b).tobytes() for b in vector)
        return self.writeto(addr, data, stop)

    @staticmethod
    def _memaddr(memaddr: int, addrsize: int) -> bytes:
        """The memory address bytes, most significant first (read_mem/write_mem)."""
        return bytes((memaddr >> shift) & 0xFF for shift in range(addrsize - 8, -1, -8))

    def readfrom_mem(self, addr: int, memaddr: int, nbytes: int, *, addrsize: int = 8) -> bytes:
        messages = [I2CMessage.write(addr, self._memaddr(memaddr, addrsize)),
                    I2CMessage.read_message(addr, int(nbytes))]
        return self._transfer(messages)[1].data

    def readfrom_mem_into(self, addr: int, memaddr: int, buf: Any, *, addrsize: int = 8) -> None:
        view = _buffer(buf, writable=True)
        view[:] = self.readfrom_mem(addr, memaddr, len(view), addrsize=addrsize)

    def writeto_mem(self, addr: int, memaddr: int, buf: Any, *, addrsize: int = 8) -> None:
        data = self._memaddr(memaddr, addrsize) + _buffer(buf).tobytes()
        self._transfer([I2CMessage.write(addr, data)])

    def __repr__(self) -> str:
        return f"I2C({self._bus.number}, freq={self.freq})"


class SoftI2C(I2C):
    """``machine.SoftI2C(scl, sda, *, freq=400000, timeout=50000)``: bit-banged on any pins;
    it reaches the bus :class:`micropython_machine` wired with ``soft_i2c``."""

    def __init__(self, scl: Any, sda: Any, *, freq: int = 400000, timeout: int = 50000) -> None:
        super().__init__(-1, scl=scl, sda=sda, freq=freq, timeout=timeout)


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
        frames = [f for pin, f in _state.frames.items() if _state.chip_selects[pin][0] == self.id]
        if not frames or self.polarity != self.phase:  # modes 1 and 2: the chip stays out
            return bytes([UNDRIVEN_BYTE]) * len(mosi)
        with frames[0].chip.lock:
            return frames[0].clock(mosi)

    def read(self, nbytes: int, write: int = 0x00) -> bytes:
        return self._clock(bytes([write & 0xFF]) * int(nbytes))

    def readinto(self, buf: Any, write: int = 0x00) -> None:
        view = _buffer(buf, writable=True)
        view[:] = self._clock(bytes([write & 0xFF]) * len(view))

    def write(self, buf: Any) -> None:
        self._clock(_buffer(buf).tobytes())

    def write_readinto(self, write_buf: Any, read_buf: Any) -> None:
        out, into = _buffer(write_buf).tobytes(), _buffer(read_buf, writable=True)
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

def _ticks_ms() -> int:
    return int(time.monotonic() * 1000) & TICKS_MAX


def _ticks_us() -> int:
    return int(time.monotonic() * 1_000_000) & TICKS_MAX


TICKS_MAX = (1 << 30) - 1  # MicroPython's ticks wrap at 2**30 (TICKS_PERIOD)


def _ticks_diff(ticks1: int, ticks2: int) -> int:
    half = (TICKS_MAX + 1) // 2
    return ((ticks1 - ticks2 + half) & TICKS_MAX) - half


_TIME_NAMES = {
    "sleep_ms": lambda ms: time.sleep(ms / 1000), "sleep_us": lambda us: time.sleep(us / 1e6),
    "ticks_ms": _ticks_ms, "ticks_us": _ticks_us, "ticks_diff": _ticks_diff,
    "ticks_add": lambda ticks, delta: (ticks + delta) & TICKS_MAX,
}


class micropython_machine(ContextDecorator):
    """Context manager (and decorator): ``import machine`` gives this module, with the
    hardware I2C buses ``i2c`` ({id: I2CBus or {address: chip}}), the bus ``soft_i2c`` for
    every ``SoftI2C``, and ``spi`` ({SPI id: {CS pin id: chip}}); yields the module."""

    def __init__(self, i2c: Mapping[int, I2CBus | Mapping[int, Any]] | None = None, *,
                 soft_i2c: int | None = None,
                 spi: Mapping[Any, Mapping[Any, Any]] | None = None) -> None:
        self.buses = {n: b if isinstance(b, I2CBus) else I2CBus(n, b) for n, b in (i2c or {}).items()}
        self.soft_i2c = soft_i2c if soft_i2c is not None else next(iter(self.buses), None)
        self.spi = {sid: dict(cs) for sid, cs in (spi or {}).items()}
        self._saved: dict[str, Any] = {}
        self._time_saved: dict[str, Any] = {}

    def __enter__(self) -> types.ModuleType:
        for bus in self.buses.values():
            register_bus(bus)
        _state.soft_i2c = self.soft_i2c
        for spi_id, selects in self.spi.items():
            for pin, chip in selects.items():
                _state.chip_selects[pin] = (spi_id, chip)
                _state.levels[pin] = 1  # chip selects idle high
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
        for name, function in _TIME_NAMES.items():
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
                _state.chip_selects.pop(pin, None)
                _state.frames.pop(pin, None)
        _state.levels.clear()  # no pin level outlives the test
        _state.soft_i2c = None
        for bus in self.buses.values():
            unregister_bus(bus)


def _micropython_module() -> types.ModuleType:
    module = types.ModuleType("micropython", "micropython's const(), for drivers run on a PC")
    module.const = lambda value: value  # type: ignore[attr-defined]
    return module
