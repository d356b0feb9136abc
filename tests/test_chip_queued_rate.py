"""``BMG160.queue_true_rate``: a rate per loop step, the samples computed only when read
(several at once), the same samples as ``stream_true_rate`` computes one at a time."""

import numpy as np
import pytest
from test_chip_streaming_rate import _rates  # a random walk in deg/s, a new rate every row

from bmg160_emu.clock import VirtualClock
from bmg160_emu.device.chip import BMG160

SEED = 5


def _loop(feed: str, rates: np.ndarray, step_s: float, read_every: int, *, hooks: bool):
    """What a driver reading every ``read_every`` steps and the hooks see while ``feed``
    hands the chip a rate per step; the FIFO on from the start, a BW change midway. Time
    moves on the shared clock, as a simulator's: nothing asks the chip between reads."""
    clock = VirtualClock()
    chip = BMG160(seed=SEED, clock=clock)
    chip.write(0x10, bytes([0x04]))  # ODR 200 Hz
    chip.write(0x3E, bytes([0x80]))  # FIFO stream mode: every sample kept
    seen: list = []
    if hooks:
        chip.truth_hooks.append(lambda c, t, r: seen.append(("truth", t, r.tolist())))
        chip.sample_hooks.append(lambda c, t, r: (seen.append(("sample", t, r.tolist())), r)[1])
    give = getattr(chip, feed)
    out = []
    for k, rate in enumerate(rates):
        give(rate)
        clock.advance(step_s)
        if k % read_every == read_every - 1:
            out.append(chip.read(0x02, 6))
            out.append(chip.read(0x3F, 6 * (chip.peek(0x0E) & 0x7F)))
        if k == len(rates) // 2:
            chip.write(0x10, bytes([0x01]))  # 2000 Hz ODR, the filter running on
    out.append(chip.dump())
    return out, seen


@pytest.mark.parametrize("read_every", [1, 10, 7])
@pytest.mark.parametrize("step_periods", [1.0, 2.5, 0.6])  # in 200 Hz output periods
@pytest.mark.parametrize("hooks", [False, True])
def test_queued_rates_give_the_streamed_samples(read_every, step_periods, hooks):
    rates = _rates(300, seed=int(step_periods * 10) + read_every)
    step_s = step_periods / 200.0
    queued = _loop("queue_true_rate", rates, step_s, read_every, hooks=hooks)
    streamed = _loop("stream_true_rate", rates, step_s, read_every, hooks=hooks)
    # every register byte and FIFO frame: rates agree to ~1e-15 (several samples filtered
    # in one block against one at a time), far below the 1/16.4 deg/s of a count
    assert queued[0] == streamed[0]
    assert [s[:2] for s in queued[1]] == [s[:2] for s in streamed[1]]  # which hook, when
    if hooks:
        truth = [s[2] for s in queued[1] if s[0] == "truth"]
        assert truth == [s[2] for s in streamed[1] if s[0] == "truth"]  # the rates given, exactly
        before = np.array([s[2] for s in queued[1] if s[0] == "sample"])
        after = np.array([s[2] for s in streamed[1] if s[0] == "sample"])
        assert np.allclose(before, after, rtol=0.0, atol=1e-11)  # rates of tens of deg/s


def test_queued_rates_are_computed_when_read_all_due_at_once(monkeypatch):
    # time moves on the shared clock (a simulator's, as EmulatedGyro's): chip.advance would
    # produce each sample as it falls due
    clock = VirtualClock()
    chip = BMG160(seed=SEED, clock=clock)
    chip.write(0x10, bytes([0x04]))
    chip.write(0x3E, bytes([0x80]))
    built = []
    build = chip.state.path.build
    monkeypatch.setattr(chip.state.path, "build", lambda k0, body, *a, **k: (
        built.append(len(body)), build(k0, body, *a, **k))[1])
    rates = _rates(40, seed=2)
    for rate in rates[:20]:  # settle in: the first queued rate catches up what was due
        chip.queue_true_rate(rate)
        clock.advance_ns(5_000_000)
    frames = chip.peek(0x0E) & 0x7F
    built.clear()
    for rate in rates[20:30]:
        chip.queue_true_rate(rate)
        clock.advance_ns(5_000_000)
    assert built == []  # ten steps, nothing computed
    assert chip.peek(0x0E) & 0x7F == frames + 10  # looked at: the ten samples are out
    assert built == [10]  # in one block, none ahead


def test_a_later_rate_input_takes_over_after_the_queued_samples():
    chip = BMG160(seed=SEED, noise=False)
    chip.write(0x10, bytes([0x04]))
    chip.advance(0.2)
    chip.queue_true_rate((50.0, 0.0, 0.0))
    chip.advance(0.1)  # 20 samples due at 50 deg/s, not computed yet
    chip.set_true_rate((-50.0, 0.0, 0.0))  # from the next sample on
    chip.write(0x3E, bytes([0x80]))
    chip.advance(0.2)
    x = np.frombuffer(chip.read(0x02, 6), dtype="<i2")[0] / chip.sensitivity
    assert abs(x + 50.0) < 0.1  # the new rate holds at the end
    chip.write(0x3E, bytes([0x00]))


@pytest.mark.parametrize("bad", [(1.0, 2.0), "abc", (1.0, float("nan"), 0.0), np.zeros((4, 3))])
def test_queue_true_rate_refuses_anything_but_three_finite_numbers(bad):
    chip = BMG160(seed=SEED)
    with pytest.raises(ValueError, match="true rate"):
        chip.queue_true_rate(bad)
