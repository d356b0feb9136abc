"""Noise profiles: built-ins, user TOML files, validation with clear errors."""

from __future__ import annotations

import math

import pytest

from bmg160_emu.noise import AxisNoise, NoiseGenerator, Profile, ProfileError, load_profile
from bmg160_emu.noise.profile import builtin_profile_names
from bmg160_emu.noise.profile_writer import format_profile, write_profile

PAPER_TEXT = """
name = "mine"
[x]
N = 0.02
B = 0.004
T = 30.0
K = 0.0004
bias = 0.1
[y]
N = 0.02
B = 0.004
T = 30.0
K = 0.0004
bias = -0.1
[z]
N = 0.02
B = 0.004
T = 30.0
K = 0.0004
bias = 0.0
Q = 0.001
R = 0.00001
"""


def test_builtin_profiles_are_paper_and_datasheet():
    assert {"paper", "datasheet"} <= set(builtin_profile_names())


def test_paper_profile_holds_the_papers_identified_values_on_every_axis():
    profile = load_profile("paper")
    for axis in profile.axes:
        assert axis.N == 1.779073e-2  # paper section 2.5
        assert axis.B == 4.047421e-3
        assert axis.K == 4.023987e-4
        assert axis.T == 33.9  # paper section 2.6.1
        assert axis.bias == 0.116359
        assert axis.sigma_K == 10.2515


def test_datasheet_profile_has_the_datasheet_noise_density():
    # the data sheet's 0.014 deg/s/sqrt(Hz) is one-sided (its 0.1 deg/s rms at 47 Hz is
    # 0.014 sqrt(47)); IEEE 952's N is two-sided: N = 0.014 / sqrt(2)
    assert all(axis.N == 0.014 / math.sqrt(2) for axis in load_profile("datasheet").axes)


def test_user_profile_file_loads_with_optional_q_and_r(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(PAPER_TEXT)
    profile = load_profile(path)
    assert profile.name == "mine"
    assert profile.y.bias == -0.1
    assert profile.z.Q == 0.001 and profile.z.R == 0.00001
    assert profile.x.Q == 0.0
    NoiseGenerator(str(path), seed=1).generate(10)


def test_written_profile_loads_back_identically(tmp_path):
    profile = load_profile("paper")
    path = tmp_path / "back.toml"
    write_profile(profile, path, header="written by a test\nsecond line")
    assert load_profile(path) == profile
    assert format_profile(profile).count("[x]") == 1


def test_unknown_profile_name_is_a_clear_error():
    with pytest.raises(ProfileError, match="unknown noise profile 'nope'.*paper"):
        load_profile("nope")


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (
            lambda t: t.replace("T = 30.0\nK = 0.0004\nbias = 0.1\n", "K = 0.0004\nbias = 0.1\n"),
            "missing field",
        ),
        (lambda t: t.replace("N = 0.02", "N = -0.02", 1), "must not be negative"),
        (lambda t: t.replace("B = 0.004", "B = 'big'", 1), "must be a number"),
        (lambda t: t.replace("K = 0.0004", "K = nan", 1), "must be finite"),
        (lambda t: t.replace("bias = 0.1", "bias = 0.1\nnoise = 3", 1), "unknown field"),
        (lambda t: t.split("[z]")[0], r"missing table \[z\]"),
        (lambda t: t + "\n[[broken", "not valid TOML"),
        (lambda t: t.replace("T = 30.0", "T = 0.0", 1), "T must be positive"),
    ],
)
def test_bad_profile_file_is_a_clear_error(tmp_path, edit, message):
    path = tmp_path / "bad.toml"
    path.write_text(edit(PAPER_TEXT))
    with pytest.raises(ProfileError, match=message):
        load_profile(path)


def test_generator_rejects_a_bad_profile_with_a_value_error():
    with pytest.raises(ValueError, match="unknown noise profile"):
        NoiseGenerator("missing-profile")


def test_paper_mode_needs_the_paper_fields():
    with pytest.raises(ValueError, match="paper mode needs sigma_gyro and sigma_K"):
        NoiseGenerator("datasheet", mode="paper")


def test_paper_mode_profile_whose_std_cannot_hold_its_terms_is_rejected_up_front():
    # sigma_gyro below B leaves a negative variance for the white term (paper eq. 16)
    axis = AxisNoise(N=0.0178, B=0.004, T=33.9, K=4e-4, bias=0.0, sigma_gyro=0.003, sigma_K=10.0)
    with pytest.raises(ValueError, match="eq. 16"):
        NoiseGenerator(Profile("bad", axis, axis, axis), mode="paper")
