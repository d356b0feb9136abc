"""The chip's small state machines beside the data path: power mode (6.7), fast offset
compensation (6.9), self-test (6.8), NVM (6.10) and the temperature sensor (5.2).

Each keeps its own state and reads or writes register bytes through the table's fields,
like ``fifo.py`` and ``interrupts.py``; the chip wires them to registers in ``regmap.py``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from functools import lru_cache

import numpy as np

from bmg160_emu.clock import NS_PER_S
from bmg160_emu.device import spec_choices as choice
from bmg160_emu.device.registers import (
    NVM_ADDRESSES,
    address_of,
    field_of,
    offset_bits,
    offset_parts,
)

NEVER = 1 << 62  # "no sample due": a time in ns no clock reaches
NORMAL, DEEP_SUSPEND, SUSPEND, FAST_POWER_UP, POWER_SAVE = (
    "normal", "deep suspend", "suspend", "fast power-up", "advanced power saving")
MODES = (NORMAL, DEEP_SUSPEND, SUSPEND, FAST_POWER_UP, POWER_SAVE)
SAMPLING_MODES = (NORMAL, POWER_SAVE)  # 6.7: power saving samples as normal (unconfirmed)

_SUSPEND = field_of("LPM1", "suspend").mask
_DEEP_SUSPEND = field_of("LPM1", "deep_suspend").mask
_FAST_POWER_UP = field_of("LPM2", "fast_power_up").mask
_POWER_SAVE = field_of("LPM2", "power_save_mode").mask


def power_mode(lpm1: int, lpm2: int) -> str:
    """Power mode from LPM1/LPM2 by the physical priority rule of spec 6.7 (unconfirmed)."""
    if lpm1 & _DEEP_SUSPEND:
        return DEEP_SUSPEND
    if lpm1 & _SUSPEND:
        return FAST_POWER_UP if lpm2 & _FAST_POWER_UP else SUSPEND
    if lpm2 & _POWER_SAVE:
        return POWER_SAVE
    return NORMAL


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


_RATE_OK = field_of("BIST", "rate_ok")
_BIST_FAIL = field_of("BIST", "bist_fail")
_BIST_RDY = field_of("BIST", "bist_rdy")


class SelfTest:
    """The built-in self-test (6.8): ready BIST_TIME_NS after the trigger."""

    def __init__(self) -> None:
        self.start_ns: int | None = None

    def trigger(self, now_ns: int) -> None:
        self.start_ns = now_ns

    def register(self, now_ns: int, rate_ok: bool, inject_failure: bool) -> int:
        """The BIST register's read-only bits; ``inject_failure`` makes a finished test fail."""
        rdy = fail = 0
        if self.start_ns is not None and now_ns - self.start_ns >= choice.BIST_TIME_NS:
            rdy, fail = 1, int(inject_failure)
        return _RATE_OK.insert(_BIST_FAIL.insert(_BIST_RDY.insert(0, rdy), fail), rate_ok)


_NVM_REMAIN = field_of("TRIM_NVM_CTRL", "nvm_remain")
_NVM_RDY = field_of("TRIM_NVM_CTRL", "nvm_rdy")
_NVM_PROG_MODE = field_of("TRIM_NVM_CTRL", "nvm_prog_mode")
NVM_MAX_REMAIN = _NVM_REMAIN.mask >> _NVM_REMAIN.lsb  # 15: what the 4-bit counter holds
_TRIM_NVM_CTRL = address_of("TRIM_NVM_CTRL")


class Nvm:
    """The NVM image of the NVM-backed registers, its cycles left and its busy time (6.10)."""

    def __init__(self, image: bytes, remain: int) -> None:
        if len(image) != len(NVM_ADDRESSES):
            raise ValueError(f"nvm_image must be {len(NVM_ADDRESSES)} bytes "
                             f"(0x{NVM_ADDRESSES[0]:02X}..0x{NVM_ADDRESSES[-1]:02X})")
        if not 0 <= remain <= NVM_MAX_REMAIN:
            raise ValueError(f"nvm_remain must be 0..{NVM_MAX_REMAIN}")
        self.image = bytearray(image)
        self.remain = remain
        self.busy_until_ns = -1

    def ready(self, now_ns: int) -> bool:
        return now_ns >= self.busy_until_ns

    def load_into(self, regs: bytearray) -> None:
        for i, address in enumerate(NVM_ADDRESSES):
            regs[address] = self.image[i]

    def program(self, regs: bytearray, now_ns: int) -> bool:
        """nvm_prog_trig: store the registers if unlocked, ready and cycles are left."""
        unlocked = regs[_TRIM_NVM_CTRL] & _NVM_PROG_MODE.mask
        if not (self.ready(now_ns) and unlocked and self.remain > 0):
            return False
        self.image[:] = bytes(regs[a] for a in NVM_ADDRESSES)
        self.remain -= 1
        self.busy_until_ns = now_ns + choice.NVM_PROG_TIME_NS
        return True

    def register(self, stored: int, now_ns: int) -> int:
        """TRIM_NVM_CTRL as read: cycles left, ready, and the stored nvm_prog_mode."""
        value = _NVM_REMAIN.insert(0, self.remain)
        value = _NVM_RDY.insert(value, self.ready(now_ns))
        return value | stored & _NVM_PROG_MODE.mask


_TEMP = field_of("TEMP", "temp")


class Thermometer:
    """The TEMP register (5.2): one conversion per rate sample, frozen while not sampling."""

    def __init__(self, temperature_c: float | Callable[[float], float]) -> None:
        self.temperature_c = temperature_c
        self.frozen: tuple[int, int] | None = None  # (raw, last sample ns) when stopped

    @staticmethod
    def check(temperature_c: float | Callable[[float], float]) -> None:
        if not callable(temperature_c) and not math.isfinite(float(temperature_c)):
            raise ValueError("temperature must be finite")

    def raw(self, have_sample: bool, last_sample_ns: int) -> int:
        """The register byte: the conversion of the last sample, 0 before the first."""
        if not have_sample:
            return 0
        frozen = self.frozen
        if frozen is not None and last_sample_ns <= frozen[1]:
            return frozen[0]
        temp = self.temperature_c
        if callable(temp):
            temp = float(temp(last_sample_ns / NS_PER_S))
        raw = round((temp - choice.TEMP_ZERO_C) / choice.TEMP_LSB_K)
        return _TEMP.insert(0, max(-128, min(127, raw)))  # two's complement byte

    def freeze(self, have_sample: bool, last_sample_ns: int) -> None:
        self.frozen = (self.raw(have_sample, last_sample_ns), last_sample_ns)


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
