"""What each register does beyond being stored, keyed by its spec name (Zephyr's register-map
emulator idea: the table in ``registers.py`` is the data, only leftover behaviour lives here).

Three kinds of hook, each a function of ``s``, the chip's state (``state.ChipState``: the
hooks see the chip only through it):

- ``PEEK[name](s, now_ns) -> byte``: the content of a register the chip computes (status,
  counters, FIFO head); a register without one reads as stored. Reads and dumps use it.
- ``ACTIONS[name](s, value, now_ns)``: what a bus *write* does beyond storing (triggers,
  soft reset, emptying the FIFO). An upset (``poke``) does not trigger them.
- ``EFFECTS[name](s, old, new, now_ns)``: what follows from the stored content changing
  (data path, schedule, engines). Bus writes and ``poke`` share them: one table, so an upset
  and a write that leave the same content leave the same s. A write runs its action first
  and the effect of the content after (a FIFO configuration write empties the FIFO, then the
  FIFO interrupt is evaluated for the new configuration).

Decisions where the spec leaves room (documented in docs/device-model.md):

- RANGE acts on the data only through the sensitivity of its range code (4.8: bits 7:3 have no
  effect, codes 5..7 produce data as +-2000 deg/s), so computed-ahead samples are dropped
  only when the sensitivity changes.
- The offsets are the 12-bit fields of OFC1..OFC4 and TRIM_GP0[3:0] (4.24); gp0 (TRIM_GP0[7:4])
  and TRIM_GP1 are general-purpose bits with no effect on the output, so only a change of an
  offset bit drops computed-ahead samples.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from bmg160_emu.clock import NEVER
from bmg160_emu.device import fifo as fifo_mod
from bmg160_emu.device import offsets
from bmg160_emu.device import spec_choices as choice
from bmg160_emu.device.interrupts import LATCHED, latch_hold_ns
from bmg160_emu.device.offsets import FastOffset
from bmg160_emu.device.power_modes import (
    DEEP_SUSPEND,
    FAST_POWER_UP,
    SAMPLING_MODES,
    SUSPEND,
    power_mode,
)
from bmg160_emu.device.registers import REGISTERS, address_of, field_of, offset_mask
from bmg160_emu.device.spec_choices import bw_code, range_code
from bmg160_emu.device.state import ChipState

SOFTRESET_KEY = 0xB6  # 4.13: the one BGW_SOFTRESET value that resets

_LPM1, _LPM2 = address_of("LPM1"), address_of("LPM2")
_A_FOC, _TRIM_NVM_CTRL = address_of("A_FOC"), address_of("TRIM_NVM_CTRL")
_ANY_TH, _INT_EN_0, _INT_RST_LATCH = (
    address_of("ANY_TH"), address_of("INT_EN_0"), address_of("INT_RST_LATCH"))
_FIFO_WM_EN, _FIFO_CONFIG_0, _FIFO_CONFIG_1 = (
    address_of("FIFO_WM_EN"), address_of("FIFO_CONFIG_0"), address_of("FIFO_CONFIG_1"))
_FIFO_EN = field_of("INT_EN_0", "fifo_en").mask
_INT_EN_1 = address_of("INT_EN_1")
_INT_MAP_0, _INT_MAP_1, _INT_MAP_2 = (
    address_of("INT_MAP_0"), address_of("INT_MAP_1"), address_of("INT_MAP_2"))
_INT_LVL = (field_of("INT_EN_1", "int1_lvl").mask, field_of("INT_EN_1", "int2_lvl").mask)
_FIFO_WM = field_of("FIFO_WM_EN", "fifo_wm_en").mask
_FIFO_TAG = field_of("FIFO_CONFIG_0", "tag").mask
_FIFO_WATERMARK = field_of("FIFO_CONFIG_0", "fifo_water_mark_level_trigger_retain")
_FIFO_SELECT = field_of("FIFO_CONFIG_1", "fifo_data_select")
_DATA_HIGH_BW = field_of("RATE_HBW", "data_high_bw").mask
_SHADOW_DIS = field_of("RATE_HBW", "shadow_dis").mask
_DATA_EN = field_of("INT_EN_0", "data_en").mask
_RESET_INT = field_of("INT_RST_LATCH", "reset_int").mask
_OFFSET_RESET = field_of("INT_RST_LATCH", "offset_reset").mask
_FAST_OFFSET_EN = field_of("A_FOC", "fast_offset_en").mask
_NVM_LOAD = field_of("TRIM_NVM_CTRL", "nvm_load").mask
_NVM_PROG_TRIG = field_of("TRIM_NVM_CTRL", "nvm_prog_trig").mask
_TRIG_BIST = field_of("BIST", "trig_bist").mask
_FIFO_OVERRUN = field_of("FIFO_STATUS", "fifo_overrun").lsb
_FOC_RUNNING = field_of("A_FOC", "fast_offset_en").mask


# ------------------------------------------------------------------------------- reads


def _peek_int_status_0(s: ChipState, now: int) -> int:
    return s.irq.status_0(s.regs, now)


def _peek_int_status_1(s: ChipState, now: int) -> int:
    return s.irq.status_1(s.regs, now, data_int(s, now))


def _peek_fifo_status(s: ChipState, now: int) -> int:
    count = fifo_count(s)
    return s.fifo.overrun << _FIFO_OVERRUN | count


def _peek_bist(s: ChipState, now: int) -> int:
    rate_ok = s.power_mode in SAMPLING_MODES and now >= s.data_start_ns
    return s.bist.register(now, rate_ok, s.chip.inject_bist_failure)


def _peek_fifo_data(s: ChipState, now: int) -> int:
    sync_bypass(s)
    axis, tag = frame_format(s)
    return s.fifo.peek(axis.stop - axis.start, bool(tag))


PEEK: dict[str, Callable[[ChipState, int], int]] = {
    "TEMP": lambda s, now: s.thermometer.raw(s.have_sample, s.last_sample_ns),
    "INT_STATUS_0": _peek_int_status_0,
    "INT_STATUS_1": _peek_int_status_1,
    "INT_STATUS_2": lambda s, now: s.irq.int_status_2,
    "INT_STATUS_3": lambda s, now: s.irq.int_status_3,
    "FIFO_STATUS": _peek_fifo_status,
    "A_FOC": lambda s, now: s.regs[_A_FOC] | (_FOC_RUNNING if s.foc else 0),
    "TRIM_NVM_CTRL": lambda s, now: s.nvm.register(s.regs[_TRIM_NVM_CTRL], now),
    "BIST": _peek_bist,
    "FIFO_DATA": _peek_fifo_data,
}

# ------------------------------------------------------------------------------ writes


def _softreset(s: ChipState, value: int, now: int) -> None:
    if value == SOFTRESET_KEY:
        s.reset(now, powered=False)


def _int_rst_latch(s: ChipState, value: int, now: int) -> None:
    if value & _RESET_INT:
        s.irq.reset_int()
    if value & _OFFSET_RESET:
        offsets.set_offsets(s.regs, (0, 0, 0))
        s.invalidate()


def _a_foc(s: ChipState, value: int, now: int) -> None:
    if value & _FAST_OFFSET_EN:
        start_foc(s)


def _nvm_command(s: ChipState, value: int, now: int) -> None:
    if value & _NVM_LOAD:
        if s.nvm.ready(now):
            s.nvm.load_into(s.regs)
            s.invalidate()
        else:
            s.strict_warning("nvm_load while NVM busy ignored (6.10)")
    if value & _NVM_PROG_TRIG and not s.nvm.program(s.regs, now):
        s.strict_warning("nvm_prog_trig ignored: needs nvm_prog_mode, nvm_rdy and cycles")


def _bist(s: ChipState, value: int, now: int) -> None:
    if value & _TRIG_BIST:
        s.bist.trigger(now)


def _empty_fifo(overrun: bool) -> Callable[[ChipState, int, int], None]:
    def action(s: ChipState, value: int, now: int) -> None:
        s.fifo.clear(overrun=overrun)  # 4.26: any write empties it
        s.bypass_seq = s.sample_seq

    return action


ACTIONS: dict[str, Callable[[ChipState, int, int], None]] = {
    "BGW_SOFTRESET": _softreset,
    "INT_RST_LATCH": _int_rst_latch,
    "A_FOC": _a_foc,
    "TRIM_NVM_CTRL": _nvm_command,
    "BIST": _bist,
    "FIFO_CONFIG_0": _empty_fifo(overrun=False),
    "FIFO_CONFIG_1": _empty_fifo(overrun=True),
}

# ----------------------------------------------------------------------------- effects


def _range(s: ChipState, old: int, new: int, now: int) -> None:
    if s.sensitivity_table[range_code(old)] != s.sensitivity_table[range_code(new)]:
        s.invalidate()


def _bw(s: ChipState, old: int, new: int, now: int) -> None:
    if bw_code(old) != bw_code(new):
        change_bandwidth(s)


def _lpm(s: ChipState, old: int, new: int, now: int, *, lpm1: bool) -> None:
    r = s.regs
    old_mode = power_mode(old, r[_LPM2]) if lpm1 else power_mode(r[_LPM1], old)
    power_transition(s, old_mode, _LPM1 if lpm1 else _LPM2, new, now)


def _rate_hbw(s: ChipState, old: int, new: int, now: int) -> None:
    if (old ^ new) & _DATA_HIGH_BW:
        s.invalidate()
    if new & _SHADOW_DIS:
        s.msb_latch = [None, None, None]
        s.latched = False


def _offsets(address: int) -> Callable[[ChipState, int, int, int], None]:
    mask = offset_mask(address)

    def effect(s: ChipState, old: int, new: int, now: int) -> None:
        if (old ^ new) & mask:
            s.invalidate()

    return effect


def _int_en_0(s: ChipState, old: int, new: int, now: int) -> None:
    if new & ~old & _DATA_EN:
        # 6.3: data_int is set only by samples taken while data_en = 1, so a held
        # data_int (hold_data_int) starts from the first sample after enabling
        s.data_ready_pending = False
    engine_config_changed(s, now)


def _engines(s: ChipState, old: int, new: int, now: int) -> None:
    engine_config_changed(s, now)


def _fifo_config(s: ChipState, old: int, new: int, now: int) -> None:
    s.update_engine_flags()
    update_fifo_int(s, now)


EFFECTS: dict[str, Callable[[ChipState, int, int, int], None]] = {
    "RANGE": _range,
    "BW": _bw,
    "LPM1": lambda s, old, new, now: _lpm(s, old, new, now, lpm1=True),
    "LPM2": lambda s, old, new, now: _lpm(s, old, new, now, lpm1=False),
    "RATE_HBW": _rate_hbw,
    **{reg.name: _offsets(reg.address) for reg in REGISTERS if offset_mask(reg.address)},
    "INT_EN_0": _int_en_0,
    "ANY_EN": _engines,
    "HIGH_TH_X": _engines,
    "HIGH_TH_Y": _engines,
    "HIGH_TH_Z": _engines,
    "FIFO_WM_EN": _engines,
    "FIFO_CONFIG_0": _fifo_config,
    "FIFO_CONFIG_1": _fifo_config,
}


# ------------------------------------------------------------- behaviour behind the hooks


def power_transition(s: ChipState, old_mode: str, addr: int, value: int, now: int) -> None:
    """LPM1/LPM2 changed (6.7): stop or start sampling; leaving deep suspend is a reset."""
    new_mode = s.power_mode
    if {old_mode, new_mode} in ({SUSPEND, DEEP_SUSPEND}, {FAST_POWER_UP, DEEP_SUSPEND}):
        s.strict_warning(f"direct switch {old_mode} -> {new_mode} (spec 6.7)")
    if old_mode == new_mode:
        return
    if old_mode == DEEP_SUSPEND and choice.LEAVING_DEEP_SUSPEND_RESETS:
        s.reset(now, powered=False)
        if addr == _LPM1:  # the write that woke the chip is stored on the reset map
            mask = s.part.write_masks[_LPM1]
            s.regs[_LPM1] = (s.regs[_LPM1] & ~mask) | (value & mask)
        if s.power_mode not in SAMPLING_MODES:
            s.stop_sampling()
        return
    was, now_sampling = old_mode in SAMPLING_MODES, new_mode in SAMPLING_MODES
    if was and not now_sampling:
        s.stop_sampling()
    elif now_sampling and not was:
        wake = choice.FAST_POWER_UP_WAKE_NS if old_mode == FAST_POWER_UP else s.startup_ns
        s.start_sampling(now + wake)


def change_bandwidth(s: ChipState) -> None:
    """A new BW code: new filter from the last output, next sample one new period on."""
    s.invalidate()
    old_odr = s.odr
    s.set_filter(running=True)
    if s.odr != old_odr and s.next_ns < NEVER:
        # next sample one new period after the last one (or the pending first one)
        if s.have_sample and s.last_sample_ns >= s.data_start_ns:
            s.next_ns = s.last_sample_ns + s.period_ns
        s.anchor_ns, s.anchor_k = s.next_ns, s.k + 1


def frame_format(s: ChipState) -> tuple[slice, bytes]:
    """The FIFO frame: the selected axes and the tag bytes if on (4.26)."""
    tag = b""
    if s.regs[_FIFO_CONFIG_0] & _FIFO_TAG:
        tag = choice.fifo_tag_bytes(*pins(s, s.chip.clock.now_ns()))
    return _FRAME_AXES[s.regs[_FIFO_CONFIG_1]], tag


# the selected axes by FIFO_CONFIG_1 byte (frame_format runs for every sample stored)
_FRAME_AXES = tuple(fifo_mod.AXIS_SLICES[_FIFO_SELECT.extract(byte)] for byte in range(256))


def sync_bypass(s: ChipState) -> None:
    """Bypass mode holds the newest sample only (6.5): put it there when read."""
    if s.fifo_mode == fifo_mod.BYPASS and s.have_sample and s.bypass_seq != s.sample_seq:
        axis, tag = frame_format(s)
        s.fifo.replace(s.cur[axis] + tag)
        s.bypass_seq = s.sample_seq


def fifo_count(s: ChipState) -> int:
    sync_bypass(s)
    return s.fifo.count


def update_fifo_int(s: ChipState, now: int) -> None:
    """fifo_int: at the watermark, or at 100 frames without one (6.5, spec_choices)."""
    r = s.regs
    if r[_INT_EN_0] & _FIFO_EN:
        count = fifo_count(s)
        if r[_FIFO_WM_EN] & _FIFO_WM:
            condition = count >= max(_FIFO_WATERMARK.extract(r[_FIFO_CONFIG_0]), 1)
        else:
            condition = count >= s.fifo.capacity
    else:
        condition = False
    s.irq.status["fifo"].update(condition, now, latch_hold_ns(r[_INT_RST_LATCH]))


def start_foc(s: ChipState) -> None:
    """fast_offset_en written (6.9): average from the next sample on."""
    s.irq.offset_started()
    s.foc = FastOffset(s.regs[_A_FOC], s.regs[_ANY_TH])
    s.update_engine_flags()


def engine_config_changed(s: ChipState, now: int) -> None:
    """An interrupt engine register changed: engines, flags and fifo_int follow."""
    s.irq.reconfigure(s.regs, now)
    s.update_engine_flags()
    update_fifo_int(s, now)


def finish_foc(s: ChipState) -> None:
    """The FOC average is complete: offsets written, fast_offset_int raised (6.9)."""
    foc, s.foc = s.foc, None
    if foc is None:
        return
    offsets.set_offsets(s.regs, foc.offsets_lsb(s.offset_lsb_dps, offsets.OFFSET_BITS))
    s.invalidate()
    s.irq.offset_done()
    s.update_engine_flags()


def data_int(s: ChipState, now: int) -> bool:
    """data_int (6.3): a pulse after each new sample, or held until read (hold_data_int)."""
    if not (s.regs[_INT_EN_0] & _DATA_EN and s.have_sample):
        return False
    if s.chip.hold_data_int:
        return s.data_ready_pending
    return now - s.last_sample_ns < choice.DATA_READY_PULSE_NS


def pins(s: ChipState, now: int) -> tuple[bool, bool]:
    """(INT1, INT2) asserted."""
    return s.irq.pins(s.regs, now, data_int(s, now))


def pin_level(s: ChipState, pin: int, now: int) -> int:
    """Electrical level 0/1 of INT1 or INT2 for a push-pull output (INT_EN_1 lvl bit)."""
    if pin not in (1, 2):
        raise ValueError("pin must be 1 or 2")
    active = pins(s, now)[pin - 1]
    active_high = bool(s.regs[_INT_EN_1] & _INT_LVL[pin - 1])
    return int(active == active_high)


def next_pin_change(s: ChipState, now: int) -> int | None:
    """The earliest time after ``now`` (ns) at which INT1 or INT2 may change with no bus
    access: the next sample (every engine acts on samples), the end of a data-ready pulse
    under way or of a temporary latch; None when no source is mapped to a pin or nothing is
    due. A simulator sleeps until then instead of polling the pins (bmg160-emu serve)."""
    if not (s.regs[_INT_MAP_0] | s.regs[_INT_MAP_1] | s.regs[_INT_MAP_2]):
        return None
    due = [s.next_ns] if s.next_ns != NEVER else []
    pulse_end = s.last_sample_ns + choice.DATA_READY_PULSE_NS
    if not s.chip.hold_data_int and pulse_end > now:
        due.append(pulse_end)
    due += [h for st in s.irq.status.values() if now < (h := st.hold_until_ns) < LATCHED]
    return min(due, default=None)


def _by_address(table: dict[str, Any]) -> tuple[Any, ...]:
    unknown = set(table) - {r.name for r in REGISTERS}
    if unknown:
        raise KeyError(f"regmap names registers the table does not have: {sorted(unknown)}")
    return tuple(table.get(r.name) for r in REGISTERS)


# Indexed by address, for the model's hot paths.
PEEK_AT = _by_address(PEEK)
ACTION_AT = _by_address(ACTIONS)
EFFECT_AT = _by_address(EFFECTS)
