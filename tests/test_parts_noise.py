"""Per-part noise profiles: the data-sheet figure by default, and the BMI055 fitted to the
published Allan deviation of a real unit (the BMI055 in an Intel RealSense D455)."""

from __future__ import annotations

import numpy as np
import pytest

from bmg160_emu.device.parts import PART_NAMES, make_chip, part_table
from bmg160_emu.noise import NoiseGenerator
from bmg160_emu.noise.allan import composite_avar, overlapping_adev
from bmg160_emu.noise.profile import load_profile

# the published figures of the D455's BMI055 (20.5 h at 400 Hz; bmi055_d455.toml)
ADEV_1S = (0.0052, 0.0070)  # deg/s at tau = 1 s, over the three axes
ADEV_MIN = (5.3e-4, 5.7e-4)  # deg/s
TAU_MIN_S = (215.0, 875.0)


@pytest.mark.parametrize("name", [p for p in PART_NAMES if p != "bmg160"])
def test_each_part_defaults_to_its_data_sheet_profile(name):
    chip = make_chip(name, seed=1)
    profile = chip.state.path.noise.generator.profile
    assert profile.name == part_table(name).noise_profile == name.split("_")[0] + "_datasheet"
    # 0.014 deg/s/sqrt(Hz), one-sided: BMI088 DS gyroscope table; for the BMI055/BMX055 the
    # BMG160 die's figure; IEEE 952's (two-sided) N is 0.014 / sqrt(2)
    assert all(axis.N == 0.014 / np.sqrt(2) and axis.bias == 0.0 for axis in profile.axes)


def test_the_bmg160_keeps_its_default_and_a_given_profile_wins():
    assert make_chip("bmg160", seed=1).state.path.noise.generator.profile.name == "paper"
    chip = make_chip("bmi088_gyro", seed=1, profile="bmi055_d455")
    assert chip.state.path.noise.generator.profile.name == "bmi055_d455"


@pytest.mark.parametrize("axis", range(3))
def test_bmi055_d455_profile_reproduces_the_published_figures(axis):
    p = load_profile("bmi055_d455").axes[axis]
    taus = np.logspace(-1, 4, 2001)
    adev = np.sqrt(composite_avar(taus, p.N, p.B, p.T, p.K))
    at_1s = float(np.interp(0.0, np.log10(taus), adev))
    i = int(adev.argmin())
    assert ADEV_1S[0] * 0.999 <= at_1s <= ADEV_1S[1] * 1.001
    assert ADEV_MIN[0] * 0.999 <= adev[i] <= ADEV_MIN[1] * 1.001
    assert TAU_MIN_S[0] * 0.98 <= taus[i] <= TAU_MIN_S[1] * 1.02


def test_bmi055_d455_generated_noise_has_the_fitted_adev_at_1s():
    # 20 min at 400 Hz, the dataset's rate: the overlapping ADEV at 1 s averages ~1200
    # clusters, about 3 % standard error (edf ~ N/tau for white noise); 12 % is four sigma
    rate_hz, seconds = 400.0, 1200
    x = NoiseGenerator("bmi055_d455", rate_hz=rate_hz, seed=5).generate(int(rate_hz * seconds))
    for axis, expected in enumerate(load_profile("bmi055_d455").axes):
        curve = overlapping_adev(x[:, axis], rate_hz, taus=np.array([1.0]))
        model = np.sqrt(composite_avar(np.array([1.0]), expected.N, expected.B, expected.T,
                                       expected.K))[0]
        assert curve.adev[0] == pytest.approx(model, rel=0.12), axis
