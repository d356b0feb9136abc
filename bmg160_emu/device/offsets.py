"""The offset registers (4.24: the signed X, Y, Z offsets spread over OFC1..OFC4 and
TRIM_GP0) and fast offset compensation (6.9), which writes them."""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np

from bmg160_emu.device.registers import field_of, offset_bits, offset_parts

_FOC_WORDLENGTH = field_of("A_FOC", "fast_offset_wordlength")
_FOC_AXES = tuple(field_of("A_FOC", f"fast_offset_en_{axis}").mask for axis in "xyz")
_FOC_UNFILT = field_of("ANY_TH", "fast_offset_unfilt").mask


class FastOffset:
    """One fast offset compensation run (6.9): the mean of N samples of the selected axes."""

    def __init__(self, a_foc: int, any_th: int) -> None:
        self.n = 32 << _FOC_WORDLENGTH.extract(a_foc)  # 4.21: 32, 64, 128, 256 samples
        self.axes = tuple(bool(a_foc & mask) for mask in _FOC_AXES)
        self.unfiltered = bool(any_th & _FOC_UNFILT)
        self.sum = np.zeros(3)
        self.count = 0

    def add(self, rate_dps: np.ndarray, offset_dps: np.ndarray) -> bool:
        """Take one sample (deg/s, the offset registers' part removed); True when done."""
        self.sum += np.asarray(rate_dps, dtype=float) - offset_dps
        self.count += 1
        return self.count >= self.n

    def offsets_lsb(self, lsb_dps: float, bits: int) -> list[int | None]:
        """The negated mean per selected axis in offset LSB (None: axis not selected)."""
        mean = self.sum / self.count
        top = (1 << (bits - 1)) - 1
        return [int(np.clip(np.rint(-mean[axis] / lsb_dps), -top - 1, top)) if on else None
                for axis, on in enumerate(self.axes)]


def sign_extend(value: int, bits: int) -> int:
    return value - (1 << bits) if value >> (bits - 1) & 1 else value


OFFSET_PARTS, OFFSET_BITS = offset_parts(), offset_bits()
# per axis: (address, mask, lsb, position) of each piece, as plain ints for speed
_OFFSET_PIECES = tuple(tuple((a, f.mask, f.lsb, pos) for a, f, pos in axis) for axis in OFFSET_PARTS)


def offsets_from(regs: bytearray) -> tuple[int, int, int]:
    """The signed offsets of X, Y, Z, assembled from their register fields (4.24)."""
    out = []
    for pieces in _OFFSET_PIECES:
        value = 0
        for address, mask, lsb, position in pieces:
            value |= (regs[address] & mask) >> lsb << position
        out.append(sign_extend(value, OFFSET_BITS))
    x, y, z = out
    return x, y, z


_OFFSET_SPAN = (min(p[0] for axis in _OFFSET_PIECES for p in axis),
                max(p[0] for axis in _OFFSET_PIECES for p in axis) + 1)


def offsets_dps(regs: bytearray, lsb_dps: float) -> np.ndarray:
    """The offsets in deg/s (``offsets_from`` x the offset LSB), read-only: remembered for
    the last register contents, as the data path asks for them at every block."""
    lo, hi = _OFFSET_SPAN
    return _offsets_dps(bytes(regs[lo:hi]), lsb_dps)


@lru_cache(maxsize=16)
def _offsets_dps(contents: bytes, lsb_dps: float) -> np.ndarray:
    lo, hi = _OFFSET_SPAN
    regs = bytearray(hi)
    regs[lo:hi] = contents
    out = np.asarray(offsets_from(regs), dtype=float) * lsb_dps
    out.setflags(write=False)
    return out


def set_offsets(regs: bytearray, offsets: Sequence[int | None]) -> None:
    """Write the offsets of the axes not None into their register fields (4.24)."""
    for parts, value in zip(OFFSET_PARTS, offsets):
        if value is not None:
            for address, f, position in parts:
                regs[address] = f.insert(regs[address], int(value) >> position)
