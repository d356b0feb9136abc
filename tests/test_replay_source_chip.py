"""Replay of a recording through the register interface gives back the same samples."""

from __future__ import annotations

import numpy as np
import pytest

from bmg160_emu.device.chip import BMG160
from bmg160_emu.io.recording import write_recording
from bmg160_emu.io.replay_data import load_replay_data
from bmg160_emu.session.rate_replay import ReplaySource
from bmg160_emu.session.record import record

BW_200HZ, BW_100HZ = 0x04, 0x05  # spec 5.3


def _chip(seed: int, bw: int, noise: bool = True) -> BMG160:
    chip = BMG160(seed=seed, noise=noise)
    chip.write(0x10, bytes([bw]))
    chip.write(0x0F, b"\x01")  # +-1000 deg/s
    return chip


def _original(tmp_path, suffix: str):
    chip = _chip(21, BW_200HZ)
    chip.set_true_rate(lambda t: (30.0 * np.sin(2 * np.pi * 0.5 * t), 5.0, -12.0))
    rec = record(chip, 3.0)
    path = tmp_path / f"flight{suffix}"
    write_recording(rec, path)
    return rec, path


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
@pytest.mark.parametrize("unit", ["counts", "dps"])
def test_replay_then_record_gives_back_the_same_samples_at_the_same_rate(tmp_path, suffix, unit):
    original, path = _original(tmp_path, suffix)
    data = load_replay_data(path, unit=unit)
    # a different seed: the replayed samples replace the chip's own noise
    chip = _chip(99, BW_200HZ)
    ReplaySource(data).attach(chip)
    again = record(chip, 3.0)
    assert again.odr_hz == original.odr_hz
    assert np.array_equal(again.t_s, original.t_s)
    assert np.array_equal(again.counts, original.counts)


def test_a_replay_reaches_a_driver_through_the_rate_registers(tmp_path):
    original, path = _original(tmp_path, ".csv")
    chip = _chip(5, BW_200HZ)
    ReplaySource(load_replay_data(path, unit="counts")).attach(chip)
    chip.advance(0.005 * 10)  # ten output periods: the tenth recorded sample is current
    assert tuple(np.frombuffer(chip.read(0x02, 6), "<i2")) == tuple(original.counts[9])


def test_a_slower_chip_averages_the_recording_over_each_output_period(tmp_path):
    original, path = _original(tmp_path, ".npz")
    chip = _chip(5, BW_100HZ, noise=False)
    ReplaySource(load_replay_data(path, unit="dps")).attach(chip)
    slow = record(chip, 2.0)
    assert slow.odr_hz == 100.0
    # output k (k >= 1) is the mean of the two 200 Hz samples in its 10 ms period (docs/replay.md)
    pairs = original.rate_dps[1:399:2] + original.rate_dps[2:400:2]
    expected = np.rint(pairs / 2 * chip.sensitivity)
    assert np.array_equal(slow.counts[1:200], expected[:199])
