"""The chip contract (docs/architecture.md): the primitives every device behind the buses
offers (:class:`RegisterDevice`), and their argument rules, shared by the Python model and
the simulated firmware so both refuse the same arguments with the same errors."""

from __future__ import annotations

import operator
from typing import Any, Protocol, runtime_checkable


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


PRIMITIVES = ("write", "read", "i2c_write", "i2c_read", "peek", "dump", "advance")


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
