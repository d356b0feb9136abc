"""A profile's measured output response and resonant bands (issue 37): written and read back,
drawn by generate's path (the response at the rate it was measured at, the bands then inside
it) and by the engine (the bands as resonators, before any output filter)."""

import math

import numpy as np
import pytest

from bmg160_emu.noise import NoiseGenerator
from bmg160_emu.noise.profile import AxisNoise, Profile, ProfileError, load_profile
from bmg160_emu.noise.profile_writer import write_profile
from bmg160_emu.noise.sensor_noise import profile_noise

# a two-sample average (lag-1 1/2 / (1/4 + 1/4 + ...)): |H|^2 = 1/2 + 2 (1/4) cos w
AVERAGE = (0.5, 0.25)


def _profile(band=(), response=()):
    from bmg160_emu.noise.profile import OutputStage

    axis = AxisNoise(N=0.02, B=0.0, T=0.0, K=0.0, bias=0.0, band=band, response=response)
    return Profile("t", axis, axis, axis, output=OutputStage(rate_hz=100.0))


def test_band_and_response_round_trip(tmp_path):
    p = _profile(band=((19.9, 0.5, 0.2), (20.8, 1.0, 0.18)), response=AVERAGE)
    path = tmp_path / "p.toml"
    write_profile(p, path)
    back = load_profile(path)
    assert back.x.band == p.x.band and back.x.response == p.x.response
    assert back.output == p.output


@pytest.mark.parametrize("bad, words", [
    ({"band": [{"f": 0.0, "width": 1.0, "B": 0.1}]}, "must be positive"),
    ({"band": [{"f": 10.0, "B": 0.1}]}, "needs exactly f"),
    ({"response": [0.5, 0.3]}, "c0 + 2"),
    ({"response": [0.5, "a"]}, "response[1]"),
])
def test_bad_band_or_response_is_refused(bad, words):
    table = {"N": 0.01, "B": 0.0, "T": 0.0, "K": 0.0, "bias": 0.0, **bad}
    with pytest.raises(ProfileError, match=words.replace("[", r"\[").replace("+", r"\+")):
        load_profile({"name": "t", "x": table, "y": table, "z": table})


def test_generate_applies_the_response_at_its_rate():
    gen = profile_noise(_profile(response=AVERAGE), seed=4)
    x = gen.generate(200_000)[:, 0]
    c = x - x.mean()
    lag1 = float(c[:-1] @ c[1:] / (c @ c))
    # white of std N sqrt(rate) through [1/2, 1/2]: std / sqrt(2), lag-1 0.5 (200,000
    # samples: sd of the lag-1 estimate ~0.002, of the std ~0.2 %)
    assert abs(lag1 - 0.5) < 0.01
    assert abs(x.std() / (0.02 * math.sqrt(100.0) / math.sqrt(2.0)) - 1) < 0.01
    assert "response2/2/2taps" in gen.describe() and gen.notes == []


def test_response_elsewhere_is_not_applied_and_says_so():
    gen = profile_noise(_profile(response=AVERAGE), rate_hz=200.0, seed=4)
    assert gen.responses is None and "not applied at 200 Hz" in gen.notes[0]


def test_filter_above_the_new_nyquist_is_left_out_with_a_note():
    from bmg160_emu.noise.profile import OutputStage

    axis = AxisNoise(N=0.02, B=0.0, T=0.0, K=0.0, bias=0.0)
    p = Profile("t", axis, axis, axis, output=OutputStage(order=2, corner_hz=180.0,
                                                          rate_hz=400.0))
    gen = profile_noise(p, rate_hz=200.0, seed=1)
    assert gen.bandwidth_hz is None and "above the Nyquist frequency of 200 Hz" in gen.notes[0]


def test_band_is_drawn_by_the_engine_with_its_power_and_centre():
    from scipy.signal import welch

    p = _profile(band=((15.0, 1.0, 0.06),))
    x = NoiseGenerator(p, rate_hz=100.0, seed=3).generate(400_000)[:, 0]
    # variance N^2 rate + B^2 = 0.04 + 0.0036; 400,000 samples: sd of the variance ~0.3 %
    assert abs(x.var() / (0.02**2 * 100.0 + 0.06**2) - 1) < 0.02
    f, s = welch(x, 100.0, nperseg=4096)
    assert abs(f[np.argmax(s)] - 15.0) < 0.2


def test_band_stream_is_chunk_invariant_and_leaves_other_profiles_unchanged():
    p = _profile(band=((15.0, 1.0, 0.06),))
    whole = NoiseGenerator(p, rate_hz=100.0, seed=3).generate(70_000)
    gen = NoiseGenerator(p, rate_hz=100.0, seed=3)
    cut = np.concatenate([gen.generate(n) for n in (1, 5, 1000, 33_333, 35_661)])
    assert np.array_equal(whole, cut)
    plain = _profile()
    a = NoiseGenerator(plain, rate_hz=100.0, seed=3).generate(5000)
    b = NoiseGenerator(p, rate_hz=100.0, seed=3).generate(5000)
    # the band adds its own stream and leaves the white one as it was: the difference is the
    # band alone, of std B = 0.06 (5000 samples, correlation time 1 / (pi width) = 0.3 s:
    # ~160 independent values, sd of the std ~6 %)
    assert abs((b - a)[:, 0].std() / 0.06 - 1) < 0.2


def test_band_above_nyquist_is_silent_there():
    p = _profile(band=((80.0, 1.0, 0.5),))
    x = NoiseGenerator(p, rate_hz=100.0, seed=3).generate(20_000)[:, 0]
    assert abs(x.std() / (0.02 * 10.0) - 1) < 0.03  # the 0.5 deg/s band left out at 100 Hz


def test_generate_leaves_the_bands_to_the_response():
    p = _profile(band=((15.0, 1.0, 0.5),), response=(1.0,))  # a flat measured response
    x = profile_noise(p, seed=2).generate(50_000)[:, 0]
    assert abs(x.std() / 0.2 - 1) < 0.03  # white only: the band is inside the response


def test_the_response_gives_the_same_samples_however_the_record_is_cut():
    p = _profile(response=(0.6, 0.15, 0.05))
    whole = profile_noise(p, seed=5).generate(20_000)
    gen = profile_noise(p, seed=5)
    cut = np.concatenate([gen.generate(n) for n in (1, 3, 700, 9_296, 10_000)])
    assert np.array_equal(whole, cut)
