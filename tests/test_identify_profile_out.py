"""--profile-out writes TOML that generate and firmware build read back, for every value type.

The blocker of issue 11: a fitted T on its search bound was a numpy scalar, written as
``np.float64(0.01)``, which is not TOML; identify exited 0 and generate refused the file.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bmg160_emu.cli import main
from bmg160_emu.firmware.params_header import render_params_header
from bmg160_emu.noise import NoiseGenerator, ProfileError, load_profile
from bmg160_emu.noise.profile import AxisNoise, Profile
from bmg160_emu.noise.profile_writer import format_profile, toml_float, write_profile

# values on the search bounds of identify (T = 2 / rate, T = the longest tau), zeros of
# absent terms, numpy scalars of every float width, and extreme but finite magnitudes
BOUND_VALUES = [
    AxisNoise(N=np.float64(0.0178), B=np.float64(0.0), T=np.float64(0.01), K=np.float32(0.0),
              bias=np.float64(-0.1)),
    AxisNoise(N=np.float32(1e-5), B=np.float64(4e-3), T=np.float64(163.84), K=np.float16(1e-3),
              bias=np.int64(0)),
    # extreme magnitudes within the profile's bounds (|bias| <= 1e4 deg/s keeps every sample
    # finite: noise.profile.LIMITS)
    AxisNoise(N=1e-300, B=1e-12, T=1e12, K=5e-324, bias=-1e4, Q=np.float64(1e-3),
              R=np.float64(2e-6)),
]


def test_toml_float_is_a_plain_float_literal_for_numpy_scalars():
    assert toml_float(np.float64(0.01)) == "0.01"
    assert toml_float(np.float32(0.5)) == "0.5"
    assert toml_float(np.int64(3)) == "3.0"
    with pytest.raises(ProfileError, match="finite"):
        toml_float(np.float64("nan"), "T")
    with pytest.raises(ProfileError, match="finite"):
        toml_float(math.inf, "B")


def test_values_on_every_bound_round_trip_through_the_file(tmp_path):
    profile = Profile("bounds", *BOUND_VALUES)
    path = tmp_path / "bounds.toml"
    write_profile(profile, path, header="values on the search bounds")
    back = load_profile(path)
    for mine, read in zip(profile.axes, back.axes):
        for key in ("N", "B", "T", "K", "bias", "Q", "R"):
            assert getattr(read, key) == float(getattr(mine, key)), key  # bit for bit
    assert "np." not in format_profile(profile)
    assert NoiseGenerator(path, seed=1).generate(10).shape == (10, 3)


def test_firmware_build_reads_the_written_profile(tmp_path):
    profile = Profile("fw", *[BOUND_VALUES[0], BOUND_VALUES[1], BOUND_VALUES[0]])
    path = tmp_path / "fw.toml"
    write_profile(profile, path)
    text = render_params_header(profile=path)
    assert "bmg_noise_alpha" in text and "BMG_PROFILE_NAME \"fw\"" in text


def test_the_issue_blocker_case_through_the_cli(tmp_path, capsys):
    # the issue's reproduction: record 10 min at 200 Hz, seed 7 -> identify --profile-out ->
    # generate; a 10 min record puts T on a search bound on at least one axis
    record, prof, out = tmp_path / "s.csv", tmp_path / "p.toml", tmp_path / "x.npy"
    assert main(["record", "--duration", "10min", "--rate", "200", "--seed", "7",
                 "-o", str(record)]) == 0
    assert main(["identify", str(record), "--profile-out", str(prof)]) == 0
    capsys.readouterr()
    assert "np." not in prof.read_text()
    assert main(["generate", "--profile", str(prof), "--duration", "10s", "--seed", "1",
                 "-o", str(out)]) == 0
    assert np.load(out).shape == (2000, 3)
    render_params_header(profile=prof)


def test_firmware_build_refuses_several_terms_with_a_clear_message(tmp_path):
    multi = AxisNoise(N=0.02, B=0.0, T=0.0, K=0.0, bias=0.0, gm=((1e-3, 5.0), (1e-3, 60.0)))
    path = tmp_path / "multi.toml"
    write_profile(Profile("multi", multi, multi, multi), path)
    with pytest.raises(ValueError, match="2 Gauss-Markov terms.*--poles 1"):
        render_params_header(profile=path)
