"""Virtual and real-time clocks, and virtual_sleep (time.sleep advances virtual time)."""

import time

import numpy as np
import pytest

from bmg160_emu.clock import RealTimeClock, VirtualClock, seconds_to_ns, virtual_sleep
from bmg160_emu.device.chip import BMG160


def test_virtual_clock_moves_only_when_advanced():
    clock = VirtualClock()
    assert clock.now() == 0.0
    clock.advance(0.25)
    assert clock.now_ns() == 250_000_000


def test_virtual_clock_refuses_negative_or_non_finite_steps():
    clock = VirtualClock()
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError):
            clock.advance(bad)
    with pytest.raises(TypeError):
        clock.advance(None)


def test_real_time_clock_follows_monotonic_time():
    clock = RealTimeClock()
    t0 = clock.now()
    time.sleep(0.02)
    assert 0.015 < clock.now() - t0 < 1.0


def test_virtual_sleep_turns_time_sleep_into_virtual_time():
    chip = BMG160(noise=False)
    start = time.monotonic()
    with virtual_sleep(chip):
        time.sleep(100.0)
    assert time.monotonic() - start < 5.0
    assert chip.time == pytest.approx(100.0)


def test_virtual_sleep_can_patch_monotonic_clocks_too():
    clock = VirtualClock()
    with virtual_sleep(clock, patch_clocks=True):
        t0 = time.monotonic()
        p0 = time.perf_counter()
        time.sleep(2.5)
        assert time.monotonic() - t0 == pytest.approx(2.5)
        assert time.perf_counter() - p0 == pytest.approx(2.5)
    assert time.sleep is not None and clock.now() == pytest.approx(2.5)


def test_virtual_sleep_restores_time_sleep():
    real = time.sleep
    with virtual_sleep(VirtualClock()):
        assert time.sleep is not real
    assert time.sleep is real


def test_virtual_sleep_needs_a_virtual_clock():
    with pytest.raises(TypeError), virtual_sleep(RealTimeClock()):
        pass


def test_driver_that_sleeps_between_reads_sees_new_samples():
    chip = BMG160(noise=False, true_rate=lambda t: (t * 100.0, 0.0, 0.0))
    seen = []
    with virtual_sleep(chip):
        for _ in range(5):
            seen.append(chip.read(0x02, 2))
            time.sleep(0.01)
    assert len(set(seen)) == 5


def test_a_string_is_not_a_time_step():
    clock = VirtualClock()
    with pytest.raises(TypeError, match="number of seconds"):
        clock.advance("1")
    with pytest.raises(TypeError, match="number of seconds"):
        BMG160(seed=1, noise=False).advance("0.5")
    assert clock.now() == 0.0


def test_chips_on_one_virtual_clock_share_its_lock_and_follow_a_replaced_clock():
    shared = VirtualClock()
    a, b = BMG160(seed=1, clock=shared), BMG160(seed=2, clock=shared)
    assert a.lock is b.lock is shared.lock  # one acquisition covers chip and time
    a.advance(0.01)
    assert shared.now_ns() == b.clock.now_ns() == 10_000_000
    other = VirtualClock(5.0)  # a clock with its own lock: the chip must go through it
    a.clock = other
    a.advance(0.25)
    assert other.now_ns() == 5_250_000_000 and shared.now_ns() == 10_000_000
    assert a.time == 5.25
    a.clock = RealTimeClock()
    t0 = a.time
    time.sleep(0.02)
    assert a.time - t0 >= 0.02


def test_advance_remembers_only_a_valid_step_and_rounds_each_new_one():
    # advance keeps the last step's rounding (the polling hot path): a bad step between two
    # good ones must still raise, a negative one after its positive twin too, and a mixed
    # sequence must land where seconds_to_ns of each step puts it
    chip = BMG160(seed=1, noise=False)
    steps = [0.005, 0.005, 1e-9, 0.005, 0.0, np.float64(0.005), 2.5e-10, 0.0025, 0.005]
    for step in steps:
        chip.advance(step)
    assert chip.clock.now_ns() == sum(seconds_to_ns(float(s)) for s in steps)
    before = chip.clock.now_ns()
    for bad in (-0.005, float("nan"), "0.005", float("inf")):
        with pytest.raises((TypeError, ValueError, OverflowError)):
            chip.advance(bad)
        with pytest.raises((TypeError, ValueError, OverflowError)):
            chip.advance(bad)  # the second time too: a failed step is not remembered
        chip.advance(0.005)
    assert chip.clock.now_ns() == before + 4 * 5_000_000
