"""The chip contract (docs/architecture.md): the primitives every device behind the buses
offers (:class:`RegisterDevice`), what a gyro offers besides (:class:`RateSensor`), and
their argument rules, shared by the Python model and
the simulated firmware so both refuse the same arguments with the same errors."""

from __future__ import annotations

import operator
from typing import Any, Protocol, runtime_checkable

import numpy as np

from bmg160_emu.clock import seconds_to_ns
from bmg160_emu.device.spec_choices import VALID_ADDRESSES


@runtime_checkable
class RegisterDevice(Protocol):
    """What a front end (I2CBus, FakeSpiDev, i2c-stub, umockdev) needs of a device.

    ``lock`` is a re-entrant lock every primitive takes; ``time`` is the device's current
    time in seconds. Implemented by ``BMG160``, ``SimulatedFirmwareChip`` and the test suite's
    register-file stand-in (``tests/test_chip_contract.py`` checks all three).
    """

    lock: Any

    @property
    def time(self) -> float: ...

    def write(self, reg: int, data: bytes) -> None: ...

    def read(self, reg: int, n: int) -> bytes: ...

    def i2c_write(self, data: bytes) -> None: ...

    def i2c_read(self, n: int) -> bytes: ...

    def peek(self, reg: int) -> int: ...

    def dump(self) -> bytes: ...

    def advance(self, seconds: float) -> None: ...


@runtime_checkable
class RateSensor(RegisterDevice, Protocol):
    """A register device that measures angular rate: a gyro part (``BMG160`` and the parts
    of ``device.parts``, ``SimulatedFirmwareChip``). Besides the primitives it takes the
    true rate it senses, in deg/s (a 3-tuple, a function of time, samples; ``BMG160``'s
    ``set_true_rate`` documents them). A register-file stand-in (``device.standin``) is a
    ``RegisterDevice`` only: it holds registers and makes no data.

    As every Zephyr emulator offers its bus API and a sensor's also the sensor backend API,
    front ends ask ``isinstance(device, RateSensor)`` (the gyro to watch, a script's default
    chip, the adapter a kernel route gives it), never which attributes a device happens to
    have."""

    def set_true_rate(self, rate: Any) -> None: ...


@runtime_checkable
class InterruptPins(Protocol):
    """A device that drives interrupt lines (the gyro parts' INT1 and INT2, spec 4.15-4.16): a
    front end that carries pin levels (serve's events, virtio-gpio) asks
    ``isinstance(device, InterruptPins)``, as Zephyr's emulators offer a GPIO backend."""

    def int_pin_level(self, pin: int) -> int: ...

    def next_pin_change_ns(self) -> int | None: ...


@runtime_checkable
class SpiFramedDevice(RegisterDevice, Protocol):
    """A register device that decodes its SPI frames itself: a register-file stand-in
    (``device.standin``), whose chip may shift out a dummy byte before read data, start in
    I2C mode, or have its 3-wire bit elsewhere. Every other device is framed as the BMG160
    frames SPI (spec 2.2-2.4, ``bus.spi.SpiFrame``).

    ``spi_frame()`` is called when chip select falls; the frame it returns offers
    ``clock(mosi) -> bytes`` (what the chip drives), ``access()`` (the last clock in register
    terms: kind, register, written, read), ``three_wire()``, ``dummy_bytes`` and ``chip``."""

    def spi_frame(self) -> Any: ...

    def spi_three_wire(self) -> bool: ...


PRIMITIVES = ("write", "read", "i2c_write", "i2c_read", "peek", "dump", "advance")
NOISE_MODES = ("physical", "paper")


def _index(value: Any, what: str) -> int:
    if isinstance(value, bool):
        raise TypeError(f"{what} must be an int, not bool")
    try:
        return operator.index(value)
    except TypeError:
        raise TypeError(f"{what} must be an int, not {type(value).__name__}") from None


def check_register(reg: Any) -> int:
    """A register address as the bus carries it: 8 bits (0x40 and up are outside the map)."""
    reg = _index(reg, "register")
    if not 0 <= reg <= 0xFF:
        raise ValueError(f"register 0x{reg:X} out of range 0x00..0xFF")
    return reg


def check_count(n: Any) -> int:
    """A number of bytes to read."""
    n = _index(n, "byte count")
    if n < 0:
        raise ValueError("byte count must be >= 0")
    return n


def check_data(data: Any) -> bytes:
    """Bytes to write: bytes or a sequence of ints 0..255 (an int or a str is a mistake)."""
    if isinstance(data, (int, str)):
        raise TypeError("data must be bytes or a sequence of ints 0..255")
    try:
        return bytes(data)
    except ValueError:
        raise ValueError("data bytes must be in 0..255") from None


def check_chip_options(address: Any, noise_mode: Any, seed: Any) -> None:
    """The BMG160 constructor's address, noise mode and seed."""
    if address not in VALID_ADDRESSES:
        raise ValueError(f"BMG160 address must be 0x68 or 0x69, not {address!r}")
    if noise_mode not in NOISE_MODES:
        raise ValueError(f"noise_mode must be 'physical' or 'paper', not {noise_mode!r}")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))):
        raise TypeError(f"seed must be an int or None, not {type(seed).__name__}")


def check_clock(clock: Any) -> None:
    if not hasattr(clock, "now_ns"):
        raise TypeError("clock must be a VirtualClock or RealTimeClock")


def duration_ns(seconds: float) -> int:
    """``advance``'s argument in integer ns: the fast path for a plain number; anything else
    (a string, NaN, a negative time) gets clock.seconds_to_ns's clear error."""
    try:
        ns = round(seconds * 1e9)
    except (TypeError, ValueError, OverflowError):
        ns = -1
    return ns if ns >= 0 else seconds_to_ns(seconds)
