"""Small helpers shared by the chip model tests."""

from __future__ import annotations

import struct

from bmg160_emu.device.chip import BMG160


def rates(chip: BMG160) -> tuple[int, int, int]:
    """The signed X, Y, Z counts of one 6-byte burst from RATE_X_LSB."""
    return struct.unpack("<3h", chip.read(0x02, 6))


def quiet_chip(**kwargs) -> BMG160:
    """A noiseless chip (counts are exact functions of the true rate)."""
    kwargs.setdefault("noise", False)
    return BMG160(**kwargs)


def period_s(chip: BMG160) -> float:
    return 1.0 / chip.odr_hz
