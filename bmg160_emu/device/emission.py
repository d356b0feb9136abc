"""The samples as they come out of the data path, for ``BMG160``'s catch-up (chip.py).

``catch_up``: every sample due by a time; ``emit_one``: one sample through the truth and
sample hooks and the per-sample engines (interrupts, fast offset, FIFO); ``emit_batch``: n
samples when no per-sample engine runs, where only the last sample and the FIFO's frames
matter. Both work on the chip's state, as
``regmap`` does."""

from __future__ import annotations

from typing import Any

import numpy as np

from bmg160_emu.clock import NS_PER_S
from bmg160_emu.device import datapath, regmap
from bmg160_emu.device.registers import address_of, field_of

_RATE_HBW, _DATA_HIGH_BW = address_of("RATE_HBW"), field_of("RATE_HBW", "data_high_bw").mask


def emit_batch(chip: Any, n: int) -> None:
    """n samples with no per-sample engine: only the last one and the FIFO matter."""
    k_first = chip._k + 1
    k_last = chip._k + n
    fifo_mode = chip._fifo_store_mode
    wanted = range(0)
    if fifo_mode:
        wanted = chip._fifo.kept(k_first, n, fifo_mode)
        frames: list[bytes] = []
        axis, tag = regmap.frame_format(chip)
    k = k_first
    while True:
        b = chip._block_for(k, want=k_last - k + 1)
        seg_end = min(b.end, k_last + 1)
        if wanted:
            frames += b.frames(max(k, wanted.start), min(seg_end, wanted.stop), axis, tag)
        if seg_end > k_last:
            break
        chip._k = seg_end - 1
        k = seg_end
    i = 6 * (k_last - b.k0)
    chip._cur = b.rate_bytes[i:i + 6]
    chip._k = k_last
    chip._last_sample_ns = chip._next_ns + (n - 1) * chip._period_ns
    chip._next_ns = chip._last_sample_ns + chip._period_ns
    chip._data_ready_pending = True
    if fifo_mode:
        chip._fifo.push_many(frames, fifo_mode, total=n)
    if chip._fifo_int_on:
        regmap.update_fifo_int(chip, chip._last_sample_ns)


def first_not_due(chip: Any, now: int) -> int:
    """The index of the first sample not yet due at ``now`` (ns)."""
    t = chip._next_ns
    return chip._k + 1 + ((now - t) // chip._period_ns + 1 if now >= t else 0)


def catch_up(chip: Any, now: int) -> None:
    """Produce every sample due by ``now`` (``BMG160._catch_up``)."""
    while now >= chip._next_ns:
        t = chip._next_ns
        period = chip._period_ns
        if chip._per_sample or chip.sample_hooks or chip.truth_hooks:
            if chip._emitting:  # a hook called a primitive: finish this sample first
                return
            chip._emitting = True
            try:
                # (a queued rate computes all that are due at once; others as they were)
                emit_one(chip, 1 if chip._rate.ahead else (now - t) // period + 1)
            finally:
                chip._emitting = False
            continue
        emit_batch(chip, (now - t) // period + 1)


def emit_one(chip: Any, due: int = 1) -> None:
    """One sample through the hooks and the per-sample engines; ``due``: the samples due,
    this one included (a missing block is built for all of them)."""
    k = chip._k + 1
    b = chip._block_for(k, due)
    i = k - b.k0
    t_ns = chip._next_ns
    t_s = t_ns / NS_PER_S
    chip._k = k
    chip._next_ns = t_ns + chip._period_ns
    for hook in list(chip.truth_hooks):
        hook(chip, t_s, np.array(b.body[i], dtype=float))
    dps_pre = None
    irq = chip._irq
    if chip.sample_hooks:  # the hooks' rate replaces the block's counts (not computed then)
        high_bw = chip._regs[_RATE_HBW] & _DATA_HIGH_BW
        rate = datapath.run_sample_hooks(chip, t_s, b.dps_u[i] if high_bw else b.dps_f[i])
        if rate is None:
            chip._seq_base += 1  # a lost sample: not counted, no data-ready, no register update
            return
        counts_f, rate_bytes = datapath.counts_of(rate.tolist(), chip.sensitivity)
        counts_u = counts_f
        dps_pre = rate
    else:
        rate_bytes = b.rate_bytes[6 * i:6 * i + 6]
        if irq.any_axes or irq.high_axes:
            counts_f, counts_u = b.counts_f[i], b.counts_u[i]
    chip._cur = rate_bytes
    chip._last_sample_ns = t_ns
    chip._data_ready_pending = True
    if irq.any_axes or irq.high_axes:  # (step does nothing with both engines off)
        irq.step(chip._regs, counts_f, counts_u, chip._odr, t_ns)
    foc = chip._foc
    if foc is not None:
        if dps_pre is None:
            dps_pre = b.dps_u[i] if foc.unfiltered else b.dps_f[i]
        if foc.add(dps_pre, chip._offset_dps()):
            regmap.finish_foc(chip)
    if chip._fifo_store_mode:
        select, tag = regmap.frame_format(chip)
        chip._fifo.push(rate_bytes[select] + tag, chip._fifo_store_mode)
    if chip._fifo_int_on:
        regmap.update_fifo_int(chip, t_ns)
