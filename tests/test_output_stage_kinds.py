"""Each kind of output stage a real sensor has, simulated, found by
noise.output_response.find_output_stage and recovered within stated tolerances.

White noise of N = 0.01 deg/s/sqrt(Hz) at 100 Hz, 30 min (180,000 samples, a Welch PSD of
86 segments of 4096). The tolerances are from 10 seeds of each case (scratch study of
issue 37): response autocorrelation at lags 1-5 off by at most 0.017 (tolerance 0.03), band
centre 0.04 Hz (0.1), width 17 % (25 %), power 19 % (25 %), line amplitude 3.6 % (10 %) and
frequency 0.002 Hz (0.01); here one fixed seed per case."""

import math

import numpy as np
import pytest
from scipy.signal import butter, lfilter, welch

from bmg160_emu.noise.output_response import find_output_stage, fit_fast_shape
from bmg160_emu.noise.resonant_bands import Resonance

RATE = 100.0
SAMPLES = 180_000
SEGMENT = 4096
N = 0.01


def _white(seed: int) -> np.ndarray:
    return np.random.default_rng(seed).standard_normal(SAMPLES + 2000) * N * math.sqrt(RATE)


def _psd(x: np.ndarray):
    f, s = welch(x - x.mean(), RATE, nperseg=SEGMENT)
    return f[1:], s[1:], (SAMPLES - SEGMENT) / (SEGMENT // 2) + 1


def _true_acf(b, a, lags: int = 5) -> np.ndarray:
    h = lfilter(b, a, np.r_[1.0, np.zeros(4000)])
    r = np.correlate(h, h, "full")[h.size - 1:]
    return r[1: lags + 1] / r[0]


def _acf(response, lags: int = 5) -> np.ndarray:
    r = np.r_[response.autocovariance(), np.zeros(lags + 1)]
    return r[1: lags + 1] / r[0]


FILTERS = {
    "none": ([1.0], [1.0]),
    "average of 4 samples": (np.ones(4) / 4.0, [1.0]),
    **{f"Butterworth {o} at 20 Hz": butter(o, 20.0 / (RATE / 2.0)) for o in (1, 2, 3, 4)},
}


@pytest.mark.parametrize("name", list(FILTERS))
def test_broadband_response_recovered(name):
    b, a = FILTERS[name]
    x = lfilter(b, a, _white(11))[2000:]
    f, s, segments = _psd(x)
    found = find_output_stage(f, s, segments, RATE)
    assert found.bands == [] and found.lines == []
    assert np.max(np.abs(_acf(found.response) - _true_acf(b, a))) < 0.03
    assert abs(found.N_psd / N - 1) < 0.07  # the level read at DC (the Allan fit decides N)
    whole, _level = fit_fast_shape(f, s, segments, RATE)
    assert np.max(np.abs(_acf(whole) - _true_acf(b, a))) < 0.03
    if name == "none":
        assert whole.order <= 2 and abs(whole.lag1) < 0.01


def test_resonant_band_recovered():
    rng = np.random.default_rng(12)
    truth = Resonance(15.0, 1.0, 0.06)
    g, a1, a2 = truth.coefficients(RATE)
    band = lfilter([g], [1.0, -a1, -a2], rng.standard_normal(SAMPLES + 5000))[5000:]
    f, s, segments = _psd(_white(12)[2000:] + band)
    found = find_output_stage(f, s, segments, RATE)
    assert len(found.bands) == 1 and found.lines == []
    band_found = found.bands[0]
    assert abs(band_found.centre_hz - 15.0) < 0.1
    assert abs(band_found.width_hz / 1.0 - 1) < 0.25
    assert abs(band_found.power / truth.power - 1) < 0.25
    assert band_found.power_half > 0 and band_found.centre_half > 0
    # the resonators that draw it hold its power
    assert abs(sum(r.power for r in band_found.resonances) / band_found.power - 1) < 0.3


def test_line_recovered_and_not_a_band():
    t = np.arange(SAMPLES) / RATE
    x = _white(13)[2000:] + 0.02 * np.sin(2 * np.pi * 7.3 * t + 1.0)
    f, s, segments = _psd(x)
    found = find_output_stage(f, s, segments, RATE)
    assert found.bands == [] and len(found.lines) == 1
    amplitude, frequency, half = found.lines[0]
    assert abs(amplitude / 0.02 - 1) < 0.1 and abs(frequency - 7.3) < 0.01
    assert 0 < half < amplitude


def test_minimum_phase_fir_reproduces_the_shape():
    from bmg160_emu.noise.output_response import OutputResponse

    b, a = FILTERS["Butterworth 2 at 20 Hz"]
    r = np.r_[_true_acf(b, a, 30)]
    cosine = np.r_[1.0, r] / (1.0 + 2.0 * r.sum())
    response = OutputResponse(RATE, tuple(cosine))
    h = response.taps
    assert abs(h.sum() - 1.0) < 1e-12
    got = np.correlate(h, h, "full")[h.size - 1:]
    assert np.allclose(got[1:6] / got[0], r[:5], atol=1e-3)
