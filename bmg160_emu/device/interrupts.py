"""Interrupt statuses with the chip's latch modes, and the any-motion and high-rate engines.

Spec 6.3 (statuses, latching, pins) and 6.4 (engine models, unconfirmed in detail).
"""

from __future__ import annotations

from bmg160_emu.device import spec_choices
from bmg160_emu.device.registers import address_of, field_of

LATCHED = 1 << 62  # "held until reset_int", as a time in ns no clock reaches

# 4.19: latch_int code -> hold time after the condition ends, in ns (0 = non-latched).
_LATCH_HOLD_NS = {
    0x0: 0, 0x8: 0, 0x7: LATCHED, 0xF: LATCHED,
    0x1: 250_000_000, 0x2: 500_000_000, 0x3: 1_000_000_000, 0x4: 2_000_000_000,
    0x5: 4_000_000_000, 0x6: 8_000_000_000,
    0x9: 250_000, 0xA: 500_000, 0xB: 1_000_000, 0xC: 12_500_000, 0xD: 25_000_000,
    0xE: 50_000_000,
}


_LATCH_INT = field_of("INT_RST_LATCH", "latch_int")


def latch_hold_ns(int_rst_latch: int) -> int:
    """How long a status stays set after its condition ends, for an INT_RST_LATCH byte."""
    return _LATCH_HOLD_NS[_LATCH_INT.extract(int_rst_latch)]


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


# ---------------------------------------------------------------- the chip's interrupt block

SOURCES = ("any", "high", "fifo", "fast_offset", "auto_offset")  # latched statuses (6.3)
_INT_RST_LATCH = address_of("INT_RST_LATCH")
_INT_DATA_SRC = address_of("INT_DATA_SRC")
_ANY_UNFILT = field_of("INT_DATA_SRC", "any_unfilt_data").mask
_HIGH_UNFILT = field_of("INT_DATA_SRC", "high_unfilt_data").mask
_ANY_TH_REG, _ANY_EN_REG = address_of("ANY_TH"), address_of("ANY_EN")
_ANY_TH = field_of("ANY_TH", "any_th")
_ANY_DURSAMPLE = field_of("ANY_EN", "any_dursample")
_ANY_AXES = tuple(field_of("ANY_EN", f"any_en_{axis}").mask for axis in "xyz")
# per axis: (HIGH_TH address, high_th, high_hy, high_en, HIGH_DUR address, high_dur)
_HIGH_AXES = tuple(
    (address_of(f"HIGH_TH_{axis.upper()}"), field_of(f"HIGH_TH_{axis.upper()}", f"high_th_{axis}"),
     field_of(f"HIGH_TH_{axis.upper()}", f"high_hy_{axis}"),
     field_of(f"HIGH_TH_{axis.upper()}", f"high_en_{axis}").mask,
     address_of(f"HIGH_DUR_{axis.upper()}"),
     field_of(f"HIGH_DUR_{axis.upper()}", f"high_dur_{axis}"))
    for axis in "xyz")
# source -> the (register, bit) mapping it to INT1 and to INT2 (4.16)
_MAP = {
    source: tuple((address_of(reg), field_of(reg, f"{pin}_{name}").mask) for pin, reg in regs)
    for source, name, regs in (
        ("high", "high", (("int1", "INT_MAP_0"), ("int2", "INT_MAP_2"))),
        ("any", "any", (("int1", "INT_MAP_0"), ("int2", "INT_MAP_2"))),
        ("data", "data", (("int1", "INT_MAP_1"), ("int2", "INT_MAP_1"))),
        ("fast_offset", "fast_offset", (("int1", "INT_MAP_1"), ("int2", "INT_MAP_1"))),
        ("fifo", "fifo", (("int1", "INT_MAP_1"), ("int2", "INT_MAP_1"))),
        ("auto_offset", "auto_offset", (("int1", "INT_MAP_1"), ("int2", "INT_MAP_1"))),
    )
}
_LATCH_STATUS_BITS = field_of("INT_RST_LATCH", "latch_status_bits").mask
_STATUS_0 = tuple((source, field_of("INT_STATUS_0", f"{source}_int").lsb) for source in ("any", "high"))
_STATUS_1 = tuple((source, field_of("INT_STATUS_1", f"{source}_int").lsb)
                  for source in ("auto_offset", "fast_offset", "fifo"))
_DATA_INT_LSB = field_of("INT_STATUS_1", "data_int").lsb


class Interrupts:
    """The statuses, the any-motion and high-rate engines and what they report (6.3, 6.4)."""

    def __init__(self) -> None:
        self.status = {name: InterruptStatus() for name in SOURCES}
        self.any = AnyMotion()
        self.high = HighRate()
        self.int_status_2 = 0  # any-motion axis and sign (4.6)
        self.int_status_3 = 0  # high-rate axis and sign
        self.any_axes = 0  # bit per axis: engine enabled
        self.high_axes = 0

    def configure(self, regs: bytearray) -> None:
        any_en = regs[_ANY_EN_REG]
        self.any_axes = sum(1 << axis for axis, mask in enumerate(_ANY_AXES) if any_en & mask)
        self.high_axes = sum(1 << axis for axis, (th, _, _, en, _, _) in enumerate(_HIGH_AXES)
                             if regs[th] & en)

    def reconfigure(self, regs: bytearray, now_ns: int) -> None:
        """An engine register was written: an engine switched on starts afresh, one
        switched off also drops its condition."""
        had_any, had_high = self.any_axes, self.high_axes
        self.configure(regs)
        hold = latch_hold_ns(regs[_INT_RST_LATCH])
        if not self.any_axes and had_any:
            self.any.reset()
            self.status["any"].update(False, now_ns, hold)
        elif self.any_axes and not had_any:
            self.any.reset()
        if not self.high_axes and had_high:
            self.high.reset()
            self.status["high"].update(False, now_ns, hold)
        elif self.high_axes and not had_high:
            self.high.reset()

    def step(self, regs: bytearray, counts_f, counts_u, odr_hz: int, t_ns: int) -> None:
        """Feed one output sample (counts filtered / unfiltered) to the enabled engines."""
        hold = latch_hold_ns(regs[_INT_RST_LATCH])
        if self.any_axes:
            src = counts_u if regs[_INT_DATA_SRC] & _ANY_UNFILT else counts_f
            rose = self.any.step(
                (int(src[0]), int(src[1]), int(src[2])), self.any_axes,
                (1 + _ANY_TH.extract(regs[_ANY_TH_REG])) * 16,  # 4.17: (1 + any_th) * 16 LSB
                4 * (_ANY_DURSAMPLE.extract(regs[_ANY_EN_REG]) + 1),  # 4, 8, 12, 16 samples
                -(-odr_hz // spec_choices.ANY_MOTION_MAX_RATE_HZ))
            if rose:
                self.int_status_2 = self.any.status_byte()
            self.status["any"].update(self.any.active, t_ns, hold)
        if self.high_axes:
            src = counts_u if regs[_INT_DATA_SRC] & _HIGH_UNFILT else counts_f
            ths, hys, durs = [], [], []
            for th_reg, th, hy, _, dur_reg, dur in _HIGH_AXES:  # 4.20
                ths.append((255 + 256 * th.extract(regs[th_reg])) * 4)
                hys.append((255 + 256 * hy.extract(regs[th_reg])) * 4)
                durs.append(-(-(1 + dur.extract(regs[dur_reg])) * 25 * odr_hz // 10000))
            rose = self.high.step((int(src[0]), int(src[1]), int(src[2])), self.high_axes,
                                  ths, hys, durs)
            if rose:
                self.int_status_3 = self.high.status_byte()
            self.status["high"].update(self.high.active, t_ns, hold)

    def offset_done(self) -> None:
        """Fast offset compensation finished: an event, held until reset_int (spec_choices)."""
        st = self.status["fast_offset"]
        st.condition, st.seen = True, True

    def offset_started(self) -> None:
        st = self.status["fast_offset"]
        st.condition = st.seen = False

    def reset_int(self) -> None:
        """reset_int (4.19): latches forgotten; a live condition stays."""
        for st in self.status.values():
            st.reset_latch()
        self.offset_started()
        self.int_status_2 = self.any.status_byte() if self.any.active else 0
        self.int_status_3 = self.high.status_byte() if self.high.active else 0

    def pins(self, regs: bytearray, now_ns: int, data_int: bool) -> tuple[bool, bool]:
        """(INT1, INT2) asserted: any mapped source active (4.16)."""
        int1 = int2 = False
        for source, ((reg1, bit1), (reg2, bit2)) in _MAP.items():
            active = data_int if source == "data" else self.status[source].pin_active(now_ns)
            if active:
                int1 = int1 or bool(regs[reg1] & bit1)
                int2 = int2 or bool(regs[reg2] & bit2)
        return int1, int2

    def status_0(self, regs: bytearray, now_ns: int) -> int:
        """INT_STATUS_0 (4.4)."""
        held = bool(regs[_INT_RST_LATCH] & _LATCH_STATUS_BITS)
        return sum(self.status[s].status(now_ns, held) << lsb for s, lsb in _STATUS_0)

    def status_1(self, regs: bytearray, now_ns: int, data_int: bool) -> int:
        """INT_STATUS_1 (4.5)."""
        held = bool(regs[_INT_RST_LATCH] & _LATCH_STATUS_BITS)
        return (data_int << _DATA_INT_LSB
                | sum(self.status[s].status(now_ns, held) << lsb for s, lsb in _STATUS_1))
