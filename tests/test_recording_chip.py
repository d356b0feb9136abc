"""Recording the chip: what a driver reads at the ODR, with the truth beside it."""

from __future__ import annotations

import numpy as np
import pytest

from bmg160_emu.device.chip import BMG160
from bmg160_emu.io.recording import read_recording, write_recording
from bmg160_emu.session.record import record

TRUE_RATE = (10.0, -5.0, 2.5)


def _quiet_chip(bw_code: int = 0x04, range_code: int = 0x00) -> BMG160:
    chip = BMG160(seed=1, noise=False)
    chip.write(0x10, bytes([bw_code]))
    chip.write(0x0F, bytes([range_code]))
    chip.set_true_rate(TRUE_RATE)
    return chip


def test_one_sample_per_output_period_at_the_chip_odr():
    chip = _quiet_chip(bw_code=0x04)  # 200 Hz (spec 5.3)
    rec = record(chip, 2.0)
    assert len(rec) == 400
    assert np.allclose(np.diff(rec.t_s), 1 / 200, rtol=0, atol=1e-9)
    assert rec.odr_hz == 200.0
    assert rec.metadata["range_dps"] == 2000


def test_counts_are_the_true_rate_scaled_once_the_filter_has_settled():
    chip = _quiet_chip(range_code=0x02)  # +-500 deg/s
    rec = record(chip, 1.0)
    assert rec.lsb_per_dps == chip.sensitivity
    settled = rec.counts[100:]  # 0.5 s: many time constants of the 23 Hz filter
    expected = np.rint(np.array(TRUE_RATE) * chip.sensitivity)
    assert np.array_equal(settled, np.broadcast_to(expected, settled.shape))
    assert np.array_equal(rec.true_rate_dps, np.broadcast_to(TRUE_RATE, rec.true_rate_dps.shape))


def test_the_counts_are_what_a_burst_read_of_the_rate_registers_returns():
    chip = BMG160(seed=3)  # noisy
    chip.write(0x10, b"\x05")  # 100 Hz
    rec = record(chip, 0.2)
    raw = chip.read(0x02, 6)
    assert tuple(rec.counts[-1]) == tuple(np.frombuffer(raw, "<i2"))


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_a_noisy_recording_survives_its_file(tmp_path, suffix):
    chip = BMG160(seed=9)
    chip.write(0x10, b"\x04")
    rec = record(chip, 1.0)
    write_recording(rec, tmp_path / f"r{suffix}")
    back = read_recording(tmp_path / f"r{suffix}")
    assert np.array_equal(back.counts, rec.counts) and np.array_equal(back.t_s, rec.t_s)


def test_bad_durations_are_refused():
    chip = _quiet_chip()
    with pytest.raises(ValueError, match="positive"):
        record(chip, -1.0)
    with pytest.raises(ValueError, match="shorter than one output period"):
        record(chip, 1e-4)
