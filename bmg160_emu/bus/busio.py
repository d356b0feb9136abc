"""CircuitPython's ``busio`` module (``I2C``, ``SPI``) over the emulated buses, for driver code
written for CircuitPython (directly or through ``adafruit_bus_device``) and tested on a PC.

:class:`~bmg160_emu.bus.board.circuitpython_board` puts this module in
``sys.modules["busio"]`` (with ``board`` and ``digitalio``) for a test. The behaviour follows
CircuitPython's ``shared-bindings/busio``: a bus must be locked (``try_lock``) before any
transfer (``RuntimeError: Function requires lock`` otherwise); ``start``/``end`` slice the
buffers without copying; ``writeto_then_readfrom`` is one combined transfer (a repeated
start); a pin serves one bus at a time (``ValueError: SCL in use`` until ``deinit``).
Errors are ``OSError`` with CircuitPython's errno: ENODEV (19) when nobody acknowledges
the address, ETIMEDOUT (110) for a timeout, EIO (5) for any other bus failure (the RP2040
port's common-hal/busio/I2C.c). Arguments follow shared-bindings/busio/I2C.c: ``start`` and
``end`` count the buffer's elements (normalize_buffer_bounds), a read needs at least one
byte (``ValueError: buffer length must be >= 1``), a ``str`` is a buffer to write from
(its UTF-8 bytes) and an address must be an int (:mod:`.micropython_rules`).

SPI: a chip wired to a chip-select pin takes part in a transfer while that pin is driven low
through ``digitalio.DigitalInOut`` (each low period is one frame, bmg160_emu.bus.spi), in
SPI modes 0 and 3 only.
"""

from __future__ import annotations

import threading
from typing import Any

from bmg160_emu.bus.i2c import I2CBus, I2CMessage
from bmg160_emu.bus.micropython_rules import (
    get_int,
    micropython_error,
    read_buffer,
    write_buffer,
)
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


INT_MAX = 0x7FFFFFFF  # the default ``end`` of every slice (CircuitPython's INT_MAX)


def _bounds(buffer: Any, start: Any, end: Any, writable: bool = False) -> memoryview:
    """``buffer[start:end]`` as CircuitPython slices it (shared/runtime/buffer_helper.c,
    normalize_buffer_bounds): ``start`` and ``end`` count elements of the buffer's type (2
    bytes for an ``array('h')``), a negative one from the end, ``end`` clipped to the
    length, ``start`` not clipped; the bytes of that slice. A slice that reaches outside
    the buffer makes the board read or write beyond it: the emulator stops there."""
    if writable:
        raw = write_buffer(buffer)
        stride = memoryview(buffer).itemsize
    elif isinstance(buffer, str):
        raw, stride = memoryview(read_buffer(buffer)), 1
    else:
        try:
            stride = memoryview(buffer).itemsize
        except TypeError:
            raise TypeError("object with buffer protocol required") from None
        raw = memoryview(read_buffer(buffer))
    length = len(raw) // stride
    first, last = get_int(start), INT_MAX if end is None else get_int(end)
    if last < 0:
        last += length
    elif last > length:
        last = length
    if first < 0:
        first += length
    count = 0 if last < first else last - first
    if count and (first < 0 or first + count > length):
        raise ValueError(f"start={start!r}, end={end!r} on a buffer of {length} elements reach "
                         "outside it: CircuitPython would read or write past the buffer")
    return raw[first * stride:(first + count) * stride]


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
        for name, pin in (("scl", scl), ("sda", sda)):
            if not hasattr(pin, "name"):  # validate_obj_is_pin
                raise TypeError(f"{name} must be of type Pin, not {type(pin).__name__}")
        bus = wiring.i2c.get((scl, sda))
        if bus is None:
            raise ValueError("Invalid pins")
        _claim(scl, sda)
        self._pins = (scl, sda)
        self._bus = bus
        self.frequency = get_int(frequency)
        self.timeout = get_int(timeout)

    def _transfer(self, messages: list[I2CMessage]) -> list[I2CMessage]:
        try:
            return self._bus.i2c_transfer(messages, kernel_limits=False)
        except OSError as exc:
            raise micropython_error(exc) from None

    @staticmethod
    def _address(address: Any) -> int:
        """The address as the port sends it: an int (TypeError otherwise); one beyond 7 bits
        is not acknowledged (ENODEV)."""
        value = get_int(address)
        if not 0 <= value <= 0x7F:
            raise micropython_error(OSError(19, "ENODEV"))
        return value

    def probe(self, address: Any) -> bool:
        """Whether a device acknowledges ``address`` (a write of no data)."""
        self._check()
        value = get_int(address)
        return 0 <= value <= 0x7F and self._bus.probe(value)

    def scan(self) -> list[int]:
        self._check()
        return self._bus.scan()

    def writeto(self, address: Any, buffer: Any, *, start: Any = 0, end: Any = None) -> None:
        self._check()
        data = _bounds(buffer, start, end).tobytes()
        self._transfer([I2CMessage.write(self._address(address), data)])

    def readfrom_into(self, address: Any, buffer: Any, *, start: Any = 0,
                      end: Any = None) -> None:
        self._check()
        view = _bounds(buffer, start, end, writable=True)
        if not len(view):
            raise ValueError("buffer length must be >= 1")
        messages = [I2CMessage.read_message(self._address(address), len(view))]
        view[:] = self._transfer(messages)[0].data

    def writeto_then_readfrom(self, address: Any, out_buffer: Any, in_buffer: Any, *,
                              out_start: Any = 0, out_end: Any = None,
                              in_start: Any = 0, in_end: Any = None) -> None:
        self._check()
        out = _bounds(out_buffer, out_start, out_end).tobytes()
        into = _bounds(in_buffer, in_start, in_end, writable=True)
        if not len(into):  # the port names the wrong buffer in this message
            raise ValueError("out_buffer length must be >= 1")
        target = self._address(address)
        messages = [I2CMessage.write(target, out), I2CMessage.read_message(target, len(into))]
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
        view = _bounds(buffer, start, end, writable=True)
        view[:] = self._clock(bytes([write_value & 0xFF]) * len(view))

    def write_readinto(self, out_buffer: Any, in_buffer: Any, *, out_start: int = 0,
                       out_end: int | None = None, in_start: int = 0,
                       in_end: int | None = None) -> None:
        self._check()
        out = _bounds(out_buffer, out_start, out_end).tobytes()
        into = _bounds(in_buffer, in_start, in_end, writable=True)
        if len(out) != len(into):
            raise ValueError("buffer slices must be of equal length")
        into[:] = self._clock(out)
