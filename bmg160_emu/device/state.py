"""The chip's state and its sample schedule, under public names: what the chip's parts act on.

``BMG160`` (chip.py) keeps the lock, the primitives, the hook lists and the reset entry points.
Everything a register hook (``regmap``), a bus transaction (``register_access``) or the
output samples (``output_samples``) read or change lives in one ``ChipState`` per chip, and those modules take
that object, never the chip: they see the chip only through it (docs/architecture.md, "The
chip's state"). It also holds the few operations of the schedule they call: ``invalidate``
(the configuration changed), ``start_sampling`` and ``stop_sampling`` (power modes, 6.7),
``reset`` (6.6), ``set_filter`` (BW, 5.3), ``block_for`` (the computed-ahead samples holding
sample k) and ``update_engine_flags`` (what runs per sample).

Of the chip itself the state knows only ``PublicChip``: its public options, clock and hook
lists. Time is integer nanoseconds: sample k of a run is at
``anchor_ns + (k - anchor_k) * period_ns``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np

from bmg160_emu.clock import NEVER, NS_PER_S, RealTimeClock, VirtualClock
from bmg160_emu.device import datapath, offsets
from bmg160_emu.device import fifo as fifo_mod
from bmg160_emu.device import spec_choices as choice
from bmg160_emu.device.environment import ErrorBudget
from bmg160_emu.device.interrupts import Interrupts
from bmg160_emu.device.nvm import Nvm
from bmg160_emu.device.offsets import FastOffset
from bmg160_emu.device.power_modes import power_mode
from bmg160_emu.device.registers import address_of, field_of
from bmg160_emu.device.self_test import SelfTest
from bmg160_emu.device.thermometer import Thermometer
from bmg160_emu.device.true_rate import TrueRate, true_rate_source

# strict mode's messages go where they always went: the chip's logger (logging imported
# on the first message: ~13 ms of a chip's cold start otherwise, issue 26)
LOGGER_NAME = "bmg160_emu.device.chip"

_RANGE, _BW, _LPM1, _LPM2 = (address_of(name) for name in ("RANGE", "BW", "LPM1", "LPM2"))
_RATE_HBW, _INT_EN_0 = address_of("RATE_HBW"), address_of("INT_EN_0")
_FIFO_CONFIG_1 = address_of("FIFO_CONFIG_1")
_DATA_HIGH_BW = field_of("RATE_HBW", "data_high_bw").mask
_FIFO_EN = field_of("INT_EN_0", "fifo_en").mask
_FIFO_MODE = field_of("FIFO_CONFIG_1", "fifo_mode")
_FIFO_MODE_RESERVED = 3  # 4.26: fifo_mode 3 is reserved


class PublicChip(Protocol):
    """What the chip's parts read of the chip itself: BMG160's public attributes of these
    names (its options, its clock, and the hook lists whose first argument is the chip)."""

    address: int
    strict: bool
    strict_log: list[str]
    hold_data_int: bool
    inject_bist_failure: bool
    sample_hooks: list[Callable[..., Any]]
    truth_hooks: list[Callable[..., Any]]

    @property
    def clock(self) -> VirtualClock | RealTimeClock: ...


class PartTable(Protocol):
    """What the state and the parts read of a part (``part_spec.Part``): its tables by
    register address, the NVM-backed reset and the FIFO depth of each mode."""

    @property
    def reset_values(self) -> bytes: ...

    @property
    def write_masks(self) -> bytes: ...

    @property
    def absent(self) -> frozenset[int]: ...

    @property
    def peek_at(self) -> tuple[Callable[[ChipState, int], int] | None, ...]: ...

    @property
    def action_at(self) -> tuple[Callable[[ChipState, int, int], None] | None, ...]: ...

    @property
    def effect_at(self) -> tuple[Callable[[ChipState, int, int, int], None] | None, ...]: ...

    def load_nvm(self, nvm: Nvm, regs: bytearray) -> None: ...

    def fifo_depth(self, mode: int) -> int: ...


class ChipState:
    """One chip's mutable state and sample schedule.

    Fixed for the chip's life: ``chip`` (its public face, ``PublicChip``), ``part`` (the
    register tables), ``sensitivity_table`` (LSB per deg/s by RANGE code;
    ``sensitivity_of_range`` the same by RANGE byte), ``startup_ns``
    (reset and wake to the first sample, 6.6), ``thermometer``, ``nvm`` and ``bist`` (the
    engines of 5.2, 6.10 and 6.8), ``budget`` (the unit's errors) and ``path`` (the data path;
    both set by the chip right after construction: the budget reads this state's
    ``times_ns``).

    The register file: ``regs`` (64 bytes as stored), ``cur`` (the 6 bytes RATE_X_LSB ..
    RATE_Z_MSB of the last sample), ``msb_latch`` and ``latched`` (the MSBs shadowed by LSB
    reads, 6.2), ``data_ready_pending`` (a sample not yet read, for ``hold_data_int``).

    The engines, new at each reset: ``fifo``, ``bypass_seq`` (the sample bypass mode last
    stored), ``irq`` (interrupt statuses and engines), ``foc`` (a fast offset run or None).
    What runs per sample, from the registers (``update_engine_flags``): ``fifo_mode``,
    ``fifo_store_mode`` (FIFO or stream, else 0), ``fifo_int_on``, ``per_sample`` (an
    engine needs every sample) and ``plain`` (nothing per sample: no engine, no FIFO storage,
    no FIFO interrupt).

    The schedule: ``k`` (index of the last sample produced), ``seq_base`` (``k`` at the last
    reset), ``next_ns`` (when the next sample is due, ``NEVER`` when not sampling),
    ``last_sample_ns``, ``data_start_ns`` (the first sample after start-up), ``anchor_ns`` and
    ``anchor_k`` (sample ``anchor_k`` is at ``anchor_ns``), ``odr`` (Hz) and ``period_ns``,
    ``rate`` (the true-rate source), ``block`` (the computed-ahead samples in use or None),
    ``span`` and ``span_used`` (how far ahead, ``datapath.next_piece``), ``emitting`` (a
    sample is going through the hooks)."""

    __slots__ = (
        "anchor_k", "anchor_ns", "bist", "block", "budget", "bypass_seq", "chip", "cur",
        "data_ready_pending", "data_start_ns", "emitting", "fifo", "fifo_int_on", "fifo_mode",
        "fifo_store_mode", "foc", "irq", "k", "last_sample_ns", "latched", "msb_latch",
        "next_ns", "nvm", "odr", "part", "path", "per_sample", "period_ns", "plain", "rate",
        "regs", "sensitivity_of_range", "sensitivity_table", "seq_base", "span", "span_used",
        "startup_ns", "thermometer",
    )
    chip: PublicChip
    part: PartTable
    sensitivity_table: tuple[float, ...]
    sensitivity_of_range: tuple[float, ...]
    startup_ns: int
    thermometer: Thermometer
    nvm: Nvm
    bist: SelfTest
    budget: ErrorBudget
    path: datapath.DataPath
    regs: bytearray
    cur: bytes
    msb_latch: list[int | None]
    latched: bool
    data_ready_pending: bool
    fifo: fifo_mod.Fifo
    bypass_seq: int
    irq: Interrupts
    foc: FastOffset | None
    fifo_mode: int
    fifo_store_mode: int
    fifo_int_on: bool
    per_sample: bool
    plain: bool
    k: int
    seq_base: int
    next_ns: int
    last_sample_ns: int
    data_start_ns: int
    anchor_ns: int
    anchor_k: int
    odr: int
    period_ns: int
    rate: TrueRate
    block: datapath.Block | None
    span: tuple[int, int]
    span_used: int
    emitting: bool

    def __init__(self, chip: PublicChip, part: PartTable, *,
                 sensitivity_table: tuple[float, ...], startup_ns: int,
                 thermometer: Thermometer, nvm: Nvm) -> None:
        self.chip = chip
        self.part = part
        self.sensitivity_table = sensitivity_table
        # LSB per deg/s by RANGE byte: one index per sample instead of decoding the field
        self.sensitivity_of_range = tuple(sensitivity_table[choice.range_code(byte)]
                                          for byte in range(256))
        self.startup_ns = startup_ns
        self.thermometer = thermometer
        self.nvm = nvm
        self.bist = SelfTest()
        self.k = self.seq_base = -1
        self.block = None
        self.span = (0, 0)
        self.span_used = datapath.SPAN
        self.rate = true_rate_source((0.0, 0.0, 0.0), None, first_k=0, first_ns=0)
        self.next_ns = NEVER
        self.emitting = False

    # ------------------------------------------------------------------ views

    @property
    def sample_seq(self) -> int:
        """Samples produced since the last reset (every sample moves ``k`` on by one)."""
        return self.k - self.seq_base

    @property
    def have_sample(self) -> bool:
        return self.k > self.seq_base

    @property
    def power_mode(self) -> str:
        return power_mode(self.regs[_LPM1], self.regs[_LPM2])

    @property
    def sensitivity(self) -> float:
        """LSB per deg/s of the current range."""
        return self.sensitivity_of_range[self.regs[_RANGE]]

    @property
    def offset_lsb_dps(self) -> float:
        """deg/s per offset LSB: one count of the +-2000 deg/s range (6.9, unconfirmed)."""
        return 1.0 / self.sensitivity_table[choice.OFFSET_LSB_RANGE_CODE]

    def offset_dps(self) -> np.ndarray:
        return offsets.offsets_dps(self.regs, self.offset_lsb_dps)

    def strict_warning(self, message: str) -> None:
        """Questionable driver behaviour: logged when the chip is strict."""
        chip = self.chip
        if chip.strict:
            chip.strict_log.append(message)
            import logging

            logging.getLogger(LOGGER_NAME).warning("BMG160 0x%02X: %s", chip.address, message)

    # ------------------------------------------------------------------ reset and schedule

    def reset(self, now: int, *, powered: bool) -> None:
        """Soft reset, power-on reset and leaving deep suspend (6.6, 6.7)."""
        self.block = None
        self.regs = bytearray(self.part.reset_values)
        self.part.load_nvm(self.nvm, self.regs)
        self.nvm.busy_until_ns = -1
        self.cur = bytes(6)
        self.seq_base = self.k  # samples since this reset: k - seq_base
        self.last_sample_ns = -NEVER
        self.data_ready_pending = False
        self.msb_latch = [None, None, None]
        self.latched = False
        self.fifo = fifo_mod.Fifo()
        self.bypass_seq = 0
        self.irq = Interrupts()
        self.bist.start_ns = None
        self.foc = None
        self.budget.power_cycle()
        self.set_filter()
        self.path.restart_filter = True
        self.update_engine_flags()
        self.start_sampling(now if powered else now + self.startup_ns)

    def start_sampling(self, first_ns: int) -> None:
        """The first sample at ``first_ns``, then one per period."""
        self.invalidate()
        self.anchor_ns = first_ns
        self.anchor_k = self.k + 1
        self.next_ns = first_ns
        self.data_start_ns = first_ns
        self.path.restart_filter = True

    def stop_sampling(self) -> None:
        self.invalidate()
        self.next_ns = NEVER
        # 5.2: TEMP keeps its last conversion until the next sample (frozen while not sampling)
        self.thermometer.freeze(self.have_sample, self.last_sample_ns)

    def update_engine_flags(self) -> None:
        """What runs per sample, from the registers: engines, FIFO mode, FIFO interrupt."""
        r = self.regs
        self.irq.configure(r)
        self.fifo_int_on = bool(r[_INT_EN_0] & _FIFO_EN)
        mode = _FIFO_MODE.extract(r[_FIFO_CONFIG_1])
        if mode == _FIFO_MODE_RESERVED:
            mode = choice.FIFO_RESERVED_MODE_AS
        self.fifo_mode = mode
        self.fifo_store_mode = mode if mode in (fifo_mod.FIFO, fifo_mod.STREAM) else 0
        self.fifo.capacity = self.part.fifo_depth(mode)  # a part's stream depth (part_spec)
        self.per_sample = bool(self.irq.any_axes or self.irq.high_axes or self.foc is not None)
        self.plain = not (self.per_sample or self.fifo_store_mode or self.fifo_int_on)

    # ------------------------------------------------------------------ data path

    def set_filter(self, *, running: bool = False) -> None:
        """ODR and filter from BW's code (codes 8..15 as code & 7); the noise realisation
        carries on (a running filter too)."""
        set_filter = self.path.change_bandwidth if running else self.path.set_filter
        set_filter(choice.bw_code(self.regs[_BW]), used_end=self.k + 1)
        odr = self.path.odr_hz
        assert odr is not None  # set by set_filter
        self.odr, self.period_ns = odr, NS_PER_S // odr

    def invalidate(self) -> None:
        """Drop the computed-ahead samples after the current one (configuration changed)."""
        if self.block is not None:
            self.span_used = max(self.k + 1 - self.span[0], 1)
        self.path.invalidate(self.block, self.k)
        self.block = None

    def times_ns(self, k0: int, n: int) -> np.ndarray:
        """The times of samples k0 .. k0 + n - 1 in ns."""
        return self.anchor_ns + (np.arange(k0, k0 + n) - self.anchor_k) * self.period_ns

    def block_for(self, k: int, want: int = 1) -> datapath.Block:
        """The block holding sample k, built for ``want`` samples from k if it is missing."""
        b = self.block
        if b is not None and b.k0 <= k < b.end:
            return b
        first, n, self.span = datapath.next_piece(b, k, want, self.span, self.span_used)
        if not self.rate.ahead:  # rates still to come (queue_true_rate): only what is due
            n = min(n, want)
        body = self.rate.block(k, n, self.times_ns)
        b = self.block = self.path.build(
            k, body, self.offset_dps(), self.sensitivity,
            bool(self.regs[_RATE_HBW] & _DATA_HIGH_BW), self.rate.constant, first=first)
        return b
