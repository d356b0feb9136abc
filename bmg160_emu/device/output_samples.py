"""The samples as they come out of the data path, for ``BMG160``'s catch-up (chip.py).

``catch_up``: every sample due by a time; ``emit_one``: one sample through the truth and
sample hooks and the per-sample engines (interrupts, fast offset, FIFO); ``emit_batch``: n
samples when no per-sample engine runs, where only the last sample and the FIFO's frames
matter. Each takes ``s``, the chip's state (``state.ChipState``), as ``regmap`` does; the
hooks get the chip itself (``s.chip``), their documented first argument."""

from __future__ import annotations

from bmg160_emu.clock import NS_PER_S
from bmg160_emu.device import datapath, regmap
from bmg160_emu.device.registers import address_of, field_of
from bmg160_emu.device.state import ChipState

_RATE_HBW, _DATA_HIGH_BW = address_of("RATE_HBW"), field_of("RATE_HBW", "data_high_bw").mask


def emit_batch(s: ChipState, n: int) -> None:
    """n samples with no per-sample engine: only the last one and the FIFO matter."""
    k_first = s.k + 1
    k_last = s.k + n
    fifo_mode = s.fifo_store_mode
    wanted = range(0)
    if fifo_mode:
        wanted = s.fifo.kept(k_first, n, fifo_mode)
        frames: list[bytes] = []
        axis, tag = regmap.frame_format(s)
    k = k_first
    while True:
        b = s.block_for(k, want=k_last - k + 1)
        seg_end = min(b.end, k_last + 1)
        if wanted:
            frames += b.frames(max(k, wanted.start), min(seg_end, wanted.stop), axis, tag)
        if seg_end > k_last:
            break
        s.k = seg_end - 1
        k = seg_end
    i = 6 * (k_last - b.k0)
    s.cur = b.rate_bytes[i:i + 6]
    s.k = k_last
    s.last_sample_ns = s.next_ns + (n - 1) * s.period_ns
    s.next_ns = s.last_sample_ns + s.period_ns
    s.data_ready_pending = True
    if fifo_mode:
        s.fifo.push_many(frames, fifo_mode, total=n)
    if s.fifo_int_on:
        regmap.update_fifo_int(s, s.last_sample_ns)


def first_not_due(s: ChipState, now: int) -> int:
    """The index of the first sample not yet due at ``now`` (ns)."""
    t = s.next_ns
    return s.k + 1 + ((now - t) // s.period_ns + 1 if now >= t else 0)


def catch_up(s: ChipState, now: int) -> None:
    """Produce every sample due by ``now`` (between transactions, never inside one)."""
    chip = s.chip
    while now >= s.next_ns:
        if s.per_sample or chip.sample_hooks or chip.truth_hooks:
            if s.emitting:  # a hook called a primitive: finish this sample first
                return
            s.emitting = True
            try:
                while True:  # each due sample, while one needs to go through emit_one
                    # (a queued rate computes all that are due at once; others as they were)
                    emit_one(s, 1 if s.rate.ahead else (now - s.next_ns) // s.period_ns + 1)
                    if now < s.next_ns or not (s.per_sample or chip.sample_hooks
                                               or chip.truth_hooks):
                        break
            finally:
                s.emitting = False
            continue
        emit_batch(s, (now - s.next_ns) // s.period_ns + 1)


def emit_one(s: ChipState, due: int = 1) -> None:
    """One sample through the hooks and the per-sample engines; ``due``: the samples due,
    this one included (a missing block is built for all of them)."""
    k = s.k + 1
    b = s.block
    if b is None or not b.k0 <= k < b.end:  # (block_for's own test, without the call)
        b = s.block_for(k, due)
    i = k - b.k0
    t_ns = s.next_ns
    t_s = t_ns / NS_PER_S
    s.k = k
    s.next_ns = t_ns + s.period_ns
    chip = s.chip
    if chip.truth_hooks:
        for hook in list(chip.truth_hooks):
            hook(chip, t_s, b.body[i].copy())  # (a float array's row: np.array's result)
    dps_pre = None
    irq = s.irq
    if chip.sample_hooks:  # the hooks' rate replaces the block's counts (not computed then)
        high_bw = s.regs[_RATE_HBW] & _DATA_HIGH_BW
        rate = datapath.run_sample_hooks(chip, t_s, b.dps_u[i] if high_bw else b.dps_f[i])
        if rate is None:
            s.seq_base += 1  # a lost sample: not counted, no data-ready, no register update
            return
        counts_f, rate_bytes = datapath.counts_of(rate.tolist(), s.sensitivity)
        counts_u = counts_f
        dps_pre = rate
        engines = irq.any_axes or irq.high_axes  # (after the hooks, which may write)
    else:
        rate_bytes = b.rate_bytes[6 * i:6 * i + 6]
        engines = irq.any_axes or irq.high_axes
        if engines:
            counts_f, counts_u = b.counts_f[i], b.counts_u[i]
    s.cur = rate_bytes
    s.last_sample_ns = t_ns
    s.data_ready_pending = True
    if engines:  # (step does nothing with both engines off)
        irq.step(s.regs, counts_f, counts_u, s.odr, t_ns)
    foc = s.foc
    if foc is not None:
        if dps_pre is None:
            dps_pre = b.dps_u[i] if foc.unfiltered else b.dps_f[i]
        if foc.add(dps_pre, s.offset_dps()):
            regmap.finish_foc(s)
    mode = s.fifo_store_mode
    if mode:
        select, tag = regmap.frame_format(s)
        s.fifo.push(rate_bytes[select] + tag, mode)
    if s.fifo_int_on:
        regmap.update_fifo_int(s, t_ns)
