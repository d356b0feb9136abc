"""A closed loop's true rate, one constant per step (``set_true_rate`` between samples): the
model recomputes only the sample a step changes, not the block it had computed ahead, and
gives the samples it gave when it recomputed whole blocks."""

import numpy as np
import pytest

from bmg160_emu.device import datapath
from bmg160_emu.device.chip import BMG160

SEED = 11


def _rates(n: int, seed: int) -> np.ndarray:
    # a random walk in deg/s: no two consecutive rows equal, as a simulator's rate
    steps = np.random.default_rng(seed).normal(0.0, 3.0, size=(n, 3))
    return np.cumsum(steps, axis=0) + np.array([10.0, -20.0, 5.0])


def _whole_spans(block, k, want, span, hint):
    """The policy before pieces: every span computed in one block after any change."""
    return _PIECES(block, k, want, span, datapath.SPAN)


_PIECES = datapath.next_piece


def _run(rates: np.ndarray, bw: int, *, stepped: bool, tail_s: float = 0.0):
    """(register bytes after each step, the rates hooks saw, bytes after the tail)."""
    chip = BMG160(seed=SEED, true_rate=rates[0] if stepped else rates)
    chip.write(0x10, bytes([bw]))  # at t = 0: sample 0 is already out at BW code 0
    seen: list[np.ndarray] = []
    chip.sample_hooks.append(lambda c, t, r: seen.append(r.copy()))
    period = 1.0 / chip.odr_hz
    reads = []
    for k in range(1, len(rates)):
        if stepped:
            chip.set_true_rate(rates[k])
        chip.advance(period)
        reads.append(chip.read(0x02, 6))
    reads.append(chip.dump())
    tail = []
    if tail_s:  # left alone after the loop: the held rate, pieces growing back to spans
        chip.sample_hooks.clear()
        chip.write(0x3E, bytes([0x80]))  # stream mode: the FIFO keeps the last 100 frames
        for seconds in (tail_s, 0.0005, 3 * tail_s):
            chip.advance(seconds)
            tail.append(chip.read(0x3F, 600) + chip.dump())
    return reads, seen, tail


@pytest.mark.parametrize("bw", [0x04, 0x01])  # 200 Hz and 2000 Hz ODR
def test_set_true_rate_each_step_gives_the_samples_of_whole_blocks(bw, monkeypatch):
    rates = _rates(400, seed=bw)
    pieces = _run(rates, bw, stepped=True, tail_s=0.3)
    monkeypatch.setattr(datapath, "next_piece", _whole_spans)
    blocks = _run(rates, bw, stepped=True, tail_s=0.3)
    assert pieces[0] == blocks[0]  # every read and the final dump
    # the rates before scaling, bit for bit: a one-sample block is the first sample of a
    # long one (the low-pass's sub-block products add exact zeros for the samples after it)
    assert len(pieces[1]) == len(blocks[1]) == len(rates) - 1
    assert all(np.array_equal(a, b) for a, b in zip(pieces[1], blocks[1]))
    # left alone, pieces of 1, 2, 4, ... samples: the same register bytes (the low-pass's
    # matrix sub-blocks round differently in different pieces, ~1e-15 of the rate, far below
    # the 1/16.384 deg/s of one count)
    assert pieces[2] == blocks[2]


@pytest.mark.parametrize("bw", [0x04, 0x01])
def test_set_true_rate_each_step_gives_the_samples_of_the_rates_as_rows(bw):
    rates = _rates(400, seed=bw + 1)
    stepped = _run(rates, bw, stepped=True)
    rows = _run(rates, bw, stepped=False)
    assert stepped[0] == rows[0]
    # rows are filtered in whole blocks, steps one sample at a time: equal to rounding
    # (lowpass.py: about 1e-15 of the signal; 1e-12 deg/s on rates of tens of deg/s)
    assert np.allclose(np.array(stepped[1]), np.array(rows[1]), rtol=0.0, atol=1e-12)
