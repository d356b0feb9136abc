"""Slow bands (noise/slow_bands.py, issue 37): a bump in the slow spectrum, below the output
stage's range, found against the fit's own terms, carried in the profile's ``slow_band`` and
drawn by generate in every route (never left to the measured response).

The simulated sensor: white noise N = 0.04 deg/s/sqrt(Hz), a Gauss-Markov bias of 60 s, a
resonant band at 20 Hz (so that the record goes through the measured-response route, as the
ADIS16405's z axis does) and a slow band at 0.3 Hz, 0.06 Hz wide, B = 0.015 deg/s; 50 min at
100 Hz. Over seeds 0-4 the band was found every time: centre 0.288-0.313 Hz (largest error
0.013 Hz), width 0.027-0.052 Hz, power 0.62-1.21 of the truth; the tolerances below are about
twice those.
"""

from __future__ import annotations

import numpy as np
import pytest

from bmg160_emu.noise.identify import identify_axis
from bmg160_emu.noise.profile import AxisNoise, Profile, ProfileError, load_profile
from bmg160_emu.noise.profile_writer import write_profile
from bmg160_emu.noise.sensor_noise import profile_noise

RATE = 100.0
SLOW = (0.3, 0.06, 0.015)  # f Hz, width Hz, B deg/s


def _record(slow: tuple = (SLOW,), seed: int = 0, n: int = 300_000) -> np.ndarray:
    from bmg160_emu.noise.profile import OutputStage

    axis = AxisNoise(N=0.04, B=0.0, T=0.0, K=0.0, bias=0.0, gm=((0.01, 60.0),),
                     band=((20.0, 1.0, 0.2),), slow_band=slow)
    profile = Profile("t", axis, axis, axis, output=OutputStage(rate_hz=RATE))
    return profile_noise(profile, RATE, seed=seed).generate(n)[:, 0]


@pytest.fixture(scope="module")
def identified():
    return identify_axis(_record(), RATE)


def test_a_slow_band_is_found_with_its_centre_width_and_power(identified):
    bands = identified.stage.slow_bands
    assert len(bands) == 1
    band = bands[0]
    assert abs(band.centre_hz - SLOW[0]) < 0.03
    assert SLOW[1] / 3.0 < band.width_hz < SLOW[1] * 3.0
    assert 0.4 < band.power / SLOW[2] ** 2 < 2.0
    assert band.power - band.power_half > 0  # kept: its power's interval leaves out 0
    assert any("slow band" in note for note in identified.notes)
    from bmg160_emu.noise.identification_result import Identification

    summary = Identification(RATE, 300_000, [identified], "t").summary()
    assert "slow band at 0.2" in summary or "slow band at 0.3" in summary


def test_the_profile_carries_it_and_generate_draws_it_beside_the_response(identified, tmp_path):
    from bmg160_emu.noise.identification_result import Identification

    result = Identification(RATE, 300_000, [identified], "t")
    profile = result.to_profile("slow")
    assert profile.x.slow_band and profile.x.response and profile.x.band
    path = tmp_path / "slow.toml"
    write_profile(profile, path)
    assert "slow_band = [" in path.read_text(encoding="utf-8")
    loaded = load_profile(str(path))
    assert np.allclose(loaded.x.slow_band, profile.x.slow_band, rtol=1e-15)
    noise = profile_noise(loaded, RATE, seed=1)
    drawn = noise.generator.profile.x
    assert drawn.band == () and drawn.slow_band == loaded.x.slow_band  # bands left to the
    # response at its rate, the slow band drawn beside it
    # the emulated record has the bump: power at 0.25-0.35 Hz over that at 0.6-0.9 Hz
    from scipy.signal import welch

    y = noise.generate(300_000)[:, 0]
    f, p = welch(y - y.mean(), RATE, nperseg=1 << 13)
    x = _record(seed=7)
    _, p2 = welch(x - x.mean(), RATE, nperseg=1 << 13)
    bump = (f > 0.25) & (f < 0.35)
    side = (f > 0.6) & (f < 0.9)
    ratio_emulated = p[bump].mean() / p[side].mean()
    ratio_true = p2[bump].mean() / p2[side].mean()
    # each ratio is a mean of ~30 Welch bins over ~70 segments: scatter about 4 %
    assert ratio_emulated == pytest.approx(ratio_true, rel=0.25)
    assert ratio_emulated > 1.15  # without the band: 1.0 within 4 %


def test_no_slow_band_on_a_record_without_one():
    assert identify_axis(_record(slow=()), RATE).stage.slow_bands == []


def test_a_malformed_slow_band_is_named(tmp_path):
    path = tmp_path / "bad.toml"
    axis = "N = 0.01\nB = 0.0\nT = 0.0\nK = 0.0\nbias = 0.0\n"
    path.write_text(f"name = 'bad'\n[x]\n{axis}slow_band = [{{ f = 0.3, width = 0.0, B = 0.01 }}]"
                    f"\n[y]\n{axis}[z]\n{axis}", encoding="utf-8")
    with pytest.raises(ProfileError, match=r"slow_band\[0\]: f and width must be positive"):
        load_profile(str(path))


def test_a_flat_record_gets_its_slow_band_too():
    """No output stage (white at the output, as the MPU-6050 record): the band is searched
    against the white-noise fit the record gets anyway, found, and fitted with it."""
    axis = AxisNoise(N=0.04, B=0.0, T=0.0, K=0.0, bias=0.0, gm=((0.01, 60.0),),
                     slow_band=(SLOW,))
    x = profile_noise(Profile("t", axis, axis, axis), RATE, seed=0).generate(300_000)[:, 0]
    found = identify_axis(x, RATE)
    assert found.stage is not None and found.stage.response.order == 0
    (band,) = found.stage.slow_bands
    assert abs(band.centre_hz - SLOW[0]) < 0.03
    assert 0.4 < band.power / SLOW[2] ** 2 < 2.0
    assert found.to_axis_noise().slow_band and not found.to_axis_noise().response
