"""Sampling in time: one sample per output period, no drift, shared and real-time clocks."""

import time

import pytest
from _chip_helpers import quiet_chip

from bmg160_emu.clock import RealTimeClock, VirtualClock
from bmg160_emu.device.chip import BMG160


@pytest.mark.parametrize("code, odr", [(0, 2000), (2, 1000), (3, 400), (4, 200), (5, 100)])
def test_advance_produces_exactly_one_sample_per_output_period(code, odr):
    chip = quiet_chip()
    chip.write(0x10, bytes([code]))
    chip.read(0x00)
    assert chip.odr_hz == odr
    start = chip.state.sample_seq
    for _ in range(1000):
        chip.advance(1.0 / odr)
        # 1/odr is not exact in binary floating point: counting must not drift
    assert chip.state.sample_seq - start == 1000


def test_long_advance_counts_samples_exactly():
    chip = quiet_chip()
    chip.read(0x00)  # sample 0, at t = 0
    start = chip.state.sample_seq
    chip.advance(12.3456)  # 2000 Hz -> floor(24691.2) samples
    assert chip.state.sample_seq - start == 24691


def test_odr_change_keeps_the_sample_grid_from_the_last_sample():
    chip = quiet_chip()
    chip.advance(0.0005)
    chip.write(0x10, b"\x05")  # 100 Hz
    start = chip.state.sample_seq
    chip.advance(0.0099)
    assert chip.state.sample_seq == start
    chip.advance(0.0001)
    assert chip.state.sample_seq == start + 1


def test_two_chips_on_one_clock_stay_in_step():
    clock = VirtualClock()
    a = BMG160(seed=1, clock=clock, address=0x68, noise=False)
    b = BMG160(seed=1, clock=clock, address=0x69, noise=False)
    a.advance(0.25)  # advancing through one chip moves the shared clock
    assert b.time == a.time == 0.25
    b.read(0x00)
    assert a.state.sample_seq == b.state.sample_seq


def test_real_time_clock_chip_produces_samples_in_real_time():
    chip = BMG160(noise=False, clock=RealTimeClock())
    chip.write(0x10, b"\x05")  # 100 Hz
    t_before_first = time.monotonic()
    chip.read(0x00)
    t_after_first = time.monotonic()
    start = chip.state.sample_seq
    time.sleep(0.1)
    t_before_second = time.monotonic()
    chip.read(0x00)
    t_after_second = time.monotonic()
    produced = chip.state.sample_seq - start
    # the samples due between the two reads, bounded by the times around them (+-1 edge)
    assert (t_before_second - t_after_first) * 100 - 1 <= produced
    assert produced <= (t_after_second - t_before_first) * 100 + 1


def test_chip_time_is_the_clock_time():
    chip = quiet_chip()
    chip.advance(1.5)
    assert chip.time == 1.5
