"""Recording files: CSV and NPZ keep every sample exactly, and broken files are named."""

from __future__ import annotations

import numpy as np
import pytest

from bmg160_emu.io.rate_table import RateFileError
from bmg160_emu.io.recording import Recording, read_recording, write_recording
from bmg160_emu.io.replay_data import load_replay_data


def _recording(with_truth: bool = True) -> Recording:
    rng = np.random.default_rng(3)
    n = 50
    t = 0.005 * np.arange(1, n + 1)
    counts = rng.integers(-32768, 32768, size=(n, 3))
    truth = rng.normal(size=(n, 3)) if with_truth else None
    return Recording(t, counts, 16.384, truth, {"odr_hz": 200.0, "range_dps": 2000, "seed": 3})


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_every_sample_survives_the_file_round_trip(tmp_path, suffix):
    rec = _recording()
    path = tmp_path / f"out{suffix}"
    write_recording(rec, path)
    back = read_recording(path)
    assert np.array_equal(back.t_s, rec.t_s)
    assert np.array_equal(back.counts, rec.counts)
    assert np.array_equal(back.rate_dps, rec.rate_dps)
    assert np.array_equal(back.true_rate_dps, rec.true_rate_dps)
    assert back.lsb_per_dps == rec.lsb_per_dps
    assert back.metadata == rec.metadata
    assert back.odr_hz == 200.0


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_a_recording_without_truth_keeps_none(tmp_path, suffix):
    path = tmp_path / f"out{suffix}"
    write_recording(_recording(with_truth=False), path)
    assert read_recording(path).true_rate_dps is None


def test_rate_in_dps_is_counts_over_sensitivity():
    rec = _recording()
    assert np.allclose(rec.rate_dps * 16.384, rec.counts)


def test_csv_columns_and_settings_are_self_describing(tmp_path):
    path = tmp_path / "out.csv"
    write_recording(_recording(), path)
    lines = path.read_text().splitlines()
    assert lines[0] == "# bmg160-emu recording v1"
    assert '"lsb_per_dps": 16.384' in lines[1]
    assert lines[2].startswith("t_s,x_counts,y_counts,z_counts,x_dps,y_dps,z_dps,true_x_dps")


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
@pytest.mark.parametrize("unit", ["dps", "counts"])
def test_a_recording_is_valid_replay_data_in_either_unit(tmp_path, suffix, unit):
    rec = _recording()
    path = tmp_path / f"out{suffix}"
    write_recording(rec, path)
    data = load_replay_data(path, unit=unit, max_gap_factor=10)
    assert np.array_equal(data.t_s, rec.t_s)
    assert np.allclose(data.rate_dps, rec.rate_dps, rtol=0, atol=1e-12)


def test_a_damaged_csv_row_is_named(tmp_path):
    path = tmp_path / "out.csv"
    write_recording(_recording(), path)
    lines = path.read_text().splitlines()
    lines[10] = lines[10].rsplit(",", 1)[0]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(RateFileError, match=r"out.csv:11: 9 columns, expected 10"):
        read_recording(path)


def test_unknown_suffix_is_refused(tmp_path):
    with pytest.raises(RateFileError, match=r"recording file must end in \.csv, \.npz or \.resd, "
                                            r"not 'out\.txt'"):
        write_recording(_recording(), tmp_path / "out.txt")
    assert not (tmp_path / "out.txt").exists()
