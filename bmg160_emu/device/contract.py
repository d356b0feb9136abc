"""Argument rules of the chip primitives (docs/architecture.md), shared by every device that
sits behind the buses (the Python model and the simulated firmware), so both refuse the same
arguments with the same errors."""

from __future__ import annotations

import operator
from typing import Any


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
