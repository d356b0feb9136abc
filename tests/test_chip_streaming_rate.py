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


def _loop(feed: str, rates: np.ndarray, step_s: float, *, hooks: bool, **options):
    """Everything a driver and the hooks see while ``feed`` hands the chip a rate per step:
    each read, the FIFO (stream mode, from the middle on), a BW change, the final dump."""
    chip = BMG160(seed=SEED, **options)
    chip.write(0x10, bytes([0x04]))  # ODR 200 Hz
    seen: list = []
    if hooks:
        chip.truth_hooks.append(lambda c, t, r: seen.append(("truth", t, r.tolist())))
        chip.sample_hooks.append(lambda c, t, r: (seen.append(("sample", t, r.tolist())), r)[1])
    give = getattr(chip, feed)
    out = []
    for k, rate in enumerate(rates):
        give(rate)
        chip.advance(step_s)
        out.append(chip.read(0x02, 6))
        if k == len(rates) // 3:
            chip.write(0x3E, bytes([0x80]))  # FIFO stream mode: frames stored per sample
        if k == len(rates) // 2:
            chip.write(0x10, bytes([0x01]))  # 2000 Hz ODR, the filter running on
        if k % 50 == 49:
            out.append(chip.read(0x3F, 6 * 10))
    out.append(chip.dump())
    return out, seen


@pytest.mark.parametrize("step_periods", [1.0, 2.0, 0.6, 3.3])  # in 200 Hz output periods
@pytest.mark.parametrize("hooks", [False, True])
def test_stream_true_rate_gives_set_true_rates_samples_bit_for_bit(step_periods, hooks):
    rates = _rates(300, seed=int(step_periods * 10))
    step_s = step_periods / 200.0
    streamed = _loop("stream_true_rate", rates, step_s, hooks=hooks)
    stepped = _loop("set_true_rate", rates, step_s, hooks=hooks)
    assert streamed[0] == stepped[0]
    assert streamed[1] == stepped[1]  # times, true rates and rates before scaling, exactly
    if hooks:
        assert len(streamed[1]) > 300


def test_stream_true_rate_through_mounting_and_a_units_errors():
    # the sensor-frame transform and the error budget before the filter: still bit for bit
    options = {"mounting": [[0, 0, 1], [1, 0, 0], [0, 1, 0]], "scale_factor": [0.01, -0.02, 0.0],
               "misalignment": [[0, 0.001, 0], [0.002, 0, 0], [0, 0, 0]], "unit": 4}
    rates = _rates(300, seed=3)
    streamed = _loop("stream_true_rate", rates, 1 / 200.0, hooks=True, **options)
    stepped = _loop("set_true_rate", rates, 1 / 200.0, hooks=True, **options)
    assert streamed == stepped


def test_stream_true_rate_holds_the_rate_and_computes_one_sample_a_step(monkeypatch):
    chip = BMG160(seed=SEED)
    chip.write(0x10, bytes([0x04]))
    built = []
    build = chip.state.path.build
    monkeypatch.setattr(chip.state.path, "build", lambda k0, body, *a, **k: (
        built.append(len(body)), build(k0, body, *a, **k))[1])
    for rate in _rates(50, seed=4):
        chip.stream_true_rate(rate)
        chip.advance(1 / 200.0)
        chip.read(0x02, 6)
    assert set(built[2:]) == {1}  # after the first steps: the one sample each step changes
    chip.stream_true_rate((100.0, 0.0, 0.0))
    chip.advance(0.5)  # left alone: the rate holds, computed in growing pieces
    assert built[-1] > 1
    counts = np.frombuffer(chip.read(0x02, 6), dtype="<i2")
    assert abs(counts[0] / chip.sensitivity - 100.0) < 0.5  # the paper's noise: ~0.1 deg/s


@pytest.mark.parametrize("bad", [(1.0, 2.0), "abc", (1.0, float("nan"), 0.0),
                                 lambda t: (0.0, 0.0, 0.0), np.zeros((4, 3))])
def test_stream_true_rate_refuses_anything_but_three_finite_numbers(bad):
    chip = BMG160(seed=SEED)
    with pytest.raises(ValueError, match="true rate"):
        chip.stream_true_rate(bad)


def test_stream_true_rate_replaces_a_failing_rate_function_as_set_true_rate_does():
    chip = BMG160(seed=SEED, true_rate=lambda t: 1 / 0 if t > 0.01 else (1.0, 2.0, 3.0))
    with pytest.raises(ZeroDivisionError):
        chip.advance(0.1)
    chip.stream_true_rate((4.0, 5.0, 6.0))  # the samples it could not give come from this one
    chip.advance(0.1)
    counts = np.frombuffer(chip.read(0x02, 6), dtype="<i2") / chip.sensitivity
    assert np.allclose(counts, (4.0, 5.0, 6.0), atol=0.5)
