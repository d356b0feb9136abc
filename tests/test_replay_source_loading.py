"""Replay of real data: recordings are checked line by line, and resampled as documented."""

from __future__ import annotations

import numpy as np
import pytest

from bmg160_emu.io.rate_table import RateFileError
from bmg160_emu.io.replay_data import ReplayData, load_replay_data
from bmg160_emu.session.rate_replay import ReplaySource


def _csv(tmp_path, text: str, name: str = "flight.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_headerless_four_column_csv_is_time_and_xyz_in_dps(tmp_path):
    path = _csv(tmp_path, "# lab turntable\n0.00,1,2,3\n0.01,4,5,6\n0.02,7,8,9\n")
    data = load_replay_data(path)
    assert data.t_s.tolist() == [0.0, 0.01, 0.02]
    assert data.rate_dps[1].tolist() == [4.0, 5.0, 6.0]


def test_header_names_pick_columns_in_any_order(tmp_path):
    path = _csv(tmp_path, "temp,gz,gy,gx,time\n20,3,2,1,0.0\n20,6,5,4,0.1\n")
    data = load_replay_data(path)
    assert data.rate_dps.tolist() == [[1, 2, 3], [4, 5, 6]]


def test_counts_are_converted_with_the_given_sensitivity(tmp_path):
    path = _csv(tmp_path, "t_s,x_counts,y_counts,z_counts\n0,164,0,-164\n0.005,0,0,0\n")
    data = load_replay_data(path, unit="counts", lsb_per_dps=16.4)
    assert data.rate_dps[0] == pytest.approx([10.0, 0.0, -10.0])
    with pytest.raises(RateFileError, match="need the sensitivity"):
        load_replay_data(path, unit="counts")


def test_wrong_column_count_names_the_line(tmp_path):
    path = _csv(tmp_path, "0.0,1,2,3\n0.1,1,2\n")
    with pytest.raises(RateFileError, match=r"flight.csv:2: 3 columns, expected 4"):
        load_replay_data(path)
    path = _csv(tmp_path, "0.0,1,2,3,4\n", name="five.csv")
    with pytest.raises(RateFileError, match=r"five.csv:1: 5 columns without a header"):
        load_replay_data(path)


def test_non_monotonic_time_names_the_line(tmp_path):
    path = _csv(tmp_path, "t,x,y,z\n0.00,0,0,0\n0.01,0,0,0\n0.01,0,0,0\n0.03,0,0,0\n")
    with pytest.raises(RateFileError, match=r"flight.csv:4: time 0.01 s is not after"):
        load_replay_data(path)


def test_gap_names_the_line_after_it(tmp_path):
    rows = [f"{0.01 * k:.2f},0,0,0" for k in range(10)] + ["0.50,0,0,0"]
    path = _csv(tmp_path, "\n".join(rows) + "\n")
    with pytest.raises(RateFileError, match=r"flight.csv:11: gap of 0.41 s"):
        load_replay_data(path)
    assert len(load_replay_data(path, max_gap_factor=100).t_s) == 11


def test_unit_mismatch_in_header_is_refused(tmp_path):
    path = _csv(tmp_path, "t,x_counts,y_counts,z_counts\n0,1,2,3\n1,1,2,3\n")
    with pytest.raises(RateFileError, match="unit mismatch: column 'x_counts' holds counts"):
        load_replay_data(path, unit="dps")


def test_counts_given_as_dps_are_caught_by_their_size(tmp_path):
    path = _csv(tmp_path, "0,1,2,3\n0.01,16384,0,0\n")
    with pytest.raises(RateFileError, match=r"flight.csv:2: .* beyond the widest range.*use unit counts"):
        load_replay_data(path, unit="dps")


def test_dps_given_as_counts_are_caught_by_their_fractions(tmp_path):
    path = _csv(tmp_path, "0,1,2,3\n0.01,0.25,0,0\n")
    with pytest.raises(RateFileError, match=r"flight.csv:2: raw counts must be whole numbers"):
        load_replay_data(path, unit="counts", lsb_per_dps=16.384)


def test_not_a_number_names_the_line(tmp_path):
    path = _csv(tmp_path, "0,1,2,3\n0.01,abc,0,0\n")
    with pytest.raises(RateFileError, match=r"flight.csv:2: not a number: 'abc'"):
        load_replay_data(path)


def test_npz_with_counts_when_dps_were_asked_is_a_unit_mismatch(tmp_path):
    path = tmp_path / "bench.npz"
    np.savez(path, t_s=np.arange(3) * 0.01, counts=np.zeros((3, 3)))
    with pytest.raises(RateFileError, match="unit mismatch"):
        load_replay_data(path, unit="dps")
    assert load_replay_data(path, unit="counts", lsb_per_dps=16.384).rate_dps.shape == (3, 3)


def test_npz_rows_are_named_in_errors(tmp_path):
    path = tmp_path / "bench.npz"
    np.savez(path, t=np.array([0.0, 0.01, 0.005]), rate_dps=np.zeros((3, 3)))
    with pytest.raises(RateFileError, match=r"bench.npz: row 2: time"):
        load_replay_data(path)


class _Chip:
    """Only what the hook reads: the output data rate."""

    def __init__(self, odr_hz: float):
        self.odr_hz = odr_hz
        self.sample_hooks: list = []


def test_equal_rate_plays_the_recorded_samples_exactly():
    t = 0.005 * np.arange(1, 6)
    rate = np.arange(15, dtype=float).reshape(5, 3)
    source = ReplaySource(ReplayData(t, rate))
    chip = _Chip(200.0)
    played = [source(chip, 10.0 + 0.005 * k, None) for k in range(5)]
    assert np.array_equal(np.array(played), rate)


def test_slower_odr_averages_each_output_period_and_faster_interpolates():
    t = 0.001 * np.arange(100)
    rate = np.column_stack([t * 1000, np.zeros(100), np.zeros(100)])  # x ramps 1 deg/s per ms
    slow = ReplaySource(ReplayData(t, rate))
    chip = _Chip(100.0)  # 10 ms periods over 1 ms samples: mean of 10 samples
    slow(chip, 0.0, None)
    second = slow(chip, 0.010, None)
    assert second[0] == pytest.approx(np.mean(np.arange(1, 11)))
    fast = ReplaySource(ReplayData(t, rate))
    chip = _Chip(2000.0)
    fast(chip, 0.0, None)
    assert fast(chip, 0.0005, None)[0] == pytest.approx(0.5)


def test_after_the_end_the_last_value_is_held_or_the_recording_loops():
    t = np.array([0.0, 0.01, 0.02])
    rate = np.array([[1.0, 0, 0], [2.0, 0, 0], [3.0, 0, 0]])
    held = ReplaySource(ReplayData(t, rate))
    chip = _Chip(100.0)
    assert [held(chip, 0.01 * k, None)[0] for k in range(5)] == [1, 2, 3, 3, 3]
    looped = ReplaySource(ReplayData(t, rate), loop=True)
    assert [looped(chip, 0.01 * k, None)[0] for k in range(5)] == pytest.approx([1, 2, 3, 1, 2])
