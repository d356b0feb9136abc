"""CircuitPython's ``busio`` module (``I2C``, ``SPI``) over the emulated buses, for driver code
written for CircuitPython (directly or through ``adafruit_bus_device``) and tested on a PC.

:class:`~bmg160_emu.bus.board.circuitpython_board` puts this module in
``sys.modules["busio"]`` (with ``board`` and ``digitalio``) for a test. The behaviour follows
CircuitPython's ``shared-bindings/busio``: a bus must be locked (``try_lock``) before any
transfer (``RuntimeError: Function requires lock`` otherwise); ``start``/``end`` slice the
buffers without copying; ``writeto_then_readfrom`` is one combined transfer (a repeated
start); a pin serves one bus at a time (``ValueError: SCL in use`` until ``deinit``).
Errors are ``OSError`` with CircuitPython's errno: ENODEV (19) when nobody acknowledges
the address, ETIMEDOUT (110) for a timeout, EIO (5) for any other bus failure.

SPI: a chip wired to a chip-select pin takes part in a transfer while that pin is driven low
through ``digitalio.DigitalInOut`` (each low period is one frame, bmg160_emu.bus.spi), in
SPI modes 0 and 3 only.
"""

from __future__ import annotations

import threading
from typing import Any

from bmg160_emu.bus.i2c import I2CBus, I2CMessage
from bmg160_emu.bus.machine import micropython_error
from bmg160_emu.bus.spi import UNDRIVEN_BYTE, SpiFrame

__all__ = ["I2C", "SPI", "Wiring", "chip_select", "wiring"]


class Wiring:
    """What the test wired to the board: the I2C bus on each (SCL, SDA) pair, the SPI bus
    pins, each chip's chip-select pin, the pins in use and the frames in progress."""

    def __init__(self) -> None:
        self.i2c: dict[tuple[Any, Any], I2CBus] = {}
        self.spi_pins: tuple[Any, Any, Any] | None = None  # (clock, MOSI, MISO)
        self.chip_selects: dict[Any, Any] = {}  # pin -> chip
        self.frames: dict[Any, SpiFrame] = {}  # pin -> the frame while it is low
        self.in_use: set[Any] = set()

    def clear(self) -> None:
        self.__init__()  # type: ignore[misc]


wiring = Wiring()


def chip_select(pin: Any, level: bool) -> None:
    """A chip-select pin driven: falling starts a frame for its chip, rising ends it."""
    chip = wiring.chip_selects.get(pin)
    if chip is None:
        return
    if not level and pin not in wiring.frames:
        wiring.frames[pin] = SpiFrame(chip)
    elif level:
        wiring.frames.pop(pin, None)


def _claim(*pins: Any) -> None:
    for pin in pins:
        if pin is not None and pin in wiring.in_use:
            raise ValueError(f"{getattr(pin, 'name', pin)} in use")
    wiring.in_use.update(p for p in pins if p is not None)


def _bounds(buffer: Any, start: int, end: int | None) -> memoryview:
    view = memoryview(buffer).cast("B")
    length = len(view)
    end = length if end is None else end
    start, end = max(0, min(start, length)), max(0, min(end, length))
    return view[start:max(start, end)]


class _Lockable:
    """try_lock / unlock, and the check every transfer makes."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._locked = False
        self._pins: tuple[Any, ...] = ()

    def try_lock(self) -> bool:
        self._check_alive()
        if self._lock.acquire(blocking=False):
            self._locked = True
            return True
        return False

    def unlock(self) -> None:
        if self._locked:
            self._locked = False
            self._lock.release()

    def _check(self) -> None:
        self._check_alive()
        if not self._locked:
            raise RuntimeError("Function requires lock")

    def _check_alive(self) -> None:
        if self._pins is None:
            raise ValueError("Object has been deinitialized and can no longer be used. "
                             "Create a new object.")

    @property
    def deinitialized(self) -> bool:
        """``deinit()`` was called: the object can no longer be used."""
        return self._pins is None

    def deinit(self) -> None:
        if self._pins is not None:
            wiring.in_use.difference_update(self._pins)
        self._pins = None  # type: ignore[assignment]

    def __enter__(self) -> Any:
        return self

    def __exit__(self, *exc: object) -> None:
        self.deinit()


class I2C(_Lockable):
    """``busio.I2C(scl, sda, *, frequency=100000, timeout=255)``."""

    def __init__(self, scl: Any, sda: Any, *, frequency: int = 100000, timeout: int = 255) -> None:
        super().__init__()
        bus = wiring.i2c.get((scl, sda))
        if bus is None:
            raise ValueError("Invalid pins")
        _claim(scl, sda)
        self._pins = (scl, sda)
        self._bus = bus
        self.frequency = frequency

    def _transfer(self, messages: list[I2CMessage]) -> list[I2CMessage]:
        try:
            return self._bus.i2c_transfer(messages)
        except OSError as exc:
            raise micropython_error(exc) from None

    def probe(self, address: int) -> bool:
        """Whether a device acknowledges ``address`` (a write of no data)."""
        self._check()
        return self._bus.probe(address)

    def scan(self) -> list[int]:
        self._check()
        return self._bus.scan()

    def writeto(self, address: int, buffer: Any, *, start: int = 0, end: int | None = None) -> None:
        self._check()
        self._transfer([I2CMessage.write(address, _bounds(buffer, start, end).tobytes())])

    def readfrom_into(self, address: int, buffer: Any, *, start: int = 0,
                      end: int | None = None) -> None:
        self._check()
        view = _bounds(buffer, start, end)
        if not len(view):
            raise ValueError("Buffer must be at least length 1")
        view[:] = self._transfer([I2CMessage.read_message(address, len(view))])[0].data

    def writeto_then_readfrom(self, address: int, out_buffer: Any, in_buffer: Any, *,
                              out_start: int = 0, out_end: int | None = None,
                              in_start: int = 0, in_end: int | None = None) -> None:
        self._check()
        out = _bounds(out_buffer, out_start, out_end).tobytes()
        into = _bounds(in_buffer, in_start, in_end)
        if not len(into):
            raise ValueError("Buffer must be at least length 1")
        messages = [I2CMessage.write(address, out), I2CMessage.read_message(address, len(into))]
        into[:] = self._transfer(messages)[1].data


class SPI(_Lockable):
    """``busio.SPI(clock, MOSI=None, MISO=None, half_duplex=False)``."""

    def __init__(self, clock: Any, MOSI: Any = None, MISO: Any = None,
                 half_duplex: bool = False) -> None:
        super().__init__()
        if wiring.spi_pins is None or clock is not wiring.spi_pins[0]:
            raise ValueError("Invalid pins")
        _claim(clock, MOSI, MISO)
        self._pins = (clock, MOSI, MISO)
        self.baudrate, self.polarity, self.phase, self.bits = 250000, 0, 0, 8
        self.frequency = self.baudrate

    def configure(self, *, baudrate: int = 100000, polarity: int = 0, phase: int = 0,
                  bits: int = 8) -> None:
        self._check()
        if polarity not in (0, 1) or phase not in (0, 1):
            raise ValueError("polarity and phase must be 0 or 1")
        self.baudrate, self.polarity, self.phase, self.bits = baudrate, polarity, phase, bits
        self.frequency = baudrate

    def _clock(self, mosi: bytes) -> bytes:
        frames = list(wiring.frames.values())
        if not frames or self.polarity != self.phase:  # modes 1 and 2: the chip stays out
            return bytes([UNDRIVEN_BYTE]) * len(mosi)
        with frames[0].chip.lock:
            return frames[0].clock(mosi)

    def write(self, buffer: Any, *, start: int = 0, end: int | None = None) -> None:
        self._check()
        self._clock(_bounds(buffer, start, end).tobytes())

    def readinto(self, buffer: Any, *, start: int = 0, end: int | None = None,
                 write_value: int = 0) -> None:
        self._check()
        view = _bounds(buffer, start, end)
        view[:] = self._clock(bytes([write_value & 0xFF]) * len(view))

    def write_readinto(self, out_buffer: Any, in_buffer: Any, *, out_start: int = 0,
                       out_end: int | None = None, in_start: int = 0,
                       in_end: int | None = None) -> None:
        self._check()
        out = _bounds(out_buffer, out_start, out_end).tobytes()
        into = _bounds(in_buffer, in_start, in_end)
        if len(out) != len(into):
            raise ValueError("buffer slices must be of equal length")
        into[:] = self._clock(out)
