"""Interrupt statuses with the chip's latch modes, and the any-motion and high-rate engines.

Spec 6.3 (statuses, latching, pins) and 6.4 (engine models, unconfirmed in detail).
"""

from __future__ import annotations

from bmg160_emu.device import spec_choices

LATCHED = 1 << 62  # "held until reset_int", as a time in ns no clock reaches

# 4.19: latch_int code -> hold time after the condition ends, in ns (0 = non-latched).
_LATCH_HOLD_NS = {
    0x0: 0, 0x8: 0, 0x7: LATCHED, 0xF: LATCHED,
    0x1: 250_000_000, 0x2: 500_000_000, 0x3: 1_000_000_000, 0x4: 2_000_000_000,
    0x5: 4_000_000_000, 0x6: 8_000_000_000,
    0x9: 250_000, 0xA: 500_000, 0xB: 1_000_000, 0xC: 12_500_000, 0xD: 25_000_000,
    0xE: 50_000_000,
}


def latch_hold_ns(latch_int: int) -> int:
    """How long a status stays set after its condition ends, for a latch_int code."""
    return _LATCH_HOLD_NS[latch_int & 0xF]


class InterruptStatus:
    """One interrupt source: its live condition plus what the latch mode holds."""

    __slots__ = ("condition", "hold_until_ns", "seen")

    def __init__(self) -> None:
        self.condition = False
        self.hold_until_ns = -1
        self.seen = False  # set since the last reset_int (for latch_status_bits)

    def update(self, condition: bool, now_ns: int, hold_ns: int) -> None:
        if condition:
            if not self.condition:
                self.seen = True
            self.condition = True
            if hold_ns == LATCHED:
                self.hold_until_ns = LATCHED
        elif self.condition:
            self.condition = False
            if hold_ns == LATCHED:
                self.hold_until_ns = LATCHED
            elif hold_ns > 0:
                self.hold_until_ns = now_ns + hold_ns

    def pin_active(self, now_ns: int) -> bool:
        return self.condition or now_ns < self.hold_until_ns

    def status(self, now_ns: int, latch_status_bits: bool) -> bool:
        return self.pin_active(now_ns) or (latch_status_bits and self.seen)

    def reset_latch(self) -> None:
        """reset_int: forget what the latch holds; a live condition stays."""
        self.hold_until_ns = -1
        self.seen = self.condition

    def clear(self) -> None:
        self.condition = False
        self.hold_until_ns = -1
        self.seen = False


def _sign_bit(value: float) -> int:
    negative = value < 0
    return int(negative if spec_choices.SIGN_BIT_MEANS_NEGATIVE else not negative)


class AnyMotion:
    """Slope detector: |slope| > threshold for N consecutive points sets, N below clears."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.active = False
        self.last: tuple[int, int, int] | None = None
        self.phase = 0
        self.over = [0, 0, 0]
        self.under = [0, 0, 0]
        self.first_axis = 0
        self.sign = 0

    def step(self, counts: tuple[int, int, int], axes: int, threshold: int, n: int,
             decimation: int) -> bool:
        """Feed one output sample; return True when the interrupt condition just rose."""
        self.phase += 1
        if self.phase < decimation:
            return False
        self.phase = 0
        last, self.last = self.last, counts
        if last is None:
            return False
        rose = False
        for axis in range(3):
            if not axes >> axis & 1:
                continue
            slope = counts[axis] - last[axis]
            if abs(slope) > threshold:
                self.over[axis] += 1
                self.under[axis] = 0
                if not self.active and self.over[axis] >= n:
                    self.active, rose = True, True
                    self.first_axis, self.sign = axis, _sign_bit(slope)
            else:
                self.under[axis] += 1
                self.over[axis] = 0
        if self.active and not rose and all(
            self.under[a] >= n for a in range(3) if axes >> a & 1
        ):
            self.active = False
        return rose

    def status_byte(self) -> int:
        """INT_STATUS_2 bits: any_sign (3), any_first_z/y/x (2..0)."""
        return self.sign << 3 | 1 << self.first_axis


class HighRate:
    """|rate| above threshold for the duration sets; below threshold - hysteresis clears."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.active = False
        self.axis_active = [False, False, False]
        self.over = [0, 0, 0]
        self.first_axis = 0
        self.sign = 0

    def step(self, counts: tuple[int, int, int], axes: int, thresholds: list[int],
             hystereses: list[int], durations: list[int]) -> bool:
        rose = False
        for axis in range(3):
            if not axes >> axis & 1:
                self.axis_active[axis] = False
                self.over[axis] = 0
                continue
            magnitude = abs(counts[axis])
            if not self.axis_active[axis]:
                if magnitude > thresholds[axis]:
                    self.over[axis] += 1
                    if self.over[axis] >= durations[axis]:
                        self.axis_active[axis] = True
                        if not self.active:
                            rose = True
                            self.first_axis, self.sign = axis, _sign_bit(counts[axis])
                else:
                    self.over[axis] = 0
            elif magnitude < thresholds[axis] - hystereses[axis]:
                self.axis_active[axis] = False
                self.over[axis] = 0
        self.active = any(self.axis_active)
        return rose

    def status_byte(self) -> int:
        """INT_STATUS_3 bits: high_sign (3), high_first_z/y/x (2..0)."""
        return self.sign << 3 | 1 << self.first_axis
