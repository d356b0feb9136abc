"""What each register does beyond being stored, keyed by its spec name (Zephyr's register-map
emulator idea: the table in ``registers.py`` is the data, only leftover behaviour lives here).

Three kinds of hook, each a function of the chip:

- ``PEEK[name](chip, now_ns) -> byte``: the content of a register the chip computes (status,
  counters, FIFO head); a register without one reads as stored. Reads and dumps use it.
- ``ACTIONS[name](chip, value, now_ns)``: what a bus *write* does beyond storing (triggers,
  soft reset, emptying the FIFO). An upset (``poke``) does not trigger them.
- ``EFFECTS[name](chip, old, new, now_ns)``: what follows from the stored content changing
  (data path, schedule, engines). Bus writes and ``poke`` share them: one table, so an upset
  and a write that leave the same content leave the same chip. A write runs its action first
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
from typing import TYPE_CHECKING, Any

from bmg160_emu.device import engines
from bmg160_emu.device import fifo as fifo_mod
from bmg160_emu.device import spec_choices as choice
from bmg160_emu.device.engines import (
    DEEP_SUSPEND,
    FAST_POWER_UP,
    NEVER,
    SAMPLING_MODES,
    SUSPEND,
    FastOffset,
)
from bmg160_emu.device.interrupts import latch_hold_ns
from bmg160_emu.device.registers import REGISTERS, address_of, field_of, offset_mask

if TYPE_CHECKING:
    from bmg160_emu.device.chip import BMG160

SOFTRESET_KEY = 0xB6  # 4.13: the one BGW_SOFTRESET value that resets

_LPM1, _LPM2, _BW = address_of("LPM1"), address_of("LPM2"), address_of("BW")
_A_FOC, _TRIM_NVM_CTRL = address_of("A_FOC"), address_of("TRIM_NVM_CTRL")
_ANY_TH, _INT_EN_0, _INT_RST_LATCH = (
    address_of("ANY_TH"), address_of("INT_EN_0"), address_of("INT_RST_LATCH"))
_FIFO_WM_EN, _FIFO_CONFIG_0, _FIFO_CONFIG_1 = (
    address_of("FIFO_WM_EN"), address_of("FIFO_CONFIG_0"), address_of("FIFO_CONFIG_1"))
_FIFO_EN = field_of("INT_EN_0", "fifo_en").mask
_INT_EN_1 = address_of("INT_EN_1")
_INT_LVL = (field_of("INT_EN_1", "int1_lvl").mask, field_of("INT_EN_1", "int2_lvl").mask)
_FIFO_WM = field_of("FIFO_WM_EN", "fifo_wm_en").mask
_FIFO_TAG = field_of("FIFO_CONFIG_0", "tag").mask
_FIFO_WATERMARK = field_of("FIFO_CONFIG_0", "fifo_water_mark_level_trigger_retain")
_FIFO_SELECT = field_of("FIFO_CONFIG_1", "fifo_data_select")
_FIFO_MODE = field_of("FIFO_CONFIG_1", "fifo_mode")
_FIFO_MODE_RESERVED = 3  # 4.26: fifo_mode 3 is reserved
_RANGE_CODE = field_of("RANGE", "range")
_BW_CODE = field_of("BW", "bw")
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


def bw_code(bw: int) -> int:
    """The BW code a BW byte behaves as: codes 8..15 as code & 7 (4.9, unconfirmed)."""
    return _BW_CODE.extract(bw) % len(choice.BANDWIDTHS)


def bandwidth(bw: int) -> tuple[int, float]:
    """(ODR Hz, filter bandwidth Hz) of a BW byte (5.3)."""
    return choice.BANDWIDTHS[bw_code(bw)]


def range_code(range_reg: int) -> int:
    """The RANGE code the data is scaled for: reserved codes as spec_choices says (4.8)."""
    code = _RANGE_CODE.extract(range_reg)
    return code if code < len(choice.SENSITIVITY_BINARY) else choice.RESERVED_RANGE_AS_CODE


# ------------------------------------------------------------------------------- reads


def _peek_int_status_0(chip: BMG160, now: int) -> int:
    return chip._irq.status_0(chip._regs, now)


def _peek_int_status_1(chip: BMG160, now: int) -> int:
    return chip._irq.status_1(chip._regs, now, data_int(chip, now))


def _peek_fifo_status(chip: BMG160, now: int) -> int:
    count = fifo_count(chip)
    return chip._fifo.overrun << _FIFO_OVERRUN | count


def _peek_bist(chip: BMG160, now: int) -> int:
    rate_ok = chip.power_mode in engines.SAMPLING_MODES and now >= chip._data_start_ns
    return chip._bist.register(now, rate_ok, chip.inject_bist_failure)


def _peek_fifo_data(chip: BMG160, now: int) -> int:
    sync_bypass(chip)
    axis, tag = frame_format(chip)
    return chip._fifo.peek(axis.stop - axis.start, bool(tag))


PEEK: dict[str, Callable[[Any, int], int]] = {
    "TEMP": lambda chip, now: chip._thermometer.raw(chip._have_sample, chip._last_sample_ns),
    "INT_STATUS_0": _peek_int_status_0,
    "INT_STATUS_1": _peek_int_status_1,
    "INT_STATUS_2": lambda chip, now: chip._irq.int_status_2,
    "INT_STATUS_3": lambda chip, now: chip._irq.int_status_3,
    "FIFO_STATUS": _peek_fifo_status,
    "A_FOC": lambda chip, now: chip._regs[_A_FOC] | (_FOC_RUNNING if chip._foc else 0),
    "TRIM_NVM_CTRL": lambda chip, now: chip._nvm.register(chip._regs[_TRIM_NVM_CTRL], now),
    "BIST": _peek_bist,
    "FIFO_DATA": _peek_fifo_data,
}

# ------------------------------------------------------------------------------ writes


def _softreset(chip: BMG160, value: int, now: int) -> None:
    if value == SOFTRESET_KEY:
        chip._reset_state(now, powered=False)


def _int_rst_latch(chip: BMG160, value: int, now: int) -> None:
    if value & _RESET_INT:
        chip._irq.reset_int()
    if value & _OFFSET_RESET:
        engines.set_offsets(chip._regs, (0, 0, 0))
        chip._invalidate()


def _a_foc(chip: BMG160, value: int, now: int) -> None:
    if value & _FAST_OFFSET_EN:
        start_foc(chip)


def _nvm_command(chip: BMG160, value: int, now: int) -> None:
    if value & _NVM_LOAD:
        if chip._nvm.ready(now):
            chip._nvm.load_into(chip._regs)
            chip._invalidate()
        else:
            chip._strict("nvm_load while NVM busy ignored (6.10)")
    if value & _NVM_PROG_TRIG and not chip._nvm.program(chip._regs, now):
        chip._strict("nvm_prog_trig ignored: needs nvm_prog_mode, nvm_rdy and cycles")


def _bist(chip: BMG160, value: int, now: int) -> None:
    if value & _TRIG_BIST:
        chip._bist.trigger(now)


def _empty_fifo(overrun: bool) -> Callable[[Any, int, int], None]:
    def action(chip: BMG160, value: int, now: int) -> None:
        chip._fifo.clear(overrun=overrun)  # 4.26: any write empties it
        chip._bypass_seq = chip._sample_seq

    return action


ACTIONS: dict[str, Callable[[Any, int, int], None]] = {
    "BGW_SOFTRESET": _softreset,
    "INT_RST_LATCH": _int_rst_latch,
    "A_FOC": _a_foc,
    "TRIM_NVM_CTRL": _nvm_command,
    "BIST": _bist,
    "FIFO_CONFIG_0": _empty_fifo(overrun=False),
    "FIFO_CONFIG_1": _empty_fifo(overrun=True),
}

# ----------------------------------------------------------------------------- effects


def _range(chip: BMG160, old: int, new: int, now: int) -> None:
    if chip._sensitivity[range_code(old)] != chip._sensitivity[range_code(new)]:
        chip._invalidate()


def _bw(chip: BMG160, old: int, new: int, now: int) -> None:
    if bw_code(old) != bw_code(new):
        change_bandwidth(chip)


def _lpm(chip: BMG160, old: int, new: int, now: int, *, lpm1: bool) -> None:
    r = chip._regs
    old_mode = engines.power_mode(old, r[_LPM2]) if lpm1 else engines.power_mode(r[_LPM1], old)
    power_transition(chip, old_mode, _LPM1 if lpm1 else _LPM2, new, now)


def _rate_hbw(chip: BMG160, old: int, new: int, now: int) -> None:
    if (old ^ new) & _DATA_HIGH_BW:
        chip._invalidate()
    if new & _SHADOW_DIS:
        chip._msb_latch = [None, None, None]
        chip._latched = False


def _offsets(address: int) -> Callable[[Any, int, int, int], None]:
    mask = offset_mask(address)

    def effect(chip: BMG160, old: int, new: int, now: int) -> None:
        if (old ^ new) & mask:
            chip._invalidate()

    return effect


def _int_en_0(chip: BMG160, old: int, new: int, now: int) -> None:
    if new & ~old & _DATA_EN:
        # 6.3: data_int is set only by samples taken while data_en = 1, so a held
        # data_int (hold_data_int) starts from the first sample after enabling
        chip._data_ready_pending = False
    engine_config_changed(chip, now)


def _engines(chip: BMG160, old: int, new: int, now: int) -> None:
    engine_config_changed(chip, now)


def _fifo_config(chip: BMG160, old: int, new: int, now: int) -> None:
    update_engine_flags(chip)
    update_fifo_int(chip, now)


EFFECTS: dict[str, Callable[[Any, int, int, int], None]] = {
    "RANGE": _range,
    "BW": _bw,
    "LPM1": lambda chip, old, new, now: _lpm(chip, old, new, now, lpm1=True),
    "LPM2": lambda chip, old, new, now: _lpm(chip, old, new, now, lpm1=False),
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


def power_transition(chip: BMG160, old_mode: str, addr: int, value: int, now: int) -> None:
    """LPM1/LPM2 changed (6.7): stop or start sampling; leaving deep suspend is a reset."""
    new_mode = chip.power_mode
    if {old_mode, new_mode} in ({SUSPEND, DEEP_SUSPEND}, {FAST_POWER_UP, DEEP_SUSPEND}):
        chip._strict(f"direct switch {old_mode} -> {new_mode} (spec 6.7)")
    if old_mode == new_mode:
        return
    if old_mode == DEEP_SUSPEND and choice.LEAVING_DEEP_SUSPEND_RESETS:
        chip._reset_state(now, powered=False)
        if addr == _LPM1:  # the write that woke the chip is stored on the reset map
            mask = chip.part.write_masks[_LPM1]
            chip._regs[_LPM1] = (chip._regs[_LPM1] & ~mask) | (value & mask)
        if chip.power_mode not in SAMPLING_MODES:
            chip._stop_sampling()
        return
    was, now_sampling = old_mode in SAMPLING_MODES, new_mode in SAMPLING_MODES
    if was and not now_sampling:
        chip._stop_sampling()
    elif now_sampling and not was:
        wake = choice.FAST_POWER_UP_WAKE_NS if old_mode == FAST_POWER_UP else chip._startup_ns
        chip._start_sampling(now + wake)


def change_bandwidth(chip: BMG160) -> None:
    """A new BW code: new filter from the last output, next sample one new period on."""
    chip._invalidate()
    old_odr = chip._odr
    chip._set_filter(running=True)
    if chip._odr != old_odr and chip._next_ns < NEVER:
        # next sample one new period after the last one (or the pending first one)
        if chip._have_sample and chip._last_sample_ns >= chip._data_start_ns:
            chip._next_ns = chip._last_sample_ns + chip._period_ns
        chip._anchor_ns, chip._anchor_k = chip._next_ns, chip._k + 1


def frame_format(chip: BMG160) -> tuple[slice, bytes]:
    """The FIFO frame: the selected axes and the tag bytes if on (4.26)."""
    select = _FIFO_SELECT.extract(chip._regs[_FIFO_CONFIG_1])
    tag = b""
    if chip._regs[_FIFO_CONFIG_0] & _FIFO_TAG:
        tag = choice.fifo_tag_bytes(*pins(chip, chip.clock.now_ns()))
    return fifo_mod.AXIS_SLICES[select], tag


def sync_bypass(chip: BMG160) -> None:
    """Bypass mode holds the newest sample only (6.5): put it there when read."""
    if chip._fifo_mode == fifo_mod.BYPASS and chip._have_sample \
            and chip._bypass_seq != chip._sample_seq:
        axis, tag = frame_format(chip)
        chip._fifo.replace(chip._cur[axis] + tag)
        chip._bypass_seq = chip._sample_seq


def fifo_count(chip: BMG160) -> int:
    sync_bypass(chip)
    return chip._fifo.count


def update_fifo_int(chip: BMG160, now: int) -> None:
    """fifo_int: at the watermark, or at 100 frames without one (6.5, spec_choices)."""
    r = chip._regs
    if r[_INT_EN_0] & _FIFO_EN:
        count = fifo_count(chip)
        if r[_FIFO_WM_EN] & _FIFO_WM:
            condition = count >= max(_FIFO_WATERMARK.extract(r[_FIFO_CONFIG_0]), 1)
        else:
            condition = count >= chip._fifo.capacity
    else:
        condition = False
    chip._irq.status["fifo"].update(condition, now, latch_hold_ns(r[_INT_RST_LATCH]))


def start_foc(chip: BMG160) -> None:
    """fast_offset_en written (6.9): average from the next sample on."""
    chip._irq.offset_started()
    chip._foc = FastOffset(chip._regs[_A_FOC], chip._regs[_ANY_TH])
    update_engine_flags(chip)


def update_engine_flags(chip: BMG160) -> None:
    """What runs per sample, from the registers: engines, FIFO mode, FIFO interrupt."""
    r = chip._regs
    chip._irq.configure(r)
    chip._fifo_int_on = bool(r[_INT_EN_0] & _FIFO_EN)
    mode = _FIFO_MODE.extract(r[_FIFO_CONFIG_1])
    if mode == _FIFO_MODE_RESERVED:
        mode = choice.FIFO_RESERVED_MODE_AS
    chip._fifo_mode = mode
    chip._fifo_store_mode = mode if mode in (fifo_mod.FIFO, fifo_mod.STREAM) else 0
    chip._fifo.capacity = chip.part.fifo_depth(mode)  # a part's stream depth (part_spec)
    chip._per_sample = bool(chip._irq.any_axes or chip._irq.high_axes or chip._foc is not None)
    chip._plain = not (chip._per_sample or chip._fifo_store_mode or chip._fifo_int_on)


def engine_config_changed(chip: BMG160, now: int) -> None:
    """An interrupt engine register changed: engines, flags and fifo_int follow."""
    chip._irq.reconfigure(chip._regs, now)
    update_engine_flags(chip)
    update_fifo_int(chip, now)


def finish_foc(chip: BMG160) -> None:
    """The FOC average is complete: offsets written, fast_offset_int raised (6.9)."""
    foc, chip._foc = chip._foc, None
    if foc is None:
        return
    engines.set_offsets(chip._regs, foc.offsets_lsb(chip.offset_lsb_dps, engines.OFFSET_BITS))
    chip._invalidate()
    chip._irq.offset_done()
    update_engine_flags(chip)


def data_int(chip: BMG160, now: int) -> bool:
    """data_int (6.3): a pulse after each new sample, or held until read (hold_data_int)."""
    if not (chip._regs[_INT_EN_0] & _DATA_EN and chip._have_sample):
        return False
    if chip.hold_data_int:
        return chip._data_ready_pending
    return now - chip._last_sample_ns < choice.DATA_READY_PULSE_NS


def pins(chip: BMG160, now: int) -> tuple[bool, bool]:
    """(INT1, INT2) asserted."""
    return chip._irq.pins(chip._regs, now, data_int(chip, now))


def pin_level(chip: BMG160, pin: int, now: int) -> int:
    """Electrical level 0/1 of INT1 or INT2 for a push-pull output (INT_EN_1 lvl bit)."""
    if pin not in (1, 2):
        raise ValueError("pin must be 1 or 2")
    active = pins(chip, now)[pin - 1]
    active_high = bool(chip._regs[_INT_EN_1] & _INT_LVL[pin - 1])
    return int(active == active_high)


def _by_address(table: dict[str, Any]) -> tuple[Any, ...]:
    unknown = set(table) - {r.name for r in REGISTERS}
    if unknown:
        raise KeyError(f"regmap names registers the table does not have: {sorted(unknown)}")
    return tuple(table.get(r.name) for r in REGISTERS)


# Indexed by address, for the model's hot paths.
PEEK_AT = _by_address(PEEK)
ACTION_AT = _by_address(ACTIONS)
EFFECT_AT = _by_address(EFFECTS)
